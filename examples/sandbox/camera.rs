//! The orbit camera and the cursor ray.

use super::*;

pub(super) fn orbit_camera(
    mut orbit: ResMut<OrbitCamera>,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    egui_wants: Option<Res<bevy_egui::input::EguiWantsInput>>,
    mut camera: Query<&mut Transform, With<Camera3d>>,
) {
    let over_ui = egui_wants.is_some_and(|w| w.wants_any_pointer_input());
    if !over_ui {
        if buttons.pressed(MouseButton::Right) {
            orbit.yaw -= motion.delta.x * 0.006;
            orbit.pitch = (orbit.pitch + motion.delta.y * 0.006).clamp(-1.5, 1.5);
        }
        if buttons.pressed(MouseButton::Middle) {
            let rot = Quat::from_euler(EulerRot::YXZ, orbit.yaw, -orbit.pitch, 0.0);
            let d = orbit.distance * 0.0015;
            orbit.focus += rot * Vec3::new(-motion.delta.x * d, motion.delta.y * d, 0.0);
        }
        if scroll.delta.y != 0.0 {
            orbit.distance = (orbit.distance * (1.0 - scroll.delta.y * 0.1)).clamp(0.2, 50.0);
        }
    }
    for mut t in &mut camera {
        let rot = Quat::from_euler(EulerRot::YXZ, orbit.yaw, -orbit.pitch, 0.0);
        t.translation = orbit.focus + rot * Vec3::new(0.0, 0.0, orbit.distance);
        t.look_at(orbit.focus, Vec3::Y);
    }
}

pub(super) fn cursor_ray(
    window: &Query<&Window, With<PrimaryWindow>>,
    camera: &Query<(&Camera, &GlobalTransform)>,
) -> Option<(Ray3d, Vec2)> {
    let window = window.single().ok()?;
    let cursor = window.cursor_position()?;
    let (cam, tf) = camera.iter().next()?;
    Some((cam.viewport_to_world(tf, cursor).ok()?, cursor))
}
