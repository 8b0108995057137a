//! A headless app that loads glTF files through Bevy's loader (no renderer): the plugins it
//! needs besides `MinimalPlugins`, loading a whole file without its materials, and — for
//! tests that need them — the file's materials as `StandardMaterial`s, as the renderer's PBR
//! plugin makes them. Shared by the benchmarks, the sandbox's tests and the integration tests.

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

/// What the renderer does for an app, in a headless one: the image loader (Bevy 0.19
/// registers it in its render plugin; without it an image load waits forever), and each glTF
/// material as a `StandardMaterial` (base colour and its texture) on the mesh entities that
/// use it — so a scene depends on its textures as it does in a game. Call after
/// `app.finish()`.
#[allow(dead_code)] // not every user of this file needs materials
pub fn add_standard_materials(app: &mut App) {
    app.register_asset_loader(bevy::image::ImageLoader::new(
        bevy::image::CompressedImageFormats::NONE,
    ));
    app.init_asset::<StandardMaterial>()
        .register_type::<MeshMaterial3d<StandardMaterial>>();
    app.world_mut()
        .resource_mut::<bevy::gltf::extensions::GltfExtensionHandlers>()
        .0
        .write_blocking()
        .push(Box::new(StandardMaterials));
}

/// Turns each glTF material into a `StandardMaterial` on its meshes (see
/// [`add_standard_materials`]).
#[derive(Clone)]
struct StandardMaterials;

impl bevy::gltf::extensions::GltfExtensionHandler for StandardMaterials {
    fn dyn_clone(&self) -> Box<dyn bevy::gltf::extensions::ErasedGltfExtensionHandler> {
        Box::new(self.clone())
    }

    fn on_material(
        &mut self,
        load_context: &mut bevy::asset::LoadContext<'_>,
        _gltf_material: &gltf::Material,
        _material: Handle<bevy::gltf::GltfMaterial>,
        material_asset: &bevy::gltf::GltfMaterial,
        material_label: &str,
    ) {
        let standard = StandardMaterial {
            base_color: material_asset.base_color,
            base_color_texture: material_asset.base_color_texture.clone(),
            ..default()
        };
        load_context.add_labeled_asset(format!("{material_label}/standard"), standard);
    }

    fn on_spawn_mesh_and_material(
        &mut self,
        load_context: &mut bevy::asset::LoadContext<'_>,
        _primitive: &gltf::Primitive,
        _mesh: &gltf::Mesh,
        _material: &gltf::Material,
        entity: &mut EntityWorldMut,
        material_label: &str,
    ) {
        let label = format!("{material_label}/standard");
        let handle = load_context.get_label_handle::<StandardMaterial>(label);
        entity.insert(MeshMaterial3d(handle));
    }
}
