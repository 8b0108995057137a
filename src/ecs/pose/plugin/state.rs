//! A character's internal state, one component per concern. Each stage of the plugin reads and
//! writes its own part; nothing here is public (runtime state, rebuilt from the scene):
//!
//! | component | what it holds | written by |
//! |---|---|---|
//! | [`ModelBuild`] | the model being built and where it goes | `prepare.rs` (removed once built) |
//! | [`PoseDrivers`] | the driver set a solver was built for, its reference pose, limits, mirror pairs, where each effector came from | `request.rs` |
//! | [`GroundContacts`] | the automatic ground contacts (planted or not) and the placement they are in | the standing step, `ground_contacts::stand_on` (asked by `request.rs`, or by `in_frame.rs` for an in-frame character) |
//! | [`PoseSolves`] | constraints waiting and running, where the next solve starts, the background task, an in-frame solve's outcome | `request.rs`, `poll.rs`, `in_frame.rs` |
//! | [`LastSolve`] | the solver and solution the next solve warm-starts from, and the pose it wrote | `solve::store_landed` (forgotten by `request.rs` when the driver set changes) |
//! | [`BlendMemory`](super::super::blend::BlendMemory) | the animation under the blend layer | `apply.rs` |
//! | [`CharacterSpace`] | marks a model built in character space (shared between instances) | `prepare.rs` |
//!
//! The shared steps — launching a solve (background or in the frame) and storing one that
//! landed — are in `solve.rs`; the stages call those, never each other.

use std::sync::Arc;

use bevy::prelude::*;
use bevy::tasks::Task;

use super::super::{ModelKey, PoseEffector, PoseFailed, PoseStatus, PoseableError};
use super::constraints::SetKey;
use super::solve::SolveResult;
use super::symmetry::Symmetry;
use crate::ecs::DeformPhase;
use crate::ecs::tasks::LatestTask;
use crate::pose::{
    JointLimits, PoseConstraints, PoseSolution, PoseSolver, SkeletonPose, SkinnedModel,
};

/// A character whose skin was found and whose model is being built (or taken from another
/// instance of its asset). Removed when [`PosedSkeleton`](super::super::PosedSkeleton) is inserted.
#[derive(Component)]
pub(super) struct ModelBuild {
    /// The background build (`None` when the model was shared).
    pub(super) task: Option<Task<Result<SkinnedModel, PoseableError>>>,
    /// The joint entities in skeleton order.
    pub(super) joints: Vec<Entity>,
    /// The skinned primitives and the first combined vertex of each.
    pub(super) primitives: Vec<(Entity, u32)>,
    /// World ← character space when the model is built in character space.
    pub(super) placement: Option<glam::DAffine3>,
    /// The [`PoseModels`](super::super::PoseModels) entry this build fills, if shared.
    pub(super) shared_key: Option<ModelKey>,
}

/// Marks a character whose model is in character space (placed by a similarity, shared by
/// every instance of its asset): its [`PosedSkeleton::placement`](super::super::PosedSkeleton) follows
/// its world transform.
#[derive(Component, Debug, Clone, Copy, Default)]
pub(super) struct CharacterSpace;

/// What drives a character's pose: the set the solver was built for and what it is relative
/// to.
#[derive(Component, Default)]
pub(super) struct PoseDrivers {
    /// The handles, pins, anchor and effectors of the current set (`None`: nothing drives).
    pub(super) key: Option<SetKey>,
    /// The pose the current set's targets are relative to (what was on screen when it began).
    pub(super) reference: Option<SkeletonPose>,
    /// The character's [`PoseLimits`](super::super::PoseLimits), resolved against its skeleton.
    pub(super) limits: Option<Arc<JointLimits>>,
    /// Left/right pairs and mirrored vertex sets, built when symmetric editing first needs
    /// them.
    pub(super) symmetry: Option<Symmetry>,
    /// Where each effector of the latest constraints came from (index in
    /// `PoseConstraints::effectors`, its entity and component): an in-frame solve reads their
    /// goals again after animation.
    pub(super) effector_sources: Vec<(usize, Entity, PoseEffector)>,
}

/// The character's automatic ground contacts ([`PoseGround`](super::super::PoseGround)), kept
/// from solve to solve (planted or not), and what its floor's casts found on the ground.
#[derive(Component, Default)]
pub(super) struct GroundContacts {
    /// The contacts, and the placement they are in character space of (`None` until it
    /// first stands).
    pub(super) tracker: Option<(crate::pose::ContactTracker, glam::DAffine3)>,
    /// The floor's grid of casts remembered from the last frames, and the ground they were
    /// cast on (world space: a character walking over the same ground casts only the nodes
    /// new under it).
    pub(super) floor: Option<(crate::ecs::SceneGround, crate::pose::FloorMemory)>,
}

/// The solves of a character: what waits, what runs, where the next one starts.
#[derive(Component, Default)]
pub(super) struct PoseSolves {
    /// Constraints waiting for a solve (the latest request).
    pub(super) pending: Option<PoseConstraints>,
    /// Where the pending solve starts when not from the held pose (an additive layer starts
    /// from the pose on screen).
    pub(super) start: Option<SkeletonPose>,
    /// The constraints of the running background solve (queued again while it settles).
    pub(super) running: Option<PoseConstraints>,
    /// The background solve (the latest request wins).
    pub(super) task: LatestTask<SolveResult>,
    /// The constraints of the last in-frame solve (with effectors): asked again when only
    /// their targets moved after `Update`.
    pub(super) solved: Option<PoseConstraints>,
    /// An in-frame solve's outcome (its time, or why it failed), until its message is written.
    pub(super) in_frame_outcome: Option<Result<f64, PoseableError>>,
}

/// What the last landed solve left: the solver and solution a following solve of the same set
/// warm-starts from, and the pose it wrote.
#[derive(Component, Default)]
pub(super) struct LastSolve {
    /// The solver of the current set (rebuilt when the set changes).
    pub(super) solver: Option<Arc<PoseSolver>>,
    /// Its last solution.
    pub(super) solution: Option<Arc<PoseSolution>>,
    /// The pose it wrote to [`PosedSkeleton::pose`](super::super::PosedSkeleton): anything else there
    /// was put by the app (a loaded or reset pose).
    pub(super) written: Option<SkeletonPose>,
}

impl LastSolve {
    /// The last solved pose, if a solve landed (a planted limb's start: `stand_on`).
    pub(super) fn solved_pose(&self) -> Option<&SkeletonPose> {
        self.solution.as_ref().map(|s| &s.pose)
    }

    /// Forgets the solver and its solution (a new driver set).
    pub(super) fn forget_solver(&mut self) {
        self.solver = None;
        self.solution = None;
    }
}

/// Marks a character failed: its status, a warning in the log and a [`PoseFailed`] message.
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
