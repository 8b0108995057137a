//! Avian physics for bent meshes and posed characters (cargo feature `avian`, avian3d 0.8).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `builder.rs` | The collider builder: one long-lived background thread at the lowest priority that builds bent meshes' colliders (refitting the replaced triangle mesh when the triangles are the same) and frees the ones they replace, handed its work over a channel. |
//! | `plugin.rs` | Systems of [`DeformPhysicsPlugin`]: collider rebuilds after settled solves, the colliders marked [`GroundMesh`] as the scene's ground, capsules on posed bones. |
//!
//! - [`DeformCollider`] on a [`Deformable`](crate::ecs::Deformable) rebuilds its Avian
//!   [`Collider`] from the bent mesh after each settled solve: the shape is built on a
//!   background thread of its own and swapped in when ready, so the main thread only copies
//!   the mesh's positions and index buffer (the thread makes the triangles). Avian's triangle
//!   meshes are shared and read-only, so a bend gets a new collider: a copy of the old
//!   triangle mesh with the bent positions and its tree refitted when the triangles are the
//!   same (most bends), else one built anew. It replaces the old one in place, and Avian
//!   picks up the changed collider in its next step.
//! - [`GroundMesh`](crate::ecs::GroundMesh) entities with a [`Collider`] become the scene's ground
//!   ([`SceneGround`](crate::ecs::SceneGround)) through Avian's ray casts against those
//!   colliders, for characters with [`PoseGround`](crate::ecs::PoseGround) and meshes with
//!   [`DeformGround`](crate::ecs::DeformGround). When at least one such collider exists, the
//!   colliders are the ground and mesh-only `GroundMesh` entities are not cast on.
//!
//! - [`PosedColliders`] on a [`Poseable`](crate::ecs::Poseable) character gives each bone a
//!   kinematic capsule fitted to its skin ([`crate::pose::fit_bone_capsules`]), a child of the
//!   joint entity, so it follows the pose and the animation: hits and pushes meet the posed
//!   body.
//!
//! Add [`DeformPhysicsPlugin`] beside Avian's `PhysicsPlugins`.

mod builder;
mod plugin;

use avian3d::prelude::*;
use bevy::prelude::*;
use glam::DVec3;

use crate::pose::{Ground, GroundPlane};

pub use plugin::{DeformPhysicsPlugin, DeformPhysicsSystems};

/// The collider a [`DeformCollider`] builds from the bent mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum ColliderShape {
    /// A triangle mesh: the exact surface, hollow (for static bodies: a ramp, a plank).
    #[default]
    Trimesh,
    /// The convex hull of the bent vertices (for dynamic bodies).
    ConvexHull,
}

/// Rebuilds this [`Deformable`](crate::ecs::Deformable)'s Avian [`Collider`] from its bent
/// mesh after each settled solve ([`DeformPhysicsPlugin`]).
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
#[require(DeformColliderStatus)]
pub struct DeformCollider {
    /// Which shape to build.
    pub shape: ColliderShape,
}

/// What the collider rebuilds of a [`DeformCollider`] did; readable by UIs and tests.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
pub struct DeformColliderStatus {
    /// Colliders built and swapped in.
    pub rebuilds: u64,
    /// The deform solve count ([`DeformStatus::solves`](crate::ecs::DeformStatus::solves)) the
    /// current collider was built from.
    pub built_from_solve: u64,
    /// Why the last rebuild failed (the previous collider stays), if it did.
    pub error: Option<String>,
}

/// A collider being built in the background ([`builder`]).
#[derive(Component)]
pub(crate) struct ColliderBuild {
    result: crossbeam_channel::Receiver<builder::BuildResult>,
    solve: u64,
}

/// Kinematic capsules on a posed character's bones ([`DeformPhysicsPlugin`]), built once the
/// character is prepared: one per joint carrying skin, a child of the joint entity.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct PosedColliders {
    /// A vertex belongs to a joint's capsule when weighted at least this much to it.
    pub min_weight: f32,
}

impl Default for PosedColliders {
    fn default() -> Self {
        Self { min_weight: 0.5 }
    }
}

/// A capsule of [`PosedColliders`] (on the child entity of a joint).
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct BoneCollider {
    /// The character whose bone this is.
    #[entities]
    pub character: Entity,
}

/// The scene's ground as Avian colliders, cast on one by one (with their bounding boxes as a
/// first test). A snapshot: shapes are shared, not copied.
#[derive(Clone, Default)]
pub struct ColliderGround {
    colliders: Vec<(Collider, Vec3, Quat, ColliderAabb)>,
}

impl ColliderGround {
    /// A ground of `colliders` placed at (translation, rotation), with their world boxes.
    pub fn new(colliders: Vec<(Collider, Vec3, Quat, ColliderAabb)>) -> Self {
        Self { colliders }
    }

    /// Colliders in the ground.
    pub fn len(&self) -> usize {
        self.colliders.len()
    }

    /// Whether the ground has no collider.
    pub fn is_empty(&self) -> bool {
        self.colliders.is_empty()
    }
}

impl Ground for ColliderGround {
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        let (origin, dir) = (from.as_vec3(), down.normalize_or_zero().as_vec3());
        let end = origin + dir * max as f32;
        let (lo, hi) = (origin.min(end), origin.max(end));
        let mut best: Option<(f32, Vec3)> = None;
        for (collider, translation, rotation, aabb) in &self.colliders {
            if aabb.max.cmplt(lo).any() || aabb.min.cmpgt(hi).any() {
                continue;
            }
            let Some((t, normal)) =
                collider.cast_ray(*translation, *rotation, origin, dir, max as f32, true)
            else {
                continue;
            };
            if best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, normal));
            }
        }
        let (t, normal) = best?;
        // The face's normal, turned to face the ray (a trimesh's winding may face either way).
        let normal = if normal.dot(dir) > 0.0 {
            -normal
        } else {
            normal
        };
        GroundPlane::new((origin + dir * t).as_dvec3(), normal.as_dvec3())
    }
}
