//! Bend a plank and watch the balls follow the bend (feature `avian`): the plank is a static
//! Avian body whose collider is rebuilt from the bent mesh after each settled solve
//! (`DeformCollider`); balls drop on it every second. Behind it the Fox stands on the floor
//! (`PoseGround`: the floor's Avian collider is the `GroundMesh`) with a kinematic capsule on each
//! bone (`PosedColliders`), and every other ball bounces off it. Press on the plank (or the
//! Fox), drag, release.
//!
//! ```text
//! cargo run --release --features avian --example physics [-- --screenshot PATH --frames N]
//! ```
//! The unattended run pushes the plank's middle down by a scripted grab first, so the balls
//! gather in the dip.

use avian3d::prelude::*;
use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::deform::synth;
use bevy_wii_deform::ecs::physics::{DeformCollider, DeformPhysicsPlugin, PosedColliders};
use bevy_wii_deform::prelude::*;

use bevy_wii_deform_examples::cli;
use bevy_wii_deform_examples::screenshot;

use screenshot::{ScreenshotPlugin, UnattendedFrame};

const USAGE: &str = "\
usage: physics [--screenshot PATH [--frames N]]

  --screenshot PATH  bend the plank by a scripted grab, save frame N to PATH, exit
  --frames N         the frame to save (default 240)";

fn main() {
    let mut app = App::new();
    app.add_plugins(DefaultPlugins)
        .add_plugins((PhysicsPlugins::default(), DeformPhysicsPlugin))
        .add_plugins((
            DeformPlugin::default(),
            PosePlugin,
            GrabPlugin,
            MeshPickingPlugin,
        ))
        .add_systems(Startup, setup)
        .add_systems(Update, (drop_balls, clear_fallen_balls));
    if let Some(shot) = unattended() {
        app.add_plugins(shot).add_systems(Update, push_the_plank);
    }
    app.run();
}

/// `--screenshot PATH --frames N`, when given.
fn unattended() -> Option<ScreenshotPlugin> {
    let (mut path, mut frames) = (None, 240);
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("screenshot") => path = Some(cli::string(&mut parser, USAGE)),
            cli::Arg::Long("frames") => frames = cli::value(&mut parser, USAGE),
            other => cli::unexpected(other, USAGE),
        }
    }
    path.map(|path| ScreenshotPlugin { path, frames })
}

/// The bendable plank.
#[derive(Component)]
struct Plank;

/// A dropped ball.
#[derive(Component)]
struct Ball;

/// The balls' look, made once.
#[derive(Resource)]
struct BallLook(Handle<Mesh>, Handle<StandardMaterial>);

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
) {
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.9, 3.0).looking_at(Vec3::new(0.0, 0.0, 0.0), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight {
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(2.0, 4.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.3, 0.35, 0.3))),
        Transform::from_xyz(0.0, -0.8, 0.0),
        RigidBody::Static,
        Collider::half_space(Vec3::Y),
        GroundMesh,
    ));
    // The Fox (about a metre long at this scale) standing on the floor behind the plank.
    commands.spawn((
        WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("models/Fox.glb"))),
        Transform::from_xyz(0.0, -0.8, -1.0)
            .with_scale(Vec3::splat(0.01))
            .with_rotation(Quat::from_rotation_y(1.2)),
        Poseable::default(),
        PoseGround::default(),
        PosedColliders::default(),
        Grabbable::default(),
    ));
    // A plank 2.4 long, 0.5 wide and 0.08 thick, lying along X (generated along +Y, turned
    // onto its side), both ends held.
    let bar = synth::plank(2.4, 0.5, 0.08, 25.0);
    let mesh = mesh_from_triangles(&bar.positions, &bar.triangles);
    let collider = Collider::trimesh_from_mesh(&mesh).expect("a closed bar");
    let ends: Vec<u32> = (0..bar.positions.len() as u32)
        .filter(|&v| (bar.positions[v as usize].y - 1.2).abs() > 1.0)
        .collect();
    commands.spawn((
        Mesh3d(meshes.add(mesh)),
        MeshMaterial3d(materials.add(Color::srgb(0.75, 0.55, 0.3))),
        Transform::from_xyz(-1.2, 0.0, 0.0)
            .with_rotation(Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2)),
        Deformable::default(),
        FixedRegion(ends),
        Grabbable {
            radius: 0.1,
            region_radius: 0.6,
            ..default()
        },
        RigidBody::Static,
        collider,
        DeformCollider::default(),
        Plank,
    ));
    commands.insert_resource(BallLook(
        meshes.add(Sphere::new(0.08).mesh().ico(3).expect("a small ico sphere")),
        materials.add(Color::srgb(0.85, 0.85, 0.9)),
    ));
}

/// A ball every second over a random-looking spot of the plank.
fn drop_balls(
    mut commands: Commands,
    time: Res<Time>,
    look: Res<BallLook>,
    mut next: Local<f32>,
    mut count: Local<u32>,
) {
    if time.elapsed_secs() < *next {
        return;
    }
    *next = time.elapsed_secs() + 1.0;
    *count += 1;
    // Every other ball over the Fox's back.
    let x = ((*count as f32 * 0.618).fract() - 0.5) * 1.6;
    let at = match *count % 2 {
        0 => Vec3::new(x, 1.0, 0.0),
        _ => Vec3::new(x * 0.2, 1.0, -1.0),
    };
    commands.spawn((
        Ball,
        RigidBody::Dynamic,
        Collider::sphere(0.08),
        Mesh3d(look.0.clone()),
        MeshMaterial3d(look.1.clone()),
        Transform::from_translation(at),
    ));
}

/// Balls that rolled off the plank go when they reach the floor.
fn clear_fallen_balls(mut commands: Commands, balls: Query<(Entity, &Transform), With<Ball>>) {
    for (entity, transform) in &balls {
        if transform.translation.y < -0.7 {
            commands.entity(entity).despawn();
        }
    }
}

/// The unattended run: grab the plank's middle at frame 20 and push it down over 15 frames.
fn push_the_plank(
    frame: Res<UnattendedFrame>,
    plank: Single<Entity, With<Plank>>,
    camera: Single<(Entity, &Camera, &GlobalTransform)>,
    mut grab: MessageWriter<GrabStart>,
    mut moves: MessageWriter<GrabMove>,
) {
    let (camera, cam, cam_transform) = *camera;
    let middle = Vec3::new(0.0, 0.04, 0.0);
    let pointer = PointerId::Mouse;
    if frame.0 == 20 {
        grab.write(GrabStart {
            pointer,
            entity: *plank,
            point: middle,
            camera,
        });
    }
    if (21..=35).contains(&frame.0)
        && let Ok(from) = cam.world_to_viewport(cam_transform, middle)
    {
        moves.write(GrabMove {
            pointer,
            from,
            to: from + Vec2::new(0.0, 8.0),
            rotate: false,
        });
    }
}
