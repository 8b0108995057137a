//! What a pose solve must respect, beyond the shape: [`PoseConstraints`] gathers it all.
//!
//! | question | file |
//! |---|---|
//! | everything a solve respects: handles, pins, joint handles, effectors, stiffness, limits, balance, contacts, the floor, the shape's rest | `mod.rs` ([`PoseConstraints`], [`JointHandle`]) |
//! | effectors (position, orientation, aim, centroid) and reference stiffness; effectors mirrored | `effectors.rs` |
//! | joint limits: swing cones with twist, hinges, RON files | `limits.rs` ([`JointLimits`]) |
//! | the humanoid limits preset, by joint names | `humanoid_limits.rs` ([`JointLimits::humanoid`]) |
//! | constraints brought from world space into a character's frame (a similarity) | `frame.rs` ([`frame::similarity`]) |
//!
//! [`JointLimits`]: limits::JointLimits
//! [`JointLimits::humanoid`]: limits::JointLimits::humanoid

pub mod effectors;
pub mod frame;
mod humanoid_limits;
pub mod limits;

use crate::deform::constraints::same_keys;
use crate::deform::{Handle, RigidTransform};
use crate::pose::constraints::effectors::{CentroidEffector, Effector, ReferenceStiffness};
use crate::pose::constraints::limits::JointLimits;
use crate::pose::ground::balance::Balance;
use crate::pose::ground::contact::Contact;
use crate::pose::ground::floor::Floor;
use crate::pose::rig::skeleton::SkeletonPose;
use std::sync::Arc;

/// A joint driven to a rigid motion of where it was in the reference pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointHandle {
    /// Joint index in the skeleton.
    pub joint: usize,
    /// Motion applied to the joint's reference world transform (pivot usually the joint's
    /// reference position).
    pub transform: RigidTransform,
}

/// What a pose solve must respect. Vertex indices are *welded* (map render indices with
/// `model.topology().welded_set(..)`). Targets are rigid motions of where the vertices (or
/// joints) were in the reference pose given to [`PoseSolver::new`]. The *sets* fix the
/// precompute; the transforms may change every solve.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseConstraints {
    /// Vertex sets moved rigidly (grab the hand's vertices).
    pub handles: Vec<Handle>,
    /// Vertices kept where they were in the reference pose.
    pub fixed_vertices: Vec<u32>,
    /// Joints kept where they were in the reference pose, position and orientation (pin the
    /// feet).
    pub fixed_joints: Vec<usize>,
    /// Joints moved rigidly (grab the hand joint).
    pub joint_handles: Vec<JointHandle>,
    /// Effectors on joints: positions, orientations, aims, each blended in by a weight (see
    /// [`crate::pose::constraints::effectors`]). They may change freely between solves.
    pub effectors: Vec<Effector>,
    /// Centroids of vertex sets to world points.
    pub centroid_effectors: Vec<CentroidEffector>,
    /// A per-joint pull towards a reference pose ("preferred angles").
    pub stiffness: Option<ReferenceStiffness>,
    /// Joint limits every step respects ([`crate::pose::constraints::limits`]); `None` = every joint free.
    pub limits: Option<Arc<JointLimits>>,
    /// The centre of mass kept over the support polygon ([`crate::pose::ground::balance`]); it may change
    /// freely between solves.
    pub balance: Option<Balance>,
    /// Skin patches on the ground, free or planted ([`crate::pose::ground::contact`]); they may change
    /// freely between solves.
    pub contacts: Vec<Contact>,
    /// Every skin vertex near the ground kept above it ([`crate::pose::ground::floor`]).
    pub floor: Option<Floor>,
    /// The pose whose shape the ARAP energy keeps (`None`: the bind pose). With it, the
    /// energy is tilted so this pose is at rest: a solve with nothing pulling leaves it as it
    /// is, and effectors bend the body away from it (an additive layer sets it to the
    /// animation under it; see `shape_rest.rs`). The energies in [`PoseSolveStats`] are then
    /// relative to it and may be negative.
    pub shape_rest: Option<SkeletonPose>,
}

impl PoseConstraints {
    pub(crate) fn same_sets(&self, other: &PoseConstraints) -> bool {
        self.fixed_vertices == other.fixed_vertices
            && self.fixed_joints == other.fixed_joints
            && same_keys(&self.handles, &other.handles, |h| &h.vertices)
            && same_keys(&self.joint_handles, &other.joint_handles, |h| &h.joint)
    }
}
