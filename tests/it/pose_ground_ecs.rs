//! `PoseGround` and `PoseBalance` through the pose plugin: a character grabbed by
//! the head and pushed down into a `GroundMesh` stops at it, its feet planted.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_wii_deform::pose::rig::synth_rig::mannequin_rig;
use bevy_wii_deform::prelude::*;

use crate::common;
use common::{drive_solves, pose_of, spawn_handle, spawn_rig, update_until};

/// A headless app with the pose plugin, 16 ms a frame.
fn pose_app() -> App {
    let mut app = common::app();
    app.add_plugins(PosePlugin);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        16,
    )));
    app
}

/// The deepest skinned vertex below `ground_y` (negative: below), world space, after a grab of
/// the head pushed 0.6 m down, with or without `PoseGround` + `PoseBalance`; and the size.
fn pushed_down(stand: bool) -> (f32, f32, usize) {
    let mut app = pose_app();
    let rig = mannequin_rig(20);
    let offset = Vec3::new(1.0, 0.25, -0.5);
    let (root, joints, _) = spawn_rig(&mut app, &rig, offset);
    let lowest = rig
        .mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    let ground_y = lowest + offset.y;
    let plane = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Plane3d::default().mesh().size(20.0, 20.0));
    app.world_mut().spawn((
        Mesh3d(plane),
        Transform::from_xyz(0.0, ground_y, 0.0),
        GroundMesh,
    ));
    app.world_mut().entity_mut(root).insert(Poseable {
        max_iterations: 8,
        ..default()
    });
    if stand {
        app.world_mut()
            .entity_mut(root)
            .insert((PoseGround::default(), PoseBalance::default()));
    }
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let head: Vec<u32> = (0..rig.mesh.positions.len() as u32)
        .filter(|&i| rig.mesh.positions[i as usize].y > 1.6)
        .collect();
    let (handle, pivot) = spawn_handle(&mut app, root, head, ());
    for step in 1..=12 {
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .translation = pivot - Vec3::Y * 0.05 * step as f32;
        drive_solves(&mut app, root, handle, 2);
    }
    app.update();
    let triangles = app
        .world()
        .get_resource::<SceneGround>()
        .map_or(0, |g| g.triangles);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let pose = pose_of(&app, &joints);
    let skinned = posed.to_world(posed.model.skin_render(&pose));
    let deepest = skinned
        .iter()
        .map(|p| p.y as f32 - ground_y)
        .fold(f32::INFINITY, f32::min);
    let size = posed.model.topology().bounding_diagonal() as f32;
    (deepest, size, triangles)
}

#[test]
fn a_character_pushed_into_the_ground_stops_at_it() {
    let (sunk, _, triangles) = pushed_down(false);
    assert_eq!(triangles, 2, "the GroundMesh plane is the scene's ground");
    assert!(sunk < -0.1, "without PoseGround the push sinks it: {sunk}");
    let (deepest, size, _) = pushed_down(true);
    assert!(
        deepest > -1e-3 * size,
        "with PoseGround no skin vertex goes below the ground: {deepest} (size {size})"
    );
}

/// A character with `PoseGround` and nothing else driving it, placed a little above a
/// 10° slope, stands on it: a solve places its feet, each sole's lowest point on the slope and
/// no skin vertex below it.
#[test]
fn a_character_placed_above_a_slope_stands_on_it() {
    let mut app = pose_app();
    let rig = mannequin_rig(20);
    let lowest = rig
        .mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    let offset = Vec3::new(-2.0, 0.4, 1.0);
    let (root, joints, _) = spawn_rig(&mut app, &rig, offset);
    // The slope passes 3 cm under the feet's centre.
    let tilt = Quat::from_rotation_z(10f32.to_radians());
    let at = Vec3::new(offset.x, offset.y + lowest - 0.03, offset.z);
    let plane = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Plane3d::default().mesh().size(20.0, 20.0));
    app.world_mut().spawn((
        Mesh3d(plane),
        Transform::from_translation(at).with_rotation(tilt),
        GroundMesh,
    ));
    app.world_mut().entity_mut(root).insert((
        Poseable {
            max_iterations: 30,
            ..default()
        },
        PoseGround::default(),
    ));
    update_until(&mut app, "the stance", |a| {
        a.world()
            .get::<PoseStatus>(root)
            .is_some_and(|s| s.solves > 0)
    });
    app.update();
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let pose = pose_of(&app, &joints);
    let skinned = posed.to_world(posed.model.skin_render(&pose));
    let normal = (tilt * Vec3::Y).as_dvec3();
    let height = |p: &glam::DVec3| (*p - at.as_dvec3()).dot(normal);
    let size = posed.model.topology().bounding_diagonal();
    let deepest = skinned.iter().map(height).fold(f64::INFINITY, f64::min);
    assert!(
        deepest > -1e-3 * size,
        "a vertex is {deepest} below the slope"
    );
    for side in [1.0f32, -1.0] {
        let foot = (0..rig.mesh.positions.len())
            .filter(|&i| {
                let p = rig.mesh.positions[i];
                p.y < lowest + 0.02 && p.x * side > 0.0
            })
            .map(|i| height(&skinned[i]))
            .fold(f64::INFINITY, f64::min);
        assert!(
            foot.abs() < 3e-3 * size,
            "the foot on the {side} side is {foot} from the slope"
        );
    }
}

/// A box behind the mannequin (world space: 0.45 high, z from −0.6 to −0.2): how deep the skin
/// is in it (the deepest vertex over its footprint under its top; 0 when none is) the frame
/// the hips are pulled back over it and down to 5 cm under its top in one move — sitting
/// down — solved in the frame (ten iterations) with `PoseGround`, or in the background (the
/// second solve to land after the move, the first started after it) — the size; and how high
/// the hips' lowest vertex is then.
fn hips_pulled_onto_a_box_at_once(in_frame: bool) -> (f32, f32, f32) {
    let mut app = pose_app();
    let rig = mannequin_rig(20);
    let (root, joints, _) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    let ground_y = rig
        .mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    let top = ground_y + 0.45;
    let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
    let plane = meshes.add(Plane3d::default().mesh().size(20.0, 20.0));
    let cuboid = meshes.add(Cuboid::new(1.0, 0.45, 0.4));
    app.world_mut().spawn((
        Mesh3d(plane),
        Transform::from_xyz(0.0, ground_y, 0.0),
        GroundMesh,
    ));
    app.world_mut().spawn((
        Mesh3d(cuboid),
        Transform::from_xyz(0.0, ground_y + 0.225, -0.4),
        GroundMesh,
    ));
    app.world_mut().entity_mut(root).insert((
        Poseable {
            max_iterations: 10,
            ..default()
        },
        PoseGround::default(),
    ));
    if in_frame {
        app.world_mut()
            .entity_mut(root)
            .insert(PoseInFrame { iterations: 10 });
    }
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let hips: Vec<u32> = (0..rig.mesh.positions.len() as u32)
        .filter(|&i| (0.85..1.0).contains(&rig.mesh.positions[i as usize].y))
        .collect();
    let (handle, pivot) = spawn_handle(&mut app, root, hips.clone(), ());
    for _ in 0..3 {
        app.update();
    }
    let solves = common::solves(&app, root);
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation = Vec3::new(pivot.x, top - 0.05, -0.35);
    app.update();
    if in_frame {
        assert!(common::solves(&app, root) > solves, "solved in the frame");
    } else {
        // (The first to land may have started before the move.)
        update_until(&mut app, "two solves", |a| {
            common::solves(a, root) > solves + 1
        });
    }
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let pose = pose_of(&app, &joints);
    let skin = posed.to_world(posed.model.skin_welded(&pose));
    let inside = skin
        .iter()
        .filter(|p| p.x.abs() < 0.5 && (-0.6..-0.2).contains(&p.z))
        .map(|p| (p.y as f32 - top).min(0.0))
        .fold(0.0f32, f32::min);
    let lowest_hips = hips
        .iter()
        .map(|&v| skin[v as usize].y as f32)
        .fold(f32::INFINITY, f32::min);
    let size = posed.model.topology().bounding_diagonal() as f32;
    (inside, size, lowest_hips - ground_y)
}

/// Skin that a solve carries into ground that was not under it where the solve
/// started is caught where it ends: the floor is cast again under the solved skin and the
/// solve taken on from there, in the same solve (in the frame or in the background). The hips
/// pulled back over a box behind the body and into it in one move: no skin vertex in the box
/// by more than 1e-3 of the size.
/// (With only the floor cast where the solve starts — the hips then 0.9 m over the floor,
/// outside the floor's band — they went 2.7 cm into the box.)
#[test]
fn a_body_pulled_onto_a_box_in_one_move_stops_on_it_that_frame() {
    for in_frame in [true, false] {
        let (inside, size, hips) = hips_pulled_onto_a_box_at_once(in_frame);
        assert!(
            hips < 0.7,
            "the hips came down from 0.9 m to the box: {hips} (in the frame: {in_frame})"
        );
        assert!(
            inside > -1e-3 * size,
            "a skin vertex is {inside} into the box (size {size}, in the frame: {in_frame})"
        );
    }
}
