//! Undo and redo requests from the keyboard (Ctrl+Z / Ctrl+Y), shared by the apps that keep an
//! undo history (the sandbox, the character app).

use bevy::prelude::*;

/// Undo or redo, from the keyboard or a panel.
#[derive(Message, Debug, Clone, Copy, PartialEq, Eq)]
pub enum HistoryCommand {
    /// One step back.
    Undo,
    /// One step forward again.
    Redo,
}

/// Ctrl+Z → [`HistoryCommand::Undo`], Ctrl+Y → [`HistoryCommand::Redo`].
pub fn undo_shortcuts(
    keys: Res<ButtonInput<KeyCode>>,
    mut commands: MessageWriter<HistoryCommand>,
) {
    let ctrl = keys.pressed(KeyCode::ControlLeft) || keys.pressed(KeyCode::ControlRight);
    if ctrl && keys.just_pressed(KeyCode::KeyZ) {
        commands.write(HistoryCommand::Undo);
    }
    if ctrl && keys.just_pressed(KeyCode::KeyY) {
        commands.write(HistoryCommand::Redo);
    }
}
