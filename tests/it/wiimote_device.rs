//! Device-layer integration tests: real captured bytes, the emulator driven by the session
//! (failure cases included), filters against ground truth.

use std::sync::Arc;

use crate::common::shared;

use bevy_wii_deform::controllers::diagnosis::{self, LinuxDevices, OpenErrorKind, RemoteProblem};
use bevy_wii_deform::controllers::wiimote::protocol::*;
use bevy_wii_deform::controllers::wiimote::*;
use bevy_wii_deform_examples::drift;
use glam::{DQuat, DVec3};
use proptest::prelude::*;

/// The captured fixtures: `None` when absent outside CI; a file that does not read or parse
/// fails.
fn fixtures() -> Option<serde_json::Value> {
    let path = shared::shared_asset("wiimote/captures/fixtures.json")?;
    let text = std::fs::read_to_string(&path).expect("fixtures.json reads");
    Some(serde_json::from_str(&text).expect("fixtures.json parses"))
}

fn hex(v: &serde_json::Value) -> Vec<u8> {
    parse_hex(v.as_str().unwrap()).unwrap()
}

/// A MotionPlus calibration block: parsed, its CRC, each range, re-encoded byte for byte.
fn check_mplus_calibration(item: &serde_json::Value, e: &serde_json::Value) {
    let bytes = hex(&item["hex"]);
    let (cal, ok) = MotionPlusCalibration::parse(&bytes).unwrap();
    assert_eq!(ok, e["crc_ok"].as_bool().unwrap());
    let crc = u32::from_str_radix(
        e["crc32_computed"]
            .as_str()
            .unwrap()
            .trim_start_matches("0x"),
        16,
    )
    .unwrap();
    assert_eq!(MotionPlusCalibration::crc(&bytes), crc);
    for (range, name) in [(&cal.fast, "fast"), (&cal.slow, "slow")] {
        let x = &e[name];
        assert_eq!(range.zero[0] as u64, x["yaw_zero16"].as_u64().unwrap());
        assert_eq!(range.zero[1] as u64, x["roll_zero16"].as_u64().unwrap());
        assert_eq!(range.zero[2] as u64, x["pitch_zero16"].as_u64().unwrap());
        assert_eq!(range.scale[0] as u64, x["yaw_scale16"].as_u64().unwrap());
        assert_eq!(range.scale[1] as u64, x["roll_scale16"].as_u64().unwrap());
        assert_eq!(range.scale[2] as u64, x["pitch_scale16"].as_u64().unwrap());
        assert_eq!(range.degrees as u64, x["degrees"].as_u64().unwrap());
        assert_eq!(range.uid as u64, x["uid"].as_u64().unwrap());
    }
    // Re-encoding reproduces the bytes exactly (CRC included).
    assert_eq!(cal.encode().to_vec(), bytes);
}

/// An accelerometer calibration block from the EEPROM.
fn check_accel_calibration(item: &serde_json::Value, e: &serde_json::Value) {
    let c = AccelCalibration::parse(&hex(&item["hex"])).unwrap();
    let z: Vec<u16> = e["zero_g"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u16)
        .collect();
    let o: Vec<u16> = e["one_g"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u16)
        .collect();
    assert_eq!(c.zero.to_vec(), z);
    assert_eq!(c.one_g.to_vec(), o);
}

/// A memory read reply (0x21): size, error, data, and what the data decodes to.
fn check_read_reply(item: &serde_json::Value, e: &serde_json::Value) {
    let InputReport::ReadReply(r) = InputReport::decode(&hex(&item["hex"])).unwrap() else {
        panic!()
    };
    assert_eq!(r.data.len() as u64, e["size"].as_u64().unwrap());
    assert_eq!(r.error as u64, e["error"].as_u64().unwrap());
    if let Some(d) = e.get("data") {
        assert_eq!(r.data, hex(d));
        let c = AccelCalibration::parse(
            &[
                &r.data[..],
                &[
                    0x40,
                    AccelCalibration::checksum(&[&r.data[..], &[0x40]].concat()),
                ],
            ]
            .concat(),
        );
        let c = c.unwrap();
        assert_eq!(c.zero[0] as u64, e["zero_g"][0].as_u64().unwrap());
        assert_eq!(c.one_g[2] as u64, e["one_g"][2].as_u64().unwrap());
    }
    if let Some(id) = e.get("id") {
        assert_eq!(r.data, hex(id));
        assert!(matches!(
            ExtensionId::parse(&r.data),
            ExtensionId::MotionPlus {
                active: false,
                mode: 5
            }
        ));
    }
}

/// An acknowledgement (0x22): the report it acknowledges and its error.
fn check_ack(item: &serde_json::Value, e: &serde_json::Value) {
    let InputReport::Ack { report, error, .. } = InputReport::decode(&hex(&item["hex"])).unwrap()
    else {
        panic!()
    };
    let want = u8::from_str_radix(
        e["acked_report"].as_str().unwrap().trim_start_matches("0x"),
        16,
    )
    .unwrap();
    assert_eq!(report, want);
    assert_eq!(error as u64, e["error"].as_u64().unwrap());
}

/// A status report (0x20).
fn check_status(item: &serde_json::Value, e: &serde_json::Value) {
    let InputReport::Status(s) = InputReport::decode(&hex(&item["hex"])).unwrap() else {
        panic!()
    };
    assert_eq!(
        s.extension_connected,
        e["extension_connected"].as_bool().unwrap()
    );
    assert_eq!(s.battery_low, e["battery_low"].as_bool().unwrap());
    assert_eq!(s.leds as u64, e["leds"].as_u64().unwrap());
    assert_eq!(s.battery as u64, e["battery"].as_u64().unwrap());
}

/// A data report (0x31, 0x35): the accelerometer and the MotionPlus frame in deg/s.
fn check_data_report(item: &serde_json::Value, e: &serde_json::Value, f: &serde_json::Value) {
    let InputReport::Data {
        accel, extension, ..
    } = InputReport::decode(&hex(&item["hex"])).unwrap()
    else {
        panic!()
    };
    let want: Vec<u16> = e["accel_raw"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u16)
        .collect();
    assert_eq!(accel.unwrap().0.to_vec(), want);
    if let Some(m) = e.get("mplus") {
        let ExtensionData::MotionPlus(fr) = classify_extension(&extension.unwrap(), true) else {
            panic!()
        };
        assert_eq!(fr.yaw as u64, m["yaw"].as_u64().unwrap());
        assert_eq!(fr.roll as u64, m["roll"].as_u64().unwrap());
        assert_eq!(fr.pitch as u64, m["pitch"].as_u64().unwrap());
        let cal_hex = &f["captured"][0]["hex"];
        let (cal, _) = MotionPlusCalibration::parse(&hex(cal_hex)).unwrap();
        let r = cal.rates_deg(&fr);
        let d = &e["deg_per_s_right_hand_using_mplus_cal_unit1_slow"];
        assert!((r.x - d["x_pitch"].as_f64().unwrap()).abs() < 0.01, "{r}");
        assert!((r.y - d["y_roll"].as_f64().unwrap()).abs() < 0.01, "{r}");
        assert!((r.z - d["z_yaw"].as_f64().unwrap()).abs() < 0.01, "{r}");
    }
}

/// Output reports encode to the captured bytes.
fn check_output_reports(item: &serde_json::Value) {
    let items = item["items"].as_object().unwrap();
    let enc = |r: OutputReport| r.encode();
    assert_eq!(
        enc(OutputReport::Leds {
            leds: 1,
            ack: true,
            rumble: false
        }),
        hex(&items["leds1_ack"])
    );
    assert_eq!(
        enc(OutputReport::ReportMode {
            mode: 0x35,
            continuous: true,
            ack: true,
            rumble: false
        }),
        hex(&items["mode_0x35_continuous_ack"])
    );
    assert_eq!(
        enc(OutputReport::StatusRequest { rumble: false }),
        hex(&items["status_request"])
    );
    assert_eq!(
        enc(OutputReport::ReadMemory {
            space: AddressSpace::Eeprom,
            address: 0x16,
            size: 10,
            rumble: false
        }),
        hex(&items["read_accel_cal_10B"])
    );
    assert_eq!(
        enc(OutputReport::write_register(0xA400F0, 0x55, false)),
        hex(&items["ext_init_1"])
    );
    assert_eq!(
        enc(OutputReport::write_register(0xA400FB, 0x00, false)),
        hex(&items["ext_init_2"])
    );
    assert_eq!(
        enc(OutputReport::write_register(0xA600F0, 0x55, false)),
        hex(&items["mplus_init"])
    );
    assert_eq!(
        enc(OutputReport::read_register(0xA600FA, 6, false)),
        hex(&items["mplus_read_id"])
    );
    assert_eq!(
        enc(OutputReport::write_register(0xA600FE, 0x04, false)),
        hex(&items["mplus_activate_0x04"])
    );
    assert_eq!(
        enc(OutputReport::read_register(0xA400FA, 6, false)),
        hex(&items["active_id_read"])
    );
    assert_eq!(
        enc(OutputReport::read_register(0xA40020, 32, false)),
        hex(&items["mplus_cal_read_active"])
    );
    assert_eq!(
        enc(OutputReport::write_register(0xA400F0, 0x55, false)),
        hex(&items["mplus_deactivate"])
    );
}

#[test]
fn captured_and_synthetic_fixtures_decode() {
    let Some(f) = fixtures() else {
        return;
    };
    let mut checked = 0;
    for item in f["captured"]
        .as_array()
        .unwrap()
        .iter()
        .chain(f["synthetic"].as_array().unwrap())
    {
        let kind = item["kind"].as_str().unwrap();
        let e = &item["expect"];
        match kind {
            "mplus_calibration_32B" => check_mplus_calibration(item, e),
            "eeprom_accel_calibration_10B" => check_accel_calibration(item, e),
            "input_report_0x21" => check_read_reply(item, e),
            "input_report_0x22" => check_ack(item, e),
            "input_report_0x20" => check_status(item, e),
            "input_report_0x35" | "input_report_0x31" => check_data_report(item, e, &f),
            "output_reports" => check_output_reports(item),
            other => panic!("unhandled fixture kind {other}"),
        }
        checked += 1;
    }
    assert!(checked >= 12, "only {checked} fixtures checked");
}

proptest! {
    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
        let _ = InputReport::decode(&bytes);
        let _ = OutputReport::decode(&bytes);
        let _ = MotionPlusCalibration::parse(&bytes);
        let _ = AccelCalibration::parse(&bytes);
        let _ = ExtensionId::parse(&bytes);
    }

    #[test]
    fn random_reports_with_valid_ids_never_panic(id in prop_oneof![Just(0x20u8), Just(0x21), Just(0x22), 0x30u8..=0x3F], tail in proptest::collection::vec(any::<u8>(), 0..30)) {
        let mut b = vec![id];
        b.extend(tail);
        if let Ok(InputReport::Data { extension: Some(e), .. }) = InputReport::decode(&b) {
            let _ = classify_extension(&e, true);
            let _ = classify_extension(&e, false);
        }
    }

    #[test]
    fn session_survives_garbage_from_the_device(seed in any::<u64>()) {
        // A transport that answers with random bytes: connect must fail cleanly.
        struct Garbage(bevy_wii_deform::controllers::wiimote::Rng, u64);
        impl Transport for Garbage {
            fn write(&mut self, r: &[u8]) -> Result<usize, TransportError> { Ok(r.len()) }
            fn read_timeout(&mut self, buf: &mut [u8], ms: u32) -> Result<usize, TransportError> {
                self.1 += ms as u64 * 1000;
                let n = (self.0.next_u64() % 23) as usize;
                for b in buf.iter_mut().take(n) { *b = self.0.next_u64() as u8; }
                Ok(n.min(buf.len()))
            }
            fn now_us(&self) -> u64 { self.1 }
        }
        let mut s = Session::new(Garbage(bevy_wii_deform::controllers::wiimote::Rng::new(seed), 0), SessionConfig { retries: 0, command_timeout_ms: 30, ..Default::default() });
        // Random bytes never make a Wii Remote: connecting fails with a typed error, and
        // polling afterwards neither panics nor reports a connection.
        prop_assert!(s.connect().is_err(), "garbage connected");
        for _ in 0..20 { let _ = s.poll(5); }
    }
}

fn connect(config: EmulatorConfig) -> Session<EmulatedRemote> {
    let mut s = Session::new(EmulatedRemote::new(config), SessionConfig::default());
    s.connect().expect("handshake");
    s
}

#[test]
fn handshake_activates_motion_plus_and_reads_calibration() {
    for variant in [Variant::Plus, Variant::Original { motion_plus: true }] {
        let emu = EmulatedRemote::new(EmulatorConfig {
            variant,
            ..Default::default()
        });
        let expected_cal = emu.motion_plus_calibration();
        let expected_accel = emu.accel_calibration();
        let mut s = Session::new(emu, SessionConfig::default());
        let info = s.connect().unwrap();
        assert_eq!(info.motion_plus, MotionPlusState::Active, "{variant:?}");
        assert!(info.motion_plus_crc_ok);
        assert_eq!(info.motion_plus_calibration, Some(expected_cal));
        assert_eq!(info.accel_calibration, expected_accel);
        assert!(info.accel_calibration_valid);
        assert_eq!(
            info.kind,
            if variant == Variant::Plus {
                RemoteKind::Plus
            } else {
                RemoteKind::Original
            }
        );
        assert!(s.transport().motion_plus_active());
        assert_eq!(s.transport().leds(), 0b0001);
        assert_eq!(s.transport().reporting(), (0x35, true, true));
    }
}

#[test]
fn original_without_motion_plus_gives_accelerometer_only() {
    let mut s = connect(EmulatorConfig {
        variant: Variant::Original { motion_plus: false },
        ..Default::default()
    });
    assert_eq!(s.motion_plus_state(), MotionPlusState::Absent);
    for _ in 0..50 {
        s.poll(20).unwrap();
    }
    let samples: Vec<_> = s
        .drain_events()
        .filter_map(|e| match e {
            SessionEvent::Imu(i) => Some(i),
            _ => None,
        })
        .collect();
    assert!(samples.len() > 20);
    assert!(samples.iter().all(|i| i.gyro_dps.is_none()));
    assert!((samples.last().unwrap().accel_g - DVec3::Z).length() < 0.1);
}

#[test]
fn balance_board_is_rejected() {
    let mut s = Session::new(
        EmulatedRemote::new(EmulatorConfig {
            variant: Variant::BalanceBoard,
            ..Default::default()
        }),
        SessionConfig::default(),
    );
    assert!(matches!(
        s.connect(),
        Err(SessionError::UnsupportedDevice(_))
    ));
}

#[test]
fn activation_without_status_reports_still_ends_active_within_3s() {
    let mut s = Session::new(
        EmulatedRemote::new(EmulatorConfig {
            drop_activation_status: true,
            activation_fails_n_times: 1,
            ..Default::default()
        }),
        SessionConfig::default(),
    );
    let info = s.connect().unwrap();
    assert_eq!(info.motion_plus, MotionPlusState::Active);
    assert!(
        s.transport().now_us() < 5_000_000,
        "took {} µs",
        s.transport().now_us()
    );
}

#[test]
fn quirky_transports_are_tolerated() {
    for config in [
        EmulatorConfig {
            windows_padding: true,
            ..Default::default()
        },
        EmulatorConfig {
            always_ack: true,
            ..Default::default()
        },
        EmulatorConfig {
            error2_acks: true,
            seed: 5,
            ..Default::default()
        },
        EmulatorConfig {
            drop_probability: 0.05,
            burst: Some(3),
            ..Default::default()
        },
        EmulatorConfig {
            report_rate_hz: 200.0,
            ..Default::default()
        },
    ] {
        let mut s = connect(config.clone());
        for _ in 0..200 {
            s.poll(20).unwrap();
        }
        let n = s
            .drain_events()
            .filter(|e| matches!(e, SessionEvent::Orientation(_)))
            .count();
        assert!(n > 100, "{config:?}: {n} samples");
    }
}

#[test]
fn same_seed_gives_identical_byte_stream() {
    let stream = |seed| {
        let mut e = EmulatedRemote::new(EmulatorConfig {
            seed,
            ..Default::default()
        });
        e.controls().set_motion(Arc::new(DemoMotion));
        e.write(&[0x12, 0x04, 0x31]).unwrap();
        let mut out = Vec::new();
        let mut buf = [0u8; 32];
        for _ in 0..200 {
            let n = e.read_timeout(&mut buf, 50).unwrap();
            out.extend_from_slice(&buf[..n]);
        }
        out
    };
    assert_eq!(stream(9), stream(9));
    assert_ne!(stream(9), stream(10));
}

#[test]
fn constant_rate_per_axis_has_the_right_sign_for_normal_and_reversed_units() {
    for reversed in [false, true] {
        for (axis, name) in [(DVec3::X, "pitch"), (DVec3::Y, "roll"), (DVec3::Z, "yaw")] {
            let sensors = SensorModel {
                reversed,
                ..SensorModel::ideal()
            };
            let emu = EmulatedRemote::new(EmulatorConfig {
                sensors,
                jitter_us: 0,
                ..Default::default()
            });
            emu.controls().set_motion(Arc::new(ConstantRate {
                start: DQuat::IDENTITY,
                axis,
                rate: 10f64.to_radians(),
            }));
            let mut s = Session::new(emu, SessionConfig::default());
            s.connect().unwrap();
            for _ in 0..50 {
                s.poll(20).unwrap();
            }
            let rates: Vec<DVec3> = s
                .drain_events()
                .filter_map(|e| match e {
                    SessionEvent::Imu(i) => i.gyro_dps,
                    _ => None,
                })
                .collect();
            let mean = rates.iter().sum::<DVec3>() / rates.len() as f64;
            assert!(
                (mean - axis * 10.0).length() < 0.3,
                "{name} reversed={reversed}: {mean}"
            );
        }
    }
}

#[test]
fn status_report_stops_data_until_mode_is_resent() {
    let mut e = EmulatedRemote::new(EmulatorConfig::default());
    let mut buf = [0u8; 32];
    e.write(&[0x12, 0x04, 0x31]).unwrap();
    let n = e.read_timeout(&mut buf, 50).unwrap();
    assert_eq!(buf[0], 0x31, "{:?}", &buf[..n]);
    e.write(&[0x15, 0x00]).unwrap();
    let mut ids = Vec::new();
    for _ in 0..10 {
        let n = e.read_timeout(&mut buf, 20).unwrap();
        if n > 0 {
            ids.push(buf[0]);
        }
    }
    assert!(ids.contains(&0x20));
    let after: Vec<_> = ids.iter().skip_while(|i| **i != 0x20).skip(1).collect();
    assert!(after.is_empty(), "data after status without 0x12: {ids:?}");
    e.write(&[0x12, 0x04, 0x31]).unwrap();
    let n = e.read_timeout(&mut buf, 50).unwrap();
    assert!(n > 0 && buf[0] == 0x31);
}

#[test]
fn emulator_memory_errors_follow_the_spec() {
    let mut e = EmulatedRemote::new(EmulatorConfig {
        variant: Variant::Original { motion_plus: false },
        ..Default::default()
    });
    let read_err = |e: &mut EmulatedRemote, report: &[u8]| -> (u8, u8) {
        e.write(report).unwrap();
        let mut buf = [0u8; 32];
        loop {
            let n = e.read_timeout(&mut buf, 100).unwrap();
            assert!(n > 0, "no answer to {report:02X?}");
            match InputReport::decode(&buf[..n]).unwrap() {
                InputReport::ReadReply(r) => return (0x21, r.error),
                InputReport::Ack { report, error, .. } => return (report, error),
                _ => {}
            }
        }
    };
    assert_eq!(
        read_err(&mut e, &[0x17, 0x04, 0xA6, 0x00, 0xFA, 0x00, 0x06]),
        (0x21, 7)
    );
    assert_eq!(
        read_err(&mut e, &[0x17, 0x00, 0x00, 0x17, 0x00, 0x00, 0x10]),
        (0x21, 8)
    );
    assert_eq!(
        read_err(&mut e, &[0x17, 0x04, 0xA0, 0x00, 0x00, 0x00, 0x10]),
        (0x21, 8)
    );
    assert_eq!(
        read_err(&mut e, &[0x17, 0x0C, 0xA4, 0x00, 0x00, 0x00, 0x10]),
        (0x17, 6)
    );
    assert_eq!(
        read_err(
            &mut e,
            &[
                0x16, 0x04, 0xA4, 0x00, 0xF0, 0x01, 0x55, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                0
            ]
        ),
        (0x16, 7)
    );
    // Second read while one is answered → busy.
    e.write(&[0x17, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00])
        .unwrap();
    assert_eq!(
        read_err(&mut e, &[0x17, 0x00, 0x00, 0x00, 0x16, 0x00, 0x0A]),
        (0x17, 4)
    );
}

#[test]
fn motion_plus_unplug_and_replug_is_detected() {
    let mut s = connect(EmulatorConfig {
        variant: Variant::Original { motion_plus: true },
        ..Default::default()
    });
    for _ in 0..20 {
        s.poll(20).unwrap();
    }
    s.transport().controls().set_motion_plus_plugged(false);
    for _ in 0..100 {
        s.poll(20).unwrap();
    }
    assert_ne!(s.motion_plus_state(), MotionPlusState::Active);
    s.transport().controls().set_motion_plus_plugged(true);
    for _ in 0..800 {
        s.poll(20).unwrap();
    }
    assert_eq!(s.motion_plus_state(), MotionPlusState::Active);
    let states: Vec<_> = s
        .drain_events()
        .filter_map(|e| match e {
            SessionEvent::MotionPlus(m) => Some(m),
            _ => None,
        })
        .collect();
    assert!(states.contains(&MotionPlusState::Lost), "{states:?}");
}

#[test]
fn nunchuk_passthrough_frames_reach_the_session() {
    let emu = EmulatedRemote::new(EmulatorConfig::default());
    emu.controls().set_nunchuk(Some(NunchukFrame {
        stick_x: 200,
        stick_y: 128,
        c: false,
        z: true,
    }));
    let mut s = Session::new(emu, SessionConfig::default());
    s.connect().unwrap();
    assert_eq!(s.motion_plus_state(), MotionPlusState::Active);
    for _ in 0..60 {
        s.poll(20).unwrap();
    }
    let events: Vec<_> = s.drain_events().collect();
    let nunchuk = events
        .iter()
        .find_map(|e| match e {
            SessionEvent::Nunchuk(n) => Some(*n),
            _ => None,
        })
        .expect("nunchuk frames");
    assert_eq!((nunchuk.stick_x, nunchuk.z, nunchuk.c), (200, true, false));
    assert!(
        events
            .iter()
            .any(|e| matches!(e, SessionEvent::Imu(i) if i.gyro_dps.is_some()))
    );
}

#[test]
fn disconnect_is_an_error_and_reconnect_works() {
    let mut s = connect(EmulatorConfig::default());
    s.transport().controls().set_connected(false);
    assert!(matches!(
        s.poll(20),
        Err(SessionError::Transport(TransportError::Disconnected))
    ));
    s.transport().controls().set_connected(true);
    let info = s.connect().unwrap();
    assert_eq!(info.motion_plus, MotionPlusState::Active);
}

#[test]
fn buttons_and_rumble_round_trip() {
    let mut s = connect(EmulatorConfig::default());
    s.transport()
        .controls()
        .set_buttons(Buttons(Buttons::B | Buttons::A));
    s.set_rumble(true).unwrap();
    for _ in 0..10 {
        s.poll(20).unwrap();
    }
    assert!(s.transport().rumble());
    assert!(s.drain_events().any(|e| matches!(e, SessionEvent::Buttons { buttons, .. } if buttons.pressed(Buttons::B) && buttons.pressed(Buttons::A))));
    // Rumble stays on through other reports (carried in every report).
    s.set_leds(0b1010).unwrap();
    assert!(s.transport().rumble());
    assert_eq!(s.transport().leds(), 0b1010);
}

#[test]
fn filters_track_a_short_drift_session() {
    // A 2-minute slice of the §14 scenario: ours must beat the paper on tilt.
    let rec = drift::record_session(3, 180.0);
    assert!(rec.samples.len() > 10_000, "{}", rec.samples.len());
    let paper = drift::score(FilterKind::Paper, &rec);
    let ours = drift::score(FilterKind::Fusion, &rec);
    let raw = drift::score(FilterKind::Raw, &rec);
    assert!(
        ours.tilt_rms_deg < paper.tilt_rms_deg,
        "ours {ours:?} paper {paper:?}"
    );
    assert!(ours.tilt_rms_deg < 2.0, "{ours:?}");
    assert!(
        raw.attitude_rms_deg > ours.attitude_rms_deg,
        "raw {raw:?} ours {ours:?}"
    );
}

/// `VqfFilter` against the authors' C++ implementation (the `vqf` 2.1.2 Python package,
/// `VQF(0.01).updateBatch(gyr, acc)['quat6D']`, default parameters) on this sequence: 400
/// samples at 100 Hz, t = k / 100,
/// gyr = (0.3 sin 1.1t, −0.2 cos 0.7t, 0.25 + 0.1 sin 2.3t) rad/s,
/// acc = 9.81 · normalise(0.1 sin 0.5t, −0.15 cos 0.9t + 0.05, 1) m/s².
#[test]
fn vqf_matches_the_reference_implementation() {
    let reference = [
        (
            99,
            [
                0.984650478187492,
                0.009338481755786632,
                -0.04959200702871836,
                0.1670833965494606,
            ],
        ),
        (
            199,
            [
                0.9505755105187943,
                0.11452586736199794,
                -0.049470309321723055,
                0.284328530053755,
            ],
        ),
        (
            399,
            [
                0.8429663902993155,
                0.00043600676348170067,
                -0.008395216512598258,
                0.5379005438401705,
            ],
        ),
    ];
    let mut f = VqfFilter::default();
    let mut checked = 0;
    for k in 0..400u64 {
        let t = k as f64 / 100.0;
        let gyr = DVec3::new(
            0.3 * (1.1 * t).sin(),
            -0.2 * (0.7 * t).cos(),
            0.25 + 0.1 * (2.3 * t).sin(),
        );
        let a = DVec3::new(0.1 * (0.5 * t).sin(), -0.15 * (0.9 * t).cos() + 0.05, 1.0);
        f.update(&ImuSample {
            timestamp_us: k * 10_000,
            dt: 0.01,
            gyro_dps: Some(gyr * (180.0 / std::f64::consts::PI)),
            gyro_fast: [false; 3],
            accel_g: a.normalize() * 9.81 / 9.80665,
        });
        if let Some((_, [w, x, y, z])) = reference.iter().find(|(i, _)| *i == k) {
            let q = f.orientation();
            let err = (q.w - w)
                .abs()
                .max((q.x - x).abs())
                .max((q.y - y).abs())
                .max((q.z - z).abs());
            assert!(err < 1e-9, "sample {k}: {q:?} vs {:?}", [w, x, y, z]);
            checked += 1;
        }
    }
    assert_eq!(checked, reference.len());
}

#[test]
fn every_filter_is_scored_on_every_session_set() {
    for set in drift::SessionSet::ALL {
        let rec = set.record(2, 120.0);
        assert!(
            rec.samples.len() > 10_000,
            "{}: {}",
            set.name(),
            rec.samples.len()
        );
        for kind in FilterKind::ALL {
            let s = drift::score(kind, &rec);
            let all = [
                s.tilt_rms_deg,
                s.yaw_drift_deg_per_min,
                s.attitude_rms_deg,
                s.relative_rotation_p95_deg,
                s.heading_rmse_deg,
                s.inclination_rmse_deg,
            ];
            assert!(
                all.iter().all(|v| v.is_finite() && *v >= 0.0),
                "{} {}: {s:?}",
                set.name(),
                kind.name()
            );
            // Inclination error is the tilt error measured another way.
            assert!(
                (s.inclination_rmse_deg - s.tilt_rms_deg).abs() < 0.05 * s.tilt_rms_deg + 1e-6,
                "{s:?}"
            );
        }
        let ours = drift::score(FilterKind::Fusion, &rec);
        assert!(ours.tilt_rms_deg < 2.0, "{}: {ours:?}", set.name());
        assert!(ours.heading_rmse_deg < 15.0, "{}: {ours:?}", set.name());
    }
}

#[test]
fn continuous_sessions_never_hold_still_for_a_second() {
    let scenario = drift::ContinuousScenario::new(4, 300.0);
    let mut still_run = 0.0f64;
    let mut longest = 0.0f64;
    let mut t = 5.0;
    while t < scenario.duration() {
        let rate = body_rate(&scenario, t).length().to_degrees();
        still_run = if rate < 0.5 { still_run + 0.01 } else { 0.0 };
        longest = longest.max(still_run);
        t += 0.01;
    }
    assert!(longest < 1.0, "still for {longest} s");
}

#[test]
fn paper_filter_snaps_tilt_when_still_without_warm_up() {
    // Without warm-up drift the paper's bias stays valid, so in the final still phase its
    // stillness test passes and tilt is snapped onto the accelerometer's gravity.
    let rec = drift::SessionSet::NoWarmUp.record(1, 160.0);
    let mut paper = PaperFilter::default();
    for s in &rec.samples {
        paper.update(s);
    }
    assert!(*rec.still.last().unwrap());
    assert!(paper.is_still());
    let truth = *rec.truth.last().unwrap();
    let tilt = (truth.inverse() * DVec3::Z)
        .angle_between(paper.orientation().inverse() * DVec3::Z)
        .to_degrees();
    let floor = drift::accelerometer_tilt_floor(&rec);
    assert!(
        tilt < floor + 1.0,
        "tilt {tilt}° (accelerometer floor {floor}°)"
    );
}

#[test]
fn heading_and_inclination_split_an_error_rotation() {
    let (h, i) = drift::heading_inclination_deg(DQuat::from_rotation_z(10f64.to_radians()));
    assert!((h - 10.0).abs() < 1e-9 && i.abs() < 1e-6, "{h} {i}");
    let (h, i) = drift::heading_inclination_deg(DQuat::from_rotation_x(-5f64.to_radians()));
    assert!(h.abs() < 1e-9 && (i - 5.0).abs() < 1e-9, "{h} {i}");
    let q = DQuat::from_rotation_z(0.3) * DQuat::from_rotation_y(0.2);
    let (h, i) = drift::heading_inclination_deg(q);
    assert!(
        (h - 0.3f64.to_degrees()).abs() < 1e-9 && (i - 0.2f64.to_degrees()).abs() < 1e-9,
        "{h} {i}"
    );
}

/// A fake sysfs + /dev tree with one Wii Remote Plus at hidraw3 (HID id 0005:057E:0330.0007),
/// its node's mode and its bound driver chosen by the test.
struct FakeDevices {
    root: std::path::PathBuf,
}

impl FakeDevices {
    fn new(name: &str, mode: u32, driver: &str) -> Self {
        use std::os::unix::fs::{PermissionsExt, symlink};
        let root = std::env::temp_dir().join(format!("wii-sysfs-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let hid = root.join("sys/devices/virtual/bluetooth/hci0/0005:057E:0330.0007");
        let drivers = root.join("sys/bus/hid/drivers");
        std::fs::create_dir_all(hid.join("hidraw/hidraw3")).unwrap();
        std::fs::create_dir_all(drivers.join(driver)).unwrap();
        std::fs::create_dir_all(root.join("sys/class/hidraw")).unwrap();
        std::fs::create_dir_all(root.join("dev")).unwrap();
        std::fs::write(
            hid.join("uevent"),
            "DRIVER=x\nHID_ID=0005:0000057E:00000330\nHID_NAME=Nintendo RVL-CNT-01-TR\n",
        )
        .unwrap();
        symlink(drivers.join(driver), hid.join("driver")).unwrap();
        symlink(&hid, hid.join("hidraw/hidraw3/device")).unwrap();
        symlink(
            hid.join("hidraw/hidraw3"),
            root.join("sys/class/hidraw/hidraw3"),
        )
        .unwrap();
        // An unrelated hidraw device (a keyboard) that must be ignored.
        let other = root.join("sys/devices/pci/0003:046D:C31C.0001");
        std::fs::create_dir_all(other.join("hidraw/hidraw0")).unwrap();
        std::fs::write(other.join("uevent"), "HID_ID=0003:0000046D:0000C31C\n").unwrap();
        symlink(&other, other.join("hidraw/hidraw0/device")).unwrap();
        symlink(
            other.join("hidraw/hidraw0"),
            root.join("sys/class/hidraw/hidraw0"),
        )
        .unwrap();
        for node in ["hidraw3", "hidraw0"] {
            let path = root.join("dev").join(node);
            std::fs::write(&path, b"").unwrap();
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
        }
        Self { root }
    }

    /// The tree as seen by an ordinary user (uid 1000, not in the node's group).
    fn devices(&self) -> LinuxDevices {
        let user = diagnosis::UserIds {
            uid: 1000,
            groups: vec![1000],
        };
        LinuxDevices::at(self.root.join("sys"), self.root.join("dev"), user)
    }

    fn node(&self) -> std::path::PathBuf {
        self.root.join("dev/hidraw3")
    }
}

impl Drop for FakeDevices {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

#[test]
fn diagnosis_finds_only_the_remote_and_its_hid_id() {
    let fake = FakeDevices::new("list", 0o666, "hid-generic");
    let nodes = fake.devices().wiimote_nodes();
    assert_eq!(nodes.len(), 1, "{nodes:?}");
    assert_eq!(nodes[0].node, fake.node());
    assert_eq!(nodes[0].hid_id, "0005:057E:0330.0007");
    assert_eq!(nodes[0].driver.as_deref(), Some("hid-generic"));
}

#[test]
fn diagnosis_of_a_root_only_node_gives_the_udev_rule() {
    let fake = FakeDevices::new("root-only", 0o600, "hid-generic");
    let problems = fake.devices().diagnose(&fake.node(), None);
    assert_eq!(
        problems,
        vec![RemoteProblem::PermissionDenied {
            node: fake.node().display().to_string()
        }]
    );
    let text = problems[0].to_string();
    assert!(
        text.contains("60-motion-controllers.rules") && text.contains("057E:0330"),
        "{text}"
    );
    // The error of an actual open is authoritative, whatever the mode bits say.
    let open_error = OpenErrorKind::PermissionDenied;
    let fake_open = FakeDevices::new("root-only-open", 0o666, "hid-generic");
    assert!(matches!(
        fake_open
            .devices()
            .diagnose(&fake_open.node(), Some(&open_error))[..],
        [RemoteProblem::PermissionDenied { .. }]
    ));
}

#[test]
fn diagnosis_of_a_node_bound_to_hid_wiimote_gives_the_unbind_line() {
    let fake = FakeDevices::new("bound", 0o666, "wiimote");
    let problems = fake.devices().diagnose(&fake.node(), None);
    assert_eq!(problems.len(), 1, "{problems:?}");
    let RemoteProblem::KernelDriverBound { hid_id, .. } = &problems[0] else {
        panic!("{problems:?}");
    };
    assert_eq!(hid_id, "0005:057E:0330.0007");
    let text = problems[0].to_string();
    assert!(
        text.contains("echo 0005:057E:0330.0007 > /sys/bus/hid/drivers/wiimote/unbind"),
        "{text}"
    );
    assert!(text.contains("blacklist hid_wiimote"), "{text}");
}

#[test]
fn diagnosis_of_a_root_only_node_bound_to_hid_wiimote_gives_both_fixes() {
    let fake = FakeDevices::new("both", 0o600, "wiimote");
    let problems = fake.devices().diagnose(&fake.node(), None);
    assert!(
        matches!(
            problems[..],
            [
                RemoteProblem::KernelDriverBound { .. },
                RemoteProblem::PermissionDenied { .. }
            ]
        ),
        "{problems:?}"
    );
    assert_eq!(fake.devices().diagnose_all(), problems);
}

#[test]
fn diagnosis_of_a_usable_node_finds_nothing() {
    let fake = FakeDevices::new("neither", 0o660, "hid-generic");
    // Group read/write does not help a user outside the group …
    assert_eq!(fake.devices().diagnose(&fake.node(), None).len(), 1);
    // … but does help one inside it (gid 0 here: the test's files belong to root's group).
    let mut devices = fake.devices();
    devices.user = Some(diagnosis::UserIds {
        uid: 1000,
        groups: vec![1000, file_gid(&fake.node())],
    });
    assert!(devices.diagnose(&fake.node(), None).is_empty());
    let open = FakeDevices::new("neither-open", 0o666, "hid-generic");
    assert!(open.devices().diagnose(&open.node(), None).is_empty());
    assert!(open.devices().diagnose_all().is_empty());
    // A busy node says so.
    assert_eq!(
        open.devices()
            .diagnose(&open.node(), Some(&OpenErrorKind::Busy)),
        vec![RemoteProblem::Busy {
            node: open.node().display().to_string()
        }]
    );
}

fn file_gid(path: &std::path::Path) -> u32 {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).unwrap().gid()
}

#[test]
fn a_session_recorded_with_another_sensor_model_uses_it() {
    // Same motion and seed; the accelerometer's misalignment and scale error removed: its
    // gravity reference while still must get better (it is what limits tilt on the default
    // set), and the same call with the set's own model must reproduce `record`.
    let set = drift::SessionSet::Default;
    let real = set.record(4, 40.0);
    let same = set.record_with_sensor(set.sensor(), 4, 40.0);
    assert_eq!(real.samples, same.samples);
    let ideal_accel = bevy_wii_deform::controllers::wiimote::SensorModel {
        accel_misalignment: 0.0,
        accel_scale_error: 0.0,
        ..set.sensor()
    };
    let ideal = set.record_with_sensor(ideal_accel, 4, 40.0);
    let (floor_real, floor_ideal) = (
        drift::accelerometer_tilt_floor(&real),
        drift::accelerometer_tilt_floor(&ideal),
    );
    assert!(
        floor_ideal < 0.8 * floor_real,
        "accelerometer tilt while still: ideal {floor_ideal}°, real {floor_real}°"
    );
}
