//! Undo and redo: paint strokes, selection edits, and pose drags by either control.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use crate::selection::{RegionsChanged, Selection};
use crate::{Model, SandboxSet};

/// Undo history, Ctrl+Z / Ctrl+Y, and drags recorded as they end.
pub struct HistoryPlugin;

impl Plugin for HistoryPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<History>()
            .add_message::<HistoryCommand>()
            .add_systems(
                Update,
                (record_drags, shortcuts, apply_history)
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

/// Undo and redo stacks.
#[derive(Resource, Default)]
pub struct History {
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
}

impl History {
    /// Records the state before an edit; a new edit drops the redo stack.
    pub fn checkpoint(&mut self, before: Snapshot) {
        self.undo.push(before);
        self.redo.clear();
    }

    /// Forgets everything (a new model).
    pub fn clear(&mut self) {
        self.undo.clear();
        self.redo.clear();
    }

    /// There is something to undo.
    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    /// There is something to redo.
    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }
}

/// Undo or redo, from the panel or the keyboard.
#[derive(Message, Debug, Clone, Copy, PartialEq, Eq)]
pub enum HistoryCommand {
    Undo,
    Redo,
}

/// Turns each finished mouse drag or Wii Remote grab into an undo entry (the pose at its
/// start, as the controls recorded it: independent of system order).
fn record_drags(
    model: Res<Model>,
    selection: Res<Selection>,
    controls: Query<(Option<&MouseHandleControl>, Option<&WiimoteHandleControl>)>,
    mut drag_start: Local<Option<Transform>>,
    mut history: ResMut<History>,
) {
    let start = model
        .handle
        .and_then(|h| controls.get(h).ok())
        .and_then(|(mouse, wii)| {
            mouse
                .and_then(MouseHandleControl::drag_start)
                .or_else(|| wii.and_then(WiimoteHandleControl::grab_start))
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

fn shortcuts(keys: Res<ButtonInput<KeyCode>>, mut commands: MessageWriter<HistoryCommand>) {
    let ctrl = keys.pressed(KeyCode::ControlLeft) || keys.pressed(KeyCode::ControlRight);
    if ctrl && keys.just_pressed(KeyCode::KeyZ) {
        commands.write(HistoryCommand::Undo);
    }
    if ctrl && keys.just_pressed(KeyCode::KeyY) {
        commands.write(HistoryCommand::Redo);
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
        let h = &mut *history;
        let (from, to) = match command {
            HistoryCommand::Undo => (&mut h.undo, &mut h.redo),
            HistoryCommand::Redo => (&mut h.redo, &mut h.undo),
        };
        let Some(target) = from.pop() else { continue };
        to.push(current);
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
