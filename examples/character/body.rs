//! The "Body" panel: the full-body settings a game developer toggles while posing — joint
//! limits from the humanoid preset (`PoseLimits::Humanoid`), mirrored editing
//! (`SymmetricEditing`: an effector on one side drives its mirror image), and the feet planted
//! by position effectors (ankles free) instead of pinned rigidly.

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::egui;
use bevy_wii_deform::prelude::*;

use crate::scene::{Character, feet};

/// Marks the effectors that plant the feet (so the toggle can take them back).
#[derive(Component)]
pub struct PlantedFoot;

/// What the panel reads of the character: its skeleton and which settings it has.
type CharacterBody = (
    Entity,
    &'static PosedSkeleton,
    Has<PoseLimits>,
    Has<SymmetricEditing>,
);

/// What the body panel reads and edits.
#[derive(SystemParam)]
pub struct BodyPanel<'w, 's> {
    commands: Commands<'w, 's>,
    character: Query<'w, 's, CharacterBody, With<Character>>,
    planted: Query<'w, 's, Entity, With<PlantedFoot>>,
    joints: Query<'w, 's, &'static GlobalTransform>,
}

/// The panel's checkboxes.
pub fn body_ui(ui: &mut egui::Ui, panel: &mut BodyPanel) {
    let Ok((character, posed, limited, mirrored)) = panel.character.single() else {
        ui.label("(no character yet)");
        return;
    };
    let mut limits = limited;
    if ui
        .checkbox(&mut limits, "Joint limits (humanoid preset)")
        .changed()
    {
        let mut entity = panel.commands.entity(character);
        if limits {
            entity.insert(PoseLimits::Humanoid);
        } else {
            entity.remove::<PoseLimits>();
        }
    }
    let mut mirror = mirrored;
    if ui
        .checkbox(&mut mirror, "Mirror edits (left ↔ right)")
        .changed()
    {
        let mut entity = panel.commands.entity(character);
        if mirror {
            entity.insert(SymmetricEditing);
        } else {
            entity.remove::<SymmetricEditing>();
        }
    }
    let mut plant = !panel.planted.is_empty();
    if ui
        .checkbox(&mut plant, "Plant feet (ankles free)")
        .on_hover_text(
            "Position effectors hold the feet where they are; unchecked, they are pinned rigidly",
        )
        .changed()
    {
        let feet = feet(posed);
        if plant {
            plant_feet(&mut panel.commands, character, &feet, &panel.joints);
        } else {
            for effector in &panel.planted {
                panel.commands.entity(effector).despawn();
            }
            panel.commands.entity(character).insert(PinnedJoints(feet));
        }
    }
}

/// Replaces the feet's pins with position effectors at where the feet are now.
fn plant_feet(
    commands: &mut Commands,
    character: Entity,
    feet: &[Entity],
    joints: &Query<&GlobalTransform>,
) {
    commands.entity(character).remove::<PinnedJoints>();
    for &foot in feet {
        let at = joints
            .get(foot)
            .map(GlobalTransform::translation)
            .unwrap_or_default();
        commands.spawn((
            PoseEffector::position(character, foot),
            Transform::from_translation(at),
            PlantedFoot,
            Name::new("planted foot"),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::ecs::system::RunSystemOnce;

    /// Planting replaces the pins by one position effector per foot, at the foot.
    #[test]
    fn planting_the_feet_swaps_pins_for_position_effectors_at_the_feet() {
        let mut world = World::new();
        let feet: Vec<Entity> = [Vec3::new(0.2, 0.0, 0.1), Vec3::new(-0.2, 0.0, -0.1)]
            .into_iter()
            .map(|at| world.spawn(GlobalTransform::from_translation(at)).id())
            .collect();
        let character = world.spawn(PinnedJoints(feet.clone())).id();
        let planted = feet.clone();
        world
            .run_system_once(
                move |mut commands: Commands, joints: Query<&GlobalTransform>| {
                    plant_feet(&mut commands, character, &planted, &joints)
                },
            )
            .unwrap();
        assert!(world.get::<PinnedJoints>(character).is_none());
        let mut effectors = world.query::<(&PoseEffector, &Transform, &PlantedFoot)>();
        let found: Vec<(PoseEffector, Vec3)> = effectors
            .iter(&world)
            .map(|(e, t, _)| (e.clone(), t.translation))
            .collect();
        assert_eq!(found.len(), 2);
        for (effector, at) in found {
            assert_eq!(effector.character, character);
            assert_eq!(effector.kind, PoseEffectorKind::Position);
            let foot = world.get::<GlobalTransform>(effector.joint).unwrap();
            assert_eq!(at, foot.translation());
        }
    }
}
