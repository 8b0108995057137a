//! A headless app that loads glTF files through Bevy's loader (no renderer): the plugins it
//! needs besides `MinimalPlugins`, and loading a whole file without its materials. Shared by
//! the crowd benchmark and the integration tests.

use bevy::prelude::*;

/// Adds the plugins that load glTF scenes (meshes, skins, animation) from the asset folder
/// `dir` (an absolute path: Bevy resolves relative ones against the executable's folder). Add
/// `MinimalPlugins` (or your own task pools) first, and call `app.finish()` after: the glTF
/// loader is registered there.
pub fn add_gltf_plugins(app: &mut App, dir: &std::path::Path) {
    app.add_plugins((
        bevy::asset::AssetPlugin {
            file_path: dir.display().to_string(),
            // Files written to a temporary directory outside the asset folder load too.
            unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow,
            ..default()
        },
        bevy::mesh::MeshPlugin,
        bevy::transform::TransformPlugin,
        bevy::image::ImagePlugin::default(),
        bevy::world_serialization::WorldSerializationPlugin,
        bevy::animation::AnimationPlugin,
        bevy::gltf::GltfPlugin::default(),
    ));
}

/// Starts loading the whole file `path` (its clips too) without materials, cameras or lights:
/// nothing is drawn. Keep the handle: loading a part of the file later with other settings
/// would load it again and respawn its scenes.
pub fn load_gltf_without_materials(app: &App, path: &str) -> Handle<bevy::gltf::Gltf> {
    app.world()
        .resource::<AssetServer>()
        .load_builder()
        .with_settings(|s: &mut bevy::gltf::GltfLoaderSettings| {
            s.load_materials = bevy::asset::RenderAssetUsages::empty();
            s.load_cameras = false;
            s.load_lights = false;
        })
        .load(path.to_string())
}
