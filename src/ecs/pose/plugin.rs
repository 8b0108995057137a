//! The character plugin: its system sets and the wiring of the stages — `prepare.rs` (skins →
//! models), `request.rs` (drivers → solves), `poll.rs` (landed background solves, timelines),
//! `in_frame.rs` (solves inside the frame) and `apply.rs` (the pose onto the joints after
//! animation). The per-character state they share is in `state.rs`, one component per
//! concern; the steps of a solve every path shares are in `solve.rs`.

use bevy::app::AnimationSystems;
use bevy::picking::PickingSystems;
use bevy::picking::backend::PointerHits;
use bevy::picking::backend::ray::RayMap;
use bevy::prelude::*;

use bevy::transform::TransformSystems;

use super::apply::apply_poses;
use super::in_frame::solve_in_frame;
use super::picking::{ignore_bind_pose_picking, pick_posed_characters};
use super::poll::{poll_pose_solves, show_timelines};
use super::prepare::{find_skins, finish_models};
use super::request::request_pose_solves;
use super::{
    HandlePositionOnly, PinnedJoints, PoseAnchor, PoseBlend, PoseEffector, PoseFailed, PoseInFrame,
    PoseJointHandle, PoseSolved, PoseStatus, PoseStiffness, Poseable, SymmetricEditing,
};
use crate::ecs::DeformSystems;
use crate::ecs::scene::{SceneWarning, add_scene_roots, note_missing_scene_assets};

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
