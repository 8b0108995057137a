//! Camera, light, ground, and the character: a glTF scene with `Poseable` on its root.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use crate::Args;

/// Spawns the stage and the character; pins the feet once the skeleton is known.
pub struct ScenePlugin;

impl Plugin for ScenePlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Startup, setup).add_systems(
            Update,
            (frame_camera, ground_under_character, pin_feet_once),
        );
    }
}

/// The poseable character (the scene root).
#[derive(Component)]
pub struct Character;

/// The stage's floor (the crate's `GroundMesh`: what `PoseGround` stands the character on).
#[derive(Component)]
struct Stage;

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
    args: Res<Args>,
) {
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight {
            shadow_maps_enabled: true,
            illuminance: 8000.0,
            ..default()
        },
        Transform::from_xyz(2.0, 4.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(1000.0, 1000.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.3, 0.35, 0.3))),
        Stage,
        GroundMesh,
    ));
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(args.model.clone()));
    commands.spawn((
        WorldAssetRoot(scene),
        Poseable::default(),
        Character,
        // Joints named "tail" swing on springs (T turns them off); other rigs have none.
        crate::springy_tails::tail_springs(),
    ));
}

/// Puts the ground under the character's lowest posed point once it is known: rigs from other
/// exporters often have their origin at the hips, not at the feet as the Fox has.
fn ground_under_character(
    character: Query<&PosedSkeleton, (With<Character>, Added<PosedSkeleton>)>,
    mut ground: Single<&mut Transform, With<Stage>>,
) {
    for posed in &character {
        let lowest = posed
            .skinned_positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::MAX, f32::min);
        if lowest.is_finite() {
            ground.translation.y = lowest;
        }
    }
}

/// Frames the camera on the character once its skinned positions are known.
fn frame_camera(
    character: Query<&PosedSkeleton, (With<Character>, Added<PosedSkeleton>)>,
    mut camera: Single<&mut Transform, With<Camera3d>>,
) {
    for posed in &character {
        let points = posed.skinned_positions();
        let (lo, hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
        let centre = (lo + hi) / 2.0;
        let size = (hi - lo).length();
        **camera = Transform::from_translation(
            centre + Vec3::new(0.9, 0.45, 0.9).normalize() * size * 1.3,
        )
        .looking_at(centre, Vec3::Y);
    }
}

/// The joints the character stands on: every joint within 4 % of its size above the lowest
/// one (`PosedSkeleton::lowest_joints`).
pub fn feet(posed: &PosedSkeleton) -> Vec<Entity> {
    posed.lowest_joints(0.04)
}

/// A character whose skeleton was just prepared.
pub type NewCharacter = (With<Character>, Added<PosedSkeleton>);

fn pin_feet_once(mut commands: Commands, character: Query<(Entity, &PosedSkeleton), NewCharacter>) {
    for (entity, posed) in &character {
        commands.entity(entity).insert(PinnedJoints(feet(posed)));
    }
}
