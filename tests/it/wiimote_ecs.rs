//! Two emulated Wii Remotes in one app, paced by the app's clock: each turns only its own
//! handle, and Home recentres only the remote it is pressed on.

use std::sync::Arc;
use std::time::Duration;

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;
use bevy_wii_deform::wiimote::protocol::Buttons;
use bevy_wii_deform::wiimote::{EmulatorClock, FnMotion, Still};
use glam::{DQuat, DVec3};

use crate::common::{self, app};

/// Two emulated remotes sharing the app's clock (10 ms per update), connected and
/// calibrated; a handle for each (a plain `Transform` entity) controlled by that remote.
/// Returns the app, the remotes' entities and controls (in emulator order), the handles.
fn two_remotes() -> (App, [Entity; 2], [EmulatorControls; 2], [Entity; 2]) {
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    let clock = EmulatorClock::new();
    let config = || EmulatorConfig {
        clock: Some(clock.clone()),
        ..default()
    };
    app.add_plugins((
        WiimotePlugin {
            source: WiimoteSource::Emulator(vec![config(), config()]),
            ..default()
        },
        WiimoteControlPlugin,
    ));
    let controls = app.world().resource::<WiimoteEmulators>().0.clone();
    for c in &controls {
        c.set_motion(Arc::new(Still(DQuat::IDENTITY)));
    }
    common::update_until(&mut app, "two calibrated remotes", |a| {
        let mut q = a.world_mut().query::<&Wiimote>();
        q.iter(a.world())
            .filter(|w| {
                w.connection == ConnectionState::Connected
                    && matches!(w.calibration, WiimoteCalibration::Calibrated(_))
            })
            .count()
            == 2
    });
    // Which entity is which emulator: yaw the first emulator and see which remote turns.
    let remotes: Vec<(Entity, u32)> = {
        let mut q = app.world_mut().query::<(Entity, &Wiimote)>();
        let mut v: Vec<(Entity, u32)> = q.iter(app.world()).map(|(e, w)| (e, w.id)).collect();
        v.sort_by_key(|r| r.1);
        v
    };
    let remotes = [remotes[0].0, remotes[1].0];
    let handles = remotes.map(|remote| {
        app.world_mut()
            .spawn((
                Transform::default(),
                WiimoteHandleControl::default().with_remote(remote),
            ))
            .id()
    });
    (
        app,
        remotes,
        [controls[0].clone(), controls[1].clone()],
        handles,
    )
}

/// The remote's time now, seconds.
fn remote_time(app: &App, remote: Entity) -> f64 {
    app.world().get::<Wiimote>(remote).unwrap().timestamp_us as f64 * 1e-6
}

/// Steps until both remotes have delivered samples up to `t` seconds.
fn run_until(app: &mut App, remotes: [Entity; 2], t: f64) {
    common::update_until(app, "the remotes' samples", |a| {
        remotes.iter().all(|&r| remote_time(a, r) >= t)
    });
    app.update();
}

/// Steps for `seconds` of the remotes' time.
fn run_for(app: &mut App, remotes: [Entity; 2], seconds: f64) {
    let t = remote_time(app, remotes[0]) + seconds;
    run_until(app, remotes, t);
}

/// A yaw of `degrees` over one second from `t0` (about the remote's top axis).
fn yaw_from(t0: f64, degrees: f64) -> Arc<FnMotion<impl Fn(f64) -> (DQuat, DVec3) + Send + Sync>> {
    Arc::new(FnMotion(move |t: f64| {
        let s = (t - t0).clamp(0.0, 1.0);
        (
            DQuat::from_rotation_z((s * degrees).to_radians()),
            DVec3::ZERO,
        )
    }))
}

fn yaw_degrees(q: Quat) -> f32 {
    let (axis, angle) = q.to_axis_angle();
    angle.to_degrees() * axis.y.signum()
}

/// Which emulator drives which entity: the one whose orientation follows emulator 0's yaw.
fn emulator_order(
    app: &mut App,
    remotes: [Entity; 2],
    controls: &[EmulatorControls; 2],
) -> [usize; 2] {
    let t0 = remote_time(app, remotes[0]) + 0.05;
    controls[0].set_motion(yaw_from(t0, 20.0));
    run_until(app, remotes, t0 + 1.2);
    let turned = |e: Entity| yaw_degrees(app.world().get::<Wiimote>(e).unwrap().orientation).abs();
    if turned(remotes[0]) > turned(remotes[1]) {
        [0, 1]
    } else {
        [1, 0]
    }
}

#[test]
fn two_remotes_each_turn_only_their_own_handle() {
    let (mut app, remotes, controls, handles) = two_remotes();
    let order = emulator_order(&mut app, remotes, &controls);
    let (first, second) = (&controls[order[0]], &controls[order[1]]);
    // Both hold B; only the first turns, 40° more.
    first.set_buttons(Buttons(Buttons::B));
    second.set_buttons(Buttons(Buttons::B));
    run_for(&mut app, remotes, 0.1);
    let t0 = remote_time(&app, remotes[0]) + 0.05;
    first.set_motion(Arc::new(FnMotion(move |t: f64| {
        let s = (t - t0).clamp(0.0, 1.0);
        (
            DQuat::from_rotation_z((20.0 + s * 40.0f64).to_radians()),
            DVec3::ZERO,
        )
    })));
    run_until(&mut app, remotes, t0 + 1.5);
    let turned = |app: &App, h: Entity| {
        app.world()
            .get::<Transform>(h)
            .unwrap()
            .rotation
            .to_axis_angle()
            .1
            .to_degrees()
    };
    let (a, b) = (turned(&app, handles[0]), turned(&app, handles[1]));
    assert!(
        (a - 40.0).abs() < 1.0,
        "the first handle turned {a}° for 40°"
    );
    assert!(
        b < 0.5,
        "the second handle turned {b}° with its remote still"
    );
}

#[test]
fn home_recentres_only_the_remote_it_is_pressed_on() {
    let (mut app, remotes, controls, _) = two_remotes();
    let order = emulator_order(&mut app, remotes, &controls);
    // Both remotes yawed 20° (emulator 0 by `emulator_order`, emulator 1 now).
    let t0 = remote_time(&app, remotes[0]) + 0.05;
    controls[1].set_motion(yaw_from(t0, 20.0));
    run_until(&mut app, remotes, t0 + 1.2);
    let yaw =
        |app: &App, e: Entity| yaw_degrees(app.world().get::<Wiimote>(e).unwrap().orientation);
    // (The 6-axis filter reads a yaw within ~2° of the emulated one.)
    assert!((yaw(&app, remotes[0]).abs() - 20.0).abs() < 2.5);
    assert!((yaw(&app, remotes[1]).abs() - 20.0).abs() < 2.5);
    let other_before = app.world().get::<Wiimote>(remotes[1]).unwrap().orientation;
    // Home on the first: it reads identity from here, the second keeps its 20°.
    controls[order[0]].set_buttons(Buttons(Buttons::HOME));
    run_for(&mut app, remotes, 0.2);
    controls[order[0]].set_buttons(Buttons(0));
    run_for(&mut app, remotes, 0.2);
    let after = app.world().get::<Wiimote>(remotes[0]).unwrap().orientation;
    assert!(
        after.angle_between(Quat::IDENTITY).to_degrees() < 1.0,
        "the recentred remote reads {}°",
        after.angle_between(Quat::IDENTITY).to_degrees()
    );
    let other = app.world().get::<Wiimote>(remotes[1]).unwrap().orientation;
    assert!(
        other.angle_between(other_before).to_degrees() < 0.5,
        "Home moved the other remote by {}°",
        other.angle_between(other_before).to_degrees()
    );
    // Turning on from the recentre: 30° more reads 30°.
    let t1 = remote_time(&app, remotes[0]) + 0.05;
    controls[order[0]].set_motion(Arc::new(FnMotion(move |t: f64| {
        let s = (t - t1).clamp(0.0, 1.0);
        (
            DQuat::from_rotation_z((20.0 + s * 30.0f64).to_radians()),
            DVec3::ZERO,
        )
    })));
    run_until(&mut app, remotes, t1 + 1.2);
    let now = yaw(&app, remotes[0]).abs();
    assert!(
        (now - 30.0).abs() < 1.5,
        "30° after the recentre reads {now}°"
    );
}
