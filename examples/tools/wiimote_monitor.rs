//! Terminal monitor for every motion controller — Wii Remotes, DualSense, DualShock 4, Switch
//! Pro, Joy-Con: lists them, shows live orientation, buttons, battery and calibration state.
//! `--emulate` runs the same against a software emulator (`--device` picks which).
//!
//! ```text
//! cargo run --release --example wiimote_monitor [-- --emulate [--device dualsense]] [--seconds 30] [--filter ours|vqf|paper|raw]
//! ```
//! On Linux, when a controller is listed but unusable (or none is), it prints why with the
//! exact fix: hidraw permissions → the udev rules to add; the hid-wiimote or hid-nintendo
//! kernel driver bound → the unbind line with the device's real HID id, or the blacklist
//! line; Steam's controller support holding a pad; busy; no answer.

use bevy_wii_deform_examples::cli;

use std::sync::Arc;
use std::time::{Duration, Instant};

use bevy_wii_deform::controllers::diagnosis::LinuxDevices;
use bevy_wii_deform::controllers::manager::{
    ControllerManager, ManagerConfig, ManagerEvent, RemoteId, RemoteSource,
};
use bevy_wii_deform::controllers::pads::PadEmulatorConfig;
use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
use bevy_wii_deform::controllers::wiimote::*;
use bevy_wii_deform::controllers::{ControllerKind, Link};

fn button_names(b: Buttons) -> String {
    let names = [
        (Buttons::A, "A"),
        (Buttons::B, "B"),
        (Buttons::ONE, "1"),
        (Buttons::TWO, "2"),
        (Buttons::PLUS, "+"),
        (Buttons::MINUS, "-"),
        (Buttons::HOME, "Home"),
        (Buttons::UP, "Up"),
        (Buttons::DOWN, "Down"),
        (Buttons::LEFT, "Left"),
        (Buttons::RIGHT, "Right"),
    ];
    let v: Vec<&str> = names
        .iter()
        .filter(|(m, _)| b.pressed(*m))
        .map(|(_, n)| *n)
        .collect();
    if v.is_empty() {
        "-".into()
    } else {
        v.join(" ")
    }
}

/// The emulator (with a scripted motion) or real remotes over hidapi, listing what hidapi
/// sees and, when it sees none, why (permissions, the kernel driver); `None` without hidapi.
fn remote_source(emulate: Option<ControllerKind>) -> Option<RemoteSource> {
    if let Some(kind) = emulate {
        let controls = EmulatorControls::default();
        controls.set_motion(Arc::new(DemoMotion));
        println!("Using the software emulator ({kind}, scripted motion).");
        let emulated = match kind {
            ControllerKind::WiiRemote => EmulatorConfig::default().into(),
            pad => PadEmulatorConfig::new(pad, Link::Bluetooth).into(),
        };
        return Some(RemoteSource::Emulated(vec![(emulated, controls)]));
    }
    #[cfg(feature = "hidapi")]
    {
        let pads = bevy_wii_deform::controllers::discover_pads().unwrap_or_default();
        for p in &pads {
            println!(
                "found {} over {} ({:?}) at {}",
                p.kind,
                p.link.name(),
                p.serial,
                p.path
            );
        }
        match discover() {
            Ok(list) if !list.is_empty() || !pads.is_empty() => {
                for d in &list {
                    println!(
                        "found {} (PID {:04X}) {:?} at {}",
                        d.product.as_deref().unwrap_or("?"),
                        d.product_id,
                        d.serial,
                        d.path
                    );
                }
            }
            Ok(_) => {
                println!(
                    "No motion controller visible through hidapi. Pair a Wii Remote with its red \
                     SYNC button, a pad with its pairing button, or plug it in."
                );
                for problem in LinuxDevices::system().diagnose_all() {
                    println!("- {problem}");
                }
            }
            Err(e) => println!("hidapi failed: {e}"),
        }
        Some(RemoteSource::Hid)
    }
    #[cfg(not(feature = "hidapi"))]
    {
        println!("built without the `hidapi` feature; use --emulate");
        None
    }
}

/// Prints the events that are news (connections, problems, extensions, IR dots).
fn print_event(event: &ManagerEvent) {
    match event {
        ManagerEvent::Connected { id, info } => println!(
            "remote {id} connected: {:?}, MotionPlus {:?} (calibration CRC {}), accel cal valid {}, battery {}",
            info.kind,
            info.motion_plus,
            if info.motion_plus_crc_ok {
                "ok"
            } else {
                "failed: fallback constants"
            },
            info.accel_calibration_valid,
            info.battery
        ),
        ManagerEvent::PadConnected { id, info } => println!(
            "controller {id} connected: {} over {}, {} calibration",
            info.kind,
            info.link.name(),
            if info.factory_calibration {
                "factory"
            } else {
                "datasheet (the unit's could not be read)"
            }
        ),
        ManagerEvent::Disconnected { id, reason } => {
            println!("remote {id} disconnected: {reason}")
        }
        ManagerEvent::Problem { id, problem } => match id {
            Some(id) => println!("remote {id} is unusable: {problem}"),
            None => println!("problem: {problem}"),
        },
        ManagerEvent::MotionPlus { id, state } => println!("remote {id}: MotionPlus {state:?}"),
        ManagerEvent::Extension { id, state } => println!("remote {id}: extension {state:?}"),
        ManagerEvent::Ir { id, dots, .. } => {
            let seen: Vec<String> = dots
                .iter()
                .flatten()
                .map(|d| format!("({}, {})", d.x, d.y))
                .collect();
            if !seen.is_empty() {
                println!("remote {id}: IR dots {}", seen.join(" "));
            }
        }
        ManagerEvent::Buttons { .. }
        | ManagerEvent::Battery { .. }
        | ManagerEvent::Orientation { .. }
        | ManagerEvent::Nunchuk { .. } => {}
    }
}

const USAGE: &str = "\
usage: wiimote_monitor [--emulate] [--device KIND] [--seconds S] [--filter fusion|paper|vqf|raw]

  --emulate    the built-in emulator instead of a real controller
  --device K   which one to emulate: wiimote (default), dualsense, dualsense-edge, ds4,
               switch-pro, joycon-l, joycon-r (joycon = joycon-r)
  --seconds S  how long to print samples (default 30)
  --filter F   the orientation filter (default fusion)";

fn main() {
    let (mut emulate, mut seconds, mut filter) = (false, 30.0f64, FilterKind::Fusion);
    let mut device = ControllerKind::WiiRemote;
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("emulate") => emulate = true,
            cli::Arg::Long("device") => {
                let name = cli::string(&mut parser, USAGE);
                device = ControllerKind::from_name(&name)
                    .unwrap_or_else(|| cli::fail(format!("unknown device {name:?}"), USAGE));
            }
            cli::Arg::Long("seconds") => seconds = cli::value(&mut parser, USAGE),
            cli::Arg::Long("filter") => {
                filter = match cli::string(&mut parser, USAGE).as_str() {
                    "paper" => FilterKind::Paper,
                    "raw" => FilterKind::Raw,
                    "vqf" => FilterKind::Vqf,
                    "fusion" => FilterKind::Fusion,
                    v => cli::fail(format!("unknown filter {v:?}"), USAGE),
                }
            }
            other => cli::unexpected(other, USAGE),
        }
    }
    let Some(source) = remote_source(emulate.then_some(device)) else {
        return;
    };
    let manager = ControllerManager::start(ManagerConfig {
        source,
        session: SessionConfig {
            filter,
            ..Default::default()
        },
        channel_capacity: 1024,
    });
    let start = Instant::now();
    let mut last_print = Instant::now();
    let mut latest: Option<(RemoteId, OrientationSample)> = None;
    let mut buttons = Buttons(0);
    let mut battery = 0u8;
    while start.elapsed().as_secs_f64() < seconds {
        while let Ok(e) = manager.events().recv_timeout(Duration::from_millis(20)) {
            match e {
                ManagerEvent::Buttons { buttons: b, .. } => buttons = b,
                ManagerEvent::Battery { level, .. } => battery = level,
                ManagerEvent::Orientation { id, sample } => latest = Some((id, sample)),
                other => print_event(&other),
            }
            if last_print.elapsed() > Duration::from_millis(250) {
                break;
            }
        }
        if last_print.elapsed() > Duration::from_millis(250) {
            last_print = Instant::now();
            if let Some((id, s)) = latest {
                let (z, x, y) = s.orientation.to_euler(glam::EulerRot::ZXY);
                println!(
                    "[{id}] yaw {:7.1}° pitch {:6.1}° roll {:6.1}° | |ω| {:6.1}°/s | still {} | calibration {:?} conf {:.2} | buttons {} | battery {}",
                    z.to_degrees(),
                    x.to_degrees(),
                    y.to_degrees(),
                    s.angular_velocity.length().to_degrees(),
                    s.still,
                    s.calibration.phase,
                    s.calibration.confidence,
                    button_names(buttons),
                    battery
                );
            }
        }
    }
}
