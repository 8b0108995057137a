//! The shortest path from "I have a Bevy game" to "my player can bend things": a few objects —
//! a bar, a capsule, the cactus, and a glTF scene (Kenney's alien, `assets/models/alien.glb`)
//! — that you grab with the mouse and bend. Press on a thing, drag, release: the pose stays.
//!
//! ```text
//! cargo run --release --example playground [-- --pointer [emulated]] [--wobble] [--screenshot PATH --frames N]
//! ```
//! **W** (or `--wobble`): things wobble when let go and spring back to their shape.
//! Three things make an object bendable: `Deformable` (on a mesh, or on a glTF scene root: it
//! applies to the meshes below), `Grabbable` (radii along the surface), and the plugins —
//! `DeformPlugin`, `GrabPlugin` and a picking backend (`MeshPickingPlugin`). The unattended
//! run and the Wii Remote pointer are in [`harness`].

use bevy::prelude::*;
use bevy_wii_deform::deform::{TriMesh, synth};
use bevy_wii_deform::prelude::*;

use bevy_wii_deform_examples::cli;
mod harness;
use bevy_wii_deform_examples::missing_textures;
use bevy_wii_deform_examples::remote_cursor;
use bevy_wii_deform_examples::screenshot;

fn main() {
    let options = harness::Options::parse();
    App::new()
        .add_plugins(harness::default_plugins(&options))
        .add_plugins((DeformPlugin::default(), GrabPlugin, MeshPickingPlugin))
        .add_plugins(missing_textures::MissingTexturesPlugin)
        .add_systems(Startup, setup)
        .add_plugins(harness::HarnessPlugin(options))
        .run();
}

/// Marks the bar, which the unattended run bends by a scripted grab.
#[derive(Component)]
pub struct Bar;

/// Marks the floor (drawn unlit on the web, where frames are often software-rendered).
#[derive(Component)]
pub struct Floor;

/// Marks the cactus (the unattended `--drag cactus` run grabs it).
#[derive(Component)]
pub struct Cactus;

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
        Floor,
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
    match cactus() {
        Ok(cactus) => {
            commands.spawn((
                Mesh3d(meshes.add(mesh_from_triangles(&cactus.positions, &cactus.triangles))),
                material(0.3, 0.7, 0.3),
                Transform::from_xyz(0.6, 0.0, 0.0),
                bendable.clone(),
                Cactus,
            ));
        }
        Err(e) => warn!("no cactus ({e}); run `cargo run --example make_assets`"),
    }
    // A glTF scene: Deformable on its root reaches every mesh below it once it spawns.
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset("models/alien.glb"));
    commands.spawn((
        WorldAssetRoot(scene),
        Transform::from_xyz(1.5, 0.0, 0.0).with_scale(Vec3::splat(0.6)),
        bendable,
    ));
}

/// The cactus: read from `assets/` on the desktop; on the web, which has no file system,
/// generated in the page from the same signed distance function that made the file (a 1.9 MB
/// OBJ compiled in would be that much more to download).
fn cactus() -> Result<TriMesh, bevy_wii_deform::deform::MeshIoError> {
    #[cfg(target_arch = "wasm32")]
    return Ok(bevy_wii_deform_examples::models::cactus());
    #[cfg(not(target_arch = "wasm32"))]
    TriMesh::read("assets/models/cactus.obj")
}
