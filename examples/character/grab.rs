//! Mouse grab on the posed character through the library's `GrabPlugin` (the pose plugin is a
//! picking backend that hits the CPU-skinned triangles: Bevy's mesh picking sees the bind pose
//! of skinned meshes); F toggles the feet pins; with `--remote`, a Wii Remote drives a handle
//! on the head.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use crate::scene::{Character, NewCharacter, feet};

/// Grab radius as a fraction of the character's size.
const RADIUS: f32 = 0.08;

/// Press on the character to grab, drag to pose (Shift turns, the wheel twists), release to
/// keep the pose — the library's `GrabPlugin`; F toggles the feet pins.
pub struct CharacterGrabPlugin;

impl Plugin for CharacterGrabPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(GrabPlugin)
            .add_systems(
                Update,
                (make_grabbable, toggle_pins).before(PoseSystems::Request),
            )
            .add_systems(Update, show_handles);
    }
}

/// Grabbable once the character's size is known: radii in world units.
fn make_grabbable(
    mut commands: Commands,
    character: Query<(Entity, &PosedSkeleton), NewCharacter>,
) {
    for (entity, posed) in &character {
        let size = posed.model.topology().bounding_diagonal() as f32;
        commands.entity(entity).insert(Grabbable {
            radius: RADIUS * size,
            region_radius: 0.4 * size,
            ..default()
        });
    }
}

/// The topmost point of the posed mesh (the Fox's ear tips).
pub fn top_point(posed: &PosedSkeleton) -> Vec3 {
    posed
        .skinned_positions()
        .into_iter()
        .max_by(|a, b| a.y.total_cmp(&b.y))
        .unwrap_or(Vec3::ZERO)
}

/// Grabs the vertices within `RADIUS` of a point on the posed character (scripted grabs).
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
        let handle = grab_at(&mut commands, entity, posed, top_point(posed));
        // World space (`space: None`), as every character handle.
        commands
            .entity(handle)
            .insert(MotionHandleControl::default());
    }
}
