//! Undo and redo (Ctrl+Z / Ctrl+Y, or the panel's buttons) of everything that edits the
//! character: grabs, pins, keys, applied and loaded poses. An edit is noticed when it is done
//! (no grab held, no solve running, the timeline not playing): the state before it becomes an
//! undo step. Scrubbing the timeline is viewing, not editing, and makes no step.

use bevy::prelude::*;
use bevy_wii_deform::ecs::ActiveGrabs;
use bevy_wii_deform::history::UndoStack;
use bevy_wii_deform::pose::{PoseClip, SkeletonPose};
use bevy_wii_deform::prelude::*;

use crate::scene::Character;
pub use crate::undo_keys::HistoryCommand;
use crate::undo_keys::undo_shortcuts;

/// Undo/redo of the character's pose, keys and pins.
pub struct UndoPlugin;

impl Plugin for UndoPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<History>()
            .add_message::<HistoryCommand>()
            .add_systems(
                Update,
                (undo_shortcuts, undo_redo, record_edits)
                    .chain()
                    .after(PoseSystems::Timeline),
            );
    }
}

/// What an undo step restores.
#[derive(Debug, Clone, PartialEq)]
pub struct EditState {
    /// The pose shown.
    pub pose: SkeletonPose,
    /// The keys.
    pub clip: PoseClip,
    /// The pinned joints.
    pub pins: Vec<Entity>,
}

/// The history and the state last seen.
#[derive(Resource, Default)]
pub struct History {
    /// Undo and redo steps.
    pub stack: UndoStack<EditState>,
    /// The state after the last edit (or undo) and the timeline time it was seen at.
    seen: Option<(EditState, f32)>,
}

impl History {
    /// Notices `now` (seen at timeline time `time`): a change since the last state seen is an
    /// edit, recorded as an undo step — unless only the pose changed while the time moved
    /// (scrubbing shows the clip, it does not edit it).
    pub fn notice(&mut self, now: EditState, time: f32) {
        match self.seen.take() {
            Some((before, at)) if before != now => {
                let scrubbed = before.clip == now.clip && before.pins == now.pins && at != time;
                if !scrubbed {
                    self.stack.checkpoint(before);
                }
            }
            _ => {}
        }
        self.seen = Some((now, time));
    }

    /// Takes a step back (`undo`) or forward from `now`; the state to restore.
    pub fn step(
        &mut self,
        command: HistoryCommand,
        now: EditState,
        time: f32,
    ) -> Option<EditState> {
        let target = match command {
            HistoryCommand::Undo => self.stack.undo(now),
            HistoryCommand::Redo => self.stack.redo(now),
        }?;
        self.seen = Some((target.clone(), time));
        Some(target)
    }
}

type Edited = (
    &'static PosedSkeleton,
    &'static PoseTimeline,
    Option<&'static PinnedJoints>,
    &'static PoseStatus,
);

fn state_of(
    posed: &PosedSkeleton,
    timeline: &PoseTimeline,
    pins: Option<&PinnedJoints>,
) -> EditState {
    EditState {
        pose: posed.pose.clone(),
        clip: timeline.clip.clone(),
        pins: pins.map(|p| p.0.clone()).unwrap_or_default(),
    }
}

fn record_edits(
    character: Query<Edited, With<Character>>,
    grabs: Option<Res<ActiveGrabs>>,
    mut history: ResMut<History>,
) {
    let Some((posed, timeline, pins, status)) = character.iter().next() else {
        return;
    };
    let busy = grabs.is_some_and(|g| !g.is_empty())
        || status.phase == DeformPhase::Solving
        || timeline.playing;
    if !busy {
        history.notice(state_of(posed, timeline, pins), timeline.time);
    }
}

fn undo_redo(
    mut commands: Commands,
    mut requests: MessageReader<HistoryCommand>,
    mut history: ResMut<History>,
    mut character: Query<
        (
            Entity,
            &mut PosedSkeleton,
            &mut PoseTimeline,
            Option<&PinnedJoints>,
        ),
        With<Character>,
    >,
) {
    let Some((entity, mut posed, mut timeline, pins)) = character.iter_mut().next() else {
        return;
    };
    let mut pins_now = pins.map(|p| p.0.clone()).unwrap_or_default();
    for &command in requests.read() {
        let now = EditState {
            pose: posed.pose.clone(),
            clip: timeline.clip.clone(),
            pins: pins_now.clone(),
        };
        let Some(target) = history.step(command, now, timeline.time) else {
            continue;
        };
        posed.pose = target.pose;
        // Not a timeline change: the restored pose is shown, not the clip's sample.
        timeline.bypass_change_detection().clip = target.clip;
        if target.pins != pins_now {
            commands
                .entity(entity)
                .insert(PinnedJoints(target.pins.clone()));
            pins_now = target.pins;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy_wii_deform::pose::{JointTransform, KeyInterpolation};

    fn pose(angle: f64) -> SkeletonPose {
        SkeletonPose {
            local: vec![JointTransform {
                rotation: glam::DQuat::from_rotation_z(angle),
                ..JointTransform::IDENTITY
            }],
        }
    }

    fn state(angle: f64, keys: &[f32]) -> EditState {
        let mut clip = PoseClip::new();
        for &t in keys {
            clip.set_key(t, pose(angle), KeyInterpolation::Linear)
                .unwrap();
        }
        EditState {
            pose: pose(angle),
            clip,
            pins: Vec::new(),
        }
    }

    /// Undo restores the pose and keys exactly, redo re-applies; scrubbing makes no step.
    #[test]
    fn undo_restores_pose_and_keys_and_redo_reapplies() {
        let mut h = History::default();
        let start = state(0.0, &[]);
        h.notice(start.clone(), 0.0);
        let grabbed = state(0.4, &[]);
        h.notice(grabbed.clone(), 0.0); // a grab
        let keyed = state(0.4, &[0.0]);
        h.notice(keyed.clone(), 0.0); // a key set
        // Scrubbing: the pose changes with the time, the keys do not.
        let mut scrubbed = keyed.clone();
        scrubbed.pose = pose(0.1);
        h.notice(scrubbed.clone(), 0.7);
        assert_eq!(
            h.step(HistoryCommand::Undo, scrubbed.clone(), 0.7),
            Some(grabbed.clone())
        );
        assert_eq!(
            h.step(HistoryCommand::Undo, grabbed.clone(), 0.7),
            Some(start.clone())
        );
        assert_eq!(h.step(HistoryCommand::Undo, start.clone(), 0.7), None);
        assert_eq!(
            h.step(HistoryCommand::Redo, start.clone(), 0.7),
            Some(grabbed.clone())
        );
        assert_eq!(h.step(HistoryCommand::Redo, grabbed, 0.7), Some(scrubbed));
    }
}
