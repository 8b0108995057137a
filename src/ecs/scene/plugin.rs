//! [`SceneRootPlugin`]: scene roots marked spawned, missing dependencies reported.

use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};

use super::{MissingSceneAssets, SceneAssetsMissing, SceneDependenciesSettled, SceneSpawned};

/// Watches glTF scene roots (`WorldAssetRoot`): marks them spawned, and says when a scene's
/// dependency is missing ([`MissingSceneAssets`]). Added by the deform and pose plugins.
#[derive(Debug, Clone, Copy, Default)]
pub struct SceneRootPlugin;

impl Plugin for SceneRootPlugin {
    fn build(&self, app: &mut App) {
        app.add_message::<SceneAssetsMissing>()
            .add_observer(mark_scene_spawned)
            .add_systems(
                PreUpdate,
                (forget_replaced_scenes, report_missing_scene_assets).chain(),
            );
    }
}

/// Adds [`SceneRootPlugin`] unless the app has it.
pub(crate) fn add_scene_roots(app: &mut App) {
    if !app.is_plugin_added::<SceneRootPlugin>() {
        app.add_plugins(SceneRootPlugin);
    }
}

/// The first line of an asset error (a backtrace may follow).
fn first_line(error: &impl std::fmt::Display) -> String {
    error
        .to_string()
        .lines()
        .next()
        .unwrap_or_default()
        .to_string()
}

/// A root given another scene is watched again.
fn forget_replaced_scenes(
    mut commands: Commands,
    replaced: Query<Entity, (Changed<WorldAssetRoot>, With<SceneDependenciesSettled>)>,
) {
    for entity in &replaced {
        commands
            .entity(entity)
            .try_remove::<(SceneDependenciesSettled, MissingSceneAssets)>();
    }
}

/// Scene roots whose own file loaded but a dependency did not get [`MissingSceneAssets`].
/// A root is looked at until its dependencies have settled (all loaded, or one failed), then
/// not again (two asset-server look-ups a root a frame while it loads, none after).
fn report_missing_scene_assets(
    mut commands: Commands,
    roots: Query<(Entity, &WorldAssetRoot), Without<SceneDependenciesSettled>>,
    assets: Option<Res<AssetServer>>,
    mut missing: MessageWriter<SceneAssetsMissing>,
) {
    use bevy::asset::{LoadState, RecursiveDependencyLoadState};
    let Some(assets) = assets else {
        return;
    };
    for (entity, root) in &roots {
        let own = assets.get_load_state(&root.0);
        let error = match assets.get_recursive_dependency_load_state(&root.0) {
            Some(RecursiveDependencyLoadState::Failed(error)) => error,
            Some(RecursiveDependencyLoadState::Loaded) => {
                commands.entity(entity).try_insert(SceneDependenciesSettled);
                continue;
            }
            _ => continue,
        };
        commands.entity(entity).try_insert(SceneDependenciesSettled);
        if !matches!(own, Some(LoadState::Loaded)) {
            continue; // the file itself failed: `scene_load_failure` reports it
        }
        let message = first_line(&error);
        warn!("scene {entity}: a dependency is missing, the rest is used: {message}");
        commands.entity(entity).try_insert(MissingSceneAssets {
            message: message.clone(),
        });
        missing.write(SceneAssetsMissing { entity, message });
    }
}

/// A status component that carries a scene's missing-dependency warning (the pose and deform
/// statuses).
pub(crate) trait SceneWarning:
    Component<Mutability = bevy::ecs::component::Mutable>
{
    /// Where the warning goes.
    fn warning_mut(&mut self) -> &mut Option<String>;
}

/// Copies a scene root's [`MissingSceneAssets`] message into its status `S` (each plugin adds
/// it for its own status).
pub(crate) fn note_missing_scene_assets<S: SceneWarning>(
    mut roots: Query<(&MissingSceneAssets, &mut S), Changed<MissingSceneAssets>>,
) {
    for (missing, mut status) in &mut roots {
        *status.warning_mut() = Some(missing.message.clone());
    }
}

/// Marks a scene root [`SceneSpawned`] when its instance is ready.
pub(crate) fn mark_scene_spawned(ready: On<WorldInstanceReady>, mut commands: Commands) {
    if let Ok(mut entity) = commands.get_entity(ready.entity) {
        entity.try_insert(SceneSpawned);
    }
}

/// Why a scene root has nothing below it yet: still loading (`None`), or its load failed.
/// A scene whose own file loaded is not failed when only a dependency (a texture) is missing:
/// it spawns without it ([`MissingSceneAssets`]).
pub(crate) fn scene_load_failure(
    assets: &AssetServer,
    root: Option<&WorldAssetRoot>,
) -> Option<String> {
    use bevy::asset::{LoadState, RecursiveDependencyLoadState};
    let handle = &root?.0;
    if let Some(LoadState::Failed(error)) = assets.get_load_state(handle) {
        return Some(first_line(&error));
    }
    if matches!(assets.get_load_state(handle), Some(LoadState::Loaded)) {
        return None; // it spawns; a missing dependency is only a warning
    }
    match assets.get_recursive_dependency_load_state(handle)? {
        RecursiveDependencyLoadState::Failed(error) => Some(first_line(&error)),
        _ => None,
    }
}
