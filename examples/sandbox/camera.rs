//! The stage: camera, light and the orbit controls; the cursor ray.

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy::window::PrimaryWindow;

use crate::SandboxSet;

/// Camera, light, and orbiting with the right/middle mouse buttons and the wheel.
pub struct StagePlugin {
    /// `--demo` looks straight at the model, so the remote's roll maps onto the task's axis.
    pub demo: bool,
}

impl Plugin for StagePlugin {
    fn build(&self, app: &mut App) {
        let (yaw, pitch) = if self.demo { (0.0, 0.05) } else { (0.3, 0.15) };
        app.insert_resource(OrbitCamera {
            yaw,
            pitch,
            distance: 3.0,
            focus: Vec3::new(0.0, 0.8, 0.0),
        })
        .insert_resource(ClearColor(BACKGROUND))
        .add_systems(Startup, setup_stage)
        .add_systems(Update, orbit_camera.in_set(SandboxSet::Edit));
    }
}

/// The background colour (the challenge turns it green when done).
pub const BACKGROUND: Color = Color::srgb(0.12, 0.13, 0.16);

/// Where the orbit camera looks from.
#[derive(Resource, Default)]
pub struct OrbitCamera {
    pub yaw: f32,
    pub pitch: f32,
    pub distance: f32,
    pub focus: Vec3,
}

fn setup_stage(mut commands: Commands) {
    commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 1.0, 3.0)));
    commands.spawn((
        DirectionalLight {
            illuminance: 9000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(2.0, 4.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.insert_resource(GlobalAmbientLight {
        brightness: 400.0,
        ..default()
    });
}

fn orbit_camera(
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

/// The ray under the cursor, from the first camera.
pub fn cursor_ray(
    window: &Query<&Window, With<PrimaryWindow>>,
    camera: &Query<(&Camera, &GlobalTransform)>,
) -> Option<Ray3d> {
    let cursor = window.single().ok()?.cursor_position()?;
    screen_ray(window, camera, cursor)
}

/// The ray through a window position (logical pixels), from the first camera.
pub fn screen_ray(
    window: &Query<&Window, With<PrimaryWindow>>,
    camera: &Query<(&Camera, &GlobalTransform)>,
    at: Vec2,
) -> Option<Ray3d> {
    window.single().ok()?;
    let (cam, tf) = camera.iter().next()?;
    cam.viewport_to_world(tf, at).ok()
}

/// True unless the pointer is over the egui panel.
pub fn not_over_ui(world: &World) -> bool {
    world
        .get_resource::<bevy_egui::input::EguiWantsInput>()
        .is_none_or(|w| !w.wants_any_pointer_input())
}
