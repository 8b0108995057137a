//! Gyro pads in the ECS: one entity per controller whatever its kind, a DualSense turning a
//! handle 1:1, and the gyro pointer.

use std::sync::Arc;
use std::time::Duration;

use bevy::prelude::*;
use bevy_wii_deform::controllers::gyro_pointer::GyroPointerSettings;
use bevy_wii_deform::controllers::pads::PadEmulatorConfig;
use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
use bevy_wii_deform::controllers::wiimote::{EmulatorClock, FnMotion, Still};
use bevy_wii_deform::controllers::{ControllerKind, Link};
use bevy_wii_deform::prelude::*;
use glam::{DQuat, DVec3};

use crate::common::{self, app};

/// An app with emulated pads of `kinds` paced by its clock (10 ms per update), each with a
/// handle entity it turns.
fn pads_app(kinds: &[ControllerKind], gyro_pointer: Option<GyroPointerSettings>) -> App {
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    let clock = EmulatorClock::new();
    let source = kinds
        .iter()
        .map(|&kind| {
            PadEmulatorConfig {
                clock: Some(clock.clone()),
                ..PadEmulatorConfig::new(kind, Link::Bluetooth)
            }
            .into()
        })
        .collect();
    app.add_plugins((
        MotionControllerPlugin {
            source: ControllerSource::Emulator(source),
            gyro_pointer,
            ..default()
        },
        MotionControlPlugin,
    ));
    app
}

fn controllers(app: &mut App) -> Vec<(Entity, MotionController)> {
    let mut q = app.world_mut().query::<(Entity, &MotionController)>();
    let mut all: Vec<(Entity, MotionController)> =
        q.iter(app.world()).map(|(e, w)| (e, w.clone())).collect();
    all.sort_by_key(|(_, w)| w.id);
    all
}

fn calibrated(app: &mut App, n: usize) {
    common::update_until(app, "calibrated pads", |a| {
        let all = controllers(a);
        all.len() == n
            && all.iter().all(|(_, w)| {
                w.connection == ConnectionState::Connected
                    && matches!(w.calibration, ControllerCalibration::Calibrated(_))
            })
    });
}

fn update_until_sample(app: &mut App, t: f64) {
    common::update_until(app, "the pads' samples", |a| {
        controllers(a)
            .iter()
            .all(|(_, w)| w.timestamp_us as f64 * 1e-6 >= t)
    });
    app.update();
}

#[test]
fn each_pad_gets_an_entity_with_its_kind_and_battery() {
    let kinds = [ControllerKind::DualSense, ControllerKind::SwitchPro];
    let mut app = pads_app(&kinds, None);
    calibrated(&mut app, 2);
    let all = controllers(&mut app);
    assert_eq!(all[0].1.kind, ControllerKind::DualSense);
    assert_eq!(all[1].1.kind, ControllerKind::SwitchPro);
    // 80 % on both scales: Sony's 10 % steps, Nintendo's 25 % steps (75 %), × 2.
    assert_eq!(all[0].1.battery, 160);
    assert_eq!(all[1].1.battery, 150);
    assert!(
        all.iter()
            .all(|(_, w)| w.motion_plus && w.pointer.is_none())
    );
}

#[test]
fn an_emulated_dualsense_turns_a_handle_40_degrees_for_40() {
    let mut app = pads_app(&[ControllerKind::DualSense], None);
    let controls = app.world().resource::<ControllerEmulators>().0[0].clone();
    controls.set_motion(Arc::new(Still(DQuat::IDENTITY)));
    calibrated(&mut app, 1);
    let handle = app
        .world_mut()
        .spawn((Transform::default(), MotionHandleControl::default()))
        .id();
    // R2 is the clutch (B to the emulator).
    controls.set_buttons(Buttons(Buttons::B));
    common::update_until(&mut app, "the grab", |a| {
        a.world()
            .get::<MotionHandleControl>(handle)
            .unwrap()
            .is_grabbing()
    });
    let t0 = common::emulated_start(&app, 0.1);
    controls.set_motion(Arc::new(FnMotion(move |t: f64| {
        let angle = ((t - t0) / 1.0).clamp(0.0, 1.0) * 40f64.to_radians();
        (DQuat::from_rotation_z(angle), DVec3::ZERO)
    })));
    update_until_sample(&mut app, t0 + 1.5);
    let rot = app.world().get::<Transform>(handle).unwrap().rotation;
    let (_, angle) = rot.to_axis_angle();
    assert!(
        (angle.to_degrees() - 40.0).abs() < 1.0,
        "handle turned {}° for 40°",
        angle.to_degrees()
    );
    // About Bevy's +Y (the pad's face normal), the same way.
    let want = Quat::from_rotation_y(40f32.to_radians());
    assert!(rot.angle_between(want) < 2f32.to_radians(), "{rot}");
}

#[test]
fn the_gyro_pointer_moves_by_its_sensitivity_and_recentres() {
    let settings = GyroPointerSettings {
        sensitivity: 0.02,
        aspect: 16.0 / 9.0,
    };
    let mut app = pads_app(&[ControllerKind::SwitchPro], Some(settings));
    let controls = app.world().resource::<ControllerEmulators>().0[0].clone();
    controls.set_motion(Arc::new(Still(DQuat::IDENTITY)));
    calibrated(&mut app, 1);
    let start = controllers(&mut app)[0].1.pointer.unwrap();
    assert!((start - Vec2::splat(0.5)).length() < 0.01, "{start}");
    // Turn 10° to the right over half a second.
    let t0 = common::emulated_start(&app, 0.05);
    controls.set_motion(Arc::new(FnMotion(move |t: f64| {
        let angle = ((t - t0) / 0.5).clamp(0.0, 1.0) * -10f64.to_radians();
        (DQuat::from_rotation_z(angle), DVec3::ZERO)
    })));
    update_until_sample(&mut app, t0 + 0.8);
    let moved = controllers(&mut app)[0].1.pointer.unwrap() - start;
    // 10° · 0.02 = 0.2 of the width, to the right, within 1 %.
    assert!((moved.x - 0.2).abs() < 0.002, "moved {moved}");
    assert!(moved.y.abs() < 0.01, "moved {moved}");
    // Home (the recentre role) puts it back at the centre.
    // (Waited for by the button itself: reports the emulator made before the press may still
    // be on their way, with sample times past any chosen from the last one read.)
    controls.set_buttons(Buttons(Buttons::HOME));
    common::update_until(&mut app, "the recentre button", |a| {
        controllers(a)[0].1.buttons & Buttons::HOME != 0
    });
    let t1 = controllers(&mut app)[0].1.timestamp_us as f64 * 1e-6 + 0.1;
    update_until_sample(&mut app, t1);
    let back = controllers(&mut app)[0].1.pointer.unwrap();
    assert!((back - Vec2::splat(0.5)).length() < 0.005, "{back}");
}
