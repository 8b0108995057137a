//! `WiimoteHandleControl`: the paper's interaction — the handle turns 1:1 with the remote
//! (relative to the moment of grabbing, in camera space), with a clutch on B and translation
//! at the same time.

use bevy::prelude::*;

use super::wiimote::{ConnectionState, Wiimote, WiimoteLink};
use crate::wiimote::RemoteCommand;
use crate::wiimote::protocol::Buttons;

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
pub struct WiimoteHandleControl {
    /// Which remote (its entity); `None` = the first connected remote.
    pub remote: Option<Entity>,
    /// Camera whose frame defines "right/up/forward"; `None` = the first `Camera3d`.
    pub camera: Option<Entity>,
    /// Entity whose `GlobalTransform` defines the handle's space (e.g. the mesh); `None` =
    /// world space.
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

impl Default for WiimoteHandleControl {
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

impl WiimoteHandleControl {
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

/// Applies remote motion to controlled handles.
pub fn drive_handles(
    time: Res<Time>,
    link: Option<Res<WiimoteLink>>,
    remotes: Query<(Entity, &Wiimote)>,
    cameras: Query<(Entity, &GlobalTransform), With<Camera3d>>,
    spaces: Query<&GlobalTransform>,
    mut handles: Query<(&mut WiimoteHandleControl, &mut Transform)>,
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
            .map(|(_, g)| g.compute_transform().rotation)
            .unwrap_or(Quat::IDENTITY);
        let space = control
            .space
            .and_then(|s| spaces.get(s).ok())
            .map(|g| g.compute_transform().rotation)
            .unwrap_or(Quat::IDENTITY);
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
            let world = camera * v * control.speed * time.delta_secs();
            let local = space.inverse() * world;
            if local.is_finite() {
                transform.translation += local;
            }
        }
    }
}
