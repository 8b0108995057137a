//! [`Deformable`] on an ancestor: a glTF `WorldAssetRoot` or any node of a hierarchy. The mesh
//! primitives below it each get their own [`Deformable`] (a copy of the ancestor's, kept in
//! sync) and a [`DeformableFrom`] naming the ancestor. A scene root waits until its instance
//! has spawned; a scene that fails to load gets `DeformError::SceneLoadFailed` with the
//! loader's message; a target with no mesh below it gets `DeformError::NoMeshBelow` — once the
//! scene has spawned, or, for an entity that is not a scene root, after [`MESH_WAIT_FRAMES`]
//! frames of waiting for children that a spawner adds late.

use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;

use crate::ecs::deform::{
    DeformError, DeformFailed, DeformPhase, DeformStatus, Deformable, DeformableFrom,
    DeformableScene,
};
use crate::ecs::scene::{SceneSpawned, scene_load_failure};

/// Frames an ancestor that is not a scene root waits for mesh children to arrive (a spawner
/// that adds them a frame or a few later) before it fails with `NoMeshBelow`.
pub const MESH_WAIT_FRAMES: u32 = 30;

/// Hands an ancestor's [`Deformable`] to the mesh primitives below it (see the module docs).
#[allow(clippy::type_complexity, clippy::too_many_arguments)] // one query per role
pub(crate) fn expand_deformable_ancestors(
    mut commands: Commands,
    mut roots: Query<
        (
            Entity,
            &Deformable,
            &mut DeformStatus,
            Option<&WorldAssetRoot>,
            Has<SceneSpawned>,
        ),
        (Without<Mesh3d>, Without<DeformableScene>),
    >,
    children: Query<&Children>,
    meshes: Query<(), With<Mesh3d>>,
    assets: Option<Res<AssetServer>>,
    mut waited: Local<bevy::platform::collections::HashMap<Entity, u32>>,
    mut failed: MessageWriter<DeformFailed>,
) {
    for (root, deformable, mut status, scene, spawned) in &mut roots {
        if status.phase == DeformPhase::Failed {
            continue;
        }
        let primitives: Vec<Entity> = children
            .iter_descendants(root)
            .filter(|e| meshes.contains(*e))
            .collect();
        if primitives.is_empty() {
            let error = match (scene.is_some(), spawned) {
                (true, false) => {
                    match assets.as_deref().and_then(|a| scene_load_failure(a, scene)) {
                        Some(message) => DeformError::SceneLoadFailed(message),
                        None => continue, // the scene has not spawned yet
                    }
                }
                (false, _) => {
                    let frames = waited.entry(root).or_insert(0);
                    *frames += 1;
                    if *frames <= MESH_WAIT_FRAMES {
                        continue; // children may arrive a few frames later
                    }
                    DeformError::NoMeshBelow
                }
                (true, true) => DeformError::NoMeshBelow,
            };
            waited.remove(&root);
            warn!("Deformable {root}: {error}");
            status.phase = DeformPhase::Failed;
            status.error = Some(error.clone());
            failed.write(DeformFailed {
                entity: root,
                error,
            });
            continue;
        }
        waited.remove(&root);
        for &primitive in &primitives {
            commands
                .entity(primitive)
                .try_insert((deformable.clone(), DeformableFrom(root)));
        }
        status.phase = DeformPhase::Idle;
        commands
            .entity(root)
            .try_insert(DeformableScene { primitives });
    }
}

/// Keeps the primitives' [`Deformable`] equal to their ancestor's when it changes.
pub(crate) fn sync_deformable_ancestors(
    roots: Query<(&Deformable, &DeformableScene), Changed<Deformable>>,
    mut primitives: Query<&mut Deformable, (With<DeformableFrom>, Without<DeformableScene>)>,
) {
    for (deformable, scene) in &roots {
        for &p in &scene.primitives {
            if let Ok(mut d) = primitives.get_mut(p)
                && *d != *deformable
            {
                *d = deformable.clone();
            }
        }
    }
}
