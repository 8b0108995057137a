//! Device-layer integration tests: real captured bytes, the emulator driven by the session
//! (failure cases included), filters against ground truth.

use std::sync::Arc;

use bevy_wii_deform::wiimote::protocol::*;
use bevy_wii_deform::wiimote::*;
use glam::{DQuat, DVec3};
use proptest::prelude::*;

fn fixtures() -> Option<serde_json::Value> {
    let text = std::fs::read_to_string("../shared/wiimote/captures/fixtures.json").ok()?;
    serde_json::from_str(&text).ok()
}

fn hex(v: &serde_json::Value) -> Vec<u8> {
    parse_hex(v.as_str().unwrap()).unwrap()
}

#[test]
fn captured_and_synthetic_fixtures_decode() {
    let Some(f) = fixtures() else {
        eprintln!("skipping: ../shared/wiimote/captures/fixtures.json is absent");
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
            "mplus_calibration_32B" => {
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
            "eeprom_accel_calibration_10B" => {
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
            "input_report_0x21" => {
                let InputReport::ReadReply(r) = InputReport::decode(&hex(&item["hex"])).unwrap()
                else {
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
            "input_report_0x22" => {
                let InputReport::Ack { report, error, .. } =
                    InputReport::decode(&hex(&item["hex"])).unwrap()
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
            "input_report_0x20" => {
                let InputReport::Status(s) = InputReport::decode(&hex(&item["hex"])).unwrap()
                else {
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
            "input_report_0x35" | "input_report_0x31" => {
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
                    let ExtensionData::MotionPlus(fr) =
                        classify_extension(&extension.unwrap(), true)
                    else {
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
            "output_reports" => {
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
        struct Garbage(bevy_wii_deform::wiimote::Rng, u64);
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
        let mut s = Session::new(Garbage(bevy_wii_deform::wiimote::Rng::new(seed), 0), SessionConfig { retries: 0, command_timeout_ms: 30, ..Default::default() });
        let _ = s.connect();
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
