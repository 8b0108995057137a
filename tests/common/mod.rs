//! Helpers shared by the integration tests.
#![allow(dead_code)] // each test crate uses some of them

use bevy::asset::RenderAssetUsages;
use bevy::mesh::skinning::{SkinnedMesh as BevySkin, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_wii_deform::pose::synth_rig::SyntheticRig;
use bevy_wii_deform::prelude::{DeformHandle, PoseStatus};

/// Spawns the rig as a character entity (root) with a joint chain and a skinned mesh child,
/// placed at `offset`. Returns (root, joints, mesh entity).
pub fn spawn_rig(app: &mut App, rig: &SyntheticRig, offset: Vec3) -> (Entity, Vec<Entity>, Entity) {
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    );
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_POSITION,
        rig.mesh
            .positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    );
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(rig.mesh.joint_indices.clone()),
    );
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, rig.mesh.joint_weights.clone());
    mesh.insert_indices(Indices::U32(rig.mesh.indices.clone()));
    let world = app.world_mut();
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let ibp: Vec<Mat4> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| Mat4::from(j.inverse_bind.as_affine3a()))
        .collect();
    let ibp = world
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(SkinnedMeshInverseBindposes::from(ibp));
    let root = world
        .spawn((Transform::from_translation(offset), Name::new("character")))
        .id();
    let mut joints = Vec::new();
    for (k, joint) in rig.skeleton.joints().iter().enumerate() {
        let t = rig.rest.local[k];
        let parent = joint.parent.map_or(root, |p| joints[p]);
        let e = world
            .spawn((
                Transform::from_translation(t.translation.as_vec3()),
                Name::new(joint.name.clone()),
                ChildOf(parent),
            ))
            .id();
        joints.push(e);
    }
    let skinned = world
        .spawn((
            Mesh3d(mesh),
            BevySkin {
                inverse_bindposes: ibp,
                joints: joints.clone(),
            },
            Transform::default(),
            ChildOf(root),
        ))
        .id();
    (root, joints, skinned)
}

/// Updates until `done` holds, with a generous deadline for the background tasks.
pub fn update_until(app: &mut App, what: &str, done: impl Fn(&mut App) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !done(app) {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        app.update();
        std::thread::yield_now();
    }
}

pub fn solves(app: &App, e: Entity) -> u64 {
    app.world().get::<PoseStatus>(e).map_or(0, |s| s.solves)
}

/// Marks `handle`'s `Transform` changed `n` times, each time updating until one more solve of
/// `character` landed (a drag held still: the pose converges, with warm starts).
pub fn drive_solves(app: &mut App, character: Entity, handle: Entity, n: u32) {
    for _ in 0..n {
        let before = solves(app, character);
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .set_changed();
        update_until(app, "a solve", |a| solves(a, character) > before);
    }
}

/// Spawns a vertex handle (with `extra` components) on `target`, a character or deformable,
/// and updates until the plugin has put it at its pivot; returns the handle and the pivot.
pub fn spawn_handle(
    app: &mut App,
    target: Entity,
    vertices: Vec<u32>,
    extra: impl Bundle,
) -> (Entity, Vec3) {
    let handle = app
        .world_mut()
        .spawn((
            DeformHandle {
                target,
                vertices,
                pivot: None,
            },
            Transform::IDENTITY,
            extra,
        ))
        .id();
    update_until(app, "the pivot", |a| {
        a.world()
            .get::<DeformHandle>(handle)
            .unwrap()
            .pivot
            .is_some()
    });
    let pivot = app.world().get::<DeformHandle>(handle).unwrap().pivot;
    (handle, pivot.unwrap())
}
