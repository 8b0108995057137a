//! Systems of the character plugin: find the skin, build the model in the background, solve
//! on handle changes (latest wins), write the pose to the joints after animation.

use std::sync::Arc;

use bevy::app::AnimationSystems;
use bevy::picking::PickingSystems;
use bevy::picking::backend::PointerHits;
use bevy::picking::backend::ray::RayMap;
use bevy::prelude::*;

use crate::ecs::tasks::LatestTask;
use bevy::tasks::Task;
use bevy::transform::TransformSystems;

use super::blend::BlendMemory;
use super::constraints::{
    SetKey, core_effector, joint_handle, rebase, resolve_limits, vertex_handles,
};
use super::picking::{ignore_bind_pose_picking, pick_posed_characters};
use super::prepare::{find_skins, finish_models, joint_transform};
use super::{
    GrabAnchor, HandlePositionOnly, PinnedJoints, PoseBlend, PoseBlendMode, PoseEffector,
    PoseFailed, PoseJointHandle, PoseLimits, PoseSolved, PoseStatus, PoseStiffness, PoseTimeline,
    Poseable, PoseableError, PosedSkeleton, SymmetricEditing,
};
use crate::ecs::scene::mark_scene_spawned;
use crate::ecs::{DeformHandle, DeformPhase, DeformSystems};
use crate::pose::{
    Effector, JointLimits, JointTransform, Mirror, PoseConstraints, PoseSolution, PoseSolveOptions,
    PoseSolver, PoseSolverSettings, PoseStart, ReferenceStiffness, SkeletonPose, SkinnedModel,
    additive_layer_for, blend_pose,
};

/// Phases of the character systems. Prepare, Request, Poll and Timeline run in `Update` (Request after
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
    /// Show each [`PoseTimeline`]'s pose at its time (after Poll: a timeline that changed this
    /// frame wins over a solve that landed).
    Timeline,
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
            .register_type::<PoseBlend>()
            .add_message::<PoseSolved>()
            .add_message::<PoseFailed>()
            .add_observer(mark_scene_spawned)
            .configure_sets(
                Update,
                (
                    PoseSystems::Prepare,
                    PoseSystems::Request,
                    PoseSystems::Poll,
                    PoseSystems::Timeline,
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
                    show_timelines.in_set(PoseSystems::Timeline),
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

type SolveResult = Result<(Arc<PoseSolver>, PoseSolution, f64), PoseableError>;

/// Internal per-character state.
#[derive(Component)]
pub(crate) struct PoseState {
    pub(super) building: Option<Task<Result<SkinnedModel, PoseableError>>>,
    pub(super) joints: Vec<Entity>,
    pub(super) primitives: Vec<(Entity, u32)>,
    pub(super) key: Option<SetKey>,
    pub(super) reference: Option<SkeletonPose>,
    pub(super) solver: Option<Arc<PoseSolver>>,
    pub(super) last: Option<Arc<PoseSolution>>,
    /// The running solve (the latest request wins).
    pub(super) solve: LatestTask<SolveResult>,
    pub(super) pending: Option<PoseConstraints>,
    /// The constraints of the running solve (re-queued while the pose is still settling).
    pub(super) running: Option<PoseConstraints>,
    /// The pose the last landed solve wrote: anything else in [`PosedSkeleton::pose`] was put
    /// there by the app (a loaded or reset pose).
    pub(super) written: Option<SkeletonPose>,
    /// The character's [`PoseLimits`], resolved against its skeleton.
    pub(super) limits: Option<Arc<JointLimits>>,
    /// Left/right pairs, built when symmetric editing first needs them.
    pub(super) mirror: Option<Arc<Mirror>>,
    /// The blend layer's memory of the animation ([`PoseBlend`]).
    pub(super) blend: BlendMemory,
    /// Where the next solve starts when not from [`PosedSkeleton::pose`] (an additive layer
    /// solves from the pose on screen).
    pub(super) start: Option<SkeletonPose>,
}

/// A character grabbed with no anchor (compared in place every frame, never allocated).
static NO_ANCHOR: GrabAnchor = GrabAnchor {
    joints: Vec::new(),
    vertices: Vec::new(),
};

/// The per-character settings a solve reads besides handles and pins.
#[derive(bevy::ecs::query::QueryData)]
struct CharacterSettings {
    limits: Option<Ref<'static, PoseLimits>>,
    stiffness: Option<Ref<'static, PoseStiffness>>,
    symmetric: Has<SymmetricEditing>,
    blend: Option<&'static PoseBlend>,
}

impl CharacterSettingsItem<'_, '_> {
    /// An additive blend layer: solves start from the pose on screen, results become the
    /// layer over the animation.
    fn additive(&self) -> bool {
        self.blend
            .is_some_and(|b| b.mode == PoseBlendMode::Additive)
    }
}

pub(super) fn fail(
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

/// Starts a solve when a character's handles, pins or pose changed (latest wins).
#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
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
        let anchor = anchor.unwrap_or(&NO_ANCHOR);
        let followers: Vec<Entity> = mine
            .iter()
            .map(|(e, _, _)| *e)
            .filter(|e| position_only.contains(*e))
            .collect();
        let effector_keys: Vec<(Entity, Entity)> =
            mine_e.iter().map(|(e, p, _)| (*e, p.joint)).collect();
        let set_changed = !state.key.as_ref().is_some_and(|k| {
            k.matches(&mine, &mine_j, pinned)
                && k.anchor == *anchor
                && k.position_only == followers
                && k.effectors == effector_keys
        }) || mine.iter().any(|(_, h, _)| h.pivot.is_none())
            || mine_j.iter().any(|(_, h, _)| h.rest.is_none());
        // What is on screen: the joints as they are now (the held pose, whatever a playing or
        // paused clip left on them, or the clip plus an additive layer).
        let on_screen = || SkeletonPose {
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
        if set_changed {
            // The reference is what is on screen; an override blend's layer is its own pose
            // (the screen shows it mixed with the clip).
            let reference = if extras.additive() {
                on_screen()
            } else {
                if extras.blend.is_none() {
                    let now = on_screen();
                    if now != posed.pose {
                        posed.pose = now;
                    }
                }
                posed.pose.clone()
            };
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
                anchor: anchor.clone(),
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
            || settings_changed
            || extras.additive() && state.blend.moved;
        if !changed && state.pending.is_none() {
            continue;
        }
        let limits = match resolve_limits(&posed, extras.limits.as_ref(), &mut state.limits) {
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
        // An additive layer holds what nothing pulls on where the animation puts it now.
        let start = extras.additive().then(on_screen);
        let stiffness = extras
            .stiffness
            .zip(start.clone().or_else(|| state.reference.clone()))
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
        state.start = start;
        state.solve.supersede();
        if !state.solve.is_running() {
            spawn_pose_solve(state, &posed, poseable, &mut status);
        }
    }
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
    let warm = if reuse.is_some() && state.start.is_none() {
        state.last.clone()
    } else {
        None
    };
    let current = state.start.take().unwrap_or_else(|| posed.pose.clone());
    let options = PoseSolveOptions {
        max_iterations: poseable.max_iterations.max(1),
        tolerance: poseable.tolerance.max(0.0) as f64,
    };
    status.phase = DeformPhase::Solving;
    state.solve.spawn(move |cancellation| {
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
        let cancel = || cancellation.superseded();
        let solution = solver.solve(&constraints, &options, start, &cancel)?;
        Ok((solver, solution, t0.elapsed().as_secs_f64() * 1e3))
    });
}

/// What [`poll_pose_solves`] reads and writes of a character.
type PolledCharacter = (
    Entity,
    &'static Poseable,
    &'static mut PosedSkeleton,
    &'static mut PoseState,
    &'static mut PoseStatus,
    Option<&'static PoseBlend>,
);

/// Stores finished solves in [`PosedSkeleton::pose`]; starts the pending one.
fn poll_pose_solves(
    mut characters: Query<PolledCharacter>,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, poseable, mut posed, mut state, mut status, blend) in &mut characters {
        let state = state.bypass_change_detection();
        let Some(result) = state.solve.poll() else {
            continue;
        };
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
                let pose = match blend {
                    Some(b) if b.mode == PoseBlendMode::Additive => {
                        additive_layer(&posed, &state.blend, b, &solution.pose)
                    }
                    _ => solution.pose.clone(),
                };
                posed.pose = pose.clone();
                state.written = Some(pose);
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

/// Advances playing timelines; writes the pose of every timeline that changed.
fn show_timelines(time: Res<Time>, mut characters: Query<(&mut PoseTimeline, &mut PosedSkeleton)>) {
    for (mut timeline, mut posed) in &mut characters {
        if timeline.playing {
            timeline.advance(time.delta_secs());
        }
        if !timeline.is_changed() {
            continue;
        }
        if let Some(pose) = timeline.pose_now(&posed)
            && pose != posed.pose
        {
            posed.pose = pose;
        }
    }
}

/// The additive layer that shows `full` over the animation the blend last read.
fn additive_layer(
    posed: &PosedSkeleton,
    memory: &BlendMemory,
    blend: &PoseBlend,
    full: &SkeletonPose,
) -> SkeletonPose {
    let skeleton = posed.model.skeleton();
    let reference = memory
        .reference
        .clone()
        .unwrap_or_else(|| blend.reference_pose(skeleton));
    let animated = memory.animated_pose();
    let local = full
        .local
        .iter()
        .enumerate()
        .map(
            |(j, f)| match (animated.local.get(j), reference.local.get(j)) {
                (Some(a), Some(r)) => additive_layer_for(a, f, r),
                _ => *f,
            },
        )
        .collect();
    SkeletonPose { local }
}

/// What [`apply_poses`] reads and writes of a character.
type AppliedCharacter = (
    &'static Poseable,
    Ref<'static, PosedSkeleton>,
    Option<Ref<'static, PoseBlend>>,
    &'static mut PoseState,
);

/// Writes each character's pose to its joints: blended over the animation with a
/// [`PoseBlend`] (every frame), else every frame with `hold_pose` or when it changed.
fn apply_poses(mut characters: Query<AppliedCharacter>, mut joints: Query<&mut Transform>) {
    for (poseable, posed, blend, mut state) in &mut characters {
        let state = state.bypass_change_detection();
        let Some(blend) = blend else {
            state.blend.clear();
            if poseable.hold_pose || posed.is_changed() {
                write_pose(&posed.joints, &posed.pose, &mut joints, None);
            }
            continue;
        };
        let memory = &mut state.blend;
        let current: Vec<Option<Transform>> = posed
            .joints
            .iter()
            .map(|&j| joints.get(j).ok().copied())
            .collect();
        memory.read_animation(&current);
        let animated = memory.animated_pose();
        let skeleton = posed.model.skeleton();
        if blend.is_changed() || memory.mask.is_none() && blend.mask.is_some() {
            memory.mask = blend
                .mask
                .as_ref()
                .map(|m| m.selects(skeleton, &posed.joints));
            memory.reference = None;
        }
        let reference = memory
            .reference
            .get_or_insert_with(|| blend.reference_pose(skeleton));
        let out = blend_pose(
            &animated,
            &posed.pose,
            reference,
            blend.mode.into(),
            f64::from(blend.weight),
            memory.mask.as_deref(),
        );
        write_pose(&posed.joints, &out, &mut joints, Some(&mut memory.written));
    }
}

/// Writes local transforms to the joint entities (skipping invalid ones); `written` records
/// what each joint holds afterwards.
fn write_pose(
    entities: &[Entity],
    pose: &SkeletonPose,
    joints: &mut Query<&mut Transform>,
    mut written: Option<&mut Vec<Transform>>,
) {
    for (k, (&j, t)) in entities.iter().zip(&pose.local).enumerate() {
        if !t.is_valid() {
            continue;
        }
        let Ok(mut transform) = joints.get_mut(j) else {
            continue;
        };
        let new = Transform {
            translation: t.translation.as_vec3(),
            rotation: t.rotation.as_quat().normalize(),
            scale: t.scale.as_vec3(),
        };
        if *transform != new {
            *transform = new;
        }
        if let Some(slot) = written.as_deref_mut().and_then(|w| w.get_mut(k)) {
            *slot = new;
        }
    }
}
