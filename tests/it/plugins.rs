//! Headless plugin tests (MinimalPlugins + assets + meshes + transforms, no GPU).

use std::sync::Arc;
use std::time::{Duration, Instant};

use bevy::mesh::VertexAttributeValues;
use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::deform::{self, synth};
use bevy_wii_deform::ecs::{ActiveGrabs, GrabHandle};
use bevy_wii_deform::prelude::*;
use bevy_wii_deform::wiimote::protocol::Buttons;
use bevy_wii_deform::wiimote::{FnMotion, Still};
use glam::{DQuat, DVec3};

use crate::common;
use common::{app, cursor_to, pointer, spawn_camera, to_screen};

fn bar_mesh() -> (Mesh, deform::TriMesh) {
    let tri = synth::bar(12, 30, 0.1, 1.0);
    (mesh_from_triangles(&tri.positions, &tri.triangles), tri)
}

fn regions(tri: &deform::TriMesh) -> (Vec<u32>, Vec<u32>) {
    synth::slab_regions(&tri.positions, 1, 0.1, 0.1)
}

fn positions(app: &App, e: Entity) -> Vec<Vec3> {
    let h = app.world().get::<Mesh3d>(e).unwrap().0.clone();
    let meshes = app.world().resource::<Assets<Mesh>>();
    match meshes
        .get(&h)
        .unwrap()
        .attribute(Mesh::ATTRIBUTE_POSITION)
        .unwrap()
    {
        VertexAttributeValues::Float32x3(v) => v.iter().map(|p| Vec3::from_array(*p)).collect(),
        _ => panic!(),
    }
}

/// Updates until `n` DeformSolved/DeformFailed messages arrived (or a timeout).
fn run_until_messages(app: &mut App, n: usize) -> (Vec<DeformSolved>, Vec<DeformFailed>) {
    let (mut ok, mut bad) = (Vec::new(), Vec::new());
    let deadline = Instant::now() + Duration::from_secs(30);
    while ok.len() + bad.len() < n && Instant::now() < deadline {
        app.update();
        ok.extend(
            app.world_mut()
                .resource_mut::<Messages<DeformSolved>>()
                .drain(),
        );
        bad.extend(
            app.world_mut()
                .resource_mut::<Messages<DeformFailed>>()
                .drain(),
        );
        // The solves run on the task pool: give its threads the core, without sleeping.
        std::thread::yield_now();
    }
    (ok, bad)
}

fn spawn_bar(app: &mut App) -> (Entity, Entity, deform::TriMesh) {
    let (mesh, tri) = bar_mesh();
    let (fixed, handle) = regions(&tri);
    let mesh_for_bundle = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Deformable {
                max_iterations: Some(5),
                tolerance: Some(0.0),
                ..default()
            },
            FixedRegion(fixed),
        ))
        .id();
    let bundle = DeformHandle::bundle(&mesh_for_bundle, e, handle);
    let handle_entity = app.world_mut().spawn(bundle).id();
    (e, handle_entity, tri)
}

#[test]
fn moved_handle_matches_the_core_solver() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, tri) = spawn_bar(&mut app);
    let (ok, _) = run_until_messages(&mut app, 1); // initial solve at rest
    assert_eq!(ok.len(), 1);
    let rotation = Quat::from_rotation_z(0.5);
    {
        let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
        t.rotation = rotation;
        t.translation += Vec3::new(0.2, 0.0, 0.0);
    }
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(bad.is_empty(), "{bad:?}");
    assert_eq!(ok[0].entity, e);
    let got = positions(&app, e);

    // The same constraints through the core directly (the plugin's first solve, handles at
    // rest, starts from rest; the move is warm-started from it).
    let topology = Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
    let (fixed, hv) = regions(&tri);
    let pivot = hv.iter().map(|&i| tri.positions[i as usize]).sum::<DVec3>() / hv.len() as f64;
    let pivot32 = pivot.as_vec3();
    let mut c = Constraints::with_handle(
        fixed,
        hv,
        RigidTransform::new(DQuat::IDENTITY, DVec3::ZERO, pivot32.as_dvec3()),
    );
    let solver = ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
    let opts = SolveOptions {
        max_iterations: 5,
        tolerance: 0.0,
        acceleration: app.world().resource::<DeformConfig>().acceleration,
    };
    let first = solver
        .solve(&c, &opts, InitialGuess::Rest, &|| false)
        .unwrap();
    c.handles[0].transform = RigidTransform::new(
        rotation.as_dquat(),
        (pivot32 + Vec3::new(0.2, 0.0, 0.0)).as_dvec3() - pivot32.as_dvec3(),
        pivot32.as_dvec3(),
    );
    let second = solver
        .solve(&c, &opts, InitialGuess::Warm(&first), &|| false)
        .unwrap();
    let want = topology.to_render(&second.positions);
    let err = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a.as_dvec3() - *b).length())
        .fold(0.0, f64::max);
    assert!(err < 1e-4, "plugin vs core: {err}");
    assert!(
        got.iter()
            .zip(&tri.positions)
            .any(|(a, b)| (a.as_dvec3() - *b).length() > 0.05)
    );
}

/// The first solve on a rest pose starts from the paper's Laplacian guess only when the
/// handles are far from rest (`DeformConfig::laplacian_start_displacement`), else from rest:
/// one iteration through the plugin matches the core's one iteration from that start, and
/// not the other start's.
#[test]
fn the_first_solve_starts_from_the_laplacian_guess_only_for_a_far_pose() {
    for (offset, laplacian) in [(0.3f32, true), (0.02, false)] {
        let mut app = app();
        app.add_plugins(DeformPlugin::default());
        let (e, handle, tri) = spawn_bar(&mut app);
        app.world_mut()
            .get_mut::<Deformable>(e)
            .unwrap()
            .max_iterations = Some(1);
        let pivot = {
            let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
            let pivot = t.translation;
            t.translation += Vec3::new(offset, 0.0, 0.0);
            pivot
        };
        let (ok, bad) = run_until_messages(&mut app, 1);
        assert!(bad.is_empty() && ok.len() == 1, "{bad:?}");
        let got = positions(&app, e);

        let topology = Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
        let (fixed, hv) = regions(&tri);
        let c = Constraints::with_handle(
            fixed,
            hv,
            RigidTransform::new(
                DQuat::IDENTITY,
                (pivot + Vec3::new(offset, 0.0, 0.0)).as_dvec3() - pivot.as_dvec3(),
                pivot.as_dvec3(),
            ),
        );
        let solver =
            ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
        let opts = SolveOptions {
            max_iterations: 1,
            tolerance: 0.0,
            acceleration: app.world().resource::<DeformConfig>().acceleration,
        };
        let error_from = |start: InitialGuess| {
            let want = solver.solve(&c, &opts, start, &|| false).unwrap();
            let want = topology.to_render(&want.positions);
            got.iter()
                .zip(&want)
                .map(|(a, b)| (a.as_dvec3() - *b).length())
                .fold(0.0, f64::max)
        };
        let (from_laplacian, from_rest) = (
            error_from(InitialGuess::Laplacian),
            error_from(InitialGuess::Rest),
        );
        let (matched, other) = match laplacian {
            true => (from_laplacian, from_rest),
            false => (from_rest, from_laplacian),
        };
        assert!(
            matched < 1e-5 && other > 100.0 * matched.max(1e-6),
            "offset {offset}: from the Laplacian guess {from_laplacian:e}, from rest {from_rest:e}"
        );
    }
}

#[test]
fn a_burst_of_moves_ends_on_the_latest() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, _) = spawn_bar(&mut app);
    run_until_messages(&mut app, 1);
    for k in 1..=20 {
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .rotation = Quat::from_rotation_z(0.03 * k as f32);
        app.update();
    }
    // Let everything land.
    settle(&mut app, e);
    let status = app.world().get::<DeformStatus>(e).unwrap().clone();
    assert!(status.solves >= 2);
    // The final mesh corresponds to the final rotation: the handle centroid turned by 0.6 rad.
    let tip = positions(&app, e);
    let state_rot = Quat::from_rotation_z(0.6);
    let pivot = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .pivot
        .unwrap();
    let verts = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .vertices
        .clone();
    let (_, tri) = bar_mesh();
    for &v in &verts {
        let rest = tri.positions[v as usize].as_vec3();
        let want = pivot + state_rot * (rest - pivot);
        assert!((tip[v as usize] - want).length() < 1e-4, "vertex {v}");
    }
}

#[test]
fn invalid_constraints_fail_and_leave_the_mesh() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, tri) = spawn_bar(&mut app);
    run_until_messages(&mut app, 1);
    let before = positions(&app, e);
    // Overlap: make the fixed region contain a handle vertex.
    let hv = app.world().get::<DeformHandle>(handle).unwrap().vertices[0];
    app.world_mut()
        .get_mut::<FixedRegion>(e)
        .unwrap()
        .0
        .push(hv);
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x += 0.3;
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(ok.is_empty());
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(
        matches!(
            bad[0].error,
            DeformError::Solve(deform::SolveError::Constraint(
                deform::ConstraintError::Overlap { .. }
            ))
        ),
        "{}",
        bad[0].error
    );
    assert_eq!(positions(&app, e), before);
    assert!(app.world().get::<DeformStatus>(e).unwrap().error.is_some());
    let _ = tri;
    // NaN transform: failed, mesh unchanged, nothing non-finite written.
    app.world_mut().get_mut::<FixedRegion>(e).unwrap().0.pop();
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x = f32::NAN;
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(ok.is_empty() && bad.len() == 1);
    assert!(positions(&app, e).iter().all(|p| p.is_finite()));
}

#[test]
fn several_meshes_at_once() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (a, ha, _) = spawn_bar(&mut app);
    let (b, hb, _) = spawn_bar(&mut app);
    run_until_messages(&mut app, 2);
    app.world_mut()
        .get_mut::<Transform>(ha)
        .unwrap()
        .translation
        .x += 0.2;
    app.world_mut()
        .get_mut::<Transform>(hb)
        .unwrap()
        .translation
        .z += 0.2;
    let (ok, _) = run_until_messages(&mut app, 2);
    let entities: Vec<Entity> = ok.iter().map(|m| m.entity).collect();
    assert!(entities.contains(&a) && entities.contains(&b));
    assert_ne!(positions(&app, a), positions(&app, b));
}

/// A bar with a Wii Remote-controlled handle and one emulated remote paced by the app's clock
/// (10 ms per update): no wall-clock sleeps, the remote's samples follow the stepped time.
fn wiimote_app() -> (App, Entity, Entity) {
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    let clock = bevy_wii_deform::wiimote::EmulatorClock::new();
    app.add_plugins((
        DeformPlugin::default(),
        WiimotePlugin {
            source: WiimoteSource::Emulator(vec![EmulatorConfig {
                clock: Some(clock),
                ..default()
            }]),
            ..default()
        },
        WiimoteControlPlugin,
    ));
    let (e, handle, _) = spawn_bar(&mut app);
    app.world_mut()
        .entity_mut(handle)
        .insert(WiimoteHandleControl::default());
    (app, e, handle)
}

/// The remote entity's state, once there is one.
fn remote_state(app: &mut App) -> Option<Wiimote> {
    let mut q = app.world_mut().query::<&Wiimote>();
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
    let controls = app.world().resource::<WiimoteEmulators>().0[0].clone();
    controls.set_motion(Arc::new(Still(DQuat::IDENTITY)));
    // Connect and calibrate at rest.
    common::update_until(&mut app, "a calibrated remote", |a| {
        remote_state(a).is_some_and(|w| {
            w.connection == ConnectionState::Connected
                && w.motion_plus
                && matches!(w.calibration, WiimoteCalibration::Calibrated(_))
        })
    });
    let remote = {
        let mut q = app.world_mut().query_filtered::<Entity, With<Wiimote>>();
        q.single(app.world()).expect("one remote entity")
    };
    // Grab with B, then yaw the remote (about its top axis = Bevy +Y) by 40° over 1 s of its
    // own time, and hold still.
    controls.set_buttons(Buttons(Buttons::B));
    common::update_until(&mut app, "the grab", |a| {
        a.world()
            .get::<WiimoteHandleControl>(handle)
            .unwrap()
            .is_grabbing()
    });
    let t0 = remote_state(&mut app).unwrap().timestamp_us as f64 * 1e-6 + 0.1;
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
        a.world().get::<Wiimote>(remote).unwrap().connection == ConnectionState::Disconnected
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
            .get::<WiimoteHandleControl>(handle)
            .unwrap()
            .is_grabbing()
    );
    for p in positions(&app, e) {
        assert!(p.is_finite());
    }
    // It comes back on the same entity.
    controls.set_connected(true);
    common::update_until(&mut app, "the reconnect", |a| {
        a.world().get::<Wiimote>(remote).unwrap().connection == ConnectionState::Connected
    });
}

#[derive(Resource, Default)]
struct SeenProblems(Vec<WiimoteProblem>);

fn collect_problems(mut reader: MessageReader<WiimoteProblem>, mut seen: ResMut<SeenProblems>) {
    seen.0.extend(reader.read().cloned());
}

#[test]
fn a_remote_that_cannot_be_opened_reaches_a_message_and_its_entity() {
    use bevy_wii_deform::wiimote::{EmulatorConfig, OpenErrorKind, RemoteProblem};
    let mut app = app();
    app.add_plugins(WiimotePlugin {
        source: WiimoteSource::Emulator(vec![EmulatorConfig {
            open_error: Some(OpenErrorKind::PermissionDenied),
            ..Default::default()
        }]),
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
        assert!(Instant::now() < deadline, "no WiimoteProblem message");
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
    let remote = app.world().get::<Wiimote>(entity).expect("remote entity");
    assert_eq!(remote.connection, ConnectionState::Unusable);
    assert_eq!(remote.problems, vec![expected.clone()]);
    assert_eq!(
        app.world().resource::<WiimoteProblems>().0,
        vec![expected.clone()]
    );
    assert!(expected.to_string().contains("udev"), "{expected}");
}

#[test]
fn changing_the_region_of_interest_at_run_time_refactorizes() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, tri) = spawn_bar(&mut app);
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    {
        let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
        t.rotation = Quat::from_rotation_z(0.5);
        t.translation += Vec3::new(0.2, 0.0, 0.0);
    }
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    // Only the upper part may move now: the lower middle must go back to rest.
    let (lo, hi) = tri
        .positions
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let at = |f: f64| lo + f * (hi - lo);
    let roi: Vec<u32> = (0..tri.positions.len() as u32)
        .filter(|&i| tri.positions[i as usize].y > at(0.5))
        .collect();
    let outside: Vec<usize> = (0..tri.positions.len())
        .filter(|&i| (at(0.15)..at(0.45)).contains(&tri.positions[i].y))
        .collect();
    let moved_before = outside
        .iter()
        .map(|&i| (positions(&app, e)[i].as_dvec3() - tri.positions[i]).length())
        .fold(0.0, f64::max);
    assert!(
        moved_before > 1e-3,
        "the bend moved the lower middle: {moved_before}"
    );
    app.world_mut()
        .get_mut::<Deformable>(e)
        .unwrap()
        .region_of_interest = Some(roi);
    // Solves of the old region may still land (settling); wait until all is done.
    settle(&mut app, e);
    let status = app.world().get::<DeformStatus>(e).unwrap();
    assert!(status.error.is_none(), "{:?}", status.error);
    let got = positions(&app, e);
    let moved_after = outside
        .iter()
        .map(|&i| (got[i].as_dvec3() - tri.positions[i]).length())
        .fold(0.0, f64::max);
    assert!(
        moved_after < 1e-5,
        "outside the region of interest: moved {moved_after}"
    );
}

#[test]
fn a_handle_without_pivot_at_the_identity_transform_does_not_jump() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (mesh, tri) = bar_mesh();
    let (fixed, handle_vertices) = regions(&tri);
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((Mesh3d(h), Deformable::default(), FixedRegion(fixed)))
        .id();
    let centroid = handle_vertices
        .iter()
        .map(|&i| tri.positions[i as usize])
        .sum::<DVec3>()
        / handle_vertices.len() as f64;
    let handle = app
        .world_mut()
        .spawn((
            DeformHandle {
                target: e,
                vertices: handle_vertices,
                pivot: None,
            },
            Transform::IDENTITY,
        ))
        .id();
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(bad.is_empty() && ok.len() == 1, "{bad:?}");
    let moved = positions(&app, e)
        .iter()
        .zip(&tri.positions)
        .map(|(a, b)| (a.as_dvec3() - *b).length())
        .fold(0.0, f64::max);
    assert!(moved < 1e-4, "the mesh jumped by {moved}");
    let t = app.world().get::<Transform>(handle).unwrap();
    assert!(
        (t.translation.as_dvec3() - centroid).length() < 1e-5,
        "{t:?}"
    );
    assert_eq!(
        app.world().get::<DeformHandle>(handle).unwrap().pivot,
        Some(t.translation)
    );
}

#[test]
fn a_mesh_that_cannot_be_prepared_fails_with_a_typed_reason() {
    use bevy::mesh::PrimitiveTopology;
    use bevy_wii_deform::deform::MeshError;
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (mut nan_mesh, _) = bar_mesh();
    if let Some(VertexAttributeValues::Float32x3(p)) =
        nan_mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
    {
        p[5][1] = f32::NAN;
    }
    let lines = Mesh::new(PrimitiveTopology::LineList, Default::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3], [1.0, 0.0, 0.0]]);
    let mut spawn = |mesh: Mesh| {
        let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        app.world_mut()
            .spawn((Mesh3d(h), Deformable::default()))
            .id()
    };
    let (nan, line) = (spawn(nan_mesh), spawn(lines));
    let (ok, bad) = run_until_messages(&mut app, 2);
    assert!(ok.is_empty());
    let error_of = |e: Entity| bad.iter().find(|m| m.entity == e).map(|m| m.error.clone());
    assert_eq!(
        error_of(nan),
        Some(DeformError::Mesh(MeshError::NonFinitePosition {
            vertex: 5
        }))
    );
    assert!(
        matches!(error_of(line), Some(DeformError::NotTriangleList(_))),
        "{bad:?}"
    );
    for e in [nan, line] {
        let status = app.world().get::<DeformStatus>(e).unwrap();
        assert_eq!(status.phase, DeformPhase::Failed);
        assert!(status.error.is_some());
    }
}

#[test]
fn deformable_on_an_ancestor_applies_to_the_meshes_below_it() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    // A glTF-like hierarchy: root → node (its own transform) → primitive with the mesh.
    let (mesh, tri) = bar_mesh();
    let (fixed, handle_vertices) = regions(&tri);
    let bundle_source = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let root = app
        .world_mut()
        .spawn((
            Deformable {
                max_iterations: Some(5),
                ..default()
            },
            Transform::from_scale(Vec3::splat(2.0)),
        ))
        .id();
    let node = app
        .world_mut()
        .spawn((
            Transform::from_rotation(Quat::from_rotation_x(0.7)),
            ChildOf(root),
        ))
        .id();
    let primitive = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Transform::default(),
            FixedRegion(fixed),
            ChildOf(node),
        ))
        .id();
    let lonely = app.world_mut().spawn(Deformable::default()).id();
    let handle = app
        .world_mut()
        .spawn(DeformHandle::bundle(
            &bundle_source,
            primitive,
            handle_vertices,
        ))
        .id();
    let (ok, bad) = run_until_messages(&mut app, 2);
    assert_eq!(ok.len(), 1, "{ok:?} {bad:?}");
    assert_eq!(ok[0].entity, primitive);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert_eq!(
        (bad[0].entity, &bad[0].error),
        (lonely, &DeformError::NoMeshBelow)
    );
    assert_eq!(
        app.world().get::<DeformableScene>(root).unwrap().primitives,
        vec![primitive]
    );
    assert_eq!(
        app.world().get::<DeformableFrom>(primitive),
        Some(&DeformableFrom(root))
    );
    // The handle bends the primitive; settings changed on the root reach it.
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x += 0.2;
    let (ok, _) = run_until_messages(&mut app, 1);
    assert_eq!(ok.len(), 1);
    assert!(
        positions(&app, primitive)
            .iter()
            .zip(&tri.positions)
            .any(|(a, b)| (a.as_dvec3() - *b).length() > 0.05)
    );
    app.world_mut()
        .get_mut::<Deformable>(root)
        .unwrap()
        .max_iterations = Some(2);
    app.update();
    assert_eq!(
        app.world()
            .get::<Deformable>(primitive)
            .unwrap()
            .max_iterations,
        Some(2)
    );
}

/// Where a world point along the ray through `cursor` meets the plane through `at` facing the
/// camera.
fn under_cursor(app: &mut App, camera: Entity, at: Vec3, cursor: Vec2) -> Vec3 {
    let (cam, tf) = {
        let mut q = app.world_mut().query::<(&Camera, &GlobalTransform)>();
        let (c, t) = q.get(app.world(), camera).unwrap();
        (c.clone(), *t)
    };
    let ray = cam.viewport_to_world(&tf, cursor).unwrap();
    let normal = *tf.forward();
    ray.origin + *ray.direction * ((at - ray.origin).dot(normal) / ray.direction.dot(normal))
}

/// Updates until the deformable has been idle (no solve in flight, none landed) for 20 frames.
fn settle(app: &mut App, e: Entity) {
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut idle_frames = 0;
    while idle_frames < 20 {
        assert!(Instant::now() < deadline, "never settled");
        let before = app.world().get::<DeformStatus>(e).unwrap().solves;
        app.update();
        std::thread::yield_now();
        let status = app.world().get::<DeformStatus>(e).unwrap();
        idle_frames = if status.phase == DeformPhase::Idle && status.solves == before {
            idle_frames + 1
        } else {
            0
        };
    }
}

#[test]
fn a_mouse_drag_moves_a_handle_on_a_scaled_rotated_mesh_with_the_cursor() {
    let mut app = app();
    app.add_plugins((
        bevy::window::WindowPlugin::default(),
        bevy::input::InputPlugin,
        bevy::camera::CameraPlugin,
        DeformPlugin::default(),
        MouseControlPlugin,
    ));
    app.finish();
    app.cleanup();
    let camera = spawn_camera(
        &mut app,
        Transform::from_xyz(0.5, 1.0, 6.0).looking_at(Vec3::new(0.0, 1.0, 0.0), Vec3::Y),
    );
    let (mesh, tri) = bar_mesh();
    let (fixed, handle_vertices) = regions(&tri);
    let bundle_source = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let mesh_transform = Transform::from_xyz(0.3, 0.2, 0.0)
        .with_rotation(Quat::from_rotation_z(0.6))
        .with_scale(Vec3::splat(2.0));
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            mesh_transform,
            Deformable {
                max_iterations: Some(30),
                tolerance: Some(0.0),
                ..default()
            },
            FixedRegion(fixed),
        ))
        .id();
    let (handle_component, handle_transform) =
        DeformHandle::bundle(&bundle_source, e, handle_vertices.clone());
    let handle = app
        .world_mut()
        .spawn((
            handle_component,
            handle_transform,
            MouseHandleControl::default()
                .with_camera(camera)
                .with_space(e),
        ))
        .id();
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    app.update();
    // Where the handle is on screen.
    let world_of = |app: &App, local: Vec3| {
        app.world()
            .get::<GlobalTransform>(e)
            .unwrap()
            .transform_point(local)
    };
    let start_world = world_of(&app, handle_transform.translation);
    let start = to_screen(&mut app, camera, start_world);
    let end = start + Vec2::new(60.0, -25.0);
    // Shift + press at the handle, drag in three steps, release.
    cursor_to(&mut app, start);
    app.world_mut()
        .resource_mut::<ButtonInput<KeyCode>>()
        .press(KeyCode::ShiftLeft);
    app.world_mut()
        .resource_mut::<ButtonInput<MouseButton>>()
        .press(MouseButton::Left);
    app.update();
    for k in 1..=3 {
        cursor_to(&mut app, start + (end - start) * k as f32 / 3.0);
        app.update();
    }
    app.world_mut()
        .resource_mut::<ButtonInput<MouseButton>>()
        .release(MouseButton::Left);
    app.update();
    // The handle is under the cursor, at its depth.
    let moved_world = world_of(
        &app,
        app.world().get::<Transform>(handle).unwrap().translation,
    );
    let expected = under_cursor(&mut app, camera, start_world, end);
    let drag = expected - start_world;
    assert!(drag.length() > 0.1, "{drag}");
    assert!(
        (moved_world - expected).length() < 0.02 * drag.length(),
        "handle at {moved_world}, cursor ray at {expected}"
    );
    // The solve moves the handle's vertices by the drag, in world space; the fixed end stays.
    // (Solves of the drag's intermediate frames may land first: wait until the latest did.)
    settle(&mut app, e);
    let got = positions(&app, e);
    let mesh_to_world = app.world().get::<GlobalTransform>(e).unwrap().affine();
    for &v in handle_vertices.iter().take(20) {
        let rest = mesh_to_world.transform_point3(tri.positions[v as usize].as_vec3());
        let now = mesh_to_world.transform_point3(got[v as usize]);
        assert!(
            ((now - rest) - drag).length() < 0.02 * drag.length(),
            "vertex {v}: {}",
            now - rest
        );
    }
    let (fixed, _) = regions(&tri);
    for &v in &fixed {
        assert!((got[v as usize].as_dvec3() - tri.positions[v as usize]).length() < 1e-5);
    }
    assert!(
        !app.world()
            .get::<MouseHandleControl>(handle)
            .unwrap()
            .is_dragging()
    );
}

#[test]
fn the_arcball_turns_about_the_view_axes() {
    let centre = Vec2::new(400.0, 300.0);
    // A horizontal drag through the centre turns about the view's up axis, to the right.
    use bevy_wii_deform::ecs::arcball_rotation;
    let q = arcball_rotation(centre, centre + Vec2::new(50.0, 0.0), centre, 200.0);
    let (axis, angle) = q.to_axis_angle();
    assert!(
        axis.y > 0.99 && (angle - (0.25f32).asin()).abs() < 1e-4,
        "{axis} {angle}"
    );
    // Dragging along the rim rolls about the view direction.
    let q = arcball_rotation(
        centre + Vec2::new(300.0, 0.0),
        centre + Vec2::new(0.0, -300.0),
        centre,
        200.0,
    );
    let (axis, angle) = q.to_axis_angle();
    assert!(
        axis.z > 0.99 && (angle - std::f32::consts::FRAC_PI_2).abs() < 1e-4,
        "{axis} {angle}"
    );
}

#[test]
fn the_remote_turns_a_handle_one_to_one_in_camera_space_and_translates_only_while_grabbing() {
    use bevy::time::TimeUpdateStrategy;
    let mut app = app();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        10,
    )));
    app.add_plugins(WiimoteControlPlugin);
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
        .spawn(Wiimote {
            connection: ConnectionState::Connected,
            orientation: start,
            ..default()
        })
        .id();
    let handle = app
        .world_mut()
        .spawn((Transform::default(), WiimoteHandleControl::default()))
        .id();
    let set = |app: &mut App, orientation: Quat, buttons: u16| {
        let mut w = app.world_mut().get_mut::<Wiimote>(remote).unwrap();
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
    let speed = WiimoteHandleControl::default().speed;
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
            .get::<WiimoteHandleControl>(handle)
            .unwrap()
            .is_grabbing()
    );
}

/// A headless app with deformation and grabs, and a camera at `eye` looking at `target`.
fn grab_app(eye: Vec3, target: Vec3) -> (App, Entity) {
    let mut app = app();
    app.add_plugins((DeformPlugin::default(), GrabPlugin));
    let camera = spawn_camera(
        &mut app,
        Transform::from_translation(eye).looking_at(target, Vec3::Y),
    );
    (app, camera)
}

#[test]
fn grabbing_a_scaled_rotated_mesh_bends_it_under_the_pointer_and_keeps_the_pose() {
    let (mut app, camera) = grab_app(Vec3::new(0.0, 1.0, 7.0), Vec3::new(0.0, 1.0, 0.0));
    let (mesh, tri) = bar_mesh();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Transform::from_xyz(0.2, 0.1, 0.0)
                .with_rotation(Quat::from_rotation_z(-0.3))
                .with_scale(Vec3::splat(2.0)),
            Deformable {
                max_iterations: Some(20),
                tolerance: Some(0.0),
                ..default()
            },
            // World units: the patch is the tip's cap, the region the upper half of the bar.
            Grabbable {
                radius: 0.15,
                region_radius: 1.0,
                ..default()
            },
        ))
        .id();
    while app.world().get::<DeformStatus>(e).unwrap().vertices == 0 {
        app.update();
    }
    let world = |app: &App, p: Vec3| {
        app.world()
            .get::<GlobalTransform>(e)
            .unwrap()
            .transform_point(p)
    };
    let top = (0..tri.positions.len())
        .max_by(|&a, &b| tri.positions[a].y.total_cmp(&tri.positions[b].y))
        .unwrap();
    let bottom = (0..tri.positions.len())
        .min_by(|&a, &b| tri.positions[a].y.total_cmp(&tri.positions[b].y))
        .unwrap();
    let grab = |app: &mut App, vertex: usize, pixels: Vec2| -> Vec3 {
        let point = world(app, positions(app, e)[vertex]);
        app.world_mut().write_message(GrabStart {
            pointer: PointerId::Mouse,
            entity: e,
            point,
            camera,
        });
        let from = to_screen(app, camera, point);
        app.world_mut().write_message(GrabMove {
            pointer: PointerId::Mouse,
            from,
            to: from + pixels,
            rotate: false,
        });
        settle(app, e);
        app.world_mut().write_message(GrabEnd {
            pointer: PointerId::Mouse,
        });
        settle(app, e);
        under_cursor(app, camera, point, from + pixels) - point
    };
    let drag = grab(&mut app, top, Vec2::new(70.0, 30.0));
    assert!(drag.length() > 0.2, "{drag}");
    let handle = app.world().get::<GrabHandle>(e).expect("a grab handle").0;
    let patch = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .vertices
        .clone();
    assert!(
        patch.contains(&(top as u32)) && patch.len() < 40,
        "{}",
        patch.len()
    );
    let got = positions(&app, e);
    for &v in &patch {
        let moved = world(&app, got[v as usize]) - world(&app, tri.positions[v as usize].as_vec3());
        assert!(
            (moved - drag).length() < 0.02 * drag.length(),
            "vertex {v}: {moved} vs {drag}"
        );
    }
    // The far end is outside the region: exactly at rest.
    let far = (got[bottom].as_dvec3() - tri.positions[bottom]).length();
    assert!(far < 1e-6, "{far}");
    // Released: the pose stays. A second grab, at the bottom, keeps the first bend.
    let tip_after_first = world(&app, got[top]);
    let second = grab(&mut app, bottom, Vec2::new(-30.0, 0.0));
    assert!(second.length() > 0.05);
    let tip_now = world(&app, positions(&app, e)[top]);
    assert!(
        (tip_now - tip_after_first).length() < 0.02 * drag.length(),
        "the first bend was lost: tip at {tip_now}, was {tip_after_first}"
    );
}

#[test]
fn two_pointers_grab_two_meshes_at_once_one_moving_one_turning() {
    let (mut app, camera) = grab_app(Vec3::new(0.0, 0.6, 5.0), Vec3::new(0.0, 0.6, 0.0));
    let (_, tri) = bar_mesh();
    let mut spawn = |x: f32| {
        let (mesh, _) = bar_mesh();
        let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        app.world_mut()
            .spawn((
                Mesh3d(h),
                Transform::from_xyz(x, 0.0, 0.0),
                Deformable::default(),
                // The patch takes in the cap's ring, off the turning axis.
                Grabbable {
                    radius: 0.15,
                    region_radius: 0.6,
                    ..default()
                },
            ))
            .id()
    };
    let (a, b) = (spawn(-0.8), spawn(0.8));
    while [a, b]
        .iter()
        .any(|e| app.world().get::<DeformStatus>(*e).unwrap().vertices == 0)
    {
        app.update();
    }
    let top = (0..tri.positions.len())
        .max_by(|&i, &j| tri.positions[i].y.total_cmp(&tri.positions[j].y))
        .unwrap();
    let tip = |x: f32| tri.positions[top].as_vec3() + Vec3::X * x;
    let (mouse, finger) = (PointerId::Mouse, PointerId::Touch(1));
    for (pointer, entity, x) in [(mouse, a, -0.8), (finger, b, 0.8)] {
        app.world_mut().write_message(GrabStart {
            pointer,
            entity,
            point: tip(x),
            camera,
        });
    }
    // Let both handles be placed, then move A with the mouse and turn B with the finger.
    settle(&mut app, a);
    settle(&mut app, b);
    let (from_a, from_b) = (
        to_screen(&mut app, camera, tip(-0.8)),
        to_screen(&mut app, camera, tip(0.8)),
    );
    app.world_mut().write_message(GrabMove {
        pointer: mouse,
        from: from_a,
        to: from_a + Vec2::new(-40.0, 0.0),
        rotate: false,
    });
    app.world_mut().write_message(GrabMove {
        pointer: finger,
        from: from_b,
        to: from_b + Vec2::new(60.0, 0.0),
        rotate: true,
    });
    settle(&mut app, a);
    settle(&mut app, b);
    let handle_of = |app: &App, e: Entity| {
        let h = app.world().get::<GrabHandle>(e).unwrap().0;
        *app.world().get::<Transform>(h).unwrap()
    };
    let pivot_of = |app: &App, e: Entity| {
        let h = app.world().get::<GrabHandle>(e).unwrap().0;
        app.world().get::<DeformHandle>(h).unwrap().pivot.unwrap()
    };
    // A: moved left under the mouse, not turned.
    let ta = handle_of(&app, a);
    let moved = ta.translation - pivot_of(&app, a);
    let expected =
        under_cursor(&mut app, camera, tip(-0.8), from_a + Vec2::new(-40.0, 0.0)) - tip(-0.8);
    assert!(
        (moved - expected).length() < 0.02 * expected.length(),
        "{moved} vs {expected}"
    );
    assert!(ta.rotation.angle_between(Quat::IDENTITY) < 1e-6);
    // B: turned about the view's up axis (a horizontal arcball drag), not moved.
    let tb = handle_of(&app, b);
    assert!((tb.translation - pivot_of(&app, b)).length() < 1e-6);
    let (axis, angle) = tb.rotation.to_axis_angle();
    assert!(
        angle > 0.05 && axis.y > 0.95,
        "turned {angle} rad about {axis}"
    );
    // The meshes follow: A's tip by the drag, B's patch turned (off-axis vertices moved).
    let got_a = positions(&app, a);
    let tip_moved = got_a[top].as_dvec3() - tri.positions[top];
    assert!(
        (tip_moved.as_vec3() - expected).length() < 0.02 * expected.length(),
        "{tip_moved}"
    );
    let h = app.world().get::<GrabHandle>(b).unwrap().0;
    let patch = app.world().get::<DeformHandle>(h).unwrap().vertices.clone();
    let got_b = positions(&app, b);
    let turned = patch
        .iter()
        .map(|&v| (got_b[v as usize].as_dvec3() - tri.positions[v as usize]).length())
        .fold(0.0, f64::max);
    assert!(turned > 1e-3, "{turned}");
}

#[test]
fn normals_and_tangents_turn_with_the_surface_and_two_handles_move_one_mesh() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let tri = synth::bar(12, 30, 0.1, 1.0);
    // Rest normals and tangents (tangent along +Y, handedness −1 kept through the solve).
    let mut mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let tangents: Vec<[f32; 4]> = vec![[0.0, 1.0, 0.0, -1.0]; tri.positions.len()];
    mesh.insert_attribute(Mesh::ATTRIBUTE_TANGENT, tangents);
    let rest_normals = match mesh.attribute(Mesh::ATTRIBUTE_NORMAL).unwrap() {
        VertexAttributeValues::Float32x3(n) => n.clone(),
        _ => unreachable!(),
    };
    // Fixed middle, a handle at each end.
    let (lo, hi) = tri
        .positions
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let band = |a: f64, b: f64| -> Vec<u32> {
        (0..tri.positions.len() as u32)
            .filter(|&i| {
                (lo + a * (hi - lo)..=lo + b * (hi - lo)).contains(&tri.positions[i as usize].y)
            })
            .collect()
    };
    let (bottom, middle, top) = (band(0.0, 0.08), band(0.4, 0.6), band(0.92, 1.0));
    let bundle_source = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Deformable {
                max_iterations: Some(40),
                tolerance: Some(0.0),
                ..default()
            },
            FixedRegion(middle),
        ))
        .id();
    let top_handle = app
        .world_mut()
        .spawn(DeformHandle::bundle(&bundle_source, e, top.clone()))
        .id();
    let bottom_handle = app
        .world_mut()
        .spawn(DeformHandle::bundle(&bundle_source, e, bottom.clone()))
        .id();
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    let turn = Quat::from_rotation_z(0.5);
    {
        let mut t = app.world_mut().get_mut::<Transform>(top_handle).unwrap();
        t.rotation = turn;
        t.translation.x += 0.1;
    }
    app.world_mut()
        .get_mut::<Transform>(bottom_handle)
        .unwrap()
        .translation
        .x -= 0.15;
    settle(&mut app, e);
    let got = positions(&app, e);
    // Both handles' vertices are on their targets.
    let pivot = |v: &[u32]| {
        v.iter()
            .map(|&i| tri.positions[i as usize].as_vec3())
            .sum::<Vec3>()
            / v.len() as f32
    };
    let pt = pivot(&top);
    for &v in &top {
        let want = pt + Vec3::X * 0.1 + turn * (tri.positions[v as usize].as_vec3() - pt);
        assert!(got[v as usize].distance(want) < 1e-4, "top {v}");
    }
    for &v in &bottom {
        let want = tri.positions[v as usize].as_vec3() - Vec3::X * 0.15;
        assert!(got[v as usize].distance(want) < 1e-4, "bottom {v}");
    }
    // Normals and tangents of the turned end turned with it; the middle's stayed.
    let handle = app.world().get::<Mesh3d>(e).unwrap().0.clone();
    let meshes = app.world().resource::<Assets<Mesh>>();
    let mesh = meshes.get(&handle).unwrap();
    let (
        Some(VertexAttributeValues::Float32x3(normals)),
        Some(VertexAttributeValues::Float32x4(tangents)),
    ) = (
        mesh.attribute(Mesh::ATTRIBUTE_NORMAL),
        mesh.attribute(Mesh::ATTRIBUTE_TANGENT),
    )
    else {
        panic!("normals and tangents kept");
    };
    // (Cells whose whole one-ring is in the handle turn exactly with it: the band's inner ring.)
    let inner = |v: &&u32| {
        let y = tri.positions[**v as usize].y;
        y > lo + 0.95 * (hi - lo) && y < hi - 1e-9
    };
    let checked = top.iter().filter(inner).count();
    assert!(checked >= 12, "{checked}");
    for &v in top.iter().filter(inner) {
        let n = Vec3::from_array(normals[v as usize]);
        let want = turn * Vec3::from_array(rest_normals[v as usize]);
        assert!(
            n.angle_between(want) < 3f32.to_radians(),
            "normal {v}: {n} vs {want}"
        );
        let t = Vec4::from_array(tangents[v as usize]);
        assert!(
            t.truncate().angle_between(turn * Vec3::Y) < 3f32.to_radians(),
            "tangent {v}: {t}"
        );
        assert_eq!(t.w, -1.0);
    }
    for v in band(0.47, 0.53) {
        let n = Vec3::from_array(normals[v as usize]);
        assert!(
            n.angle_between(Vec3::from_array(rest_normals[v as usize])) < 1e-3,
            "middle {v}"
        );
    }
}

/// A headless app with a window, input, cameras, `PosePlugin` and `plugins`; a camera looking
/// at a three-bone bar character whose root joint is pinned.
fn character_app<M>(
    plugins: impl bevy::app::Plugins<M>,
) -> (
    App,
    Entity,
    bevy_wii_deform::pose::synth_rig::SyntheticRig,
    Entity,
    Vec<Entity>,
) {
    let mut app = app();
    app.add_plugins((
        bevy::window::WindowPlugin::default(),
        bevy::input::InputPlugin,
        bevy::camera::CameraPlugin,
        PosePlugin,
    ))
    .add_plugins(plugins);
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(16),
    ));
    app.finish();
    app.cleanup();
    let camera = spawn_camera(
        &mut app,
        Transform::from_xyz(0.0, 0.6, 4.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y),
    );
    let rig = bevy_wii_deform::pose::synth_rig::bar_rig(3, 12, 30);
    let (root, joints, _) = common::spawn_rig(&mut app, &rig, Vec3::ZERO);
    app.world_mut().entity_mut(root).insert((
        Poseable {
            max_iterations: 8,
            ..default()
        },
        PinnedJoints(vec![joints[0]]),
    ));
    (app, camera, rig, root, joints)
}

/// `MouseHandleControl` drives a character's handle exactly like a static mesh's: shift-drag
/// puts the handle under the cursor (world space, `space: None`) and the skeleton follows.
#[test]
fn a_mouse_drag_moves_a_character_handle_with_the_cursor() {
    let (mut app, camera, rig, root, joints) = character_app(MouseControlPlugin);
    common::update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let top: Vec<u32> = (0..rig.mesh.positions.len() as u32)
        .filter(|&i| rig.mesh.positions[i as usize].y > 0.8)
        .collect();
    let (handle, pivot) = common::spawn_handle(
        &mut app,
        root,
        top.clone(),
        MouseHandleControl::default().with_camera(camera),
    );
    app.update();
    let start = to_screen(&mut app, camera, pivot);
    let end = start + Vec2::new(70.0, 0.0);
    cursor_to(&mut app, start);
    app.world_mut()
        .resource_mut::<ButtonInput<KeyCode>>()
        .press(KeyCode::ShiftLeft);
    app.world_mut()
        .resource_mut::<ButtonInput<MouseButton>>()
        .press(MouseButton::Left);
    app.update();
    for k in 1..=3 {
        cursor_to(&mut app, start + (end - start) * k as f32 / 3.0);
        app.update();
    }
    app.world_mut()
        .resource_mut::<ButtonInput<MouseButton>>()
        .release(MouseButton::Left);
    app.update();
    let moved = app.world().get::<Transform>(handle).unwrap().translation;
    let expected = under_cursor(&mut app, camera, pivot, end);
    let drag = expected - pivot;
    assert!(drag.length() > 0.1, "{drag}");
    assert!(
        (moved - expected).length() < 0.02 * drag.length(),
        "handle at {moved}, cursor ray at {expected}"
    );
    // Let the pose settle; the top follows the drag sideways (the pinned root cannot let it
    // translate exactly: the bar bends), the root stays.
    common::settle_pose(&mut app, root);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap();
    let skinned = posed.skinned_positions();
    let centroid = top.iter().map(|&i| skinned[i as usize]).sum::<Vec3>() / top.len() as f32;
    // A rigid handle on a bar whose root is pinned: the sideways drag needs the bar to turn,
    // so the top gets most of the way, not all (it stops near 93 %).
    assert!(
        (centroid - pivot).dot(drag.normalize()) > 0.85 * drag.length(),
        "top centroid moved {}",
        centroid - pivot
    );
    let root_rotation = app.world().get::<Transform>(joints[0]).unwrap().rotation;
    assert!(
        root_rotation.angle_between(Quat::IDENTITY) < 0.01,
        "the pinned root turned {}°",
        root_rotation.angle_between(Quat::IDENTITY).to_degrees()
    );
}

/// `GrabPlugin` grabs a *posed* character from the raw pointer input (Bevy's picking sees only
/// the bind pose of skinned meshes): the press picks the CPU-skinned surface, motion drags the
/// patch in the view plane, the wheel twists it about the view axis, release ends the grab and
/// the pose stays; a second press where only the posed surface is hits it.
#[test]
fn the_pointer_grabs_a_posed_character_drags_twists_and_releases() {
    use bevy::picking::pointer::{PointerAction, PointerButton};
    let (mut app, camera, rig, root, _) = character_app((
        DeformPlugin::default(),
        GrabPlugin,
        common::picking_plugins(),
    ));
    app.world_mut().entity_mut(root).insert(Grabbable {
        radius: 0.12,
        region_radius: 1.0,
        ..default()
    });
    common::update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let tip = Vec3::new(0.0, 0.98, 0.1); // on the bar's front face, near the top
    let start = to_screen(&mut app, camera, tip);
    pointer(
        &mut app,
        start,
        PointerAction::Press(PointerButton::Primary),
    );
    common::update_until(&mut app, "the grab handle", |a| {
        a.world()
            .get::<GrabHandle>(root)
            .and_then(|h| a.world().get::<DeformHandle>(h.0))
            .is_some_and(|h| h.pivot.is_some())
    });
    let handle = app.world().get::<GrabHandle>(root).unwrap().0;
    let patch = app.world().get::<DeformHandle>(handle).unwrap().clone();
    let pivot = patch.pivot.unwrap();
    // The patch is the surface around the hit, measured along it: the top, not the bottom.
    assert!(!patch.vertices.is_empty() && patch.vertices.len() < 150);
    for &v in &patch.vertices {
        let p = rig.mesh.positions[v as usize];
        assert!(
            p.distance(tip) < 0.125,
            "vertex {v} at {p} is not near {tip}"
        );
    }
    // Drag 80 px to the right in four moves: the handle stays under the cursor.
    let end = start + Vec2::new(80.0, 0.0);
    for k in 1..=4 {
        pointer(
            &mut app,
            start + (end - start) * k as f32 / 4.0,
            PointerAction::Move {
                delta: (end - start) / 4.0,
            },
        );
        app.update();
    }
    // The patch moves with the cursor at its own depth.
    let drag =
        under_cursor(&mut app, camera, pivot, end) - under_cursor(&mut app, camera, pivot, start);
    let expected = pivot + drag;
    let moved = app.world().get::<Transform>(handle).unwrap().translation;
    assert!(drag.length() > 0.1, "{drag}");
    assert!(
        (moved - expected).length() < 0.02 * drag.length(),
        "handle at {moved}, cursor ray at {expected}"
    );
    // Three wheel lines: 30° counter-clockwise on screen (about the camera's back axis).
    let before = app.world().get::<Transform>(handle).unwrap().rotation;
    pointer(
        &mut app,
        end,
        PointerAction::Scroll {
            unit: bevy::input::mouse::MouseScrollUnit::Line,
            x: 0.0,
            y: 3.0,
            phase: bevy::input::touch::TouchPhase::Moved,
        },
    );
    app.update();
    let after = app.world().get::<Transform>(handle).unwrap().rotation;
    let back = app.world().get::<GlobalTransform>(camera).unwrap().back();
    let expected_turn = Quat::from_axis_angle(*back, 30f32.to_radians());
    let error = (after * before.inverse()).angle_between(expected_turn);
    assert!(
        error < 0.2f32.to_radians(),
        "twist off by {}°",
        error.to_degrees()
    );
    // Held still, the pose converges: the top has followed the drag.
    common::drive_solves(&mut app, root, handle, 30);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let skinned = posed.skinned_positions();
    let centroid = patch
        .vertices
        .iter()
        .map(|&i| skinned[i as usize])
        .sum::<Vec3>()
        / patch.vertices.len() as f32;
    assert!(
        (centroid - pivot).dot(drag.normalize()) > 0.9 * drag.length(),
        "the grabbed top moved {}",
        centroid - pivot
    );
    // Released: the grab ends, its handle goes, the character keeps the pose.
    pointer(
        &mut app,
        end,
        PointerAction::Release(PointerButton::Primary),
    );
    for _ in 0..20 {
        app.update();
    }
    assert_eq!(
        app.world()
            .resource::<ActiveGrabs>()
            .mesh_of(PointerId::Mouse),
        None
    );
    assert!(app.world().get_entity(handle).is_err(), "the handle stayed");
    let kept = app
        .world()
        .get::<PosedSkeleton>(root)
        .unwrap()
        .skinned_positions();
    let drift = kept
        .iter()
        .zip(&skinned)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(drift < 1e-5, "the pose moved {drift} after release");
    // Press where the posed top is now (the bind pose is not there): the character is hit.
    let posed_tip = to_screen(&mut app, camera, centroid);
    let bind_hit = posed
        .model
        .topology()
        .positions()
        .iter()
        .any(|p| (to_screen(&mut app, camera, p.as_vec3()) - posed_tip).length() < 4.0);
    assert!(
        !bind_hit,
        "the test needs a press where only the posed surface is"
    );
    pointer(
        &mut app,
        posed_tip,
        PointerAction::Press(PointerButton::Primary),
    );
    common::update_until(&mut app, "the second grab", |a| {
        a.world()
            .get::<GrabHandle>(root)
            .and_then(|h| a.world().get::<DeformHandle>(h.0))
            .is_some_and(|h| h.pivot.is_some())
    });
    // A quick flick and release, then the app resets the pose while the flick still settles:
    // the reset wins.
    let flick = posed_tip + Vec2::new(0.0, -60.0);
    let delta = Vec2::new(0.0, -60.0);
    pointer(&mut app, flick, PointerAction::Move { delta });
    app.update();
    pointer(
        &mut app,
        flick,
        PointerAction::Release(PointerButton::Primary),
    );
    let rest = posed.model.skeleton().bind_pose();
    app.world_mut().get_mut::<PosedSkeleton>(root).unwrap().pose = rest.clone();
    for _ in 0..40 {
        app.update();
        std::thread::yield_now();
    }
    let now = app.world().get::<PosedSkeleton>(root).unwrap();
    let reset = now.model.skin_render(&rest);
    let drift = now
        .skinned_positions()
        .iter()
        .zip(&reset)
        .map(|(a, b)| a.as_dvec3().distance(*b))
        .fold(0.0, f64::max);
    assert!(
        drift < 1e-5,
        "the released grab pulled the reset pose by {drift}"
    );
}

/// The core's converged pose (render order) of the bar of [`spawn_bar`] with its handle
/// entity's `Transform` at `handle_at`, and the bar's bounding diagonal.
fn converged_bar_pose(tri: &deform::TriMesh, handle_at: &Transform) -> (Vec<DVec3>, f64) {
    let topology = Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
    let (fixed, hv) = regions(tri);
    let pivot = deform::centroid(&tri.positions, &hv).as_vec3();
    let c = Constraints::with_handle(
        fixed,
        hv,
        RigidTransform::new(
            handle_at.rotation.as_dquat(),
            (handle_at.translation - pivot).as_dvec3(),
            pivot.as_dvec3(),
        ),
    );
    let solver = ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
    let options = SolveOptions {
        max_iterations: 3000,
        tolerance: 0.0,
        acceleration: deform::Acceleration::Lbfgs { depth: 8 },
    };
    let star = solver
        .solve(&c, &options, InitialGuess::Laplacian, &|| false)
        .unwrap();
    (
        topology.to_render(&star.positions),
        topology.bounding_diagonal(),
    )
}

/// After the handle stops, the plugin keeps iterating (warm, in the background) until the pose
/// has converged: the released pose ends within 5e-4 × the diagonal of the core's converged
/// pose. With settling off, the pose freezes where the last solve of the move left it, farther
/// than that.
#[test]
fn a_released_handle_settles_to_the_converged_pose() {
    let run = |settle_iterations| {
        let mut app = app();
        app.add_plugins(DeformPlugin {
            settle_iterations,
            ..default()
        });
        let (e, handle, tri) = spawn_bar(&mut app);
        app.world_mut().get_mut::<Deformable>(e).unwrap().tolerance = Some(1e-7);
        let (ok, _) = run_until_messages(&mut app, 1);
        assert_eq!(ok.len(), 1);
        {
            let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
            t.rotation = Quat::from_rotation_z(1.0);
            t.translation += Vec3::new(0.3, -0.1, 0.0);
        }
        settle(&mut app, e);
        let solves = app.world().get::<DeformStatus>(e).unwrap().solves;
        (
            positions(&app, e),
            tri,
            *app.world().get::<Transform>(handle).unwrap(),
            solves,
        )
    };
    let (settled, tri, handle_at, settled_solves) = run(DeformPlugin::default().settle_iterations);
    let (frozen, _, _, frozen_solves) = run(0);

    // The converged pose for the same constraints, from the core.
    let (want, diagonal) = converged_bar_pose(&tri, &handle_at);
    let worst = |got: &[Vec3]| {
        got.iter()
            .zip(&want)
            .map(|(a, b)| (a.as_dvec3() - *b).length())
            .fold(0.0, f64::max)
    };
    let (settled_err, frozen_err) = (worst(&settled), worst(&frozen));
    assert!(
        settled_err <= 5e-4 * diagonal,
        "settled pose {settled_err} from converged ({settled_solves} solves)"
    );
    assert!(
        frozen_err > 5e-4 * diagonal,
        "without settling {frozen_err} ({frozen_solves} solves)"
    );
    assert!(settled_solves > frozen_solves);
}

/// A new constraint set on a mesh larger than the preview region is first shown as a preview:
/// only the vertices near the handle move, the rest stay where they were shown (here, at
/// rest). The whole mesh is then factored in the background and the pose settles to the
/// whole mesh's converged pose. Without a preview the first pose moves the far vertices too.
#[test]
fn a_set_change_on_a_large_mesh_is_previewed_then_solved_whole() {
    let first_and_settled = |preview: Option<deform::PreviewRegion>| {
        let mut app = app();
        app.add_plugins(DeformPlugin {
            preview,
            ..default()
        });
        let (e, handle, tri) = spawn_bar(&mut app);
        {
            // Moved before the first solve: the first constraint set is already bent.
            let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
            t.rotation = Quat::from_rotation_z(0.6);
            t.translation += Vec3::new(0.25, -0.1, 0.0);
        }
        let (ok, bad) = run_until_messages(&mut app, 1);
        assert!(bad.is_empty(), "{bad:?}");
        assert_eq!(ok.len(), 1);
        let status = app.world().get::<DeformStatus>(e).unwrap().clone();
        let first = positions(&app, e);
        settle(&mut app, e);
        let status_after = app.world().get::<DeformStatus>(e).unwrap().clone();
        assert!(!status_after.preview);
        (
            status.preview,
            first,
            positions(&app, e),
            tri,
            *app.world().get::<Transform>(handle).unwrap(),
        )
    };
    let region = deform::PreviewRegion {
        radius: 0.25,
        max_vertices: 100,
        min_mesh_vertices: 100,
    };
    let (previewed, first, settled, tri, handle_at) = first_and_settled(Some(region));
    let (whole_previewed, whole_first, _, _, _) = first_and_settled(None);
    assert!(previewed);
    assert!(!whole_previewed);

    // The vertices at the bottom half (free, far from the handle at the top) stay at rest in
    // the preview, and move in the whole mesh's first pose.
    let (fixed, hv) = regions(&tri);
    let far: Vec<usize> = (0..tri.positions.len())
        .filter(|&v| tri.positions[v].y < 0.4 && !fixed.contains(&(v as u32)))
        .collect();
    assert!(far.len() > 50);
    let moved = |pose: &[Vec3]| {
        far.iter()
            .map(|&v| (pose[v].as_dvec3() - tri.positions[v]).length())
            .fold(0.0, f64::max)
    };
    assert!(
        moved(&first) < 1e-6,
        "preview moved far vertices {}",
        moved(&first)
    );
    assert!(moved(&whole_first) > 1e-2, "whole {}", moved(&whole_first));
    // Near the handle the preview bends.
    let near =
        (0..tri.positions.len()).filter(|&v| tri.positions[v].y > 0.7 && !hv.contains(&(v as u32)));
    assert!(
        near.clone()
            .any(|v| (first[v].as_dvec3() - tri.positions[v]).length() > 0.02)
    );

    // Settled: the whole mesh's converged pose.
    let (want, diagonal) = converged_bar_pose(&tri, &handle_at);
    let worst = settled
        .iter()
        .zip(&want)
        .map(|(a, b)| (a.as_dvec3() - *b).length())
        .fold(0.0, f64::max);
    assert!(
        worst <= 5e-4 * diagonal,
        "settled {worst} from the whole mesh's converged pose"
    );
}
