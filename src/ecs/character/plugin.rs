//! Systems of the character plugin: find the skin, build the model in the background, solve
//! on handle changes (latest wins), write the pose to the joints after animation.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use bevy::app::AnimationSystems;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh as BevySkin, SkinnedMeshInverseBindposes};
use bevy::picking::PickingSystems;
use bevy::picking::backend::PointerHits;
use bevy::picking::backend::ray::RayMap;
use bevy::prelude::*;
use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task};
use bevy::transform::TransformSystems;
use bevy::world_serialization::WorldAssetRoot;
use glam::DAffine3;

use super::picking::{ignore_bind_pose_picking, pick_posed_characters};
use super::{
    GrabAnchor, HandlePositionOnly, PinnedJoints, PoseEffector, PoseEffectorKind, PoseFailed,
    PoseJointHandle, PoseLimits, PoseSolved, PoseStatus, PoseStiffness, Poseable, PoseableError,
    PosedSkeleton, SymmetricEditing,
};
use crate::deform::{Handle as CoreHandle, RigidTransform, centroid};
use crate::ecs::control::rotation_of_space;
use crate::ecs::scene::{SceneSpawned, mark_scene_spawned, scene_load_failure};
use crate::ecs::{DeformHandle, DeformPhase, DeformSystems};
use crate::pose::{
    CentroidEffector, Effector, EffectorGoal, Joint, JointHandle, JointLimits, JointTransform,
    LimitError, Mirror, ModelSettings, PoseConstraints, PoseSolution, PoseSolveOptions, PoseSolver,
    PoseSolverSettings, PoseStart, ReferenceStiffness, Skeleton, SkeletonPose, SkinnedMesh,
    SkinnedModel,
};

/// Phases of the character systems. Prepare, Request and Poll run in `Update` (Request after
/// [`DeformSystems::Request`], so handle controls ordered before that set are seen the same
/// frame); Apply runs in `PostUpdate` after `AnimationSystems`, before transform propagation.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PoseSystems {
    /// Find skins, build models.
    Prepare,
    /// Start solves when handles or pins changed.
    Request,
    /// Collect finished solves.
    Poll,
    /// Write the pose to the joint `Transform`s.
    Apply,
}

/// Adds posing of rigged characters ([`Poseable`]).
#[derive(Debug, Clone, Default)]
pub struct PosePlugin;

impl Plugin for PosePlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<Poseable>()
            .register_type::<PinnedJoints>()
            .register_type::<PoseJointHandle>()
            .register_type::<PoseStatus>()
            .register_type::<GrabAnchor>()
            .register_type::<HandlePositionOnly>()
            .register_type::<PoseEffector>()
            .register_type::<PoseStiffness>()
            .register_type::<SymmetricEditing>()
            .add_message::<PoseSolved>()
            .add_message::<PoseFailed>()
            .add_observer(mark_scene_spawned)
            .configure_sets(
                Update,
                (
                    PoseSystems::Prepare,
                    PoseSystems::Request,
                    PoseSystems::Poll,
                )
                    .chain()
                    .after(DeformSystems::Request),
            )
            .configure_sets(
                PostUpdate,
                PoseSystems::Apply
                    .after(AnimationSystems)
                    .before(TransformSystems::Propagate),
            )
            .add_systems(
                Update,
                (
                    (find_skins, finish_models)
                        .chain()
                        .in_set(PoseSystems::Prepare),
                    request_pose_solves.in_set(PoseSystems::Request),
                    poll_pose_solves.in_set(PoseSystems::Poll),
                ),
            )
            .add_systems(PostUpdate, apply_poses.in_set(PoseSystems::Apply))
            // Posed characters are a picking backend (when bevy_picking is in the app).
            .add_message::<PointerHits>()
            .add_systems(
                PreUpdate,
                pick_posed_characters
                    .in_set(PickingSystems::Backend)
                    .run_if(resource_exists::<RayMap>),
            )
            .add_systems(Update, ignore_bind_pose_picking.after(PoseSystems::Poll));
    }
}

/// Which handles and pins a solver was built for.
#[derive(Debug, Clone, Default)]
struct SetKey {
    handles: Vec<(Entity, Vec<u32>)>,
    joint_handles: Vec<(Entity, Entity)>,
    pins: Vec<Entity>,
    anchor: GrabAnchor,
    position_only: Vec<Entity>,
    effectors: Vec<(Entity, Entity)>,
}

impl SetKey {
    /// True when the handles and pins now are the ones this key was made from (compared in
    /// place: this runs every frame).
    fn matches(
        &self,
        handles: &[(Entity, Mut<DeformHandle>, Mut<Transform>)],
        joint_handles: &[(Entity, Mut<PoseJointHandle>, Mut<Transform>)],
        pins: &[Entity],
    ) -> bool {
        self.pins == pins
            && self.handles.len() == handles.len()
            && self
                .handles
                .iter()
                .zip(handles)
                .all(|((e, v), (f, h, _))| e == f && *v == h.vertices)
            && self.joint_handles.len() == joint_handles.len()
            && self
                .joint_handles
                .iter()
                .zip(joint_handles)
                .all(|((e, j), (f, h, _))| e == f && *j == h.joint)
    }
}

type SolveResult = Result<(Arc<PoseSolver>, PoseSolution, f64), PoseableError>;

/// Internal per-character state.
#[derive(Component)]
pub(crate) struct PoseState {
    building: Option<Task<Result<SkinnedModel, PoseableError>>>,
    joints: Vec<Entity>,
    primitives: Vec<(Entity, u32)>,
    key: Option<SetKey>,
    reference: Option<SkeletonPose>,
    solver: Option<Arc<PoseSolver>>,
    last: Option<Arc<PoseSolution>>,
    task: Option<Task<SolveResult>>,
    requested: Arc<AtomicU64>,
    pending: Option<PoseConstraints>,
    /// The constraints of the running solve (re-queued while the pose is still settling).
    running: Option<PoseConstraints>,
    /// The pose the last landed solve wrote: anything else in [`PosedSkeleton::pose`] was put
    /// there by the app (a loaded or reset pose).
    written: Option<SkeletonPose>,
    /// The character's [`PoseLimits`], resolved against its skeleton.
    limits: Option<Arc<JointLimits>>,
    /// Left/right pairs, built when symmetric editing first needs them.
    mirror: Option<Arc<Mirror>>,
}

/// The per-character settings a solve reads besides handles and pins.
#[derive(bevy::ecs::query::QueryData)]
struct CharacterSettings {
    limits: Option<Ref<'static, PoseLimits>>,
    stiffness: Option<Ref<'static, PoseStiffness>>,
    symmetric: Has<SymmetricEditing>,
}

fn fail(
    entity: Entity,
    error: PoseableError,
    status: &mut PoseStatus,
    failed: &mut MessageWriter<PoseFailed>,
) {
    warn!("Poseable {entity}: {error}");
    status.phase = DeformPhase::Failed;
    status.error = Some(error.clone());
    failed.write(PoseFailed { entity, error });
}

fn affine(t: &GlobalTransform) -> DAffine3 {
    let a = t.affine();
    DAffine3::from_mat3_translation(
        glam::Mat3::from(a.matrix3).as_dmat3(),
        Vec3::from(a.translation).as_dvec3(),
    )
}

fn joint_transform(t: &Transform) -> JointTransform {
    JointTransform {
        translation: t.translation.as_dvec3(),
        rotation: t.rotation.as_dquat().normalize(),
        scale: t.scale.as_dvec3(),
    }
}

/// Reads positions, indices and skin attributes of one primitive.
fn skinned_mesh_of(mesh: &Mesh) -> Result<SkinnedMesh, PoseableError> {
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
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn find_skins(
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
            task: None,
            requested: Arc::new(AtomicU64::new(0)),
            pending: None,
            running: None,
            written: None,
            limits: None,
            mirror: None,
        });
    }
}

/// Collects built models; inserts [`PosedSkeleton`] with the joints' current pose.
fn finish_models(
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

/// Rebases the handles of a character to `reference`: vertex handles' pivots to the world
/// centroid of their skinned vertices, joint handles' rests to the joint's world transform;
/// each `Transform` to its rest.
fn rebase(
    posed: &PosedSkeleton,
    reference: &SkeletonPose,
    handles: &mut [(Entity, Mut<DeformHandle>, Mut<Transform>)],
    joint_handles: &mut [(Entity, Mut<PoseJointHandle>, Mut<Transform>)],
) {
    let model = &posed.model;
    let skinned = model.skin_render(reference);
    for (_, h, t) in handles.iter_mut() {
        let c = centroid(&skinned, &h.vertices);
        h.pivot = Some(c.as_vec3());
        **t = Transform::from_translation(c.as_vec3());
    }
    let globals = model.skeleton().global_transforms(reference);
    for (_, h, t) in joint_handles.iter_mut() {
        let Some(j) = posed.joint_index(h.joint) else {
            continue;
        };
        let (_, rotation, translation) = globals[j].to_scale_rotation_translation();
        let rest = Transform::from_translation(translation.as_vec3())
            .with_rotation(rotation.as_quat().normalize());
        h.rest = Some(rest);
        **t = rest;
    }
}

/// Starts a solve when a character's handles, pins or pose changed (latest wins).
#[allow(clippy::type_complexity)]
fn request_pose_solves(
    mut characters: Query<(
        Entity,
        &Poseable,
        &mut PosedSkeleton,
        Option<Ref<PinnedJoints>>,
        Option<&GrabAnchor>,
        CharacterSettings,
        &mut PoseState,
        &mut PoseStatus,
    )>,
    mut handles: Query<(Entity, &mut DeformHandle, &mut Transform), Without<PoseJointHandle>>,
    mut joint_handles: Query<(Entity, &mut PoseJointHandle, &mut Transform), Without<DeformHandle>>,
    joints: Query<&Transform, (Without<DeformHandle>, Without<PoseJointHandle>)>,
    (position_only, effectors): (
        Query<(), With<HandlePositionOnly>>,
        Query<(Entity, Ref<PoseEffector>, Ref<GlobalTransform>)>,
    ),
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, poseable, mut posed, pins, anchor, extras, mut state, mut status) in
        &mut characters
    {
        let mut mine_e: Vec<(Entity, Ref<PoseEffector>, Ref<GlobalTransform>)> = effectors
            .iter()
            .filter(|(_, e, _)| e.character == entity)
            .collect();
        mine_e.sort_by_key(|(e, _, _)| *e);
        let mut mine: Vec<(Entity, Mut<DeformHandle>, Mut<Transform>)> = handles
            .iter_mut()
            .filter(|(_, h, _)| h.target == entity)
            .collect();
        let mut mine_j: Vec<(Entity, Mut<PoseJointHandle>, Mut<Transform>)> = joint_handles
            .iter_mut()
            .filter(|(_, h, _)| h.target == entity)
            .collect();
        mine.sort_by_key(|(e, _, _)| *e);
        mine_j.sort_by_key(|(e, _, _)| *e);
        if mine.is_empty() && mine_j.is_empty() && mine_e.is_empty() {
            state.bypass_change_detection().key = None;
            continue; // nothing drives the pose
        }
        let pinned = pins.as_ref().map_or(&[][..], |p| &p.0[..]);
        let anchor = anchor.cloned().unwrap_or_default();
        let followers: Vec<Entity> = mine
            .iter()
            .map(|(e, _, _)| *e)
            .filter(|e| position_only.contains(*e))
            .collect();
        let effector_keys: Vec<(Entity, Entity)> =
            mine_e.iter().map(|(e, p, _)| (*e, p.joint)).collect();
        let set_changed = !state.key.as_ref().is_some_and(|k| {
            k.matches(&mine, &mine_j, pinned)
                && k.anchor == anchor
                && k.position_only == followers
                && k.effectors == effector_keys
        }) || mine.iter().any(|(_, h, _)| h.pivot.is_none())
            || mine_j.iter().any(|(_, h, _)| h.rest.is_none());
        if set_changed {
            // The reference is what is on screen: the joints as they are now (the held pose,
            // or whatever a playing or paused clip left on them).
            let on_screen = SkeletonPose {
                local: posed
                    .joints
                    .iter()
                    .zip(&posed.pose.local)
                    .map(|(&j, held)| {
                        let now = joints.get(j).map(joint_transform).ok();
                        now.filter(JointTransform::is_valid).unwrap_or(*held)
                    })
                    .collect(),
            };
            if on_screen != posed.pose {
                posed.pose = on_screen;
            }
            let reference = posed.pose.clone();
            // A handle that turned rigid (a grab being turned) keeps its target: its world
            // position and the turn just given to it, now about the patch as it is on screen.
            let turned: Vec<(Entity, Transform)> = state
                .key
                .as_ref()
                .map(|k| {
                    mine.iter()
                        .filter(|(e, h, _)| {
                            h.pivot.is_some()
                                && k.position_only.contains(e)
                                && followers.binary_search(e).is_err()
                        })
                        .map(|(e, _, t)| (*e, **t))
                        .collect()
                })
                .unwrap_or_default();
            rebase(&posed, &reference, &mut mine, &mut mine_j);
            for (e, kept) in turned {
                if let Some((_, _, t)) = mine.iter_mut().find(|(f, _, _)| *f == e) {
                    **t = kept;
                }
            }
            let state = state.bypass_change_detection();
            state.key = Some(SetKey {
                handles: mine
                    .iter()
                    .map(|(e, h, _)| (*e, h.vertices.clone()))
                    .collect(),
                joint_handles: mine_j.iter().map(|(e, h, _)| (*e, h.joint)).collect(),
                pins: pinned.to_vec(),
                anchor,
                position_only: followers,
                effectors: effector_keys,
            });
            state.reference = Some(reference);
            state.solver = None;
            state.last = None;
            continue; // the rebased Transforms trigger the solve next frame
        }
        let effectors_changed = mine_e
            .iter()
            .any(|(_, e, g)| e.is_changed() || g.is_changed());
        let settings_changed = extras.limits.as_ref().is_some_and(|l| l.is_changed())
            || extras.stiffness.as_ref().is_some_and(|s| s.is_changed());
        let changed = mine.iter().any(|(_, _, t)| t.is_changed())
            || mine_j.iter().any(|(_, _, t)| t.is_changed())
            || pins.as_ref().is_some_and(|p| p.is_changed())
            || effectors_changed
            || settings_changed;
        if !changed && state.pending.is_none() {
            continue;
        }
        let limits = match resolve_limits(&posed, extras.limits.as_ref(), &mut state) {
            Ok(limits) => limits,
            Err(e) => {
                fail(entity, e.into(), &mut status, &mut failed);
                continue;
            }
        };
        let mut fixed_joints: Vec<usize> = pins
            .as_ref()
            .map(|p| p.0.as_slice())
            .unwrap_or_default()
            .iter()
            .chain(&anchor.joints)
            .filter_map(|e| posed.joint_index(*e))
            .collect();
        fixed_joints.sort_unstable();
        fixed_joints.dedup();
        let (handles, centroid_effectors) =
            vertex_handles(&posed, state.reference.as_ref(), &mine, &followers);
        let mut effectors: Vec<Effector> = mine_e
            .iter()
            .filter_map(|(_, e, g)| core_effector(&posed, e, g))
            .collect();
        if extras.symmetric {
            let skeleton = posed.model.skeleton();
            let mirror = state
                .mirror
                .get_or_insert_with(|| Arc::new(Mirror::new(skeleton, &skeleton.bind_pose())))
                .clone();
            let frame = skeleton.joints()[0].parent_frame;
            let mirrored: Vec<Effector> = effectors
                .iter()
                .filter_map(|e| mirror.mirror_effector(e, &frame))
                .collect();
            effectors.extend(mirrored);
        }
        let stiffness = extras
            .stiffness
            .zip(state.reference.clone())
            .map(|(k, pose)| ReferenceStiffness::uniform(pose, k.0.clamp(0.0, 1.0) as f64));
        let constraints = PoseConstraints {
            centroid_effectors,
            handles,
            fixed_vertices: anchor.vertices.clone(),
            fixed_joints,
            joint_handles: mine_j
                .iter()
                .filter_map(|(_, h, t)| joint_handle(&posed, h, t))
                .collect(),
            effectors,
            stiffness,
            limits,
        };
        let state = state.bypass_change_detection();
        state.pending = Some(constraints);
        state.requested.fetch_add(1, Ordering::Relaxed);
        if state.task.is_none() {
            spawn_pose_solve(state, &posed, poseable, &mut status);
        }
    }
}

/// The character's limits, resolved against its skeleton (cached until `PoseLimits` changes).
fn resolve_limits(
    posed: &PosedSkeleton,
    source: Option<&Ref<PoseLimits>>,
    state: &mut PoseState,
) -> Result<Option<Arc<JointLimits>>, LimitError> {
    let Some(source) = source else {
        state.limits = None;
        return Ok(None);
    };
    if let Some(limits) = state.limits.as_ref().filter(|_| !source.is_changed()) {
        return Ok(Some(limits.clone()));
    }
    let skeleton = posed.model.skeleton();
    let rest = skeleton.bind_pose();
    let limits = match &**source {
        PoseLimits::Humanoid => Arc::new(JointLimits::humanoid(skeleton, &rest).0),
        PoseLimits::Ron(text) => Arc::new(JointLimits::from_ron(text, skeleton, &rest)?),
        PoseLimits::Custom(limits) => limits.clone(),
    };
    state.limits = Some(limits.clone());
    Ok(Some(limits))
}

/// The vertex handles of a character: rigid ones, and position-only ones as centroid
/// effectors (the centroid of the welded vertices, where it was in the reference pose, moved
/// by the handle's translation).
fn vertex_handles(
    posed: &PosedSkeleton,
    reference: Option<&SkeletonPose>,
    handles: &[(Entity, Mut<DeformHandle>, Mut<Transform>)],
    followers: &[Entity],
) -> (Vec<CoreHandle>, Vec<CentroidEffector>) {
    let model = &posed.model;
    let follows = |e: &Entity| followers.binary_search(e).is_ok();
    let reference_welded = (!followers.is_empty())
        .then(|| reference.map(|r| model.skin_welded(r)))
        .flatten();
    let centroids = handles
        .iter()
        .filter(|(e, _, _)| follows(e))
        .filter_map(|(_, h, t)| {
            let vertices = model.topology().welded_set(&h.vertices);
            let at_reference = centroid(reference_welded.as_ref()?, &vertices);
            let moved = (t.translation - h.pivot?).as_dvec3();
            Some(CentroidEffector {
                vertices,
                target: at_reference + moved,
                weight: 1.0,
            })
        })
        .collect();
    let rigid = handles
        .iter()
        .filter(|(e, _, _)| !follows(e))
        .map(|(_, h, t)| CoreHandle {
            vertices: model.topology().welded_set(&h.vertices),
            transform: h.rigid_transform(t),
        })
        .collect();
    (rigid, centroids)
}

/// A joint handle as the core takes it: the motion from its rest to its `Transform`.
fn joint_handle(posed: &PosedSkeleton, h: &PoseJointHandle, t: &Transform) -> Option<JointHandle> {
    let joint = posed.joint_index(h.joint)?;
    let rest = h.rest?;
    let rotation = (t.rotation * rest.rotation.inverse())
        .as_dquat()
        .normalize();
    let transform = RigidTransform::new(
        rotation,
        (t.translation - rest.translation).as_dvec3(),
        rest.translation.as_dvec3(),
    );
    Some(JointHandle { joint, transform })
}

/// A [`PoseEffector`] as the core takes it, its goal read from its `GlobalTransform`.
fn core_effector(
    posed: &PosedSkeleton,
    effector: &PoseEffector,
    global: &GlobalTransform,
) -> Option<Effector> {
    let joint = posed.joint_index(effector.joint)?;
    let point = global.translation().as_dvec3();
    let goal = match effector.kind {
        PoseEffectorKind::Position => EffectorGoal::Position(point),
        PoseEffectorKind::Orientation => {
            EffectorGoal::Orientation(rotation_of_space(&global.affine()).as_dquat())
        }
        PoseEffectorKind::Aim { axis, up } => EffectorGoal::Aim {
            axis: axis.as_dvec3(),
            target: point,
            up: up.map(|u| (u.as_dvec3(), glam::DVec3::Y)),
        },
    };
    Some(Effector {
        joint,
        goal,
        weight: f64::from(effector.weight),
    })
}

fn spawn_pose_solve(
    state: &mut PoseState,
    posed: &PosedSkeleton,
    poseable: &Poseable,
    status: &mut PoseStatus,
) {
    let Some(constraints) = state.pending.take() else {
        return;
    };
    let Some(reference) = state.reference.clone() else {
        return;
    };
    state.running = Some(constraints.clone());
    let model = posed.model.clone();
    let reuse = state.solver.clone().filter(|s| s.accepts(&constraints));
    let warm = if reuse.is_some() {
        state.last.clone()
    } else {
        None
    };
    let current = posed.pose.clone();
    let options = PoseSolveOptions {
        max_iterations: poseable.max_iterations.max(1),
        tolerance: poseable.tolerance.max(0.0) as f64,
    };
    let generation = state.requested.load(Ordering::Relaxed);
    let requested = state.requested.clone();
    status.phase = DeformPhase::Solving;
    state.task = Some(AsyncComputeTaskPool::get().spawn(async move {
        let t0 = std::time::Instant::now();
        let solver = match reuse {
            Some(s) => s,
            None => Arc::new(PoseSolver::new(
                model,
                &constraints,
                &reference,
                PoseSolverSettings::default(),
            )?),
        };
        let start = warm
            .as_deref()
            .map_or(PoseStart::Pose(&current), PoseStart::Warm);
        let calls = std::cell::Cell::new(0u32);
        let cancel = || {
            calls.set(calls.get() + 1);
            calls.get() > 1 && requested.load(Ordering::Relaxed) != generation
        };
        let solution = solver.solve(&constraints, &options, start, &cancel)?;
        Ok((solver, solution, t0.elapsed().as_secs_f64() * 1e3))
    }));
}

/// Stores finished solves in [`PosedSkeleton::pose`]; starts the pending one.
fn poll_pose_solves(
    mut characters: Query<(
        Entity,
        &Poseable,
        &mut PosedSkeleton,
        &mut PoseState,
        &mut PoseStatus,
    )>,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, poseable, mut posed, mut state, mut status) in &mut characters {
        let state = state.bypass_change_detection();
        let Some(task) = state.task.as_mut() else {
            continue;
        };
        let Some(result) = check_ready(task) else {
            continue;
        };
        state.task = None;
        // Released (no handles left) and the app set a pose since: it wins over the settling
        // of the old targets.
        let set_by_app = state.written.as_ref().is_some_and(|w| *w != posed.pose);
        if state.key.is_none() && set_by_app {
            state.pending = None;
            state.running = None;
            status.phase = DeformPhase::Idle;
            continue;
        }
        match result {
            Ok((solver, solution, ms)) => {
                // Not converged (every iteration used, still improving): keep settling with
                // the same targets until the tolerance stops it.
                let settling = !solution.stats.cancelled
                    && solution.stats.iterations >= poseable.max_iterations.max(1);
                if settling && state.pending.is_none() {
                    state.pending = state.running.take();
                }
                status.iterations = solution.stats.iterations;
                status.energy = solution
                    .stats
                    .energies
                    .last()
                    .copied()
                    .unwrap_or(solution.stats.initial_energy);
                status.solve_ms = ms;
                status.solves += 1;
                status.error = None;
                status.phase = if state.pending.is_some() {
                    DeformPhase::Solving
                } else {
                    DeformPhase::Idle
                };
                posed.pose = solution.pose.clone();
                state.written = Some(solution.pose.clone());
                state.solver = Some(solver);
                state.last = Some(Arc::new(solution));
                solved.write(PoseSolved {
                    entity,
                    iterations: status.iterations,
                    energy: status.energy,
                    solve_ms: ms,
                });
            }
            Err(error) => {
                // The last good pose is kept.
                warn!("Poseable {entity}: {error}");
                status.error = Some(error.clone());
                status.phase = DeformPhase::Idle;
                failed.write(PoseFailed { entity, error });
            }
        }
        if state.pending.is_some() {
            spawn_pose_solve(state, &posed, poseable, &mut status);
        }
    }
}

/// Writes each character's pose to its joints (every frame with `hold_pose`, else when it
/// changed).
fn apply_poses(
    characters: Query<(&Poseable, Ref<PosedSkeleton>)>,
    mut joints: Query<&mut Transform>,
) {
    for (poseable, posed) in &characters {
        if !poseable.hold_pose && !posed.is_changed() {
            continue;
        }
        for (&j, t) in posed.joints.iter().zip(&posed.pose.local) {
            if !t.is_valid() {
                continue;
            }
            if let Ok(mut transform) = joints.get_mut(j) {
                let new = Transform {
                    translation: t.translation.as_vec3(),
                    rotation: t.rotation.as_quat().normalize(),
                    scale: t.scale.as_vec3(),
                };
                if *transform != new {
                    *transform = new;
                }
            }
        }
    }
}
