//! Tails on spring bones for the Fox and rigs like it: the settings, and the T key that turns
//! them on and off in the apps.

#![allow(dead_code)] // each app uses what it needs

use bevy::prelude::*;
use bevy_wii_deform::ecs::{SpringBones, SpringPlugin};
use bevy_wii_deform::pose::SpringJoint;

/// Every chain of joints named "tail" on springs. The settings are VRM's units (world units
/// per second) for a character about 100 units long, as the Fox is: a hundred times what a
/// VRM avatar in metres would use.
pub fn tail_springs() -> SpringBones {
    SpringBones::by_names(
        &["tail"],
        SpringJoint {
            stiffness: 120.0,
            drag: 0.35,
            gravity_power: 30.0,
            hit_radius: 2.0,
            ..SpringJoint::new(0)
        },
    )
}

/// Adds [`SpringPlugin`] and the T key: tails on springs on or off.
pub struct SpringyTailsPlugin;

impl Plugin for SpringyTailsPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(SpringPlugin)
            .add_systems(Update, toggle_springs);
    }
}

fn toggle_springs(keys: Res<ButtonInput<KeyCode>>, mut springs: Query<&mut SpringBones>) {
    if keys.just_pressed(KeyCode::KeyT) {
        for mut bones in &mut springs {
            bones.enabled = !bones.enabled;
        }
    }
}
