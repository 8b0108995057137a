//! The game's ground for posing: mesh entities marked [`GroundMesh`] make one [`SceneGround`]
//! (their triangles in world space, with a grid across gravity), which the pose plugin casts
//! down on for characters with [`crate::ecs::PoseGround`]. Anything else — a physics engine's
//! colliders, a height function — goes in as a [`SceneGround`] built from a closure
//! ([`SceneGround::custom`]).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin.rs` | Keeping [`SceneGround`] current from the [`GroundMesh`] meshes. |

mod plugin;

use std::sync::Arc;

use bevy::prelude::*;
use glam::DVec3;

use crate::pose::{Ground, GroundPlane, TriangleGround};

pub use plugin::GroundPlugin;

/// Marks a mesh entity (`Mesh3d`) as ground characters stand on: its triangles, placed by its
/// `GlobalTransform`, join the [`SceneGround`].
#[derive(Component, Debug, Clone, Copy, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Default)]
pub struct GroundMesh;

/// The ground the pose plugin casts on, world space. Kept current by [`GroundPlugin`] from the
/// [`GroundMesh`] meshes (rebuilt when one is added, removed, moved or its mesh changes), or set by
/// the game ([`SceneGround::custom`]).
#[derive(Resource, Clone)]
pub struct SceneGround {
    source: Arc<dyn Ground + Send + Sync>,
    /// Triangles in the ground (0 for a custom one).
    pub triangles: usize,
    /// Whether [`GroundPlugin`] keeps it current from [`GroundMesh`] meshes (false: the game's).
    pub from_meshes: bool,
}

impl SceneGround {
    /// A ground from anything that answers a ray cast down (world space): a closure
    /// `(from, down, max_distance) → Option<GroundPlane>`, an infinite plane, a physics
    /// engine's spatial query. [`GroundPlugin`] leaves it alone.
    pub fn custom(ground: impl Ground + Send + Sync + 'static) -> Self {
        Self {
            source: Arc::new(ground),
            triangles: 0,
            from_meshes: false,
        }
    }

    /// The ground of triangles (world space).
    pub(crate) fn of_triangles(ground: TriangleGround, triangles: usize) -> Self {
        Self {
            source: Arc::new(ground),
            triangles,
            from_meshes: true,
        }
    }

    /// Whether `other` is this very ground (the same source, not an equal copy).
    pub(crate) fn same_source(&self, other: &SceneGround) -> bool {
        Arc::ptr_eq(&self.source, &other.source)
    }

    /// The first surface below `from` along `down` within `max`, world space.
    pub fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        self.source.cast_down(from, down, max)
    }

    /// How high the ground rises within `radius` of `centre` across `down` (world space,
    /// [`Ground::highest_within`]); `None` when it cannot say.
    pub fn highest_within(&self, centre: DVec3, radius: f64, down: DVec3) -> Option<f64> {
        self.source.highest_within(centre, radius, down)
    }
}

impl Ground for SceneGround {
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        self.source.cast_down(from, down, max)
    }

    fn highest_within(&self, centre: DVec3, radius: f64, down: DVec3) -> Option<f64> {
        self.source.highest_within(centre, radius, down)
    }
}

impl std::fmt::Debug for SceneGround {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneGround")
            .field("triangles", &self.triangles)
            .field("from_meshes", &self.from_meshes)
            .finish_non_exhaustive()
    }
}
