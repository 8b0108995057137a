//! Handle controls: input devices that move [`DeformHandle`](crate::ecs::DeformHandle)s (or
//! any entity with a `Transform`).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin.rs` | The handle-control plugins and the systems that apply remote motion and mouse drags to controlled handles. |
//!
//! * [`MotionHandleControl`]: the paper's interaction — the handle turns 1:1 with the remote
//!   (relative to the moment of grabbing, in camera space), with a clutch on B and
//!   translation at the same time.
//! * [`MouseHandleControl`]: the paper's mouse baseline — an arcball (Shoemake) that turns the
//!   handle on all three axes, and view-plane translation — with the same fields.
//!
//! This file holds the components; `plugin.rs` the plugins and their systems.

mod plugin;

use bevy::prelude::*;

pub use plugin::{MotionControlPlugin, MouseControlPlugin};

/// Drive this handle (`DeformHandle` entity, or any entity with a `Transform`) with a remote.
///
/// * Hold **B** to grab: while held, the handle's rotation follows the remote's rotation
///   since the grab, expressed in the camera's frame (turn the remote right → the handle
///   turns right on screen). Release to ratchet; grab again to continue.
/// * While grabbing, **D-pad** moves the handle in the view plane, **+ / −** along the view
///   direction, and a Nunchuk stick moves it in the view plane too.
/// * **Home** recentres the remote (and ends the grab).
///
/// The handle's `Transform` is assumed to be in the space of its parent (for `DeformHandle`:
/// the mesh's local space); pass that entity as `space` so camera-space motion maps correctly.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component)]
pub struct MotionHandleControl {
    /// Which remote (its entity); `None` = the first connected remote.
    #[entities]
    pub remote: Option<Entity>,
    /// Camera whose frame defines "right/up/forward"; `None` = the first `Camera3d`.
    #[entities]
    pub camera: Option<Entity>,
    /// Entity whose `GlobalTransform` defines the handle's space (e.g. the mesh); `None` =
    /// world space.
    #[entities]
    pub space: Option<Entity>,
    /// Translation speed in world units per second.
    pub speed: f32,
    /// Rotation gain (1 = the paper's 1:1 mapping).
    pub rotation_gain: f32,
    #[reflect(ignore)]
    grab: Option<Grab>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Grab {
    remote_at_grab: Quat,
    handle_rotation: Quat,
    /// The handle's whole `Transform` when the grab started (for undo histories).
    start: Transform,
}

impl Default for MotionHandleControl {
    fn default() -> Self {
        Self {
            remote: None,
            camera: None,
            space: None,
            speed: 0.5,
            rotation_gain: 1.0,
            grab: None,
        }
    }
}

impl MotionHandleControl {
    /// Controlled by `remote` (its entity).
    pub fn with_remote(mut self, remote: Entity) -> Self {
        self.remote = Some(remote);
        self
    }

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

    /// Translation speed in world units per second.
    pub fn with_speed(mut self, speed: f32) -> Self {
        self.speed = speed;
        self
    }

    /// Whether B is currently grabbing.
    pub fn is_grabbing(&self) -> bool {
        self.grab.is_some()
    }

    /// The handle's `Transform` when the current grab started (for undo histories).
    pub fn grab_start(&self) -> Option<Transform> {
        self.grab.map(|g| g.start)
    }
}

/// Drive this handle (`DeformHandle` entity, or any entity with a `Transform`) with the mouse.
///
/// * **Left-drag** (the `button`): arcball rotation about the handle's position on screen —
///   dragging across the ball turns it about axes in the view plane, dragging outside the ball
///   rolls it about the view direction.
/// * **Shift + left-drag**: translation in the view plane, at the handle's depth (the handle
///   stays under the cursor).
///
/// As for [`crate::ecs::MotionHandleControl`], the handle's `Transform` is in the space of
/// `space` (for `DeformHandle`: the mesh entity); that entity's whole `GlobalTransform` —
/// translation, rotation and scale — maps screen motion into it.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component)]
pub struct MouseHandleControl {
    /// Camera whose view is dragged in; `None` = the first `Camera3d`.
    #[entities]
    pub camera: Option<Entity>,
    /// Entity whose `GlobalTransform` defines the handle's space (e.g. the mesh); `None` =
    /// world space.
    #[entities]
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
