//! Systems that hand an ancestor's [`Deformable`] to the mesh primitives below it and keep
//! the copies in sync.

use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};

use super::{DeformableFrom, DeformableScene, SceneSpawned};
use crate::ecs::deform::{DeformError, DeformFailed, DeformPhase, DeformStatus, Deformable};

/// Marks a scene root [`SceneSpawned`] when its instance is ready.
pub(crate) fn mark_scene_spawned(ready: On<WorldInstanceReady>, mut commands: Commands) {
    if let Ok(mut entity) = commands.get_entity(ready.entity) {
        entity.insert(SceneSpawned);
    }
}

/// Hands an ancestor's [`Deformable`] to the mesh primitives below it (see the module docs).
#[allow(clippy::type_complexity)]
pub(crate) fn expand_deformable_ancestors(
    mut commands: Commands,
    mut roots: Query<
        (
            Entity,
            &Deformable,
            &mut DeformStatus,
            Has<WorldAssetRoot>,
            Has<SceneSpawned>,
        ),
        (Without<Mesh3d>, Without<DeformableScene>),
    >,
    children: Query<&Children>,
    meshes: Query<(), With<Mesh3d>>,
    mut failed: MessageWriter<DeformFailed>,
) {
    for (root, deformable, mut status, is_scene, spawned) in &mut roots {
        if status.phase == DeformPhase::Failed {
            continue;
        }
        let primitives: Vec<Entity> = children
            .iter_descendants(root)
            .filter(|e| meshes.contains(*e))
            .collect();
        if primitives.is_empty() {
            if is_scene && !spawned {
                continue; // the scene has not spawned yet
            }
            warn!("Deformable {root}: {}", DeformError::NoMeshBelow);
            status.phase = DeformPhase::Failed;
            status.error = Some(DeformError::NoMeshBelow);
            failed.write(DeformFailed {
                entity: root,
                error: DeformError::NoMeshBelow,
            });
            continue;
        }
        for &primitive in &primitives {
            commands
                .entity(primitive)
                .insert((deformable.clone(), DeformableFrom(root)));
        }
        status.phase = DeformPhase::Idle;
        commands.entity(root).insert(DeformableScene { primitives });
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
