//! [`Deformable`] on an ancestor: a glTF `WorldAssetRoot` (Bevy 0.19's scene root) or any node
//! of a hierarchy. The mesh primitives below it each get their own [`Deformable`] (a copy of
//! the ancestor's, kept in sync) and a [`DeformableFrom`] naming the ancestor.
//!
//! glTF splits a mesh into one entity per primitive under node entities that carry the node
//! transforms, and the scene is spawned some frames after its asset loads; this waits for
//! that (`WorldInstanceReady`). A target with no mesh below it gets a [`DeformFailed`] with
//! [`DeformError::NoMeshBelow`] — once the scene has spawned, or at once for an entity that is
//! not a scene root (its meshes must be below it when the [`Deformable`] is added).

use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};

use super::deform::{DeformError, DeformFailed, DeformPhase, DeformStatus, Deformable};

/// On an ancestor whose [`Deformable`] was handed to the mesh primitives below it: those
/// primitives, in hierarchy order.
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct DeformableScene {
    /// The primitive entities that are deformable because of this ancestor.
    pub primitives: Vec<Entity>,
}

/// On a mesh primitive that is deformable because an ancestor is: that ancestor. Its
/// [`Deformable`] follows the ancestor's.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct DeformableFrom(pub Entity);

/// Marks a scene root whose instance has spawned (set by an observer of
/// `WorldInstanceReady`).
#[derive(Component, Debug, Clone, Copy, Default)]
pub(crate) struct SceneSpawned;

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
