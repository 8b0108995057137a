//! What a character standing on the game's ground is told and tells: [`PoseGround`] and
//! [`PoseBalance`] (settings), [`GroundContactState`] (each contact, in
//! [`super::PoseStatus::contacts`]). The work is in `ground_contacts.rs`.

use bevy::prelude::*;

/// Stands a character on the scene's ground ([`crate::ecs::SceneGround`], from [`crate::ecs::GroundMesh`]
/// meshes or the game's own): its lowest joints (feet, paws, a prop's base) become contacts —
/// cast down every solve, planted when they touch, released when the pose lifts them — and
/// every skin vertex near the ground under it is kept above it, so a grab pushing the
/// character down stops at the ground ([`crate::pose::ground::contact`]).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct PoseGround {
    /// Joints whose skin reaches within this share of the character's size of its lowest
    /// vertex are its feet (found once, in the pose it stands in).
    pub feet_tolerance: f32,
    /// Skin vertices within this share of the size above the ground under them are kept
    /// above it in each solve ([`crate::pose::Floor::cast`]); it has to cover how far a
    /// vertex moves in one solve (a grab's drag).
    pub floor_band: f32,
}

impl Default for PoseGround {
    fn default() -> Self {
        Self {
            feet_tolerance: 0.03,
            floor_band: 0.3,
        }
    }
}

/// Keeps a character's centre of mass over its planted feet ([`crate::pose::ground::balance`]); needs
/// [`PoseGround`] (the planted contacts make the support polygon).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct PoseBalance {
    /// Balance on or off.
    pub enabled: bool,
    /// How far inside the support polygon the centre of mass stays, as a share of the
    /// character's size.
    pub margin: f32,
    /// Weight in [0, 1] (1: a thousand times a position effector's pull).
    pub weight: f32,
}

impl Default for PoseBalance {
    fn default() -> Self {
        Self {
            enabled: true,
            margin: 0.01,
            weight: 1.0,
        }
    }
}

/// One ground contact of a character standing by [`PoseGround`], as the last request left it
/// (in [`PoseStatus::contacts`](super::PoseStatus::contacts)).
#[derive(Debug, Clone, PartialEq, Reflect)]
pub struct GroundContactState {
    /// The joint that carries the patch (a foot).
    pub joint: usize,
    /// The patch's vertices (indices of the model's welded vertices).
    pub patch: Vec<u32>,
    /// Whether the patch is planted (held where it touched).
    pub planted: bool,
    /// While planted: where each patch vertex is held (world space, in patch order).
    pub held: Vec<Vec3>,
    /// Whether the last cast found ground under it.
    pub grounded: bool,
    /// The ground's normal under it (world space).
    pub ground_normal: Vec3,
    /// The joint's axis, in its bind-pose frame, that a planted contact turns to the normal.
    pub up: Option<Vec3>,
}
