//! [`Deformable`] on an ancestor: a glTF `WorldAssetRoot` (Bevy 0.19's scene root) or any node
//! of a hierarchy. The mesh primitives below it each get their own [`Deformable`] (a copy of
//! the ancestor's, kept in sync) and a [`DeformableFrom`] naming the ancestor.
//!
//! glTF splits a mesh into one entity per primitive under node entities that carry the node
//! transforms, and the scene is spawned some frames after its asset loads; this waits for
//! that (`WorldInstanceReady`). A scene that fails to load (a missing or malformed file) gets
//! a [`DeformFailed`] with `DeformError::SceneLoadFailed` and the loader's message. A target
//! with no mesh below it gets [`DeformError::NoMeshBelow`] — once the scene has spawned, or,
//! for an entity that is not a scene root, after [`MESH_WAIT_FRAMES`] frames of waiting for
//! children that a spawner adds late.
//!
//! This file holds the components; `plugin.rs` the systems, which [`DeformPlugin`](crate::ecs::DeformPlugin) adds.

mod plugin;

use bevy::prelude::*;

#[cfg(doc)]
use crate::ecs::{DeformError, DeformFailed, Deformable};

pub use plugin::MESH_WAIT_FRAMES;
pub(crate) use plugin::{
    expand_deformable_ancestors, mark_scene_spawned, scene_load_failure, sync_deformable_ancestors,
};

/// On an ancestor whose [`Deformable`] was handed to the mesh primitives below it: those
/// primitives, in hierarchy order.
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct DeformableScene {
    /// The primitive entities that are deformable because of this ancestor.
    #[entities]
    pub primitives: Vec<Entity>,
}

/// On a mesh primitive that is deformable because an ancestor is: that ancestor. Its
/// [`Deformable`] follows the ancestor's.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct DeformableFrom(#[entities] pub Entity);

/// Marks a scene root whose instance has spawned (set by an observer of
/// `WorldInstanceReady`).
#[derive(Component, Debug, Clone, Copy, Default)]
pub(crate) struct SceneSpawned;
