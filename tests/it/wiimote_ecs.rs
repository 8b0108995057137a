//! `MotionControllerPlugin` + `MotionControlPlugin` headless with emulated remotes paced by the app's
//! clock: turning a handle 1:1 in camera space, disconnects, a remote that cannot be opened,
//! two remotes each on its own handle, Home's recentre.

use std::sync::Arc;
use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
use bevy_wii_deform::controllers::wiimote::{EmulatorClock, FnMotion, Still};
use bevy_wii_deform::prelude::*;
use glam::{DQuat, DVec3};

use crate::common::bar::*;
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
        MotionControllerPlugin {
            source: ControllerSource::Emulator(vec![config().into(), config().into()]),
            ..default()
        },
        MotionControlPlugin,
    ));
    let controls = app.world().resource::<ControllerEmulators>().0.clone();
    for c in &controls {
        c.set_motion(Arc::new(Still(DQuat::IDENTITY)));
    }
    common::update_until(&mut app, "two calibrated remotes", |a| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.iter(a.world())
            .filter(|w| {
                w.connection == ConnectionState::Connected
                    && matches!(w.calibration, ControllerCalibration::Calibrated(_))
            })
            .count()
            == 2
    });
    // Which entity is which emulator: yaw the first emulator and see which remote turns.
    let remotes: Vec<(Entity, u32)> = {
        let mut q = app.world_mut().query::<(Entity, &MotionController)>();
        let mut v: Vec<(Entity, u32)> = q.iter(app.world()).map(|(e, w)| (e, w.id)).collect();
        v.sort_by_key(|r| r.1);
        v
    };
    let remotes = [remotes[0].0, remotes[1].0];
    let handles = remotes.map(|remote| {
        app.world_mut()
            .spawn((
                Transform::default(),
                MotionHandleControl::default().with_remote(remote),
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
    app.world()
        .get::<MotionController>(remote)
        .unwrap()
        .timestamp_us as f64
        * 1e-6
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
    let turned =
        |e: Entity| yaw_degrees(app.world().get::<MotionController>(e).unwrap().orientation).abs();
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
    let yaw = |app: &App, e: Entity| {
        yaw_degrees(app.world().get::<MotionController>(e).unwrap().orientation)
    };
    // (The 6-axis filter reads a yaw within ~2° of the emulated one.)
    assert!((yaw(&app, remotes[0]).abs() - 20.0).abs() < 2.5);
    assert!((yaw(&app, remotes[1]).abs() - 20.0).abs() < 2.5);
    let other_before = app
        .world()
        .get::<MotionController>(remotes[1])
        .unwrap()
        .orientation;
    // Home on the first: it reads identity from here, the second keeps its 20°.
    controls[order[0]].set_buttons(Buttons(Buttons::HOME));
    run_for(&mut app, remotes, 0.2);
    controls[order[0]].set_buttons(Buttons(0));
    run_for(&mut app, remotes, 0.2);
    let after = app
        .world()
        .get::<MotionController>(remotes[0])
        .unwrap()
        .orientation;
    assert!(
        after.angle_between(Quat::IDENTITY).to_degrees() < 1.0,
        "the recentred remote reads {}°",
        after.angle_between(Quat::IDENTITY).to_degrees()
    );
    let other = app
        .world()
        .get::<MotionController>(remotes[1])
        .unwrap()
        .orientation;
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

/// A bar with a Wii Remote-controlled handle and one emulated remote paced by the app's clock
/// (10 ms per update): no wall-clock sleeps, the remote's samples follow the stepped time.
fn wiimote_app() -> (App, Entity, Entity) {
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    let clock = bevy_wii_deform::controllers::wiimote::EmulatorClock::new();
    app.add_plugins((
        DeformPlugin::default(),
        MotionControllerPlugin {
            source: ControllerSource::Emulator(vec![
                EmulatorConfig {
                    clock: Some(clock),
                    ..default()
                }
                .into(),
            ]),
            ..default()
        },
        MotionControlPlugin,
    ));
    let (e, handle, _) = spawn_bar(&mut app);
    app.world_mut()
        .entity_mut(handle)
        .insert(MotionHandleControl::default());
    (app, e, handle)
}

/// The remote entity's state, once there is one.
fn remote_state(app: &mut App) -> Option<MotionController> {
    let mut q = app.world_mut().query::<&MotionController>();
    q.iter(app.world()).next().cloned()
}

/// Steps the app until the remote has delivered samples up to `t` seconds (its own clock).
fn update_until_sample(app: &mut App, t: f64) {
    common::update_until(app, "the remote's samples", |a| {
        remote_state(a).is_some_and(|w| w.timestamp_us as f64 * 1e-6 >= t)
    });
}

#[test]
fn an_emulated_remote_turns_a_handle_and_a_disconnect_keeps_the_pose() {
    let (mut app, e, handle) = wiimote_app();
    let controls = app.world().resource::<ControllerEmulators>().0[0].clone();
    controls.set_motion(Arc::new(Still(DQuat::IDENTITY)));
    // Connect and calibrate at rest.
    common::update_until(&mut app, "a calibrated remote", |a| {
        remote_state(a).is_some_and(|w| {
            w.connection == ConnectionState::Connected
                && w.motion_plus
                && matches!(w.calibration, ControllerCalibration::Calibrated(_))
        })
    });
    let remote = {
        let mut q = app
            .world_mut()
            .query_filtered::<Entity, With<MotionController>>();
        q.single(app.world()).expect("one remote entity")
    };
    // Grab with B, then yaw the remote (about its top axis = Bevy +Y) by 40° over 1 s of its
    // own time, and hold still.
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
    app.update();
    let rot = app.world().get::<Transform>(handle).unwrap().rotation;
    let (axis, angle) = rot.to_axis_angle();
    // 1:1 within 1° (a gain of 0.9 would be 4° short).
    assert!(
        (angle.to_degrees() - 40.0).abs() < 1.0,
        "handle turned {}° for 40°",
        angle.to_degrees()
    );
    // About +Y (the remote's top axis), the same way: a reversed turn is 80° off. (The
    // filter's tilt estimate of the emulated sensors leaves the axis ~1° off vertical.)
    let want = Quat::from_rotation_y(40f32.to_radians());
    assert!(
        rot.angle_between(want) < 2f32.to_radians(),
        "turned {}° about {axis}",
        angle.to_degrees()
    );
    // Disconnect mid-drag (B still held): the state shows it, the last pose is kept.
    controls.set_connected(false);
    common::update_until(&mut app, "the disconnect", |a| {
        a.world()
            .get::<MotionController>(remote)
            .unwrap()
            .connection
            == ConnectionState::Disconnected
    });
    let before = app.world().get::<Transform>(handle).unwrap().rotation;
    for _ in 0..50 {
        app.update();
    }
    assert_eq!(
        app.world().get::<Transform>(handle).unwrap().rotation,
        before
    );
    assert!(
        !app.world()
            .get::<MotionHandleControl>(handle)
            .unwrap()
            .is_grabbing()
    );
    for p in positions(&app, e) {
        assert!(p.is_finite());
    }
    // It comes back on the same entity.
    controls.set_connected(true);
    common::update_until(&mut app, "the reconnect", |a| {
        a.world()
            .get::<MotionController>(remote)
            .unwrap()
            .connection
            == ConnectionState::Connected
    });
}

#[derive(Resource, Default)]
struct SeenProblems(Vec<ControllerProblem>);

fn collect_problems(mut reader: MessageReader<ControllerProblem>, mut seen: ResMut<SeenProblems>) {
    seen.0.extend(reader.read().cloned());
}

#[test]
fn a_remote_that_cannot_be_opened_reaches_a_message_and_its_entity() {
    use bevy_wii_deform::controllers::diagnosis::{OpenErrorKind, RemoteProblem};
    use bevy_wii_deform::controllers::wiimote::EmulatorConfig;
    let mut app = app();
    app.add_plugins(MotionControllerPlugin {
        source: ControllerSource::Emulator(vec![
            EmulatorConfig {
                open_error: Some(OpenErrorKind::PermissionDenied),
                ..Default::default()
            }
            .into(),
        ]),
        ..Default::default()
    });
    app.init_resource::<SeenProblems>()
        .add_systems(Update, collect_problems);
    let expected = RemoteProblem::PermissionDenied {
        node: "emulator:0".into(),
    };
    // The manager's thread reports at once; updates (no sleeping) until the message is read.
    let deadline = Instant::now() + Duration::from_secs(10);
    while app.world().resource::<SeenProblems>().0.is_empty() {
        assert!(Instant::now() < deadline, "no ControllerProblem message");
        app.update();
        std::thread::yield_now();
    }
    app.update();
    let seen = &app.world().resource::<SeenProblems>().0;
    assert_eq!(seen.len(), 1, "reported once: {seen:?}");
    assert_eq!(seen[0].problem, expected);
    let entity = seen[0]
        .entity
        .expect("the problem names its remote's entity");
    let remote = app
        .world()
        .get::<MotionController>(entity)
        .expect("remote entity");
    assert_eq!(remote.connection, ConnectionState::Unusable);
    assert_eq!(remote.problems, vec![expected.clone()]);
    assert_eq!(
        app.world().resource::<ControllerProblems>().0,
        vec![expected.clone()]
    );
    assert!(expected.to_string().contains("udev"), "{expected}");
}

#[test]
fn the_remote_turns_a_handle_one_to_one_in_camera_space_and_translates_only_while_grabbing() {
    use bevy::time::TimeUpdateStrategy;
    let mut app = app();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        10,
    )));
    app.add_plugins(MotionControlPlugin);
    // A camera turned 90° about Y (its right is world −Z): the remote's motion is mapped
    // through the camera's frame, so this checks that mapping too.
    let camera_rotation = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    app.world_mut().spawn((
        Camera3d::default(),
        Transform::from_rotation(camera_rotation),
    ));
    let start = Quat::from_rotation_x(0.3);
    let remote = app
        .world_mut()
        .spawn(MotionController {
            connection: ConnectionState::Connected,
            orientation: start,
            ..default()
        })
        .id();
    let handle = app
        .world_mut()
        .spawn((Transform::default(), MotionHandleControl::default()))
        .id();
    let set = |app: &mut App, orientation: Quat, buttons: u16| {
        let mut w = app.world_mut().get_mut::<MotionController>(remote).unwrap();
        w.orientation = orientation;
        w.buttons = buttons;
    };
    app.update();
    // Turning without B does nothing.
    set(&mut app, Quat::from_rotation_y(0.5) * start, 0);
    app.update();
    assert_eq!(
        app.world().get::<Transform>(handle).unwrap().rotation,
        Quat::IDENTITY
    );
    // Grab, then turn the remote 40° about its world Y (relative to the grab).
    set(&mut app, start, Buttons::B);
    app.update();
    let turn = Quat::from_rotation_y(40f32.to_radians());
    set(&mut app, turn * start, Buttons::B);
    app.update();
    let got = app.world().get::<Transform>(handle).unwrap().rotation;
    let want = camera_rotation * turn * camera_rotation.inverse();
    let (axis, angle) = got.to_axis_angle();
    assert!(
        (angle.to_degrees() - 40.0).abs() < 0.4,
        "turned {}° for a 40° turn of the remote",
        angle.to_degrees()
    );
    assert!(got.angle_between(want) < 0.2f32.to_radians(), "axis {axis}");
    // Released: the remote turns on, the handle keeps its pose (ratchet).
    set(&mut app, Quat::from_rotation_y(1.2) * start, 0);
    app.update();
    assert!(
        app.world()
            .get::<Transform>(handle)
            .unwrap()
            .rotation
            .angle_between(got)
            < 1e-6
    );
    // D-pad right without B: no motion; with B: along the camera's right, speed × time.
    set(&mut app, start, Buttons::RIGHT);
    app.update();
    assert_eq!(
        app.world().get::<Transform>(handle).unwrap().translation,
        Vec3::ZERO
    );
    set(&mut app, start, Buttons::RIGHT | Buttons::B);
    for _ in 0..10 {
        app.update();
    }
    let moved = app.world().get::<Transform>(handle).unwrap().translation;
    let speed = MotionHandleControl::default().speed;
    let expected = camera_rotation * Vec3::X * speed * 0.1;
    assert!(
        (moved - expected).length() < 0.01 * expected.length(),
        "{moved} vs {expected}"
    );
    // Home ends the grab.
    set(&mut app, start, Buttons::B | Buttons::HOME);
    app.update();
    assert!(
        !app.world()
            .get::<MotionHandleControl>(handle)
            .unwrap()
            .is_grabbing()
    );
}

/// With a pointer set-up the plugin starts each remote's IR camera: an emulated remote aimed at
/// a screen spot (rolled 25°) shows the bar's two dots and points within 1 % of the spot; turned
/// away, the pointer is gone (the bar out of view) and the orientation streams on.
#[test]
fn the_plugin_points_with_the_ir_camera() {
    use bevy_wii_deform::controllers::wiimote::EmulatedBar;
    use bevy_wii_deform::controllers::wiimote::ir::PointerSetup;
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    let setup = PointerSetup::default();
    let position = glam::DVec3::new(-0.2, 0.4, 0.0);
    let spot = glam::DVec2::new(0.7, 0.35);
    let aim = crate::wiimote_ir::aiming(position, setup.screen_point(spot), 25f64.to_radians());
    app.add_plugins(MotionControllerPlugin {
        source: ControllerSource::Emulator(vec![
            EmulatorConfig {
                clock: Some(EmulatorClock::new()),
                sensor_bar: Some(EmulatedBar {
                    setup,
                    position,
                    noise_px: 0.0,
                }),
                ..default()
            }
            .into(),
        ]),
        pointer: Some(setup),
        ..default()
    });
    let controls = app.world().resource::<ControllerEmulators>().0[0].clone();
    controls.set_motion(Arc::new(Still(aim)));
    let pointer = |a: &mut App| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.iter(a.world()).next().and_then(|w| w.pointer)
    };
    common::update_until(&mut app, "the IR pointer", |a| pointer(a).is_some());
    let at = pointer(&mut app).unwrap();
    assert!(
        (at.as_dvec2() - spot).length() < 0.01,
        "aimed at {spot}, the pointer is at {at}"
    );
    let dots = {
        let mut q = app.world_mut().query::<&MotionController>();
        q.single(app.world()).unwrap().ir_dots.len()
    };
    assert_eq!(dots, 2, "the bar's two clusters");
    let held = |a: &mut App| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.single(a.world()).unwrap().heading_from_bar
    };
    assert!(
        held(&mut app),
        "the bar should hold the heading while in view"
    );
    // Turned 60° away: no bar, no pointer.
    controls.set_motion(Arc::new(Still(
        DQuat::from_rotation_z(60f64.to_radians()) * aim,
    )));
    common::update_until(&mut app, "the pointer to go", |a| pointer(a).is_none());
    assert!(!held(&mut app), "no bar, no heading reference");
}

/// A headless app with a bendable bar in front of a camera, and an emulated remote that sees
/// the sensor bar of `setup` from `position` and is a picking pointer (`ControllerPointerPlugin`).
fn remote_pointer_app(
    setup: bevy_wii_deform::controllers::wiimote::ir::PointerSetup,
    position: glam::DVec3,
) -> (App, Entity, Entity) {
    use bevy_wii_deform::controllers::wiimote::EmulatedBar;
    use bevy_wii_deform::deform::synth;
    let mut app = app();
    app.add_plugins((
        bevy::window::WindowPlugin::default(),
        bevy::input::InputPlugin,
        bevy::camera::CameraPlugin,
        common::picking_plugins(),
        MeshPickingPlugin,
        DeformPlugin::default(),
        GrabPlugin,
        MotionControllerPlugin {
            source: ControllerSource::Emulator(vec![
                EmulatorConfig {
                    clock: Some(EmulatorClock::new()),
                    sensor_bar: Some(EmulatedBar {
                        setup,
                        position,
                        noise_px: 0.0,
                    }),
                    ..default()
                }
                .into(),
            ]),
            pointer: Some(setup),
            ..default()
        },
        ControllerPointerPlugin,
    ));
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    app.finish();
    app.cleanup();
    let camera = common::spawn_camera(
        &mut app,
        Transform::from_xyz(0.0, 0.5, 4.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y),
    );
    let tri = synth::bar(12, 30, 0.1, 1.0);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let bar = app
        .world_mut()
        .spawn((
            Mesh3d(mesh),
            Transform::default(),
            Deformable::default(),
            Grabbable::default(),
        ))
        .id();
    common::update_until(&mut app, "the prepared mesh", |a| {
        a.world().get::<DeformStatus>(bar).unwrap().vertices > 0
    });
    (app, camera, bar)
}

/// The remote as a picking pointer: an emulated remote aimed at a bar on screen, A pressed,
/// starts a grab of that bar by the remote's own pointer at the spot it points at; with B held
/// too, turning the remote 40° turns the grab 40° (within 1°) without moving it; releasing A
/// ends it.
#[test]
fn the_remote_points_at_a_mesh_and_a_grabs_it() {
    use bevy::picking::pointer::PointerId;
    use bevy_wii_deform::controllers::wiimote::ir::PointerSetup;
    use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
    use bevy_wii_deform::ecs::ActiveGrabs;
    let setup = PointerSetup::default();
    let position = glam::DVec3::ZERO;
    let (mut app, camera, bar) = remote_pointer_app(setup, position);
    // Aim the remote at the bar's upper part as drawn (1280 × 720 window).
    let on_screen = common::to_screen(&mut app, camera, Vec3::new(0.0, 0.8, 0.1));
    let spot = (on_screen / Vec2::new(1280.0, 720.0)).as_dvec2();
    let aim = crate::wiimote_ir::aiming(position, setup.screen_point(spot), 0.0);
    let controls = app.world().resource::<ControllerEmulators>().0[0].clone();
    controls.set_motion(Arc::new(Still(aim)));
    let remote_id = |a: &mut App| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.iter(a.world())
            .find(|w| w.pointer.is_some())
            .map(|w| ControllerPointer::id(w.id))
    };
    common::update_until(&mut app, "the remote's pointer", |a| {
        let Some(id) = remote_id(a) else {
            return false;
        };
        let mut q = a.world_mut().query::<&PointerId>();
        q.iter(a.world()).any(|p| *p == id)
    });
    let id = remote_id(&mut app).unwrap();
    // As a player holds the remote still at start-up until its gyro is calibrated.
    common::update_until(&mut app, "the remote's calibration", |a| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.iter(a.world())
            .any(|w| matches!(w.calibration, ControllerCalibration::Calibrated(_)))
    });
    assert_eq!(app.world().resource::<ActiveGrabs>().len(), 0);
    controls.set_buttons(Buttons(Buttons::A));
    common::update_until(&mut app, "the remote's grab", |a| {
        a.world().resource::<ActiveGrabs>().mesh_of(id).is_some()
    });
    assert_eq!(app.world().resource::<ActiveGrabs>().mesh_of(id), Some(bar));
    // Hold B too (the clutch: turn only) and yaw the remote 40° in a second: the grab's
    // handle turns 40°, 1:1, and does not move.
    controls.set_buttons(Buttons(Buttons::A | Buttons::B));
    let handle = app
        .world()
        .get::<bevy_wii_deform::ecs::GrabHandle>(bar)
        .unwrap()
        .0;
    common::update_until(&mut app, "the grab's handle at its pivot", |a| {
        a.world()
            .get::<DeformHandle>(handle)
            .is_some_and(|h| h.pivot.is_some())
    });
    for _ in 0..5 {
        app.update();
    }
    let before = *app.world().get::<Transform>(handle).unwrap();
    let reported = |a: &mut App| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.iter(a.world()).next().unwrap().orientation
    };
    let remote_before = reported(&mut app);
    let now = |a: &mut App| {
        let mut q = a.world_mut().query::<&MotionController>();
        q.iter(a.world()).next().unwrap().timestamp_us as f64 * 1e-6
    };
    let t0 = now(&mut app) + 0.05;
    controls.set_motion(Arc::new(FnMotion(move |t: f64| {
        // A hand's turn: smooth, peaking at 60°/s.
        let s = ((t - t0) / 1.0).clamp(0.0, 1.0);
        let s = s * s * (3.0 - 2.0 * s);
        (
            DQuat::from_rotation_z((s * 40.0f64).to_radians()) * aim,
            DVec3::ZERO,
        )
    })));
    common::update_until(&mut app, "the turn", |a| now(a) > t0 + 1.5);
    app.update();
    let after = *app.world().get::<Transform>(handle).unwrap();
    let turned = (after.rotation * before.rotation.inverse())
        .to_axis_angle()
        .1
        .to_degrees();
    let remote_turned = (reported(&mut app) * remote_before.inverse())
        .to_axis_angle()
        .1
        .to_degrees();
    // 1:1 with what the remote reports (a gain of 0.9 would be 4° short)…
    assert!(
        (turned - remote_turned).abs() < 0.2,
        "the grab turned {turned}° for the remote's {remote_turned}°"
    );
    // …which is the true 40° within 1°. (Turned before the gyro's start-up calibration, the
    // turn-on bias not yet learnt, the same turn reads 42.5°.)
    assert!(
        (turned - 40.0).abs() < 1.0,
        "the grab turned {turned}° for 40° (the remote reported {remote_turned}°)"
    );
    assert!(
        after.translation.distance(before.translation) < 1e-4,
        "the clutch let the grab move"
    );
    controls.set_buttons(Buttons(0));
    common::update_until(&mut app, "the grab to end", |a| {
        a.world().resource::<ActiveGrabs>().is_empty()
    });
}
