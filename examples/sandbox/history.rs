//! Undo and redo: paint strokes, selection edits, and pose drags by either control.

use bevy::prelude::*;
use bevy_wii_deform::history::UndoStack;
use bevy_wii_deform::prelude::*;

use crate::selection::{RegionsChanged, Selection};
pub use crate::undo_keys::HistoryCommand;
use crate::undo_keys::undo_shortcuts;
use crate::{Model, SandboxSet};

/// Undo history, Ctrl+Z / Ctrl+Y, and drags recorded as they end.
pub struct HistoryPlugin;

impl Plugin for HistoryPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<History>()
            .add_message::<HistoryCommand>()
            .add_systems(
                Update,
                (record_drags, undo_shortcuts, apply_history)
                    .chain()
                    .in_set(SandboxSet::Edit),
            );
    }
}

/// The selection and the handle pose at one point in time.
#[derive(Clone, PartialEq, Debug)]
pub struct Snapshot {
    pub selection: Vec<u8>,
    pub handle: Transform,
}

/// The selection and handle pose now.
pub fn snapshot(selection: &Selection, model: &Model, transforms: &Query<&Transform>) -> Snapshot {
    Snapshot {
        selection: selection.labels.clone(),
        handle: model
            .handle
            .and_then(|h| transforms.get(h).ok().copied())
            .unwrap_or_default(),
    }
}

/// Undo and redo stacks of snapshots.
#[derive(Resource, Default, Deref, DerefMut)]
pub struct History(UndoStack<Snapshot>);

/// Turns each finished mouse drag or Wii Remote grab into an undo entry (the pose at its
/// start, as the controls recorded it: independent of system order).
fn record_drags(
    model: Res<Model>,
    selection: Res<Selection>,
    controls: Query<(Option<&MouseHandleControl>, Option<&MotionHandleControl>)>,
    mut drag_start: Local<Option<Transform>>,
    mut history: ResMut<History>,
) {
    let start = model
        .handle
        .and_then(|h| controls.get(h).ok())
        .and_then(|(mouse, wii)| {
            mouse
                .and_then(MouseHandleControl::drag_start)
                .or_else(|| wii.and_then(MotionHandleControl::grab_start))
        });
    match (start, drag_start.take()) {
        (Some(start), _) => *drag_start = Some(start),
        (None, Some(start)) => history.checkpoint(Snapshot {
            selection: selection.labels.clone(),
            handle: start,
        }),
        (None, None) => {}
    }
}

fn apply_history(
    mut commands: MessageReader<HistoryCommand>,
    mut history: ResMut<History>,
    mut selection: ResMut<Selection>,
    model: Res<Model>,
    mut transforms: Query<&mut Transform>,
    mut regions: MessageWriter<RegionsChanged>,
) {
    for command in commands.read() {
        let current = Snapshot {
            selection: selection.labels.clone(),
            handle: model
                .handle
                .and_then(|h| transforms.get(h).ok().copied())
                .unwrap_or_default(),
        };
        let target = match command {
            HistoryCommand::Undo => history.undo(current),
            HistoryCommand::Redo => history.redo(current),
        };
        let Some(target) = target else { continue };
        if target.selection != selection.labels {
            selection.labels = target.selection;
            regions.write(RegionsChanged {
                pose: Some(target.handle),
            });
        } else if let Some(mut t) = model.handle.and_then(|h| transforms.get_mut(h).ok()) {
            *t = target.handle;
        }
    }
}
