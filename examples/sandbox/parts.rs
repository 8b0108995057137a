//! A glTF model of several materials drawn as it looks while its merged mesh is edited: the
//! merged mesh (the one deformed, painted and picked) is hidden, and each of its primitives is
//! drawn by a child entity with that primitive's own material and texture coordinates, whose
//! positions, normals and selection colours are copied from the merged mesh whenever it
//! changes. A model with one material is drawn by the merged mesh itself.

use std::ops::Range;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;

/// Keeps the drawn parts of a model in step with its merged mesh.
pub struct ModelPartsPlugin;

impl Plugin for ModelPartsPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(PostUpdate, sync_parts);
    }
}

/// One primitive of a merged mesh: its vertices, its triangles and its material.
#[derive(Clone, Debug)]
pub struct PartRange {
    /// Its vertices in the merged mesh.
    pub vertices: Range<u32>,
    /// Its triangles in the merged mesh.
    pub triangles: Range<usize>,
    /// The primitive's material (`None`: a plain one).
    pub material: Option<Handle<StandardMaterial>>,
}

/// Whether the primitives use more than one material (then they are drawn as parts).
pub fn needs_parts(parts: &[PartRange]) -> bool {
    parts
        .iter()
        .any(|p| p.material.as_ref().map(|h| h.id()) != parts[0].material.as_ref().map(|h| h.id()))
}

/// On a child of the model: which vertices of the merged mesh it draws.
#[derive(Component, Debug, Clone)]
pub struct ModelPart {
    vertices: Range<u32>,
}

/// The attributes a part copies from the merged mesh.
const SHARED: [bevy::mesh::MeshVertexAttribute; 3] = [
    Mesh::ATTRIBUTE_POSITION,
    Mesh::ATTRIBUTE_NORMAL,
    Mesh::ATTRIBUTE_COLOR,
];

/// The sub-mesh of `merged` that draws `part` (its triangles renumbered from 0), with its
/// texture coordinates when the merged mesh has them.
fn part_mesh(merged: &Mesh, triangles: &[u32], part: &PartRange) -> Mesh {
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    );
    let range = part.vertices.start as usize..part.vertices.end as usize;
    for attribute in SHARED.into_iter().chain([Mesh::ATTRIBUTE_UV_0]) {
        if let Some(values) = merged
            .attribute(attribute.id)
            .and_then(|v| slice(v, &range))
        {
            mesh.insert_attribute(attribute, values);
        }
    }
    let local = triangles[part.triangles.start * 3..part.triangles.end * 3]
        .iter()
        .map(|i| i - part.vertices.start)
        .collect();
    mesh.insert_indices(Indices::U32(local));
    mesh
}

/// `values[range]` for the attribute types the sandbox's meshes use.
fn slice(values: &VertexAttributeValues, range: &Range<usize>) -> Option<VertexAttributeValues> {
    use VertexAttributeValues::*;
    let range = range.clone();
    Some(match values {
        Float32x2(v) => Float32x2(v.get(range)?.to_vec()),
        Float32x3(v) => Float32x3(v.get(range)?.to_vec()),
        Float32x4(v) => Float32x4(v.get(range)?.to_vec()),
        _ => return None,
    })
}

/// Spawns one child of `model` per primitive, each with its own material (`plain` when it
/// has none), and hides the merged mesh.
pub fn spawn_parts(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    model: Entity,
    merged: &Mesh,
    parts: &[PartRange],
    plain: &Handle<StandardMaterial>,
) {
    let Some(Indices::U32(triangles)) = merged.indices() else {
        return;
    };
    commands.entity(model).insert(Visibility::Hidden);
    for part in parts {
        let mesh = meshes.add(part_mesh(merged, triangles, part));
        commands.spawn((
            Mesh3d(mesh),
            MeshMaterial3d(part.material.clone().unwrap_or_else(|| plain.clone())),
            Transform::default(),
            // Visible although the merged mesh it belongs to is hidden.
            Visibility::Visible,
            ModelPart {
                vertices: part.vertices.clone(),
            },
            ChildOf(model),
        ));
    }
}

/// Copies positions, normals and selection colours from each changed merged mesh into its
/// parts.
fn sync_parts(
    mut changed: MessageReader<AssetEvent<Mesh>>,
    parts: Query<(&ModelPart, &Mesh3d, &ChildOf)>,
    merged: Query<&Mesh3d, Without<ModelPart>>,
    mut meshes: ResMut<Assets<Mesh>>,
) {
    let modified: Vec<AssetId<Mesh>> = changed
        .read()
        .filter_map(|e| match e {
            AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    if modified.is_empty() {
        return;
    }
    for (part, mesh, child_of) in &parts {
        let Ok(source) = merged.get(child_of.parent()) else {
            continue;
        };
        if !modified.contains(&source.0.id()) {
            continue;
        }
        let range = part.vertices.start as usize..part.vertices.end as usize;
        let Some(copied) = meshes.get(&source.0).map(|m| {
            SHARED
                .into_iter()
                .filter_map(|a| Some((a, slice(m.attribute(a.id)?, &range)?)))
                .collect::<Vec<_>>()
        }) else {
            continue;
        };
        if let Some(mut target) = meshes.get_mut(&mesh.0) {
            for (attribute, values) in copied {
                target.insert_attribute(attribute, values);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::ecs::system::RunSystemOnce;
    use bevy_wii_deform::prelude::mesh_from_triangles;
    use glam::DVec3;

    /// Two primitives of different materials: two parts, each with its vertices renumbered and
    /// its own material; when the merged mesh moves, the parts follow.
    #[test]
    fn parts_draw_their_primitives_and_follow_the_merged_mesh() {
        let mut app = App::new();
        app.add_plugins((
            MinimalPlugins,
            AssetPlugin::default(),
            bevy::mesh::MeshPlugin,
        ))
        .init_asset::<StandardMaterial>()
        .add_plugins(ModelPartsPlugin);
        let positions: Vec<DVec3> = (0..6)
            .map(|i| DVec3::new(i as f64, (i % 3) as f64, 0.0))
            .collect();
        let merged = mesh_from_triangles(&positions, &[[0, 1, 2], [3, 4, 5]]);
        let (red, blue) = {
            let mut m = app.world_mut().resource_mut::<Assets<StandardMaterial>>();
            (
                m.add(Color::srgb(1.0, 0.0, 0.0)),
                m.add(Color::srgb(0.0, 0.0, 1.0)),
            )
        };
        let parts = [
            PartRange {
                vertices: 0..3,
                triangles: 0..1,
                material: Some(red.clone()),
            },
            PartRange {
                vertices: 3..6,
                triangles: 1..2,
                material: Some(blue.clone()),
            },
        ];
        assert!(needs_parts(&parts));
        assert!(!needs_parts(&parts[..1]));
        let handle = app
            .world_mut()
            .resource_mut::<Assets<Mesh>>()
            .add(merged.clone());
        let model = app.world_mut().spawn(Mesh3d(handle.clone())).id();
        app.world_mut()
            .run_system_once(
                move |mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>| {
                    spawn_parts(&mut commands, &mut meshes, model, &merged, &parts, &red);
                },
            )
            .unwrap();
        app.update();
        let children: Vec<Entity> = app.world().get::<Children>(model).unwrap().to_vec();
        assert_eq!(children.len(), 2);
        assert_eq!(
            app.world().get::<Visibility>(model),
            Some(&Visibility::Hidden)
        );
        let part_mesh = |app: &App, k: usize| {
            let m = &app.world().get::<Mesh3d>(children[k]).unwrap().0;
            app.world()
                .resource::<Assets<Mesh>>()
                .get(m)
                .unwrap()
                .clone()
        };
        let second = part_mesh(&app, 1);
        assert_eq!(
            second.indices().unwrap().iter().collect::<Vec<_>>(),
            [0, 1, 2]
        );
        assert_eq!(
            app.world()
                .get::<MeshMaterial3d<StandardMaterial>>(children[1])
                .unwrap()
                .0,
            blue
        );
        // Move the merged mesh's vertex 4: the second part's vertex 1 follows.
        {
            let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
            let mut mesh = meshes.get_mut(&handle).unwrap();
            if let Some(VertexAttributeValues::Float32x3(p)) =
                mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
            {
                p[4] = [9.0, 9.0, 9.0];
            }
        }
        app.update();
        app.update();
        let moved = part_mesh(&app, 1);
        let Some(VertexAttributeValues::Float32x3(p)) = moved.attribute(Mesh::ATTRIBUTE_POSITION)
        else {
            panic!("no positions");
        };
        assert_eq!(p[1], [9.0, 9.0, 9.0]);
    }
}
