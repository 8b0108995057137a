//! The character plugin: its system sets and the wiring of the stages — `prepare.rs` (skins →
//! models), `request.rs` (drivers → solves), `poll.rs` (landed background solves, timelines),
//! `in_frame.rs` (solves inside the frame) and `apply.rs` (the pose onto the joints after
//! animation). The per-character state they share is in `state.rs`, one component per
//! concern; the steps of a solve every path shares are in `solve.rs`.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `apply.rs` | Writing the pose onto the joints in `PostUpdate`, after animation: held, or blended over what the clip wrote ([`super::super::PoseBlend`]). |
//! | `constraints.rs` | What a character's solve is asked: the constraint-set key that decides when handles are rebased, and the conversion of handles, joint handles, effectors and limits into the pose core's constraints. |
//! | `ground_contacts.rs` | A character standing on the scene's ground: its automatic contacts, the floor under it and its balance, added to the constraints of a solve (in character space). |
//! | `in_frame.rs` | In-frame solves ([`PoseInFrame`]): the targets a frame's `Update` set are solved in `PostUpdate`, after animation and before transform propagation, for every such character in parallel on Bevy's compute pool; the pose is then written to the joints by `apply.rs` in the same frame. |
//! | `picking.rs` | Posed characters as a bevy_picking backend: hits on the CPU-skinned surface. |
//! | `poll.rs` | Collecting landed pose solves (stored in `PosedSkeleton::pose`, settling re-queued) and showing each timeline's pose at its time. |
//! | `prepare.rs` | Preparing a character: find its skinned primitives and joints (once its scene has spawned, or report why not), build the skinned model in the background, and insert [`PosedSkeleton`] when it is ready. |
//! | `request.rs` | Requesting pose solves: each frame, a character's drivers (vertex handles, joint handles, effectors) and pins are compared with the set its solver was built for; a new set rebases the handles on the pose on screen, a moved one queues a solve (latest wins) in the background. |
//! | `solve.rs` | The two steps every path of a solve shares, background (`request.rs` → `poll.rs`) or in the frame (`in_frame.rs`): [`SolveJob::take`] takes the pending constraints with everything a solve needs (the solver when it still fits, the last solution to warm-start from, the start pose) and [`SolveJob::run`] runs it; [`store_landed`] stores the result. |
//! | `state.rs` | A character's internal state, one component per concern. |
//! | `symmetry.rs` | Symmetric editing ([`super::super::SymmetricEditing`]): every driver on one side of the character drives its mirror image too — effectors on the partner joint, grabbed vertex sets (rigid handles and position-only followers) on the vertices mirroring them. |

mod apply;
mod constraints;
mod ground_contacts;
mod in_frame;
mod picking;
mod poll;
mod prepare;
mod request;
mod solve;
mod state;
mod symmetry;

pub(crate) use constraints::resolve_limits;

use bevy::app::AnimationSystems;
use bevy::picking::PickingSystems;
use bevy::picking::backend::PointerHits;
use bevy::picking::backend::ray::RayMap;
use bevy::prelude::*;

use bevy::transform::TransformSystems;

use super::{
    HandlePositionOnly, PinnedJoints, PoseAnchor, PoseBlend, PoseEffector, PoseFailed, PoseInFrame,
    PoseJointHandle, PoseSolved, PoseStatus, PoseStiffness, Poseable, SymmetricEditing,
};
use crate::ecs::DeformSystems;
use crate::ecs::scene::{SceneWarning, add_scene_roots, note_missing_scene_assets};
use apply::apply_poses;
use in_frame::solve_in_frame;
use picking::{ignore_bind_pose_picking, pick_posed_characters};
use poll::{poll_pose_solves, show_timelines};
use prepare::{find_skins, finish_models};
use request::request_pose_solves;

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
        add_scene_roots(app);
        if !app.is_plugin_added::<crate::ecs::GroundPlugin>() {
            app.add_plugins(crate::ecs::GroundPlugin);
        }
        app.register_type::<Poseable>()
            .register_type::<PinnedJoints>()
            .register_type::<PoseJointHandle>()
            .register_type::<PoseStatus>()
            .register_type::<PoseAnchor>()
            .register_type::<HandlePositionOnly>()
            .register_type::<PoseEffector>()
            .register_type::<PoseStiffness>()
            .register_type::<SymmetricEditing>()
            .register_type::<PoseBlend>()
            .register_type::<super::PoseGround>()
            .register_type::<super::PoseBalance>()
            .add_message::<PoseSolved>()
            .add_message::<PoseFailed>()
            .init_resource::<super::PoseModels>()
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
                    note_missing_scene_assets::<PoseStatus>,
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

impl SceneWarning for PoseStatus {
    fn warning_mut(&mut self) -> &mut Option<String> {
        &mut self.warning
    }
}
