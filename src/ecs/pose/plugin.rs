//! The character plugin: its system sets, its per-character state, and the wiring of the
//! systems in `prepare.rs` (skins → models), `request.rs` (drivers → solves), `poll.rs`
//! (landed solves, timelines) and `apply.rs` (the pose onto the joints after animation).

use std::sync::Arc;

use bevy::app::AnimationSystems;
use bevy::picking::PickingSystems;
use bevy::picking::backend::PointerHits;
use bevy::picking::backend::ray::RayMap;
use bevy::prelude::*;

use crate::ecs::tasks::LatestTask;
use bevy::tasks::Task;
use bevy::transform::TransformSystems;

use super::apply::apply_poses;
use super::blend::BlendMemory;
use super::constraints::SetKey;
use super::in_frame::solve_in_frame;
use super::picking::{ignore_bind_pose_picking, pick_posed_characters};
use super::poll::{poll_pose_solves, show_timelines};
use super::prepare::{find_skins, finish_models};
use super::request::request_pose_solves;
use super::{
    GrabAnchor, HandlePositionOnly, PinnedJoints, PoseBlend, PoseEffector, PoseFailed, PoseInFrame,
    PoseJointHandle, PoseSolved, PoseStatus, PoseStiffness, Poseable, PoseableError,
    SymmetricEditing,
};
use crate::ecs::scene::mark_scene_spawned;
use crate::ecs::{DeformPhase, DeformSystems};
use crate::pose::{
    JointLimits, PoseConstraints, PoseSolution, PoseSolver, SkeletonPose, SkinnedModel,
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
    /// Show each [`PoseTimeline`](super::PoseTimeline)'s pose at its time (after Poll: a timeline that changed this
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
            .init_resource::<super::PoseModels>()
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
            .add_systems(
                PostUpdate,
                (solve_in_frame, apply_poses)
                    .chain()
                    .in_set(PoseSystems::Apply),
            )
            .register_type::<PoseInFrame>()
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

pub(super) type SolveResult = Result<(Arc<PoseSolver>, PoseSolution, f64), PoseableError>;

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
    /// Left/right pairs and mirrored vertex sets, built when symmetric editing first needs
    /// them.
    pub(super) symmetry: Option<super::symmetry::Symmetry>,
    /// The blend layer's memory of the animation ([`PoseBlend`]).
    pub(super) blend: BlendMemory,
    /// Where the next solve starts when not from [`PosedSkeleton::pose`] (an additive layer
    /// solves from the pose on screen).
    pub(super) start: Option<SkeletonPose>,
    /// An in-frame solve's outcome, until its message is written (`in_frame.rs`).
    pub(super) in_frame_outcome: Option<Result<f64, PoseableError>>,
    /// World ← character space when the model is in character space (placed by a
    /// similarity), `None` for a model in world space.
    pub(super) placement: Option<glam::DAffine3>,
    /// The [`super::PoseModels`] entry this character is building, if shared.
    pub(super) shared_key: Option<super::ModelKey>,
    /// Where each effector of the pending constraints came from (index in
    /// `PoseConstraints::effectors`, its entity and component): an in-frame solve reads their
    /// goals again after animation (`in_frame.rs`).
    pub(super) effector_sources: Vec<(usize, Entity, super::PoseEffector)>,
    /// The constraints of the last in-frame solve (with effectors), to ask again when only
    /// their targets moved after `Update`.
    pub(super) solved: Option<PoseConstraints>,
}

impl PoseState {
    /// The state of a character whose skin was found: its joints and primitives.
    pub(super) fn new(joints: Vec<Entity>, primitives: Vec<(Entity, u32)>) -> Self {
        Self {
            building: None,
            joints,
            primitives,
            key: None,
            reference: None,
            solver: None,
            last: None,
            solve: LatestTask::default(),
            pending: None,
            running: None,
            written: None,
            limits: None,
            symmetry: None,
            blend: Default::default(),
            start: None,
            in_frame_outcome: None,
            placement: None,
            shared_key: None,
            effector_sources: Vec::new(),
            solved: None,
        }
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
