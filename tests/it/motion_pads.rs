//! The gyro pads' drivers: real captured reports, every emulated report kind, malformed
//! input, calibration, axes and the Switch's sample order.

use std::sync::Arc;

use bevy_wii_deform::controllers::pads::{
    EmulatedPad, PadDecoder, PadEmulatorConfig, PadSensorModel, PadSession,
};
use bevy_wii_deform::controllers::sony::{self, SonyCalibration};
use bevy_wii_deform::controllers::switch::{self, CalibrationSource, SwitchCalibration};
use bevy_wii_deform::controllers::transport::{Transport, TransportError};
use bevy_wii_deform::controllers::wiimote::{FilterKind, FnMotion, SessionConfig, SessionEvent};
use bevy_wii_deform::controllers::{ControllerKind, DecodeError, Link};
use glam::{DQuat, DVec3};

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

// A DualShock 4 (a third-party unit reporting VID 054C / PID 05C4) lying on a table, over
// USB, and its calibration feature report 0x02: recorded with hidapi by im-0's `ds4dump`
// (github.com/im-0/random-things, ds4dump/README.md). Device output, kept as the bytes the
// pad sent.
const DS4_USB_RESTING: &str = "01808080800800c40000260c00f0fff9ffeeffea00681f0e0500000000001b000000008000000080000000008000000080000000008000000080000000008000";
const DS4_USB_CALIBRATION: &str =
    "020000000000007d22dcdd7d22dcdd7d22dcdd1c021c02002000e0002000e0002000e00700";

// A DualSense's Bluetooth full report 0x31 (a pad lying still, buttons released), cut from an
// HCI trace of a real DualSense talking to a BlueRetro adapter (darthcloud/bt_traces,
// blueretro_logs/blueretro_v0.8_ps5_dualsense_inquiry_cfg_0x31.txt, its first input report 0x31;
// the `A1` header byte stripped as hidapi delivers it). Device output, one report.
const DUALSENSE_BT_REPORT: &str = "31217f807f8000000108000000c1c672880700fdfffdffa000761f85f75e035501008000000080000000000909000000000012145501040000979a894da9090e99000000000000000000eb58c020";

// A Switch Pro Controller's reply to an SPI read of its stick calibration (0x603D, 18 bytes)
// and one of its full reports 0x30 with the IMU off, from the same collection
// (blueretro_logs/sw_pro_trace.txt).
const SWITCH_PRO_SPI_REPLY: &str = "21234000000027687fcd277a0090103d60000012f56564e1477ff8d564b16779f0755fbc75620000000000000000000000";
const SWITCH_PRO_FULL_IMU_OFF: &str = "303e4000000027787fce277a00000000000000000000000000000000000000000000000000000000000000000000000000";

#[test]
fn a_real_dualsense_bluetooth_report_checks_its_crc_and_reads_one_g() {
    let report = hex(DUALSENSE_BT_REPORT);
    let decoder = PadDecoder::new(ControllerKind::DualSense, Link::Bluetooth).unwrap();
    let decoded = decoder.decode(&report).unwrap();
    assert_eq!(decoded.crc_ok, Some(true));
    let s = decoded.samples()[0];
    let g = s.accel_mps2.length() / 9.80665;
    // Datasheet scale (no calibration report in the trace): 1 g within 2 %.
    assert!((g - 1.0).abs() < 0.02, "|a| = {g} g");
    // Mostly along the face's normal (+Z in the body frame): it lies on a table, tilted.
    assert!(
        s.accel_mps2.z / s.accel_mps2.length() > 0.9,
        "{}",
        s.accel_mps2
    );
    assert!(s.gyro_rps.length().to_degrees() < 1.0);
    // The pad's clock: 0x0155035E ticks of 1/3 µs.
    assert!((s.device_time_s.unwrap() - 0x0155_035E as f64 / 3.0e6).abs() < 1e-12);
    assert_eq!(
        decoded.buttons,
        bevy_wii_deform::controllers::PadButtons {
            raw: 0x08,
            ..Default::default()
        }
    );
    // One bit off anywhere before the CRC and it no longer checks.
    let mut flipped = report.clone();
    flipped[30] ^= 0x01;
    assert_eq!(decoder.decode(&flipped).unwrap().crc_ok, Some(false));
}

#[test]
fn real_switch_pro_replies_and_reports_decode() {
    let reply = switch::parse_reply(&hex(SWITCH_PRO_SPI_REPLY)).unwrap();
    assert!(reply.ack);
    assert_eq!(reply.id, switch::SUB_SPI_READ);
    let data = switch::spi_data(&reply, 0x603D).unwrap();
    assert_eq!(data.len(), 18);
    assert_eq!(&data[..3], &[0xF5, 0x65, 0x64]);
    // Asked for another address, the reply does not fit.
    assert!(switch::spi_data(&reply, 0x6020).is_err());
    // A full report before the IMU is enabled: a typed "IMU off", not zero samples.
    let full = hex(SWITCH_PRO_FULL_IMU_OFF);
    let cal = SwitchCalibration::nominal();
    assert_eq!(
        switch::decode(ControllerKind::SwitchPro, &full, &cal),
        Err(DecodeError::ImuOff)
    );
}

#[test]
fn a_real_dualshock4_calibration_report_parses_as_linux_reads_it() {
    let report = hex(DS4_USB_CALIBRATION);
    let cal = SonyCalibration::parse(ControllerKind::DualShock4, Link::Usb, &report).unwrap();
    assert!(cal.is_factory(), "{cal:?}");
    // speed 540 + 540 over |8829| + |−8740| counts, on every axis.
    for a in 0..3 {
        assert!((cal.gyro_dps_per_count[a] - 1080.0 / 17569.0).abs() < 1e-12);
        // ±8192 about zero: 1/8192 g per count.
        assert!((cal.accel_g_per_count[a] - 1.0 / 8192.0).abs() < 1e-12);
        assert_eq!(cal.accel_zero[a], 0.0);
    }
    // The wrong layout (Bluetooth pairs) gives other numbers: the order is checked.
    let short = &report[..20];
    assert_eq!(
        SonyCalibration::parse(ControllerKind::DualShock4, Link::Usb, short),
        Err(DecodeError::Short {
            id: 0x02,
            len: 20,
            need: 37
        })
    );
}

#[test]
fn a_real_resting_dualshock4_reads_one_g_up() {
    let report = hex(DS4_USB_RESTING);
    let cal = SonyCalibration::parse(
        ControllerKind::DualShock4,
        Link::Usb,
        &hex(DS4_USB_CALIBRATION),
    )
    .unwrap();
    let decoded = sony::decode(ControllerKind::DualShock4, Link::Usb, &report, &cal).unwrap();
    assert_eq!(decoded.crc_ok, None);
    let s = decoded.samples()[0];
    let g = s.accel_mps2 / 9.80665;
    assert!((g.length() - 1.0).abs() < 0.02, "|a| = {} g", g.length());
    // Flat on the table: the body frame's +Z (out of the face) is up.
    assert!(g.z > 0.97, "{g}");
    // At rest the gyro reads its bias only: a few counts.
    assert!(s.gyro_rps.length().to_degrees() < 2.0);
    // On its cable, full.
    let battery = decoded.battery.unwrap();
    assert!(!battery.charging && battery.percent == 100, "{battery:?}");
    // Its sensor clock: 0x0C26 ticks of 16/3 µs.
    assert!((s.device_time_s.unwrap() - 3110.0 * 16.0 / 3.0e6).abs() < 1e-12);
}

/// Every kind and link, through its emulator and the session: the start sequence answers,
/// the calibration is the unit's, and every report decodes.
#[test]
fn every_emulated_pad_connects_and_streams_clean_reports() {
    for kind in [
        ControllerKind::DualSense,
        ControllerKind::DualSenseEdge,
        ControllerKind::DualShock4,
        ControllerKind::SwitchPro,
        ControllerKind::JoyConLeft,
        ControllerKind::JoyConRight,
    ] {
        for link in [Link::Usb, Link::Bluetooth] {
            let pad = EmulatedPad::new(PadEmulatorConfig::new(kind, link));
            let mut session = PadSession::new(pad, kind, link, SessionConfig::default());
            let info = session
                .connect()
                .unwrap_or_else(|e| panic!("{kind} {link:?}: {e}"));
            assert!(info.factory_calibration, "{kind} {link:?}: {info:?}");
            let mut samples = 0;
            for _ in 0..200 {
                session.poll(50).unwrap();
                samples += session
                    .drain_events()
                    .filter(|e| matches!(e, SessionEvent::Imu(_)))
                    .count();
            }
            assert_eq!(session.malformed_reports(), 0, "{kind} {link:?}");
            let expected = if switch::is_switch(kind) { 600 } else { 200 };
            assert_eq!(samples, expected, "{kind} {link:?}");
        }
    }
}

/// A transport that damages some reports: flips a byte, cuts one short, or changes its id.
struct Damaging<T> {
    inner: T,
    n: u32,
}

impl<T: Transport> Transport for Damaging<T> {
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
        self.inner.write(report)
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError> {
        let n = self.inner.read_timeout(buf, timeout_ms)?;
        if n < 20 {
            return Ok(n);
        }
        self.n += 1;
        Ok(match self.n % 10 {
            3 => {
                buf[20] ^= 0x40;
                n
            }
            5 => 9,
            7 => {
                buf[0] = 0x77;
                n
            }
            _ => n,
        })
    }
    fn now_us(&self) -> u64 {
        self.inner.now_us()
    }
    fn get_feature_report(&mut self, buf: &mut [u8]) -> Result<usize, TransportError> {
        self.inner.get_feature_report(buf)
    }
}

#[test]
fn damaged_reports_are_typed_errors_and_the_session_goes_on() {
    let kind = ControllerKind::DualSense;
    let pad = EmulatedPad::new(PadEmulatorConfig::new(kind, Link::Bluetooth));
    let mut session = PadSession::new(
        Damaging { inner: pad, n: 0 },
        kind,
        Link::Bluetooth,
        SessionConfig::default(),
    );
    session.connect().unwrap();
    let mut orientations = 0;
    for _ in 0..300 {
        session.poll(50).unwrap();
        orientations += session
            .drain_events()
            .filter(|e| matches!(e, SessionEvent::Orientation(_)))
            .count();
    }
    // 3 of every 10 damaged: a flipped bit (CRC), a short report, an unknown id.
    assert_eq!(session.malformed_reports(), 90);
    assert_eq!(orientations, 210);

    // The decoder names each.
    let decoder = PadDecoder::new(kind, Link::Bluetooth).unwrap();
    let mut good = Vec::new();
    let mut pad = EmulatedPad::new(PadEmulatorConfig::new(kind, Link::Bluetooth));
    let mut cal = vec![0u8; 64];
    cal[0] = 0x05;
    pad.get_feature_report(&mut cal).unwrap();
    good.resize(128, 0);
    let n = pad.read_timeout(&mut good, 50).unwrap();
    good.truncate(n);
    assert_eq!(decoder.decode(&good).unwrap().crc_ok, Some(true));
    let mut flipped = good.clone();
    flipped[20] ^= 1;
    assert_eq!(decoder.decode(&flipped).unwrap().crc_ok, Some(false));
    assert_eq!(
        decoder.decode(&flipped).and_then(|r| r.verified()),
        Err(DecodeError::Crc)
    );
    assert!(matches!(
        decoder.decode(&good[..40]),
        Err(DecodeError::Short { .. })
    ));
    assert!(matches!(
        decoder.decode(&[0x42, 1, 2]),
        Err(DecodeError::UnknownReport { id: 0x42, .. })
    ));
    assert_eq!(decoder.decode(&[]), Err(DecodeError::Empty));
    assert_eq!(
        decoder.decode(&[0x01, 0x80, 0x80]),
        Err(DecodeError::NoMotion { id: 0x01 })
    );
}

#[test]
fn a_disconnect_ends_the_session_with_a_typed_error() {
    let pad = EmulatedPad::new(PadEmulatorConfig::new(
        ControllerKind::SwitchPro,
        Link::Bluetooth,
    ));
    let controls = pad.controls();
    let mut session = PadSession::new(
        pad,
        ControllerKind::SwitchPro,
        Link::Bluetooth,
        SessionConfig::default(),
    );
    session.connect().unwrap();
    session.poll(50).unwrap();
    controls.set_connected(false);
    assert!(matches!(
        session.poll(50),
        Err(
            bevy_wii_deform::controllers::wiimote::SessionError::Transport(
                TransportError::Disconnected
            )
        )
    ));
}

#[test]
fn out_of_range_calibrations_fall_back_to_the_datasheet() {
    // A DualSense whose report is all zeros: every axis falls back.
    let mut report = vec![0u8; 41];
    report[0] = 0x05;
    let cal = SonyCalibration::parse(ControllerKind::DualSense, Link::Usb, &report).unwrap();
    assert!(cal.fallback_axes.iter().all(|&f| f));
    assert_eq!(
        cal.gyro_dps_per_count,
        SonyCalibration::nominal().gyro_dps_per_count
    );
    // Over Bluetooth the same bytes fail their CRC.
    assert_eq!(
        SonyCalibration::parse(ControllerKind::DualSense, Link::Bluetooth, &report),
        Err(DecodeError::Crc)
    );
    // Erased Switch flash (0xFF): −1 everywhere, no divisor.
    let cal = SwitchCalibration::from_block(&[0xFF; 24], CalibrationSource::Factory).unwrap();
    assert!(cal.fallback_axes.iter().all(|&f| f));
    assert_eq!(cal.gyro_divisor, SwitchCalibration::nominal().gyro_divisor);
}

/// Turns an emulated pad `degrees` about body axis `axis`, smoothly over 2 s after 1 s at rest,
/// and returns the rotation the session measured (body frame, start to end).
fn measured_turn(
    kind: ControllerKind,
    link: Link,
    axis: DVec3,
    degrees: f64,
    reversed: Option<usize>,
) -> DQuat {
    let mut config = PadEmulatorConfig::new(kind, link);
    config.sensors = PadSensorModel {
        gyro_turn_on_bias_dps: 0.0,
        gyro_bias_walk_dps: 0.0,
        reversed_axis: reversed,
        ..config.sensors
    };
    config.seed = 7;
    let pad = EmulatedPad::new(config);
    let angle = degrees.to_radians();
    pad.controls().set_motion(Arc::new(FnMotion(move |t: f64| {
        let u = ((t - 1.0) / 2.0).clamp(0.0, 1.0);
        let s = u * u * (3.0 - 2.0 * u);
        (DQuat::from_axis_angle(axis, angle * s), DVec3::ZERO)
    })));
    let session_config = SessionConfig {
        filter: FilterKind::Fusion,
        ..SessionConfig::default()
    };
    let mut session = PadSession::new(pad, kind, link, session_config);
    session.connect().unwrap();
    let at = |session: &mut PadSession<EmulatedPad>, t_us: u64| {
        let mut last = None;
        while session.transport().now_us() < t_us {
            session.poll(50).unwrap();
            for e in session.drain_events() {
                if let SessionEvent::Orientation(o) = e {
                    last = Some(o.orientation);
                }
            }
        }
        last.unwrap()
    };
    let start = at(&mut session, 900_000);
    let end = at(&mut session, 3_500_000);
    start.inverse() * end
}

#[test]
fn turning_a_pad_40_degrees_turns_it_40_degrees_about_the_same_axis() {
    for (kind, link) in [
        (ControllerKind::DualSense, Link::Bluetooth),
        (ControllerKind::SwitchPro, Link::Bluetooth),
        (ControllerKind::JoyConRight, Link::Bluetooth),
        (ControllerKind::DualShock4, Link::Usb),
    ] {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let turn = measured_turn(kind, link, axis, 40.0, None);
            let (got_axis, got) = turn.to_axis_angle();
            assert!(
                (got.to_degrees() - 40.0).abs() < 1.0 && got_axis.dot(axis) > 0.99,
                "{kind} about {axis}: {:.2}° about {got_axis}",
                got.to_degrees()
            );
        }
    }
    // A unit with a reversed axis turns the other way: the check catches it.
    let turn = measured_turn(
        ControllerKind::DualSense,
        Link::Usb,
        DVec3::Z,
        40.0,
        Some(2),
    );
    let (got_axis, got) = turn.to_axis_angle();
    assert!(!((got.to_degrees() - 40.0).abs() < 1.0 && got_axis.dot(DVec3::Z) > 0.99));
}

/// The Switch's three samples per report come oldest first: under a rate that grows with
/// time, each sample matches the true rate at the instant the session gives it, and the
/// samples within a report rise. Reading them newest first would make them fall.
#[test]
fn the_switch_samples_are_integrated_oldest_first() {
    let kind = ControllerKind::SwitchPro;
    let mut config = PadEmulatorConfig::new(kind, Link::Bluetooth);
    config.sensors = PadSensorModel {
        gyro_noise_dps: 0.0,
        gyro_turn_on_bias_dps: 0.0,
        gyro_bias_walk_dps: 0.0,
        ..config.sensors
    };
    let pad = EmulatedPad::new(config);
    // Yaw rate 100·t deg/s: angle 50·t² degrees.
    pad.controls().set_motion(Arc::new(FnMotion(|t: f64| {
        (
            DQuat::from_rotation_z((50.0 * t * t).to_radians()),
            DVec3::ZERO,
        )
    })));
    let mut session = PadSession::new(pad, kind, Link::Bluetooth, SessionConfig::default());
    session.connect().unwrap();
    let mut checked = 0;
    while session.transport().now_us() < 1_500_000 {
        session.poll(50).unwrap();
        let rates: Vec<(f64, f64)> = session
            .drain_events()
            .filter_map(|e| match e {
                SessionEvent::Imu(s) => Some((s.timestamp_us as f64 * 1e-6, s.gyro_dps.unwrap().z)),
                _ => None,
            })
            .collect();
        if rates.len() == 3 && rates[0].0 > 0.3 {
            assert!(
                rates[0].1 < rates[1].1 && rates[1].1 < rates[2].1,
                "{rates:?}"
            );
            for (t, rate) in rates {
                // 0.3 deg/s: a sample 5 ms off would read 0.5 deg/s off.
                assert!(
                    (rate - 100.0 * t).abs() < 0.3,
                    "at {t}: {rate} vs {}",
                    100.0 * t
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 200, "{checked}");
}

/// Every pad carries the controls' buttons: the roles, and the d-pad and +/− that move a
/// handle (not on a Joy-Con held alone, whose arrows are face buttons or absent).
#[test]
fn the_controls_buttons_cross_every_pad() {
    use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
    let held = Buttons::B
        | Buttons::A
        | Buttons::HOME
        | Buttons::ONE
        | Buttons::UP
        | Buttons::RIGHT
        | Buttons::PLUS;
    for kind in [
        ControllerKind::DualSense,
        ControllerKind::DualShock4,
        ControllerKind::SwitchPro,
        ControllerKind::JoyConLeft,
        ControllerKind::JoyConRight,
    ] {
        let pad = EmulatedPad::new(PadEmulatorConfig::new(kind, Link::Bluetooth));
        pad.controls().set_buttons(Buttons(held));
        let mut session = PadSession::new(pad, kind, Link::Bluetooth, SessionConfig::default());
        session.connect().unwrap();
        let mut seen = None;
        for _ in 0..20 {
            session.poll(50).unwrap();
            for e in session.drain_events() {
                if let SessionEvent::Buttons { buttons, .. } = e {
                    seen = Some(buttons.0);
                }
            }
        }
        let expected = match kind {
            ControllerKind::JoyConLeft | ControllerKind::JoyConRight => {
                held & !(Buttons::UP | Buttons::RIGHT)
            }
            _ => held,
        };
        assert_eq!(seen, Some(expected), "{kind}");
    }
}

/// After the start sequence a Sony pad shows the player (lights, colour); a rumble command
/// drives its motors; over Bluetooth every output report carries a CRC the pad checks.
#[test]
fn sony_output_reports_light_the_player_and_rumble_with_a_crc() {
    for (kind, link) in [
        (ControllerKind::DualSense, Link::Bluetooth),
        (ControllerKind::DualSense, Link::Usb),
        (ControllerKind::DualShock4, Link::Bluetooth),
        (ControllerKind::DualShock4, Link::Usb),
    ] {
        let pad = EmulatedPad::new(PadEmulatorConfig::new(kind, link));
        let config = SessionConfig {
            player: 2,
            ..SessionConfig::default()
        };
        let mut session = PadSession::new(pad, kind, link, config);
        session.connect().unwrap();
        let shown = session.transport().last_output().expect("an output report");
        assert_eq!(
            shown.lightbar,
            sony::player_output(2).lightbar,
            "{kind} {link:?}"
        );
        if kind == ControllerKind::DualSense {
            assert_eq!(shown.player_lights, 0b01010);
        }
        assert_eq!((shown.strong_motor, shown.weak_motor), (0, 0));
        session.set_rumble(true).unwrap();
        let rumbling = session.transport().last_output().unwrap();
        assert!(
            rumbling.strong_motor > 0 && rumbling.weak_motor > 0,
            "{kind} {link:?}"
        );
        session.set_rumble(false).unwrap();
        assert_eq!(session.transport().last_output().unwrap().strong_motor, 0);
        assert_eq!(session.transport().refused_outputs(), 0);
    }
    // A Bluetooth output report with a wrong CRC is refused, and says why.
    let mut report = sony::output_report(
        ControllerKind::DualSense,
        Link::Bluetooth,
        1,
        &sony::player_output(1),
    );
    assert!(sony::parse_output(ControllerKind::DualSense, Link::Bluetooth, &report).is_ok());
    report[10] ^= 0x01;
    assert_eq!(
        sony::parse_output(ControllerKind::DualSense, Link::Bluetooth, &report),
        Err(DecodeError::Crc)
    );
    let mut pad = EmulatedPad::new(PadEmulatorConfig::new(
        ControllerKind::DualSense,
        Link::Bluetooth,
    ));
    pad.write(&report).unwrap();
    assert_eq!(pad.refused_outputs(), 1);
    assert_eq!(pad.last_output(), None);
}
