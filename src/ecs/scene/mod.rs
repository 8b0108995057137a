//! glTF scene roots (`WorldAssetRoot`, Bevy's scene root) as the deform and pose plugins
//! need them: when a root's instance has spawned (glTF splits a mesh into one entity per
//! primitive under node entities that carry the node transforms, and the scene is spawned some
//! frames after its asset loads), why a scene failed to load (a missing or malformed file: the
//! loader's message), and what it misses.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin.rs` | [`SceneRootPlugin`]: scene roots marked spawned, missing dependencies reported. |
//!
//! A scene whose own file loads but one of whose dependencies does not — typically a texture
//! whose image file was not copied beside the model (`"uri": "default.bmp"`) — is *not* a
//! failure: its geometry, skin and animations are all in the file. It spawns, deforms and
//! poses as usual; its root gets [`MissingSceneAssets`] naming the file that is missing, a
//! [`SceneAssetsMissing`] message is written and a warning logged, and the pose and deform
//! statuses carry it as their `warning`. Drawing such a model needs a material without the
//! missing texture (Bevy draws nothing for a material whose image failed): the examples'
//! `examples/common/src/missing_textures.rs` shows the few lines that swap it out.
//!
//! This file holds the components; `plugin.rs` the systems and [`SceneRootPlugin`], which
//! [`DeformPlugin`](crate::ecs::DeformPlugin) and [`PosePlugin`](crate::ecs::PosePlugin) add.

mod plugin;

use bevy::prelude::*;

pub use plugin::SceneRootPlugin;
pub(crate) use plugin::{
    SceneWarning, add_scene_roots, note_missing_scene_assets, scene_load_failure,
};

/// Marks a scene root whose dependencies have settled (all loaded, or one failed): the
/// missing-dependency check is done for it.
#[derive(Component, Debug, Clone, Copy, Default)]
pub(crate) struct SceneDependenciesSettled;

/// Marks a scene root whose instance has spawned (set by an observer of
/// `WorldInstanceReady`).
#[derive(Component, Debug, Clone, Copy, Default)]
pub(crate) struct SceneSpawned;

/// On a scene root whose file loaded but some of whose dependencies (images, most often) did
/// not: the loader's message for the first one, which names the missing file. The scene
/// still spawns and works; only what the missing file held is absent.
#[derive(Component, Debug, Clone, PartialEq, Eq)]
pub struct MissingSceneAssets {
    /// The loader's message (first line), e.g. `Path not found: …/default.bmp`.
    pub message: String,
}

/// Written once per scene root when [`MissingSceneAssets`] is inserted.
#[derive(Message, Debug, Clone, PartialEq, Eq)]
pub struct SceneAssetsMissing {
    /// The scene root.
    pub entity: Entity,
    /// The loader's message for the missing dependency.
    pub message: String,
}
