//! Pointer grabs: press on a [`Grabbable`] deformable, drag, release — the surface under the
//! pointer follows it, and the pose stays. How a grab behaves is documented on
//! [`GrabPlugin`]. This file holds the data types; `plugin.rs` the plugin and its systems.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin.rs` | The grab plugin: picking and pointer input to grab messages, and the systems that start, place, move and end grabs. |

mod plugin;

use std::collections::HashMap;

use bevy::picking::pointer::{PointerButton, PointerId};
use bevy::prelude::*;

#[cfg(doc)]
use crate::ecs::deform::{Deformable, FixedRegion};

pub use plugin::GrabPlugin;

/// Makes a [`Deformable`] (or, on an ancestor, every deformable primitive below it) grabbable
/// with the pointer.
#[derive(Component, Debug, Clone, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct Grabbable {
    /// Radius of the grabbed patch along the surface, world units.
    pub radius: f32,
    /// Radius of the region that may move, along the surface, world units (used when the mesh
    /// has no [`FixedRegion`]); beyond it the surface is held.
    pub region_radius: f32,
    /// At most this many vertices of the region move, the nearest along the surface: the
    /// grab's first pose waits for the region's factorization, so on a dense mesh the region
    /// shrinks rather than the grab stalling (16 384 by default; the first pose's cost is
    /// `plugin_bench --grab` in `docs/benchmarks.md`).
    pub max_region_vertices: u32,
}

impl Default for Grabbable {
    fn default() -> Self {
        Self {
            radius: 0.08,
            region_radius: 0.6,
            max_region_vertices: 16_384,
        }
    }
}

/// The pointer button that grabs: a press of it on a [`Grabbable`] starts a grab, its release
/// ends it. Presses of other buttons (a right-drag for an orbit camera, a middle-click) start
/// nothing. Primary (the left mouse button) by default.
#[derive(Resource, Debug, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Resource, Default)]
pub struct GrabButton(pub PointerButton);

impl Default for GrabButton {
    fn default() -> Self {
        Self(PointerButton::Primary)
    }
}

/// Start grabbing `entity` (a deformable mesh primitive) at the world point `point`, seen
/// from `camera`, for `pointer`.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct GrabStart {
    /// Which pointer grabs.
    pub pointer: PointerId,
    /// The mesh entity.
    pub entity: Entity,
    /// The grabbed point, world space.
    pub point: Vec3,
    /// The camera the pointer moves in.
    pub camera: Entity,
}

/// The pointer of a grab moved from `from` to `to` (viewport coordinates of its camera).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct GrabMove {
    /// Which pointer.
    pub pointer: PointerId,
    /// Previous position.
    pub from: Vec2,
    /// New position.
    pub to: Vec2,
    /// Turn the grabbed patch (an arcball about its position on screen) instead of moving it;
    /// the picking glue sets this while Shift is held.
    pub rotate: bool,
}

/// Turn a grab's patch about its camera's view axis by `radians` (counter-clockwise as seen
/// from the camera); the picking glue writes it from the mouse wheel.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct GrabTwist {
    /// Which pointer.
    pub pointer: PointerId,
    /// The angle, radians.
    pub radians: f32,
}

/// Turn a grab's patch by `rotation`, given in its camera's frame (x right, y up, z towards
/// the viewer): a remote's turn since the last frame, 1:1 (the remote pointer plugin writes
/// it while A holds a grab).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct GrabTurn {
    /// Which pointer.
    pub pointer: PointerId,
    /// The turn, camera frame.
    pub rotation: Quat,
}

/// The pointer released its grab (the pose stays).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct GrabEnd {
    /// Which pointer.
    pub pointer: PointerId,
}

/// On a mesh: the handle entity its last grab created.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct GrabHandle(#[entities] pub Entity);

/// Grabs in progress, by pointer.
#[derive(Resource, Debug, Default)]
pub struct ActiveGrabs(HashMap<PointerId, ActiveGrab>);

impl ActiveGrabs {
    /// The mesh a pointer is grabbing, if any.
    pub fn mesh_of(&self, pointer: PointerId) -> Option<Entity> {
        self.0.get(&pointer).map(|g| g.mesh)
    }

    /// The meshes being grabbed.
    pub fn meshes(&self) -> impl Iterator<Item = Entity> + '_ {
        self.0.values().map(|g| g.mesh)
    }

    /// How many grabs are in progress.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether no pointer grabs anything.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

#[derive(Debug)]
struct ActiveGrab {
    mesh: Entity,
    camera: Entity,
    /// The grabbed point in mesh space (kept until the rest pose is ready).
    point: Vec3,
    settings: Grabbable,
    /// The handle, once placed.
    handle: Option<Entity>,
    /// Pointer motion received before the handle existed: (first from, latest to).
    early_motion: Option<(Vec2, Vec2)>,
    /// A posed character: the point and the handle are in world space.
    character: bool,
}
