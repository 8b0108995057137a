//! The shortest path from "I have a Bevy game" to "my player can bend things": a few objects —
//! a bar, a capsule, the cactus, and a glTF scene (`../shared/models/alien.glb`) — that you
//! grab with the mouse and bend. Press on a thing, drag, release: the pose stays.
//!
//! ```text
//! cargo run --release --example playground [-- --pointer [emulated]] [-- --screenshot PATH --frames N]
//! ```
//! `--pointer`: a Wii Remote points too (its IR camera and a sensor bar above the screen):
//! point at a thing, hold A, move and turn the remote, release — the library's
//! `WiimotePointerPlugin`, with a ring drawn where the remote points.
//! Three things make an object bendable: `Deformable` (on a mesh, or on a glTF scene root: it
//! applies to the meshes below), `Grabbable` (radii along the surface), and the plugins —
//! `DeformPlugin`, `GrabPlugin` and a picking backend (`MeshPickingPlugin`).

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_wii_deform::deform::{TriMesh, synth};
use bevy_wii_deform::prelude::*;

#[path = "common/remote_cursor.rs"]
mod remote_cursor;

/// The glTF scene, when the shared test assets sit beside the project.
const ALIEN: &str = "../shared/models/alien.glb";

fn main() {
    let mut app = App::new();
    app.add_plugins(DefaultPlugins.set(AssetPlugin {
        // The shared models live beside the project, not in its assets folder.
        file_path: "..".into(),
        ..default()
    }))
    .add_plugins((DeformPlugin::default(), GrabPlugin, MeshPickingPlugin))
    .add_systems(Startup, setup)
    .add_systems(Update, unattended);
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--pointer") {
        // The Wii Remote as a second pointer: A grabs where it points.
        let emulated = args.get(i + 1).is_some_and(|a| a == "emulated");
        app.add_plugins((
            remote_cursor::pointing_remote(emulated),
            remote_cursor::RemoteCursorPlugin { emulated },
        ));
    }
    app.run();
}

/// Marks the bar, which `--screenshot` bends by a scripted grab.
#[derive(Component)]
struct Bar;

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
) {
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.6, 4.2).looking_at(Vec3::new(0.0, 0.7, 0.0), Vec3::Y),
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
    ));
    // Everything bendable gets the same two components (a wide region: smooth bends).
    let grab = Grabbable {
        radius: 0.1,
        region_radius: 1.0,
        ..default()
    };
    let bendable = (Deformable::default(), grab);
    let mut material = |r, g, b| MeshMaterial3d(materials.add(Color::srgb(r, g, b)));
    let bar = synth::bar(24, 60, 0.1, 1.2);
    commands.spawn((
        Mesh3d(meshes.add(mesh_from_triangles(&bar.positions, &bar.triangles))),
        material(0.8, 0.3, 0.2),
        Transform::from_xyz(-1.2, 0.0, 0.0),
        bendable.clone(),
        Bar,
    ));
    commands.spawn((
        Mesh3d(meshes.add(Capsule3d::new(0.25, 0.8).mesh().rings(24).latitudes(32))),
        material(0.2, 0.5, 0.8),
        Transform::from_xyz(-0.3, 0.65, 0.0),
        bendable.clone(),
    ));
    match TriMesh::read("assets/models/cactus.obj") {
        Ok(cactus) => {
            commands.spawn((
                Mesh3d(meshes.add(mesh_from_triangles(&cactus.positions, &cactus.triangles))),
                material(0.3, 0.7, 0.3),
                Transform::from_xyz(0.6, 0.0, 0.0),
                bendable.clone(),
            ));
        }
        Err(e) => warn!("no cactus ({e}); run `cargo run --example make_assets`"),
    }
    if std::path::Path::new(ALIEN).exists() {
        // A glTF scene: Deformable on its root reaches every mesh below it once it spawns.
        let scene = assets.load(GltfAssetLabel::Scene(0).from_asset("shared/models/alien.glb"));
        commands.spawn((
            WorldAssetRoot(scene),
            Transform::from_xyz(1.5, 0.0, 0.0).with_scale(Vec3::splat(0.6)),
            bendable,
        ));
    } else {
        warn!("{ALIEN} not found: the glTF scene is skipped");
    }
}

/// `--screenshot PATH --frames N`: bends the bar by a scripted grab, saves frame N, exits.
fn unattended(
    mut commands: Commands,
    mut frame: Local<u32>,
    bar: Single<(Entity, &GlobalTransform), With<Bar>>,
    camera: Single<(Entity, &Camera, &GlobalTransform)>,
    mut grab: MessageWriter<GrabStart>,
    mut moves: MessageWriter<GrabMove>,
    mut exit: MessageWriter<AppExit>,
) {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
    };
    let Some(path) = value("--screenshot").cloned() else {
        return;
    };
    let frames: u32 = value("--frames").and_then(|v| v.parse().ok()).unwrap_or(60);
    *frame += 1;
    let (bar, bar_transform) = *bar;
    let (camera, cam, cam_transform) = *camera;
    let tip = bar_transform.transform_point(Vec3::new(0.0, 1.2, 0.0));
    let pointer = PointerId::Mouse;
    if *frame == frames / 3 {
        grab.write(GrabStart {
            pointer,
            entity: bar,
            point: tip,
            camera,
        });
    }
    if *frame > frames / 3
        && *frame <= frames / 3 + 10
        && let Ok(from) = cam.world_to_viewport(cam_transform, tip)
    {
        moves.write(GrabMove {
            pointer,
            from,
            to: from + Vec2::new(14.0, 6.0),
            rotate: false,
        });
    }
    if *frame == frames {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(path));
    }
    if *frame == frames + 15 {
        exit.write(AppExit::Success);
    }
}
