//! Grabbing characters: a grab starts from the pose on screen; a mouse drag moves a
//! character's handle with the cursor; the pointer grabs, drags, twists and releases a posed
//! character; a pointer grab on a real character (the Fox through Bevy's glTF loader) with no
//! pinned joints bends it — the grab pins the joints its region does not reach (`PoseAnchor`)
//! and drags the grabbed point, leaving its orientation to the body (`HandlePositionOnly`).
//! (Which pointer press reaches a character — occlusion, UI — is in `grab_picking.rs`.)

use std::time::Duration;

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::ecs::{ActiveGrabs, GrabHandle, PoseAnchor};
use bevy_wii_deform::pose::rig::synth_rig::bar_rig;
use bevy_wii_deform::prelude::*;

use crate::common;
use common::bar::under_cursor;
use common::{pointer, spawn_camera, spawn_handle, spawn_rig, to_screen, update_until};

/// The joints of a posed character whose names say "foot".
fn foot_joints(posed: &PosedSkeleton) -> Vec<Entity> {
    posed
        .model
        .skeleton()
        .joints()
        .iter()
        .enumerate()
        .filter(|(_, j)| j.name.to_lowercase().contains("foot"))
        .map(|(k, _)| posed.joints[k])
        .collect()
}

/// Whether the grab on `target` has a handle placed at its pivot.
fn grab_handle_placed(app: &App, target: Entity) -> bool {
    app.world()
        .get::<GrabHandle>(target)
        .and_then(|h| app.world().get::<DeformHandle>(h.0))
        .is_some_and(|h| h.pivot.is_some())
}

/// The centroid of `vertices` as the character is drawn now.
fn skinned_centroid(app: &App, character: Entity, vertices: &[u32]) -> Vec3 {
    let now = app
        .world()
        .get::<PosedSkeleton>(character)
        .unwrap()
        .skinned_positions();
    vertices.iter().map(|&v| now[v as usize]).sum::<Vec3>() / vertices.len() as f32
}

#[test]
fn a_character_grab_without_pins_bends_it() {
    let Some(dir) = common::shared::shared_asset("models") else {
        return;
    };
    let (mut app, fox) = common::fox_app(&dir, (PosePlugin, DeformPlugin::default(), GrabPlugin));
    let posed = app.world().get::<PosedSkeleton>(fox).unwrap().clone();
    assert!(app.world().get::<PinnedJoints>(fox).is_none());
    let drawn = posed.skinned_positions();
    let size = posed.model.topology().bounding_diagonal() as f32;
    let centre = drawn.iter().sum::<Vec3>() / drawn.len() as f32;
    // Seen from its side, a little above.
    let camera = spawn_camera(
        &mut app,
        Transform::from_translation(centre + Vec3::new(2.0 * size, 0.3 * size, 0.0))
            .looking_at(centre, Vec3::Y),
    );
    app.world_mut().entity_mut(fox).insert(Grabbable {
        radius: 0.08 * size,
        region_radius: 0.4 * size,
        ..default()
    });
    // The snout: the drawn vertex farthest forward (the Fox faces +z). (Its ear tips are its
    // topmost points: with the four feet held, no bend of rigid bones lifts them by a tenth of
    // its size, so the snout is the point a head-lift drag pulls.)
    let ear = drawn
        .iter()
        .copied()
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .unwrap();
    let feet = foot_joints(&posed);
    assert!(feet.len() >= 4, "the Fox's feet");
    let feet_at = |app: &App| -> Vec<Vec3> {
        feet.iter()
            .map(|&f| app.world().get::<GlobalTransform>(f).unwrap().translation())
            .collect()
    };
    let feet_before = feet_at(&app);
    app.world_mut().write_message(GrabStart {
        pointer: PointerId::Mouse,
        entity: fox,
        point: ear,
        camera,
    });
    update_until(&mut app, "the grab's handle at its pivot", |a| {
        grab_handle_placed(a, fox)
    });
    let anchor = app
        .world()
        .get::<PoseAnchor>(fox)
        .expect("an anchor")
        .clone();
    assert!(
        anchor.joints.iter().any(|j| feet.contains(j)),
        "the feet are not among the anchored joints"
    );
    let handle = app.world().get::<GrabHandle>(fox).unwrap().0;
    let patch = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .vertices
        .clone();
    let patch_centroid = |app: &App| skinned_centroid(app, fox, &patch);
    let start = patch_centroid(&app);
    // Drag up on screen by 10 % of the Fox's size (at the snout's depth).
    let from = to_screen(&mut app, camera, ear);
    let above = to_screen(&mut app, camera, ear + Vec3::Y * 0.1 * size);
    app.world_mut().write_message(GrabMove {
        pointer: PointerId::Mouse,
        from,
        to: above,
        rotate: false,
    });
    // Let the solves converge (a held drag keeps solving while iterations run out).
    common::settle_pose(&mut app, fox);
    let moved = patch_centroid(&app) - start;
    let drag = Vec3::Y * 0.1 * size;
    assert!(
        moved.dot(drag.normalize()) > 0.9 * drag.length(),
        "the snout moved {moved} for a drag of {drag}"
    );
    for (before, now) in feet_before.iter().zip(feet_at(&app)) {
        assert!(
            (now - *before).length() < 0.02 * size,
            "a foot moved {} ({} % of the size)",
            now - *before,
            100.0 * (now - *before).length() / size
        );
    }
    // Released: the anchor goes with the grab.
    app.world_mut().write_message(GrabEnd {
        pointer: PointerId::Mouse,
    });
    app.update();
    app.update();
    assert!(app.world().get::<PoseAnchor>(fox).is_none());
}

/// A grab starts from what is on screen: a pose an animation left on the joints (here set
/// directly, as a paused clip would) is the reference, not the pose held before.
#[test]
fn a_grab_starts_from_the_pose_on_screen() {
    let mut app = common::app();
    app.add_plugins(PosePlugin);
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(16),
    ));
    let rig = bar_rig(3, 12, 20);
    let (root, joints, _) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    app.world_mut().entity_mut(root).insert(Poseable {
        hold_pose: false,
        ..default()
    });
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    // "The clip" bends joint 1 by 45° about x.
    let bend = Quat::from_rotation_x(45f32.to_radians());
    app.world_mut()
        .get_mut::<Transform>(joints[1])
        .unwrap()
        .rotation = bend;
    app.update();
    let top: Vec<u32> = (0..rig.mesh.positions.len() as u32)
        .filter(|&i| rig.mesh.positions[i as usize].y > 0.9)
        .collect();
    let (_, pivot) = spawn_handle(&mut app, root, top, ());
    // The bent top's centroid: joint 1 at y = 1/3, the top ~0.62 above it, turned 45° about x.
    let expected = Vec3::new(0.0, 1.0 / 3.0, 0.0) + bend * Vec3::new(0.0, 0.97 - 1.0 / 3.0, 0.0);
    assert!(
        (pivot - expected).length() < 0.03,
        "pivot {pivot}, expected about {expected}"
    );
    let posed = app.world().get::<PosedSkeleton>(root).unwrap();
    assert!(posed.pose.local[1].rotation.as_quat().angle_between(bend) < 1e-4);
    // Picking hits the bent bar where it is drawn, not where its bind pose is: a ray down
    // through the bent top hits it; a ray down the bind pose's axis above y = 0.5 misses.
    let down = |x: f32, z: f32| Ray3d::new(Vec3::new(x, 3.0, z), Dir3::NEG_Y);
    let bent_top = Vec3::new(0.0, 1.0 / 3.0, 0.0) + bend * Vec3::new(0.0, 0.5, 0.0);
    let (hit, _) = posed
        .ray_cast(down(bent_top.x, bent_top.z))
        .expect("the bent top is hit");
    assert!(
        (hit - bent_top).xz().length() < 1e-4 && hit.y > bent_top.y,
        "hit {hit}"
    );
    let (hit, _) = posed
        .ray_cast(down(0.0, 0.0))
        .expect("the bottom of the bar is still there");
    assert!(
        hit.y < 0.5,
        "the ray down the rest axis hit at {hit}, above the bend"
    );
}

/// A headless app with a window, input, cameras, `PosePlugin` and `plugins`; a camera looking
/// at a three-bone bar character whose root joint is pinned.
fn character_app<M>(
    plugins: impl bevy::app::Plugins<M>,
) -> (
    App,
    Entity,
    bevy_wii_deform::pose::rig::synth_rig::SyntheticRig,
    Entity,
    Vec<Entity>,
) {
    let mut app = common::input_app((PosePlugin, plugins));
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(16),
    ));
    let camera = spawn_camera(
        &mut app,
        Transform::from_xyz(0.0, 0.6, 4.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y),
    );
    let rig = bevy_wii_deform::pose::rig::synth_rig::bar_rig(3, 12, 30);
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
