//! Avian (feature `avian`): a bent plank's collider follows the bend, and `GroundMesh` colliders
//! are the scene's ground.

use std::time::{Duration, Instant};

use avian3d::prelude::*;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_wii_deform::deform::synth;
use bevy_wii_deform::ecs::physics::{
    ColliderGround, DeformCollider, DeformColliderStatus, DeformPhysicsPlugin,
};
use bevy_wii_deform::pose::Ground as _;
use bevy_wii_deform::prelude::*;
use glam::DVec3;

use crate::common::bar::{positions, settle};

/// Updates until the plank's collider is built from its last solve: the builder runs on a
/// thread of its own, and on a loaded machine it takes more frames than on an idle one.
/// (A wall-clock deadline, as `settle`'s, so a builder that never finishes fails the test.)
fn collider_caught_up(app: &mut App, plank: Entity) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let solves = app.world().get::<DeformStatus>(plank).unwrap().solves;
        let status = app.world().get::<DeformColliderStatus>(plank).unwrap();
        assert!(status.error.is_none(), "{status:?}");
        if status.built_from_solve == solves {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "the collider was never built from solve {solves}: {status:?}"
        );
        app.update();
        std::thread::yield_now();
    }
}

/// A plank 2 long, 0.6 wide and 0.2 thick (its top at y = 0.1, along world X, centred at
/// the origin) fixed at both ends, its middle pushed 0.2 then 0.4 down, then a ball of radius 0.1
/// dropped over it; the ball's resting height and the plank's top under it (world), after
/// 10 simulated seconds.
fn ball_on_a_bent_plank(rebuild: bool) -> (f32, f32) {
    let mut app = crate::common::app();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    app.add_plugins((
        PhysicsPlugins::default(),
        DeformPlugin::default(),
        DeformPhysicsPlugin,
    ));
    // Avian sets up some of its resources when the app finishes building.
    app.finish();
    app.cleanup();
    let tri = synth::plank(2.0, 0.6, 0.2, 20.0);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let collider = Collider::trimesh_from_mesh(&mesh).unwrap();
    let ends: Vec<u32> = (0..tri.positions.len() as u32)
        .filter(|&v| (tri.positions[v as usize].y - 1.0).abs() > 0.8)
        .collect();
    let middle: Vec<u32> = (0..tri.positions.len() as u32)
        .filter(|&v| (tri.positions[v as usize].y - 1.0).abs() < 0.04)
        .collect();
    let placement = Transform::from_xyz(-1.0, 0.0, 0.0)
        .with_rotation(Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2));
    let bundle = DeformHandle::bundle(&mesh, Entity::PLACEHOLDER, middle);
    let handle_mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let plank = app
        .world_mut()
        .spawn((
            Mesh3d(handle_mesh),
            placement,
            Deformable::default(),
            FixedRegion(ends),
            RigidBody::Static,
            collider,
        ))
        .id();
    if rebuild {
        app.world_mut()
            .entity_mut(plank)
            .insert(DeformCollider::default());
    }
    let (mut handle, rest) = bundle;
    handle.target = plank;
    // Pushed down in two moves, each settled: the second collider replaces one the plugin
    // built, of the same triangles (refitted, not built anew).
    let pushed = |depth: f32| {
        let mut at = rest;
        at.translation += placement
            .to_matrix()
            .inverse()
            .transform_vector3(Vec3::new(0.0, -depth, 0.0));
        at
    };
    let handle = app.world_mut().spawn((handle, pushed(0.2))).id();
    for depth in [0.2, 0.4] {
        *app.world_mut().get_mut::<Transform>(handle).unwrap() = pushed(depth);
        app.update();
        settle(&mut app, plank);
        if rebuild {
            collider_caught_up(&mut app, plank);
        }
        for _ in 0..5 {
            app.update();
        }
    }
    if rebuild {
        let status = app.world().get::<DeformColliderStatus>(plank).unwrap();
        assert!(status.rebuilds >= 2, "{status:?}");
        assert!(status.error.is_none(), "{status:?}");
    }
    let ball = app
        .world_mut()
        .spawn((
            RigidBody::Dynamic,
            Collider::sphere(0.1),
            Transform::from_xyz(0.3, 0.6, 0.0),
        ))
        .id();
    for _ in 0..600 {
        app.update();
    }
    let at = app.world().get::<Transform>(ball).unwrap().translation;
    let top = positions(&app, plank)
        .iter()
        .map(|p| placement.transform_point(*p))
        .filter(|p| (p.x - at.x).abs() < 0.06 && (p.z - at.z).abs() < 0.06)
        .map(|p| p.y)
        .fold(f32::NEG_INFINITY, f32::max);
    (at.y, top)
}

#[test]
fn a_ball_dropped_on_a_bent_plank_rests_on_the_bent_surface() {
    let (ball, top) = ball_on_a_bent_plank(true);
    assert!(top < -0.2, "the plank bent down under the ball: top {top}");
    // Within 1 % of the plank's length of resting on the bent top.
    assert!(
        (ball - (top + 0.1)).abs() < 0.02,
        "the ball rests on the bent plank: ball {ball}, top {top}"
    );

    let (ball, top) = ball_on_a_bent_plank(false);
    assert!(
        (ball - (top + 0.1)).abs() > 0.1 && (ball - 0.2).abs() < 0.02,
        "without the rebuild the ball rests on the straight shape: ball {ball}, top {top}"
    );
}

#[test]
fn ground_colliders_are_the_scene_ground() {
    let mut app = crate::common::app();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    app.add_plugins((PhysicsPlugins::default(), DeformPhysicsPlugin));
    app.finish();
    app.cleanup();
    // A slab whose top is at y = 0.5, turned 10° about X.
    let tilt = Quat::from_rotation_x(10f32.to_radians());
    app.world_mut().spawn((
        RigidBody::Static,
        Collider::cuboid(4.0, 1.0, 4.0),
        Transform::from_rotation(tilt),
        GroundMesh,
    ));
    for _ in 0..3 {
        app.update();
    }
    let ground = app.world().resource::<SceneGround>();
    assert!(!ground.from_meshes);
    let hit = ground
        .cast_down(DVec3::new(0.0, 5.0, 0.0), DVec3::NEG_Y, 10.0)
        .expect("the ray meets the slab");
    let normal = (tilt * Vec3::Y).as_dvec3();
    assert!(hit.normal.distance(normal) < 1e-5, "{hit:?}");
    assert!(
        (hit.point.y - 0.5 / 10f64.to_radians().cos()).abs() < 1e-4,
        "{hit:?}"
    );
    assert!(
        ground
            .cast_down(DVec3::new(9.0, 5.0, 0.0), DVec3::NEG_Y, 10.0)
            .is_none()
    );
    // The snapshot casts the same on its own.
    let empty = ColliderGround::default();
    assert!(empty.is_empty());
    assert!(empty.cast_down(DVec3::Y, DVec3::NEG_Y, 5.0).is_none());
}

/// A four-bone bar character (radius 0.1) lying along world +X at height 0, maybe with
/// `PosedColliders`, and a ball of radius 0.05 dropped on its middle: the ball's height after
/// 1.5 simulated seconds, and the capsules made.
fn ball_on_a_posed_bar(with_colliders: bool) -> (f32, usize) {
    use bevy_wii_deform::ecs::physics::{BoneCollider, PosedColliders};
    use bevy_wii_deform::pose::rig::synth_rig;

    let mut app = crate::common::app();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 60.0,
    )));
    app.add_plugins((PhysicsPlugins::default(), PosePlugin, DeformPhysicsPlugin));
    app.finish();
    app.cleanup();
    let rig = synth_rig::bar_rig(4, 16, 40);
    let (root, _, _) = crate::common::spawn_rig(&mut app, &rig, Vec3::ZERO);
    app.world_mut().get_mut::<Transform>(root).unwrap().rotation =
        Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2);
    app.world_mut().entity_mut(root).insert(Poseable::default());
    if with_colliders {
        app.world_mut()
            .entity_mut(root)
            .insert(PosedColliders::default());
    }
    crate::common::update_until(&mut app, "the posed character", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    for _ in 0..3 {
        app.update();
    }
    let capsules = app
        .world_mut()
        .query::<&BoneCollider>()
        .iter(app.world())
        .count();
    let ball = app
        .world_mut()
        .spawn((
            RigidBody::Dynamic,
            Collider::sphere(0.05),
            Transform::from_xyz(0.5, 0.6, 0.0),
        ))
        .id();
    for _ in 0..90 {
        app.update();
    }
    (
        app.world().get::<Transform>(ball).unwrap().translation.y,
        capsules,
    )
}

#[test]
fn a_ball_lands_on_a_posed_characters_bone_capsules() {
    let (y, capsules) = ball_on_a_posed_bar(true);
    assert_eq!(capsules, 4, "a capsule per bone");
    assert!(
        (y - 0.15).abs() < 0.03,
        "the ball rests on the bar's skin (0.1 + its radius): {y}"
    );
    let (y, capsules) = ball_on_a_posed_bar(false);
    assert_eq!(capsules, 0);
    assert!(y < -1.0, "without the capsules it falls through: {y}");
}
