//! Preparing a character: find its skinned primitives and joints (once its scene has spawned,
//! or report why not), build the skinned model in the background, and insert
//! [`PosedSkeleton`] when it is ready.

use std::sync::Arc;

use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh as BevySkin, SkinnedMeshInverseBindposes};
use bevy::prelude::*;

use crate::ecs::tasks::poll_slot;
use bevy::tasks::AsyncComputeTaskPool;
use bevy::world_serialization::WorldAssetRoot;
use glam::DAffine3;

use super::super::blend::BlendMemory;
use super::super::convert::{affine, joint_transform};
use super::super::{
    CharacterSkin, ModelKey, PoseFailed, PoseModels, PoseStatus, Poseable, PoseableError,
    PosedSkeleton, SharedModel,
};
use super::state::{
    CharacterSpace, GroundContacts, LastSolve, ModelBuild, PoseDrivers, PoseSolves, fail,
};
use crate::ecs::DeformPhase;
use crate::ecs::scene::{SceneSpawned, scene_load_failure};
use crate::pose::constraints::frame::similarity;
use crate::pose::{
    Joint, JointTransform, ModelSettings, Skeleton, SkeletonPose, SkinnedMesh, SkinnedModel,
};

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

/// What finding a character's skin reads: the hierarchy, skinned meshes, their assets and
/// the joints.
#[derive(bevy::ecs::system::SystemParam)]
pub(super) struct SkinSources<'w, 's> {
    children: Query<'w, 's, &'static Children>,
    skins: Query<'w, 's, (&'static BevySkin, &'static Mesh3d)>,
    meshes: Res<'w, Assets<Mesh>>,
    bindposes: Res<'w, Assets<SkinnedMeshInverseBindposes>>,
    joints: Query<
        'w,
        's,
        (
            &'static Transform,
            Option<&'static ChildOf>,
            Option<&'static Name>,
        ),
    >,
    globals: Query<'w, 's, &'static GlobalTransform>,
}

impl SkinSources<'_, '_> {
    /// World ← character space of `entity` when it is placed by a similarity (its model is
    /// then built in character space and shared), `None` for a model in world space.
    fn placement(&self, entity: Entity) -> Option<DAffine3> {
        self.globals
            .get(entity)
            .ok()
            .map(affine)
            .and_then(|g| similarity(&g))
    }

    /// The skinned primitives at and below `entity`.
    fn primitives(&self, entity: Entity) -> Vec<Entity> {
        std::iter::once(entity)
            .chain(self.children.iter_descendants(entity))
            .filter(|e| self.skins.contains(*e))
            .collect()
    }

    /// Reads the skin of `primitives` (the first one's skin, and every primitive sharing its
    /// joints); `Ok(None)` while an asset is still loading.
    fn read(
        &self,
        primitives: &[Entity],
        to_character: &DAffine3,
    ) -> Result<Option<CharacterSkin>, PoseableError> {
        let Some((skin, _)) = primitives.first().and_then(|p| self.skins.get(*p).ok()) else {
            return Err(PoseableError::NoSkinnedMesh);
        };
        let Some(ibp) = self.bindposes.get(&skin.inverse_bindposes) else {
            return Ok(None);
        };
        let members: Vec<Entity> = primitives
            .iter()
            .copied()
            .filter(|&p| {
                self.skins
                    .get(p)
                    .is_ok_and(|(s, _)| s.joints == skin.joints)
            })
            .collect();
        let loaded = members.iter().all(|&p| {
            self.skins
                .get(p)
                .is_ok_and(|(_, m)| self.meshes.contains(&m.0))
        });
        if !loaded {
            return Ok(None);
        }
        let (mut mesh, primitives) = self.combined_mesh(&members)?;
        let (list, reference) = self.joints_of(skin, ibp, to_character)?;
        let (skeleton, order) = Skeleton::sorted(list)?;
        let mut new_index = vec![u16::MAX; order.len()];
        for (new, &old) in order.iter().enumerate() {
            new_index[old] = new as u16;
        }
        for ji in &mut mesh.joint_indices {
            *ji = ji.map(|j| new_index.get(j as usize).copied().unwrap_or(u16::MAX));
        }
        Ok(Some(CharacterSkin {
            mesh,
            primitives,
            skeleton,
            joints: order.iter().map(|&old| skin.joints[old]).collect(),
            reference: SkeletonPose {
                local: order.iter().map(|&old| reference[old]).collect(),
            },
        }))
    }

    /// The members' meshes as one, and the first combined vertex of each member.
    fn combined_mesh(
        &self,
        members: &[Entity],
    ) -> Result<(SkinnedMesh, Vec<(Entity, u32)>), PoseableError> {
        let mut mesh = SkinnedMesh::default();
        let mut offsets = Vec::new();
        for &p in members {
            let Some(asset) = self
                .skins
                .get(p)
                .ok()
                .and_then(|(_, m)| self.meshes.get(&m.0))
            else {
                continue;
            };
            let part = skinned_mesh_of(asset)?;
            let base = mesh.positions.len() as u32;
            offsets.push((p, base));
            mesh.indices.extend(part.indices.iter().map(|i| i + base));
            mesh.positions.extend(part.positions);
            mesh.joint_indices.extend(part.joint_indices);
            mesh.joint_weights.extend(part.joint_weights);
        }
        Ok((mesh, offsets))
    }

    /// The skin's joints in skin order: parents are the nearest joint ancestors; a root's parent
    /// frame is its parent entity's world transform brought into character space by
    /// `to_character`. With their current local transforms.
    fn joints_of(
        &self,
        skin: &BevySkin,
        ibp: &SkinnedMeshInverseBindposes,
        to_character: &DAffine3,
    ) -> Result<(Vec<Joint>, Vec<JointTransform>), PoseableError> {
        let mut list = Vec::with_capacity(skin.joints.len());
        let mut reference = Vec::with_capacity(skin.joints.len());
        for (k, &j) in skin.joints.iter().enumerate() {
            let Ok((transform, child_of, name)) = self.joints.get(j) else {
                return Err(PoseableError::MissingJoint(j));
            };
            let parent = self.joint_parent(skin, child_of);
            let parent_frame = match (parent, child_of) {
                (None, Some(c)) => {
                    *to_character
                        * self
                            .globals
                            .get(c.parent())
                            .map(affine)
                            .unwrap_or(DAffine3::IDENTITY)
                }
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
        Ok((list, reference))
    }

    /// What decides a character's model, for sharing it between instances of one asset: the
    /// primitives' meshes, the skin's inverse binds, the model settings, and (rounded) each
    /// root joint's parent frame in character space and every joint's scale. `None` while
    /// the skin is not there.
    fn model_key(
        &self,
        primitives: &[Entity],
        to_character: &DAffine3,
        clusters: u32,
    ) -> Option<ModelKey> {
        let (skin, _) = self.skins.get(*primitives.first()?).ok()?;
        let meshes = primitives
            .iter()
            .filter_map(|&p| self.skins.get(p).ok())
            .filter(|(s, _)| s.joints == skin.joints)
            .map(|(_, m)| m.0.id())
            .collect();
        let round = |x: f64| (x * 1e5).round() as i64;
        let mut numbers = Vec::new();
        for &j in &skin.joints {
            let (transform, child_of, _) = self.joints.get(j).ok()?;
            numbers.extend(transform.scale.to_array().map(|x| round(f64::from(x))));
            if self.joint_parent(skin, child_of).is_none() {
                let parent = child_of.and_then(|c| self.globals.get(c.parent()).ok());
                let frame = *to_character * parent.map(affine).unwrap_or(DAffine3::IDENTITY);
                numbers.extend(frame.to_cols_array().map(round));
            }
        }
        Some(ModelKey {
            meshes,
            bindposes: skin.inverse_bindposes.id(),
            clusters,
            numbers,
        })
    }

    /// The skin index of the nearest ancestor (from `child_of` up) that is a joint of `skin`.
    fn joint_parent(&self, skin: &BevySkin, child_of: Option<&ChildOf>) -> Option<usize> {
        let mut up = child_of.map(|c| c.parent());
        while let Some(p) = up {
            if let Some(index) = skin.joints.iter().position(|&x| x == p) {
                return Some(index);
            }
            up = self
                .joints
                .get(p)
                .ok()
                .and_then(|(_, c, _)| c.map(|c| c.parent()));
        }
        None
    }
}

impl CharacterSkin {
    /// Reads the skin of the character at (or below) `character` from `world` as the pose
    /// plugin does — in character space when the character is placed by a similarity (see
    /// [`PosedSkeleton::placement`]), else in world space: what a benchmark or tool needs to
    /// build the same [`SkinnedModel`] without the plugin. `Ok(None)` while a mesh or its
    /// inverse bind poses are still loading; an error when there is no skinned mesh, a joint is
    /// missing or the skeleton is malformed.
    pub fn read(world: &mut World, character: Entity) -> Result<Option<Self>, PoseableError> {
        let mut state = bevy::ecs::system::SystemState::<SkinSources>::new(world);
        let Ok(sources) = state.get(world) else {
            // The app has no mesh or skin assets at all.
            return Err(PoseableError::NoSkinnedMesh);
        };
        let primitives = sources.primitives(character);
        if primitives.is_empty() {
            return Err(PoseableError::NoSkinnedMesh);
        }
        let to_character = sources
            .placement(character)
            .map_or(DAffine3::IDENTITY, |p| p.inverse());
        sources.read(&primitives, &to_character)
    }
}

/// Finds the skinned primitives and joints of new [`Poseable`]s and starts building their
/// models in the background — or takes the model another instance of the same asset built
/// ([`PoseModels`]), waiting while that one is still being built.
#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
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
        (Without<ModelBuild>, Without<PosedSkeleton>),
    >,
    assets: Option<Res<AssetServer>>,
    sources: SkinSources,
    mut models: ResMut<PoseModels>,
    joints: Query<&Transform>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, poseable, mut status, scene, spawned) in &mut new {
        if status.phase == DeformPhase::Failed {
            continue;
        }
        let primitives = sources.primitives(entity);
        if primitives.is_empty() {
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
        }
        // Character space when the character is placed by a similarity (then the model is
        // shared by every instance of the asset), else world space.
        let placement = sources.placement(entity);
        let to_character = placement.map_or(DAffine3::IDENTITY, |p| p.inverse());
        let clusters = poseable.clusters.max(1);
        let key = placement.and_then(|_| sources.model_key(&primitives, &to_character, clusters));
        let shared = match key.as_ref().and_then(|k| models.entries.get(k)) {
            Some(SharedModel::Building) => continue, // another instance is building it
            Some(SharedModel::Ready(model)) => model.upgrade(),
            None => None,
        };
        let found = match sources.read(&primitives, &to_character) {
            Ok(Some(found)) => found,
            Ok(None) => continue, // an asset is still loading
            Err(e) => {
                fail(entity, e, &mut status, &mut failed);
                continue;
            }
        };
        let CharacterSkin {
            mesh,
            primitives,
            skeleton,
            joints: joint_entities,
            reference,
        } = found;
        let mut build = ModelBuild {
            task: None,
            joints: joint_entities,
            primitives,
            placement,
            shared_key: None,
        };
        if let Some(model) = shared {
            insert_prepared(
                &mut commands.entity(entity),
                model,
                &build,
                &joints,
                &mut status,
            );
            continue;
        }
        if let Some(key) = key {
            models.entries.insert(key.clone(), SharedModel::Building);
            build.shared_key = Some(key);
        }
        let settings = ModelSettings {
            clusters: clusters as usize,
            ..Default::default()
        };
        build.task =
            Some(AsyncComputeTaskPool::get().spawn(async move {
                Ok(SkinnedModel::new(skeleton, &mesh, &reference, settings)?)
            }));
        status.phase = DeformPhase::BuildingTopology;
        commands.entity(entity).try_insert(build);
    }
}

/// What a character whose model is ready gets: [`PosedSkeleton`] (the joints' current pose)
/// and the solve state (see `state.rs`); its status becomes idle, with the model's joint and
/// vertex counts.
fn insert_prepared(
    entity: &mut EntityCommands,
    model: Arc<SkinnedModel>,
    build: &ModelBuild,
    joints: &Query<&Transform>,
    status: &mut PoseStatus,
) {
    status.phase = DeformPhase::Idle;
    status.joints = model.skeleton().len();
    status.vertices = model.topology().vertex_count();
    let pose = SkeletonPose {
        local: build
            .joints
            .iter()
            .map(|&j| joints.get(j).map(joint_transform).unwrap_or_default())
            .collect(),
    };
    let posed = PosedSkeleton {
        model,
        joints: build.joints.clone(),
        primitives: build.primitives.clone(),
        pose,
        placement: build.placement.unwrap_or(DAffine3::IDENTITY),
    };
    let state = (
        PoseDrivers::default(),
        GroundContacts::default(),
        PoseSolves::default(),
        LastSolve::default(),
        BlendMemory::default(),
    );
    entity.try_remove::<ModelBuild>().try_insert((posed, state));
    if build.placement.is_some() {
        entity.try_insert(CharacterSpace);
    }
}

/// Collects built models (sharing each with later instances of the asset); gives each its
/// [`PosedSkeleton`] with the joints' current pose and its solve state.
pub(super) fn finish_models(
    mut commands: Commands,
    mut building: Query<(Entity, &mut ModelBuild, &mut PoseStatus)>,
    joints: Query<&Transform>,
    mut models: ResMut<PoseModels>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, mut build, mut status) in &mut building {
        let Some(result) = poll_slot(&mut build.task) else {
            continue;
        };
        let key = build.shared_key.take();
        match result {
            Ok(model) => {
                let model = Arc::new(model);
                models.built += 1;
                if let Some(key) = key {
                    models
                        .entries
                        .insert(key, SharedModel::Ready(Arc::downgrade(&model)));
                }
                insert_prepared(
                    &mut commands.entity(entity),
                    model,
                    &build,
                    &joints,
                    &mut status,
                );
            }
            Err(e) => {
                if let Some(key) = key {
                    models.entries.remove(&key);
                }
                fail(entity, e, &mut status, &mut failed);
            }
        }
    }
}
