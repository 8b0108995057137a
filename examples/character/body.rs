//! The "Body" panel: the full-body settings a game developer toggles while posing — joint
//! limits from the humanoid preset (`PoseLimits::Humanoid`), mirrored editing
//! (`SymmetricEditing`: an effector on one side drives its mirror image), and the feet planted
//! by position effectors (ankles free) instead of pinned rigidly. A right-click on the
//! character plants the joint nearest the click (a position effector where it is: the joint
//! stays, the bones around it turn freely); a right-click there again lifts it. Alt +
//! right-click anywhere (the character, the ground) makes the head look there (a look-at
//! effector: the head's axis that faces the character's forward turns to the point); Alt +
//! right-click by the point again lets go.

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::egui;
use bevy_wii_deform::prelude::*;

use crate::scene::{Character, feet};

/// Marks the effectors that plant the feet (so the toggle can take them back).
#[derive(Component)]
pub struct PlantedFoot;

/// Marks the effectors placed by a right-click.
#[derive(Component)]
pub struct PlacedEffector;

/// Marks the look-at placed by Alt + right-click.
#[derive(Component)]
pub struct PlacedLookAt;

/// Right-clicks on the character place and lift position effectors; they are drawn.
pub struct EffectorPlacementPlugin;

impl Plugin for EffectorPlacementPlugin {
    fn build(&self, app: &mut App) {
        app.add_observer(toggle_effector_on_right_click)
            .add_systems(Update, show_effectors);
    }
}

/// The joint of `posed` nearest to `point` (world space).
fn nearest_joint(
    posed: &PosedSkeleton,
    joints: &Query<&GlobalTransform>,
    point: Vec3,
) -> Option<Entity> {
    posed
        .joints
        .iter()
        .filter_map(|&j| Some((j, joints.get(j).ok()?.translation().distance(point))))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(j, _)| j)
}

/// What a right-click reads: the character, its joints and the effectors placed so far.
#[derive(SystemParam)]
struct Placement<'w, 's> {
    commands: Commands<'w, 's>,
    character: Query<'w, 's, (Entity, &'static PosedSkeleton), With<Character>>,
    joints: Query<'w, 's, &'static GlobalTransform>,
    placed: Query<'w, 's, (Entity, &'static PoseEffector), With<PlacedEffector>>,
    looks: Query<'w, 's, (Entity, &'static GlobalTransform), With<PlacedLookAt>>,
    keys: Res<'w, ButtonInput<KeyCode>>,
}

fn toggle_effector_on_right_click(press: On<PointerPress>, mut p: Placement) {
    if press.button != PointerButton::Secondary {
        return;
    }
    let Some(point) = press.hit.position else {
        return;
    };
    if p.keys.any_pressed([KeyCode::AltLeft, KeyCode::AltRight]) {
        look_at_point(&mut p, point);
        return;
    }
    let target = press.entity;
    let Ok((_, posed)) = p.character.get(target) else {
        return;
    };
    let Some(joint) = nearest_joint(posed, &p.joints, point) else {
        return;
    };
    if let Some((existing, _)) = p.placed.iter().find(|(_, e)| e.joint == joint) {
        p.commands.entity(existing).despawn();
        return;
    }
    let at = p
        .joints
        .get(joint)
        .map(GlobalTransform::translation)
        .unwrap_or(point);
    p.commands.spawn((
        PoseEffector::position(target, joint),
        Transform::from_translation(at),
        PlacedEffector,
        Name::new("placed effector"),
    ));
}

/// Points the character's head at `point` (a look-at effector, moved if there is one), or
/// lets go when `point` is by the current target. The head is the joint named "head" (any
/// case), else the highest joint; its looking axis is the character's forward (+Z of the
/// character, as glTF characters face) in the head's frame now.
fn look_at_point(p: &mut Placement, point: Vec3) {
    let Some((character, posed)) = p.character.iter().next() else {
        return;
    };
    let size = posed.model.topology().bounding_diagonal() as f32;
    if let Some((look, at)) = p.looks.iter().next() {
        if at.translation().distance(point) < 0.05 * size {
            p.commands.entity(look).despawn();
        } else {
            p.commands
                .entity(look)
                .insert(Transform::from_translation(point));
        }
        return;
    }
    let skeleton = posed.model.skeleton();
    let named = skeleton
        .joints()
        .iter()
        .position(|j| j.name.to_lowercase().contains("head"));
    let highest = || {
        (0..posed.joints.len()).max_by(|&a, &b| {
            let y = |j: usize| {
                p.joints
                    .get(posed.joints[j])
                    .map_or(f32::MIN, |g| g.translation().y)
            };
            y(a).total_cmp(&y(b))
        })
    };
    let Some(head) = named.or_else(highest).map(|j| posed.joints[j]) else {
        return;
    };
    let (Ok(head_at), Ok(body)) = (p.joints.get(head), p.joints.get(character)) else {
        return;
    };
    let forward = (body.rotation() * Vec3::Z).normalize_or(Vec3::Z);
    let axis = head_at.rotation().inverse() * forward;
    p.commands.spawn((
        PoseEffector::look_at(character, head, axis),
        Transform::from_translation(point),
        PlacedLookAt,
        Name::new("look-at"),
    ));
}

/// Every effector as a small cyan ring at its target.
fn show_effectors(
    mut gizmos: Gizmos,
    effectors: Query<&GlobalTransform, With<PoseEffector>>,
    character: Query<&PosedSkeleton, With<Character>>,
) {
    let Some(posed) = character.iter().next() else {
        return;
    };
    let size = posed.model.topology().bounding_diagonal() as f32;
    for at in &effectors {
        gizmos.sphere(
            Isometry3d::from_translation(at.translation()),
            0.012 * size,
            Color::srgb(0.2, 0.9, 1.0),
        );
    }
}

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

    /// A right-click picks the joint nearest the clicked point.
    #[test]
    fn the_nearest_joint_to_a_click_is_picked() {
        use bevy_wii_deform::pose::rig::synth_rig::bar_rig;
        let rig = bar_rig(3, 8, 12);
        let model = rig.model().unwrap();
        let mut world = World::new();
        let joints: Vec<Entity> = rig
            .skeleton
            .global_transforms(&rig.rest)
            .iter()
            .map(|g| {
                let at = g.translation.as_vec3();
                world.spawn(GlobalTransform::from_translation(at)).id()
            })
            .collect();
        let posed = PosedSkeleton {
            model: std::sync::Arc::new(model),
            joints: joints.clone(),
            primitives: Vec::new(),
            pose: rig.rest.clone(),
            placement: glam::DAffine3::IDENTITY,
        };
        let near_last = world
            .get::<GlobalTransform>(joints[2])
            .unwrap()
            .translation()
            + Vec3::new(0.01, -0.02, 0.0);
        let picked = world
            .run_system_once(move |transforms: Query<&GlobalTransform>| {
                nearest_joint(&posed, &transforms, near_last)
            })
            .unwrap();
        assert_eq!(picked, Some(joints[2]));
    }

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
