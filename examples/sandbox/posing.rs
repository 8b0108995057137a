//! Which control drives the handle: the library's `MouseHandleControl` in Pose mode with the
//! mouse, its `MotionHandleControl` with the remote. Switching keeps the pose.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use crate::{EditMode, InputMethod, Model, SandboxSet};

/// Enables the controls for the current [`EditMode`] and [`InputMethod`].
pub struct PosingPlugin;

impl Plugin for PosingPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Update, gate_mouse_control.in_set(SandboxSet::Edit))
            .add_systems(OnEnter(InputMethod::Controller), attach_remote)
            .add_systems(OnEnter(InputMethod::Mouse), detach_remote);
    }
}

/// Turns the mouse control on in Pose mode with mouse input (not when a drag would start over
/// the panel).
fn gate_mouse_control(
    model: Res<Model>,
    mode: Res<State<EditMode>>,
    input: Res<State<InputMethod>>,
    wants_pointer: Option<Res<bevy_egui::input::EguiWantsInput>>,
    mut controls: Query<&mut MouseHandleControl>,
) {
    let Some(mut control) = model.handle.and_then(|h| controls.get_mut(h).ok()) else {
        return;
    };
    let over_ui = wants_pointer.is_some_and(|w| w.wants_any_pointer_input());
    let enabled = *mode.get() == EditMode::Pose
        && *input.get() == InputMethod::Mouse
        && (control.is_dragging() || !over_ui);
    if control.enabled != enabled {
        control.enabled = enabled;
    }
}

/// The remote takes the handle where it is.
fn attach_remote(mut commands: Commands, model: Res<Model>) {
    if let (Some(handle), Some(mesh)) = (model.handle, model.entity) {
        commands
            .entity(handle)
            .insert(MotionHandleControl::default().with_space(mesh));
    }
}

/// The mouse takes the handle where it is.
fn detach_remote(mut commands: Commands, model: Res<Model>) {
    if let Some(handle) = model.handle {
        commands.entity(handle).remove::<MotionHandleControl>();
    }
}
