//! Keeping [`SceneGround`] current from the [`GroundMesh`] meshes.

use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::prelude::*;
use glam::DVec3;

use super::{GroundMesh, SceneGround};
use crate::pose::TriangleGround;

/// Collects the [`GroundMesh`] meshes into the [`SceneGround`] resource (in `PreUpdate`, so the
/// pose plugin's requests in `Update` see this frame's ground). Added by `PosePlugin`.
#[derive(Debug, Clone, Copy, Default)]
pub struct GroundPlugin;

impl Plugin for GroundPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<GroundMesh>()
            .add_systems(PreUpdate, collect_ground);
    }
}

/// A [`GroundMesh`] entity moved or given another mesh.
type MovedGround = (
    With<GroundMesh>,
    Or<(Changed<GlobalTransform>, Changed<Mesh3d>)>,
);

/// Rebuilds the ground when a [`GroundMesh`] mesh appears, goes, moves or its mesh asset changes.
fn collect_ground(
    mut commands: Commands,
    grounds: Query<(&Mesh3d, &GlobalTransform), With<GroundMesh>>,
    changed: Query<(), MovedGround>,
    mut removed: RemovedComponents<GroundMesh>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    meshes: Res<Assets<Mesh>>,
    current: Option<Res<SceneGround>>,
) {
    if current.as_ref().is_some_and(|g| !g.from_meshes) {
        return; // the game's own ground
    }
    let ours = |id: &AssetId<Mesh>| grounds.iter().any(|(m, _)| m.0.id() == *id);
    let asset_changed = mesh_events.read().any(|e| match e {
        AssetEvent::Added { id }
        | AssetEvent::Modified { id }
        | AssetEvent::LoadedWithDependencies { id } => ours(id),
        _ => false,
    });
    let any_removed = removed.read().count() > 0;
    if changed.is_empty() && !asset_changed && !any_removed && current.is_some() {
        return;
    }
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for (mesh3d, global) in &grounds {
        let Some(mesh) = meshes.get(&mesh3d.0) else {
            continue;
        };
        append_triangles(mesh, global, &mut positions, &mut triangles);
    }
    if triangles.is_empty() && current.is_none() {
        return;
    }
    let count = triangles.len();
    commands.insert_resource(SceneGround::of_triangles(
        TriangleGround::new(positions, triangles, DVec3::NEG_Y),
        count,
    ));
}

/// Appends a mesh's triangles, placed by `global`, to the lists (a mesh that is not a
/// triangle list or has no positions adds nothing).
fn append_triangles(
    mesh: &Mesh,
    global: &GlobalTransform,
    positions: &mut Vec<DVec3>,
    triangles: &mut Vec<[u32; 3]>,
) {
    if mesh.primitive_topology() != bevy::mesh::PrimitiveTopology::TriangleList {
        return;
    }
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        return;
    };
    let base = positions.len() as u32;
    let affine = global.affine();
    positions.extend(
        p.iter()
            .map(|v| affine.transform_point3(Vec3::from_array(*v)).as_dvec3()),
    );
    let n = p.len() as u32;
    let indices: Vec<u32> = match mesh.indices() {
        Some(Indices::U16(i)) => i.iter().map(|&x| x as u32).collect(),
        Some(Indices::U32(i)) => i.clone(),
        None => (0..n).collect(),
    };
    triangles.extend(
        indices
            .chunks_exact(3)
            .filter(|t| t.iter().all(|&v| v < n))
            .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
    );
}
