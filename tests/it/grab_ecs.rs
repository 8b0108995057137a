//! `GrabPlugin` headless: grabs bend meshes under the pointer and keep the pose; two pointers
//! grab two meshes at once; the pointer grabs, drags, twists and releases a posed character.

use std::time::Duration;

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::ecs::{ActiveGrabs, GrabHandle};
use bevy_wii_deform::prelude::*;

use crate::common;
use crate::common::bar::*;
use common::{app, pointer, spawn_camera, to_screen};

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
    common::shift_drag(&mut app, start, end, 3);
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
/// Three wheel lines over the grab: it turns 30° counter-clockwise on screen (about the
/// camera's back axis), within 0.2°.
fn twist_three_lines(app: &mut App, camera: Entity, handle: Entity, at: Vec2) {
    use bevy::picking::pointer::PointerAction;
    // Three wheel lines: 30° counter-clockwise on screen (about the camera's back axis).
    let before = app.world().get::<Transform>(handle).unwrap().rotation;
    pointer(
        app,
        at,
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
}

/// Released: the grab ends, its handle goes, the character keeps the pose it showed.
fn release_keeps_the_pose(app: &mut App, root: Entity, handle: Entity, at: Vec2, skinned: &[Vec3]) {
    use bevy::picking::pointer::{PointerAction, PointerButton};
    // Released: the grab ends, its handle goes, the character keeps the pose.
    pointer(app, at, PointerAction::Release(PointerButton::Primary));
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
        .zip(skinned)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(drift < 1e-5, "the pose moved {drift} after release");
}

/// A press where the posed top is now (the bind pose is not there) grabs the character; a
/// quick flick and release, then the app resets the pose while the flick still settles: the
/// reset wins.
fn regrab_on_the_posed_surface_and_reset(
    app: &mut App,
    camera: Entity,
    root: Entity,
    posed: &PosedSkeleton,
    top: Vec3,
) {
    use bevy::picking::pointer::{PointerAction, PointerButton};
    // Press where the posed top is now (the bind pose is not there): the character is hit.
    let posed_tip = to_screen(app, camera, top);
    let bind_hit = posed
        .model
        .topology()
        .positions()
        .iter()
        .any(|p| (to_screen(app, camera, p.as_vec3()) - posed_tip).length() < 4.0);
    assert!(
        !bind_hit,
        "the test needs a press where only the posed surface is"
    );
    pointer(app, posed_tip, PointerAction::Press(PointerButton::Primary));
    common::update_until(app, "the second grab", |a| {
        a.world()
            .get::<GrabHandle>(root)
            .and_then(|h| a.world().get::<DeformHandle>(h.0))
            .is_some_and(|h| h.pivot.is_some())
    });
    // A quick flick and release, then the app resets the pose while the flick still settles:
    // the reset wins.
    let flick = posed_tip + Vec2::new(0.0, -60.0);
    let delta = Vec2::new(0.0, -60.0);
    pointer(app, flick, PointerAction::Move { delta });
    app.update();
    pointer(app, flick, PointerAction::Release(PointerButton::Primary));
    let rest = posed.model.skeleton().bind_pose();
    app.world_mut().get_mut::<PosedSkeleton>(root).unwrap().pose = rest.clone();
    for _ in 0..40 {
        app.update();
        std::thread::yield_now();
    }
    let now = app.world().get::<PosedSkeleton>(root).unwrap();
    let reset = now.to_world(now.model.skin_render(&rest));
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
    // Drag 80 px to the right in four moves: the handle stays under the cursor. Each move's
    // solve settles before the next, so the path is the same on every run: the twist splits
    // between the two free bones along a nearly flat valley of the energy, and where a pose
    // comes to rest in it depends on which solves a faster drag cut short (the top's rest
    // position then spans 0.88–0.94 of the drag over runs).
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
        common::settle_pose(&mut app, root);
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
    twist_three_lines(&mut app, camera, handle, end);
    common::settle_pose(&mut app, root);
    // Held still, the pose converges: the top has followed the drag.
    common::drive_solves(&mut app, root, handle, 30);
    // The last of those may have queued a settling solve: let it land before the release
    // (a solve running at release still lands, with the grab's targets).
    common::settle_pose(&mut app, root);
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
    release_keeps_the_pose(&mut app, root, handle, end, &skinned);
    regrab_on_the_posed_surface_and_reset(&mut app, camera, root, &posed, centroid);
}
