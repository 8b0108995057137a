//! A model whose texture files are missing is still drawn: Bevy draws nothing for a material
//! whose image failed to load, so every `StandardMaterial` that names a failed image gets that
//! slot emptied (the material's colours stay: the fallback is the untextured material). The
//! library itself reports the missing file (`MissingSceneAssets`, the pose and deform
//! statuses' `warning`); this is the drawing side, which belongs to the app.

use bevy::asset::AssetLoadFailedEvent;
use bevy::platform::collections::HashSet;
use bevy::prelude::*;

/// Empties failed image slots of standard materials.
pub struct MissingTexturesPlugin;

impl Plugin for MissingTexturesPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<FailedImages>()
            .init_resource::<MissingImages>()
            .add_systems(PostUpdate, drop_failed_textures);
    }
}

/// The paths of the images that failed to load so far, for the apps' status lines.
#[derive(Resource, Default, Debug, Clone)]
pub struct MissingImages(pub Vec<String>);

/// Images that failed to load so far.
#[derive(Resource, Default)]
struct FailedImages(HashSet<AssetId<Image>>);

fn drop_failed_textures(
    mut failures: MessageReader<AssetLoadFailedEvent<Image>>,
    mut added: MessageReader<AssetEvent<StandardMaterial>>,
    mut failed: ResMut<FailedImages>,
    mut missing: ResMut<MissingImages>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let mut sweep = false;
    for failure in failures.read() {
        warn!("image {} is missing: drawn without it", failure.path);
        sweep |= failed.0.insert(failure.id);
        missing.0.push(failure.path.to_string());
    }
    sweep |= added.read().any(|e| matches!(e, AssetEvent::Added { .. })) && !failed.0.is_empty();
    if !sweep {
        return;
    }
    let ids: Vec<AssetId<StandardMaterial>> = materials.ids().collect();
    for id in ids {
        let names_failed = |slot: &Option<Handle<Image>>| {
            slot.as_ref().is_some_and(|h| failed.0.contains(&h.id()))
        };
        let Some(material) = materials.get(id) else {
            continue;
        };
        let slots = [
            &material.base_color_texture,
            &material.emissive_texture,
            &material.metallic_roughness_texture,
            &material.normal_map_texture,
            &material.occlusion_texture,
            &material.depth_map,
        ];
        if !slots.into_iter().any(names_failed) {
            continue;
        }
        let Some(mut guard) = materials.get_mut(id) else {
            continue;
        };
        let material: &mut StandardMaterial = &mut guard;
        for slot in [
            &mut material.base_color_texture,
            &mut material.emissive_texture,
            &mut material.metallic_roughness_texture,
            &mut material.normal_map_texture,
            &mut material.occlusion_texture,
            &mut material.depth_map,
        ] {
            if names_failed(slot) {
                *slot = None;
            }
        }
    }
}
