//! A field of Foxes standing on bumpy ground, every one posed inside the frame: a position
//! effector plants each foot and paw on the ground under it (`PoseEffector`, ankles free), and
//! `PoseInFrame` solves all of them every frame in parallel — the ground rolls slowly, so the
//! legs keep adjusting.
//!
//! ```text
//! cargo run --release --example crowd [-- N] [--screenshot PATH --frames N]
//! ```
//! N Foxes (default 100) from `../shared/models/Fox.glb`. Solver time per frame for N
//! characters: `cargo run --release --example crowd_bench -- --characters N --json`.

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::prelude::*;

/// The Fox, relative to the asset folder (`..`: the shared folder beside the project).
const FOX: &str = "shared/models/Fox.glb";
/// Spacing of the Foxes, in the Fox's own units (it is about 100 long).
const SPACING: f32 = 160.0;

fn main() {
    let count = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(100usize);
    App::new()
        .add_plugins(DefaultPlugins.set(AssetPlugin {
            file_path: "..".into(),
            ..default()
        }))
        .add_plugins(PosePlugin)
        .insert_resource(Crowd(count))
        .add_systems(Startup, setup)
        .add_systems(Update, (plant_feet, roll_ground, unattended))
        .run();
}

/// How many Foxes.
#[derive(Resource)]
struct Crowd(usize);

/// A foot target: where on the ground (x, z) and how high above the ground the joint rests.
#[derive(Component)]
struct OnGround {
    x: f32,
    z: f32,
    lift: f32,
}

/// The height of the bumpy ground at (x, z) at time `t`, in the Fox's units.
fn ground_height(x: f32, z: f32, t: f32) -> f32 {
    5.0 * ((x * 0.011 + t * 0.4).sin() + (z * 0.013 - t * 0.3).cos())
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
    crowd: Res<Crowd>,
) {
    let side = (crowd.0 as f32).sqrt().ceil() as usize;
    let extent = side as f32 * SPACING;
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(extent * 0.5, extent * 0.45, extent * 1.25)
            .looking_at(Vec3::new(extent * 0.5, 0.0, extent * 0.45), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 9000.0,
            ..default()
        },
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    // Markers of the ground's height under each Fox (the ground itself rolls: its height is
    // read from `ground_height`).
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(FOX));
    let disc = meshes.add(Cylinder::new(70.0, 2.0));
    let grass = materials.add(Color::srgb(0.3, 0.45, 0.3));
    for k in 0..crowd.0 {
        let (x, z) = ((k % side) as f32 * SPACING, (k / side) as f32 * SPACING);
        commands.spawn((
            WorldAssetRoot(scene.clone()),
            Transform::from_xyz(x, ground_height(x, z, 0.0), z),
            Poseable::default(),
            PoseInFrame { iterations: 3 },
        ));
        commands.spawn((
            Mesh3d(disc.clone()),
            MeshMaterial3d(grass.clone()),
            Transform::from_xyz(x, ground_height(x, z, 0.0) - 1.0, z),
            OnGround { x, z, lift: -1.0 },
        ));
    }
}

/// Once a Fox is poseable: a position effector on each of its lowest joints (feet and paws),
/// at the ground under it.
fn plant_feet(
    mut commands: Commands,
    foxes: Query<(Entity, &PosedSkeleton), Added<PosedSkeleton>>,
    joints: Query<&GlobalTransform>,
) {
    for (fox, posed) in &foxes {
        let feet: Vec<(Entity, Vec3)> = posed
            .lowest_joints(0.04)
            .into_iter()
            .filter_map(|j| Some((j, joints.get(j).ok()?.translation())))
            .collect();
        let lowest = feet.iter().map(|(_, p)| p.y).fold(f32::MAX, f32::min);
        for (joint, p) in feet {
            commands.spawn((
                PoseEffector::position(fox, joint),
                Transform::from_translation(p),
                OnGround {
                    x: p.x,
                    z: p.z,
                    lift: p.y - lowest,
                },
            ));
        }
    }
}

/// The ground rolls: every foot target (and ground marker) follows its height.
fn roll_ground(time: Res<Time>, mut targets: Query<(&OnGround, &mut Transform)>) {
    let t = time.elapsed_secs();
    for (on, mut transform) in &mut targets {
        transform.translation.y = ground_height(on.x, on.z, t) + on.lift;
    }
}

/// `--screenshot PATH --frames N`: saves frame N and exits.
fn unattended(mut commands: Commands, mut frame: Local<u32>, mut exit: MessageWriter<AppExit>) {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
    };
    let Some(path) = value("--screenshot").cloned() else {
        return;
    };
    let frames: u32 = value("--frames")
        .and_then(|v| v.parse().ok())
        .unwrap_or(120);
    *frame += 1;
    if *frame == frames {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(path));
    }
    if *frame == frames + 10 {
        exit.write(AppExit::Success);
    }
}
