//! The handle-control plugins and the systems that apply remote motion and mouse drags to
//! controlled handles.

use bevy::prelude::*;
use bevy::window::PrimaryWindow;

use super::{Grab, MotionHandleControl, MouseHandleControl};
use crate::controllers::manager::RemoteCommand;
use crate::controllers::session::Buttons;
use crate::ecs::MotionControllerSystems;
use crate::ecs::controllers::{ConnectionState, ControllerLink, MotionController};
use crate::ecs::input::view::{
    arcball_rotation, rotation_of_space, turned_in_space, view_plane_motion,
};
use crate::ecs::input::{InputSystems, configure_input_sets};

/// Adds [`MotionHandleControl`] (requires [`MotionControllerPlugin`](crate::ecs::MotionControllerPlugin)).
#[derive(Debug, Clone, Default)]
pub struct MotionControlPlugin;

impl Plugin for MotionControlPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<MotionHandleControl>();
        app.add_systems(
            Update,
            drive_handles.in_set(MotionControllerSystems::Control),
        );
        configure_input_sets(app);
    }
}

/// Adds [`MouseHandleControl`]: mouse drags turn and move handles (in `Update`, in
/// [`InputSystems::MoveHandles`]).
#[derive(Debug, Clone, Default)]
pub struct MouseControlPlugin;

impl Plugin for MouseControlPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<MouseHandleControl>();
        app.add_systems(
            Update,
            drive_mouse_handles.in_set(InputSystems::MoveHandles),
        );
        configure_input_sets(app);
    }
}

/// Applies remote motion to controlled handles.
pub fn drive_handles(
    time: Res<Time>,
    link: Option<Res<ControllerLink>>,
    remotes: Query<(Entity, &MotionController)>,
    cameras: Query<(Entity, &GlobalTransform), With<Camera3d>>,
    spaces: Query<&GlobalTransform>,
    mut handles: Query<(&mut MotionHandleControl, &mut Transform)>,
) {
    for (mut control, mut transform) in &mut handles {
        let remote = match control.remote {
            Some(e) => remotes.get(e).ok(),
            None => remotes
                .iter()
                .find(|(_, w)| w.connection == ConnectionState::Connected),
        };
        let Some((_, wii)) = remote else {
            control.grab = None;
            continue;
        };
        if wii.connection != ConnectionState::Connected {
            // Keep the last pose; a reconnect needs a fresh grab.
            control.grab = None;
            continue;
        }
        if wii.pressed(Buttons::HOME) {
            if let Some(link) = &link {
                link.send(wii.id, RemoteCommand::Recenter);
            }
            control.grab = None;
            continue;
        }
        if !wii.pressed(Buttons::B) {
            control.grab = None;
            continue;
        }
        let grab = *control.grab.get_or_insert(Grab {
            remote_at_grab: wii.orientation,
            handle_rotation: transform.rotation,
            start: *transform,
        });
        let camera = control
            .camera
            .and_then(|c| cameras.get(c).ok())
            .or_else(|| cameras.iter().next())
            .map(|(_, g)| rotation_of_space(&g.affine()))
            .unwrap_or(Quat::IDENTITY);
        let space_affine = control
            .space
            .and_then(|s| spaces.get(s).ok())
            .map(GlobalTransform::affine)
            .unwrap_or_default();
        let space = rotation_of_space(&space_affine);
        // Rotation since the grab, in the remote's world frame, expressed in camera space,
        // then in the handle's space.
        let delta = (wii.orientation * grab.remote_at_grab.inverse()).normalize();
        let (axis, angle) = delta.to_axis_angle();
        let delta = Quat::from_axis_angle(axis, angle * control.rotation_gain);
        let in_world = camera * delta * camera.inverse();
        let in_space = space.inverse() * in_world * space;
        let rotation = (in_space * grab.handle_rotation).normalize();
        if rotation.is_finite() {
            transform.rotation = rotation;
        }
        // Translation in the view plane / along the view direction.
        let b = Buttons(wii.buttons);
        let mut v = Vec3::ZERO;
        if b.pressed(Buttons::RIGHT) {
            v.x += 1.0;
        }
        if b.pressed(Buttons::LEFT) {
            v.x -= 1.0;
        }
        if b.pressed(Buttons::UP) {
            v.y += 1.0;
        }
        if b.pressed(Buttons::DOWN) {
            v.y -= 1.0;
        }
        if b.pressed(Buttons::PLUS) {
            v.z -= 1.0;
        }
        if b.pressed(Buttons::MINUS) {
            v.z += 1.0;
        }
        v += wii.stick.extend(0.0);
        if v != Vec3::ZERO {
            // `speed` is in world units: the space's whole linear part (scale included) maps
            // the world motion into the handle's space.
            let world = camera * v * control.speed * time.delta_secs();
            let local = space_affine.inverse().transform_vector3(world);
            if local.is_finite() {
                transform.translation += local;
            }
        }
    }
}

/// Applies mouse drags to controlled handles.
#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
pub(crate) fn drive_mouse_handles(
    buttons: Res<ButtonInput<MouseButton>>,
    keys: Res<ButtonInput<KeyCode>>,
    windows: Query<&Window, With<PrimaryWindow>>,
    cameras: Query<(Entity, &Camera, &GlobalTransform), With<Camera3d>>,
    spaces: Query<&GlobalTransform>,
    mut handles: Query<(&mut MouseHandleControl, &mut Transform)>,
) {
    let window = windows.single().ok();
    let cursor = window.and_then(Window::cursor_position);
    let shift = keys.any_pressed([KeyCode::ShiftLeft, KeyCode::ShiftRight]);
    for (mut control, mut transform) in &mut handles {
        let (Some(window), Some(cursor)) = (window, cursor) else {
            control.last_cursor = None;
            continue;
        };
        if !control.enabled || !buttons.pressed(control.button) {
            control.last_cursor = None;
            continue;
        }
        let Some(previous) = control.last_cursor.replace(cursor) else {
            control.drag_start = Some(*transform); // the drag starts here
            continue;
        };
        if previous == cursor {
            continue;
        }
        let Some((_, camera, camera_transform)) = control
            .camera
            .and_then(|c| cameras.get(c).ok())
            .or_else(|| cameras.iter().next())
        else {
            continue;
        };
        let space = control
            .space
            .and_then(|s| spaces.get(s).ok())
            .map(GlobalTransform::affine)
            .unwrap_or_default();
        let inverse = space.inverse();
        let world_position = space.transform_point3(transform.translation);
        if shift {
            let delta =
                view_plane_motion(camera, camera_transform, world_position, previous, cursor);
            let local = inverse.transform_vector3(delta);
            if local.is_finite() {
                transform.translation += local;
            }
            continue;
        }
        let centre = camera
            .world_to_viewport(camera_transform, world_position)
            .unwrap_or(window.size() / 2.0);
        let radius = window.size().min_element() * control.arcball_radius;
        let (axis, angle) = arcball_rotation(previous, cursor, centre, radius).to_axis_angle();
        let in_view = Quat::from_axis_angle(axis, angle * control.rotation_gain);
        let rotation = turned_in_space(in_view, camera_transform, &space, transform.rotation);
        if rotation.is_finite() {
            transform.rotation = rotation;
        }
    }
}
