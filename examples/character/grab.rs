//! Mouse grab on the posed character: `PosedSkeleton::ray_cast` (the CPU-skinned triangles;
//! Bevy's mesh ray cast sees the bind pose of skinned meshes), take the vertices around the hit as a
//! `DeformHandle`, drag it in the view plane, let go on release; F toggles the feet pins.

use bevy::prelude::*;
use bevy::window::PrimaryWindow;
use bevy_wii_deform::prelude::*;

use crate::scene::{Character, NewCharacter, feet};

/// Grab radius as a fraction of the character's size.
const RADIUS: f32 = 0.08;

/// Press on the character to grab, drag to pose, release to keep the pose.
pub struct CharacterGrabPlugin;

impl Plugin for CharacterGrabPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<Grab>()
            .add_systems(
                Update,
                (start_grab, drag, release, toggle_pins)
                    .chain()
                    .before(PoseSystems::Request),
            )
            .add_systems(Update, show_handles);
    }
}

/// The grab in progress.
#[derive(Resource, Default)]
pub struct Grab {
    /// The handle entity, the hit point and the camera-facing plane's normal.
    pub active: Option<(Entity, Vec3, Vec3)>,
}

/// Grabs the vertices within `RADIUS` of a point on the posed character.
pub fn grab_at(
    commands: &mut Commands,
    character: Entity,
    posed: &PosedSkeleton,
    point: Vec3,
) -> Entity {
    let positions = posed.skinned_positions();
    let size = posed.model.topology().bounding_diagonal() as f32;
    let vertices: Vec<u32> = (0..positions.len() as u32)
        .filter(|&i| positions[i as usize].distance(point) < RADIUS * size)
        .collect();
    commands
        .spawn((
            DeformHandle {
                target: character,
                vertices,
                pivot: None,
            },
            Transform::IDENTITY,
        ))
        .id()
}

fn cursor_ray(window: &Window, camera: (&Camera, &GlobalTransform)) -> Option<Ray3d> {
    let cursor = window.cursor_position()?;
    camera.0.viewport_to_world(camera.1, cursor).ok()
}

fn start_grab(
    mut commands: Commands,
    mut grab: ResMut<Grab>,
    buttons: Res<ButtonInput<MouseButton>>,
    window: Single<&Window, With<PrimaryWindow>>,
    camera: Single<(&Camera, &GlobalTransform)>,
    character: Query<(Entity, &PosedSkeleton), With<Character>>,
) {
    if !buttons.just_pressed(MouseButton::Left) || grab.active.is_some() {
        return;
    }
    let Some(ray) = cursor_ray(&window, (camera.0, camera.1)) else {
        return;
    };
    for (entity, posed) in &character {
        if let Some((hit, _)) = posed.ray_cast(ray) {
            let handle = grab_at(&mut commands, entity, posed, hit);
            grab.active = Some((handle, hit, camera.1.forward().as_vec3()));
        }
    }
}

fn drag(
    grab: Res<Grab>,
    window: Single<&Window, With<PrimaryWindow>>,
    camera: Single<(&Camera, &GlobalTransform)>,
    mut handles: Query<(&DeformHandle, &mut Transform)>,
) {
    let Some((handle, hit, normal)) = grab.active else {
        return;
    };
    let Some(ray) = cursor_ray(&window, (camera.0, camera.1)) else {
        return;
    };
    let Ok((h, mut transform)) = handles.get_mut(handle) else {
        return;
    };
    let Some(pivot) = h.pivot else { return }; // rebased next frame
    let Some(d) = ray.intersect_plane(hit, InfinitePlane3d::new(normal)) else {
        return;
    };
    let target = pivot + (ray.get_point(d) - hit);
    if transform.translation != target {
        transform.translation = target;
    }
}

fn release(mut commands: Commands, mut grab: ResMut<Grab>, buttons: Res<ButtonInput<MouseButton>>) {
    if buttons.just_released(MouseButton::Left)
        && let Some((handle, _, _)) = grab.active.take()
    {
        commands.entity(handle).despawn();
    }
}

fn toggle_pins(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    character: Query<(Entity, &PosedSkeleton, Option<&PinnedJoints>), With<Character>>,
) {
    if !keys.just_pressed(KeyCode::KeyF) {
        return;
    }
    for (entity, posed, pins) in &character {
        match pins {
            Some(p) if !p.0.is_empty() => commands.entity(entity).insert(PinnedJoints(Vec::new())),
            _ => commands.entity(entity).insert(PinnedJoints(feet(posed))),
        };
    }
}

/// Yellow dots where the held handles want their vertices (their pivots, moved).
fn show_handles(
    mut gizmos: Gizmos,
    handles: Query<(&DeformHandle, &Transform)>,
    character: Query<&PosedSkeleton, With<Character>>,
) {
    let Some(posed) = character.iter().next() else {
        return;
    };
    let size = posed.model.topology().bounding_diagonal() as f32;
    for (h, t) in &handles {
        if h.pivot.is_some() {
            gizmos.sphere(
                Isometry3d::from_translation(t.translation),
                0.015 * size,
                Color::srgb(1.0, 0.9, 0.1),
            );
        }
    }
}

/// With `--remote`: a handle on the head (the topmost region) driven by the Wii Remote.
pub struct RemoteHeadPlugin;

impl Plugin for RemoteHeadPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Update, spawn_remote_handle.before(PoseSystems::Request));
    }
}

fn spawn_remote_handle(
    mut commands: Commands,
    character: Query<(Entity, &PosedSkeleton), NewCharacter>,
) {
    for (entity, posed) in &character {
        let points = posed.skinned_positions();
        let top = points
            .iter()
            .copied()
            .max_by(|a, b| a.y.total_cmp(&b.y))
            .unwrap_or(Vec3::ZERO);
        let handle = grab_at(&mut commands, entity, posed, top);
        // World space (`space: None`), as every character handle.
        commands
            .entity(handle)
            .insert(WiimoteHandleControl::default());
    }
}
