//! The bar-mesh scenes most ECS tests start from: a bar `Deformable` with fixed and handle
//! regions, reading its positions back, stepping until solves land or settle, and where the
//! cursor meets a plane.

use std::time::{Duration, Instant};

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_wii_deform::deform::{self, synth};
use bevy_wii_deform::prelude::*;

pub fn bar_mesh() -> (Mesh, deform::TriMesh) {
    let tri = synth::bar(12, 30, 0.1, 1.0);
    (mesh_from_triangles(&tri.positions, &tri.triangles), tri)
}

pub fn regions(tri: &deform::TriMesh) -> (Vec<u32>, Vec<u32>) {
    synth::slab_regions(&tri.positions, 1, 0.1, 0.1)
}

pub fn positions(app: &App, e: Entity) -> Vec<Vec3> {
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
pub fn run_until_messages(app: &mut App, n: usize) -> (Vec<DeformSolved>, Vec<DeformFailed>) {
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

pub fn spawn_bar(app: &mut App) -> (Entity, Entity, deform::TriMesh) {
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

/// Where a world point along the ray through `cursor` meets the plane through `at` facing the
/// camera.
pub fn under_cursor(app: &mut App, camera: Entity, at: Vec3, cursor: Vec2) -> Vec3 {
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
pub fn settle(app: &mut App, e: Entity) {
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
