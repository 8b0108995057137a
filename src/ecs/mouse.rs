//! `MouseHandleControl`: the paper's mouse baseline — an arcball (Shoemake) that turns the
//! handle on all three axes, and view-plane translation — beside `WiimoteHandleControl`, with
//! the same fields.

use bevy::prelude::*;
use bevy::window::PrimaryWindow;

/// Drive this handle (`DeformHandle` entity, or any entity with a `Transform`) with the mouse.
///
/// * **Left-drag** (the `button`): arcball rotation about the handle's position on screen —
///   dragging across the ball turns it about axes in the view plane, dragging outside the ball
///   rolls it about the view direction.
/// * **Shift + left-drag**: translation in the view plane, at the handle's depth (the handle
///   stays under the cursor).
///
/// As for [`crate::ecs::WiimoteHandleControl`], the handle's `Transform` is in the space of
/// `space` (for `DeformHandle`: the mesh entity); that entity's whole `GlobalTransform` —
/// translation, rotation and scale — maps screen motion into it.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component)]
pub struct MouseHandleControl {
    /// Camera whose view is dragged in; `None` = the first `Camera3d`.
    pub camera: Option<Entity>,
    /// Entity whose `GlobalTransform` defines the handle's space (e.g. the mesh); `None` =
    /// world space.
    pub space: Option<Entity>,
    /// The button that drags.
    pub button: MouseButton,
    /// Rotation gain (1 = the arcball's own mapping).
    pub rotation_gain: f32,
    /// Arcball radius as a fraction of the window's smaller side.
    pub arcball_radius: f32,
    /// Whether the control reacts (e.g. off while the user paints).
    pub enabled: bool,
    #[reflect(ignore)]
    last_cursor: Option<Vec2>,
    #[reflect(ignore)]
    drag_start: Option<Transform>,
}

impl Default for MouseHandleControl {
    fn default() -> Self {
        Self {
            camera: None,
            space: None,
            button: MouseButton::Left,
            rotation_gain: 1.0,
            arcball_radius: 0.35,
            enabled: true,
            last_cursor: None,
            drag_start: None,
        }
    }
}

impl MouseHandleControl {
    /// Motion relative to `camera`.
    pub fn with_camera(mut self, camera: Entity) -> Self {
        self.camera = Some(camera);
        self
    }

    /// The handle's `Transform` lives in the space of `space` (e.g. the deformed mesh).
    pub fn with_space(mut self, space: Entity) -> Self {
        self.space = Some(space);
        self
    }

    /// Starts enabled or not (see [`Self::enabled`]).
    pub fn with_enabled(mut self, enabled: bool) -> Self {
        self.enabled = enabled;
        self
    }

    /// Whether a drag is in progress.
    pub fn is_dragging(&self) -> bool {
        self.last_cursor.is_some()
    }

    /// The handle's `Transform` when the current drag started (for undo histories).
    pub fn drag_start(&self) -> Option<Transform> {
        self.drag_start.filter(|_| self.is_dragging())
    }
}

/// The arcball rotation (in view space: x right, y up, z towards the viewer) that takes the
/// cursor from `from` to `to` (window coordinates, y down), for a ball of `radius` pixels
/// centred at `centre`. Points outside the ball lie on its rim, so dragging there rolls about
/// the view direction.
pub fn arcball_rotation(from: Vec2, to: Vec2, centre: Vec2, radius: f32) -> Quat {
    let to_sphere = |p: Vec2| {
        let v = (p - centre) / radius.max(1.0);
        let v = Vec2::new(v.x, -v.y);
        let d2 = v.length_squared();
        if d2 <= 1.0 {
            v.extend((1.0 - d2).sqrt())
        } else {
            (v / d2.sqrt()).extend(0.0)
        }
    };
    Quat::from_rotation_arc(to_sphere(from), to_sphere(to))
}

/// Applies mouse drags to controlled handles.
#[allow(clippy::type_complexity)]
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

/// `rotation` (a handle's, in the space `space` maps to world) turned by `in_view`, a rotation
/// expressed in the camera's view frame.
pub(crate) fn turned_in_space(
    in_view: Quat,
    camera_transform: &GlobalTransform,
    space: &bevy::math::Affine3A,
    rotation: Quat,
) -> Quat {
    let camera_rotation = camera_transform.compute_transform().rotation;
    let in_world = camera_rotation * in_view * camera_rotation.inverse();
    // The rotation about a world axis, seen in the handle's space (its rotation part).
    let space_rotation = Quat::from_mat3a(&space.matrix3).normalize();
    let in_space = space_rotation.inverse() * in_world * space_rotation;
    (in_space * rotation).normalize()
}

/// World-space motion of a point at `at`'s depth that follows the cursor from `from` to `to`.
pub(crate) fn view_plane_motion(
    camera: &Camera,
    camera_transform: &GlobalTransform,
    at: Vec3,
    from: Vec2,
    to: Vec2,
) -> Vec3 {
    let (Ok(a), Ok(b)) = (
        camera.viewport_to_world(camera_transform, from),
        camera.viewport_to_world(camera_transform, to),
    ) else {
        return Vec3::ZERO;
    };
    // Intersect both rays with the plane through `at` facing the camera.
    let normal = camera_transform.forward();
    let hit = |ray: Ray3d| {
        let denom = ray.direction.dot(*normal);
        if denom.abs() < 1e-6 {
            return None;
        }
        Some(ray.origin + *ray.direction * ((at - ray.origin).dot(*normal) / denom))
    };
    match (hit(a), hit(b)) {
        (Some(pa), Some(pb)) => pb - pa,
        _ => Vec3::ZERO,
    }
}
