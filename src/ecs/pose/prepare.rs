//! Preparing a character: find its skinned primitives and joints (once its scene has spawned,
//! or report why not), build the skinned model in the background, and insert
//! [`PosedSkeleton`] when it is ready.

use std::sync::Arc;

use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh as BevySkin, SkinnedMeshInverseBindposes};
use bevy::prelude::*;

use crate::ecs::tasks::LatestTask;
use bevy::tasks::AsyncComputeTaskPool;
use bevy::tasks::futures::check_ready;
use bevy::world_serialization::WorldAssetRoot;
use glam::DAffine3;

use super::plugin::{PoseState, fail};
use super::{PoseFailed, PoseStatus, Poseable, PoseableError, PosedSkeleton};
use crate::ecs::DeformPhase;
use crate::ecs::scene::{SceneSpawned, scene_load_failure};
use crate::pose::{
    Joint, JointTransform, ModelSettings, Skeleton, SkeletonPose, SkinnedMesh, SkinnedModel,
};

pub(super) fn affine(t: &GlobalTransform) -> DAffine3 {
    let a = t.affine();
    DAffine3::from_mat3_translation(
        glam::Mat3::from(a.matrix3).as_dmat3(),
        Vec3::from(a.translation).as_dvec3(),
    )
}

pub(super) fn joint_transform(t: &Transform) -> JointTransform {
    JointTransform {
        translation: t.translation.as_dvec3(),
        rotation: t.rotation.as_dquat().normalize(),
        scale: t.scale.as_dvec3(),
    }
}

/// Reads positions, indices and skin attributes of one primitive.
pub(super) fn skinned_mesh_of(mesh: &Mesh) -> Result<SkinnedMesh, PoseableError> {
    if mesh.primitive_topology() != bevy::mesh::PrimitiveTopology::TriangleList {
        return Err(PoseableError::NotTriangleList);
    }
    let positions = match mesh.try_attribute(Mesh::ATTRIBUTE_POSITION) {
        Ok(VertexAttributeValues::Float32x3(v)) => {
            v.iter().map(|p| Vec3::from_array(*p)).collect::<Vec<_>>()
        }
        _ => return Err(PoseableError::MissingAttribute("Float32x3 positions")),
    };
    let joint_indices = match mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_INDEX) {
        Ok(VertexAttributeValues::Uint16x4(v)) => v.clone(),
        _ => return Err(PoseableError::MissingAttribute("Uint16x4 joint indices")),
    };
    let joint_weights = match mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT) {
        Ok(VertexAttributeValues::Float32x4(v)) => v.clone(),
        _ => return Err(PoseableError::MissingAttribute("Float32x4 joint weights")),
    };
    let indices = match mesh.try_indices() {
        Ok(i) => i.iter().map(|x| x as u32).collect(),
        Err(_) => (0..positions.len() as u32).collect(),
    };
    Ok(SkinnedMesh {
        positions,
        indices,
        joint_indices,
        joint_weights,
    })
}

/// Finds the skinned primitives and joints of new [`Poseable`]s and starts building their
/// models in the background.
#[allow(clippy::too_many_arguments, clippy::type_complexity)] // a system: one parameter per resource it touches
pub(super) fn find_skins(
    mut commands: Commands,
    mut new: Query<
        (
            Entity,
            &Poseable,
            &mut PoseStatus,
            Option<&WorldAssetRoot>,
            Has<SceneSpawned>,
        ),
        Without<PoseState>,
    >,
    assets: Option<Res<AssetServer>>,
    children: Query<&Children>,
    skins: Query<(&BevySkin, &Mesh3d)>,
    meshes: Res<Assets<Mesh>>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
    joints: Query<(&Transform, Option<&ChildOf>, Option<&Name>)>,
    globals: Query<&GlobalTransform>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, poseable, mut status, scene, spawned) in &mut new {
        if status.phase == DeformPhase::Failed {
            continue;
        }
        let primitives: Vec<Entity> = std::iter::once(entity)
            .chain(children.iter_descendants(entity))
            .filter(|e| skins.contains(*e))
            .collect();
        let Some(&first) = primitives.first() else {
            // A scene root waits for its instance; any other entity must have its skinned
            // mesh at or below it when `Poseable` is added (as for `Deformable`).
            let error = if scene.is_some() && !spawned {
                match assets.as_deref().and_then(|a| scene_load_failure(a, scene)) {
                    Some(message) => PoseableError::SceneLoadFailed(message),
                    None => continue, // the scene has not spawned yet
                }
            } else {
                PoseableError::NoSkinnedMesh
            };
            fail(entity, error, &mut status, &mut failed);
            continue;
        };
        let (skin, _) = skins.get(first).expect("filtered");
        let Some(ibp) = bindposes.get(&skin.inverse_bindposes) else {
            continue; // loading
        };
        let members: Vec<Entity> = primitives
            .iter()
            .copied()
            .filter(|&p| skins.get(p).is_ok_and(|(s, _)| s.joints == skin.joints))
            .collect();
        let loaded = members
            .iter()
            .all(|&p| skins.get(p).is_ok_and(|(_, m)| meshes.contains(&m.0)));
        if !loaded {
            continue; // a mesh asset is still loading
        }
        let mut mesh = SkinnedMesh::default();
        let mut offsets = Vec::new();
        let mut result: Result<(), PoseableError> = Ok(());
        for &p in &members {
            let (_, mesh3d) = skins.get(p).expect("filtered");
            let asset = meshes.get(&mesh3d.0).expect("checked loaded above");
            match skinned_mesh_of(asset) {
                Ok(part) => {
                    let base = mesh.positions.len() as u32;
                    offsets.push((p, base));
                    mesh.indices.extend(part.indices.iter().map(|i| i + base));
                    mesh.positions.extend(part.positions);
                    mesh.joint_indices.extend(part.joint_indices);
                    mesh.joint_weights.extend(part.joint_weights);
                }
                Err(e) => {
                    result = Err(e);
                    break;
                }
            }
        }
        if let Err(e) = result {
            fail(entity, e, &mut status, &mut failed);
            continue;
        }
        // The skeleton: parents are the nearest joint ancestors; a root's parent frame is its
        // parent entity's world transform.
        let mut list = Vec::with_capacity(skin.joints.len());
        let mut reference = Vec::with_capacity(skin.joints.len());
        let mut missing = None;
        for (k, &j) in skin.joints.iter().enumerate() {
            let Ok((transform, child_of, name)) = joints.get(j) else {
                missing = Some(j);
                break;
            };
            let mut up = child_of.map(|c| c.parent());
            let mut parent = None;
            while let Some(p) = up {
                if let Some(index) = skin.joints.iter().position(|&x| x == p) {
                    parent = Some(index);
                    break;
                }
                up = joints
                    .get(p)
                    .ok()
                    .and_then(|(_, c, _)| c.map(|c| c.parent()));
            }
            let parent_frame = match (parent, child_of) {
                (None, Some(c)) => globals
                    .get(c.parent())
                    .map(affine)
                    .unwrap_or(DAffine3::IDENTITY),
                _ => DAffine3::IDENTITY,
            };
            let inverse_bind = ibp
                .get(k)
                .map(|m| DAffine3::from_mat4(m.as_dmat4()))
                .unwrap_or(DAffine3::IDENTITY);
            list.push(Joint {
                name: name.map_or_else(|| format!("joint{k}"), |n| n.as_str().to_string()),
                parent,
                parent_frame,
                inverse_bind,
            });
            reference.push(joint_transform(transform));
        }
        if let Some(j) = missing {
            fail(
                entity,
                PoseableError::MissingJoint(j),
                &mut status,
                &mut failed,
            );
            continue;
        }
        let sorted = Skeleton::sorted(list);
        let (skeleton, order) = match sorted {
            Ok(s) => s,
            Err(e) => {
                fail(entity, e.into(), &mut status, &mut failed);
                continue;
            }
        };
        let mut new_index = vec![u16::MAX; order.len()];
        for (new, &old) in order.iter().enumerate() {
            new_index[old] = new as u16;
        }
        for ji in &mut mesh.joint_indices {
            *ji = ji.map(|j| new_index.get(j as usize).copied().unwrap_or(u16::MAX));
        }
        let reference = SkeletonPose {
            local: order.iter().map(|&old| reference[old]).collect(),
        };
        let settings = ModelSettings {
            clusters: poseable.clusters.max(1) as usize,
            ..Default::default()
        };
        let task = AsyncComputeTaskPool::get()
            .spawn(async move { Ok(SkinnedModel::new(skeleton, &mesh, &reference, settings)?) });
        status.phase = DeformPhase::BuildingTopology;
        commands.entity(entity).try_insert(PoseState {
            building: Some(task),
            joints: order.iter().map(|&old| skin.joints[old]).collect(),
            primitives: offsets,
            key: None,
            reference: None,
            solver: None,
            last: None,
            solve: LatestTask::default(),
            pending: None,
            running: None,
            written: None,
            limits: None,
            mirror: None,
            blend: Default::default(),
            start: None,
        });
    }
}

/// Collects built models; inserts [`PosedSkeleton`] with the joints' current pose.
pub(super) fn finish_models(
    mut commands: Commands,
    mut building: Query<(Entity, &mut PoseState, &mut PoseStatus)>,
    joints: Query<&Transform>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, mut state, mut status) in &mut building {
        let Some(task) = state.building.as_mut() else {
            continue;
        };
        let Some(result) = check_ready(task) else {
            continue;
        };
        state.building = None;
        match result {
            Ok(model) => {
                let pose = SkeletonPose {
                    local: state
                        .joints
                        .iter()
                        .map(|&j| joints.get(j).map(joint_transform).unwrap_or_default())
                        .collect(),
                };
                status.phase = DeformPhase::Idle;
                status.joints = model.skeleton().len();
                status.vertices = model.topology().vertex_count();
                commands.entity(entity).try_insert(PosedSkeleton {
                    model: Arc::new(model),
                    joints: state.joints.clone(),
                    primitives: state.primitives.clone(),
                    pose,
                });
            }
            Err(e) => fail(entity, e, &mut status, &mut failed),
        }
    }
}
