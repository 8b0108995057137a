//! Posing rigged characters: As-Rigid-As-Possible deformation in skinning space, with a
//! skeleton pose as the result. Pure math on `glam`; no Bevy.
//!
//! A game character is a skinned mesh (bind-pose positions, up to four joint weights per
//! vertex) and a skeleton. Posing it means finding joint transforms, not moving vertices:
//! following "Fast Automatic Skinning Transformations" (Jacobson et al. 2012), the mesh's
//! ARAP energy is minimised over the poses the skin can express, `p'_i = Σ_j w_ij S_j p_i`.
//! [`SkinnedModel`] welds the mesh as the static solver does, clusters vertices by weight
//! (one rotation per cluster) and reduces every energy matrix to the joints once;
//! [`PoseSolver`] then iterates at a cost independent of the vertex count. Its unknowns are
//! rigid bones (see [`PoseSolver`]), so the result is always a valid skeleton pose.
//!
//! ```
//! use std::sync::Arc;
//! use bevy_wii_deform::pose::*;
//! use bevy_wii_deform::deform::{Handle, RigidTransform};
//! use glam::{DQuat, DVec3};
//!
//! // A bar skinned to a chain of three bones along +y.
//! let rig = synth_rig::bar_rig(3, 12, 24);
//! let model = Arc::new(SkinnedModel::new(
//!     rig.skeleton.clone(), &rig.mesh, &rig.rest, ModelSettings::default()).unwrap());
//! // Hold the bottom, grab the top and swing it sideways.
//! let top = rig.vertices_where(&model, |p| p.y > 0.95);
//! let bottom = rig.vertices_where(&model, |p| p.y < 0.05);
//! let mut constraints = PoseConstraints {
//!     handles: vec![Handle { vertices: top, transform: RigidTransform::IDENTITY }],
//!     fixed_vertices: bottom,
//!     ..Default::default()
//! };
//! let solver = PoseSolver::new(model.clone(), &constraints, &rig.rest,
//!     PoseSolverSettings::default()).unwrap();
//! constraints.handles[0].transform.translation = DVec3::new(0.3, -0.05, 0.0);
//! let solved = solver.solve(&constraints, &PoseSolveOptions::default(), PoseStart::Pose(&rig.rest), &|| false)
//!     .unwrap();
//! // Bones keep their lengths: the result is a skeleton pose.
//! assert!(max_bone_length_error(model.skeleton(), &rig.rest, &solved.pose) < 1e-9);
//! ```

pub mod balance;
pub mod blend;
pub mod capsules;
pub mod clip;
pub mod contacts;
pub mod effectors;
mod file;
pub mod floor;
pub mod gait;
pub mod gltf_clip;
pub mod ground;
pub mod humanoid;
mod inertia;
pub mod library;
pub mod limits;
pub mod mirror;
mod model;
pub mod placement;
mod planted_start;
mod skeleton;
mod solver;
pub mod springs;
pub mod synth_rig;
mod triangle_ground;

pub use balance::{AllowedRegion, Balance, SupportPolygon, centre_of_mass, vertex_masses};
pub use blend::{BlendMode, additive_layer_for, blend_joint, blend_pose};
pub use capsules::{BoneCapsule, fit_bone_capsules};
pub use clip::{ClipError, KEY_TIME_EPSILON, KeyInterpolation, PoseClip, PoseKey};
pub use contacts::{Contact, GroundPlane, Rolling};
pub use effectors::{
    CentroidEffector, Effector, EffectorGoal, ReferenceStiffness, StiffnessWeighting,
};
pub use file::{PoseFile, PoseFileError};
pub use floor::{Floor, FloorCastStats, FloorSampling};
pub use gait::GaitPhases;
pub use gltf_clip::{read_gltf_clip, write_gltf_clip, write_gltf_pose_clip};
pub use ground::{ContactEvent, ContactTracker, Ground, TriangleGround, lowest_joints, sole_patch};
pub use humanoid::{HumanoidRole, Side, humanoid_role};
pub use library::PoseLibrary;
pub use limits::{JointLimit, JointLimits, LimitError};
pub use mirror::{Mirror, mirror_partners};
pub use model::{ModelSettings, SkinnedMesh, SkinnedModel};
pub use skeleton::{
    Joint, JointTransform, Skeleton, SkeletonPose, VertexInfluences, skin_positions,
};
pub use solver::{
    JointHandle, OFF_THE_HOLD, PoseConstraints, PoseSolution, PoseSolveOptions, PoseSolveStats,
    PoseSolver, PoseSolverSettings, PoseStart, THROUGH_THE_GROUND,
};
pub use springs::{
    SpringChain, SpringCollider, SpringColliderShape, SpringError, SpringJoint, SpringRig,
    SpringRonError, SpringSettings, SpringState, VrmSpringError, read_vrm_springs, step_springs,
};

use crate::deform::MeshError;

/// Why a skinned model, pose or pose solve was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseError {
    /// The skeleton has no joints.
    #[error("the skeleton has no joints")]
    NoJoints,
    /// A joint's parent is out of range, not before it, or part of a cycle.
    #[error("joint {joint} has parent {parent}, which is out of range or not before it")]
    JointOrder {
        /// The joint.
        joint: usize,
        /// Its parent index.
        parent: usize,
    },
    /// A joint matrix or transform is NaN/infinite (or a rotation is not unit length).
    #[error("joint {joint} has a non-finite transform")]
    NonFiniteJoint {
        /// The joint.
        joint: usize,
    },
    /// A pose has the wrong number of joints.
    #[error("the pose has {got} joints, the skeleton has {expected}")]
    PoseLength {
        /// Joints in the pose.
        got: usize,
        /// Joints in the skeleton.
        expected: usize,
    },
    /// Positions, joint indices and weights have different lengths.
    #[error(
        "skin attributes differ in length: {positions} positions, {joints} joint sets, {weights} weight sets"
    )]
    AttributeLength {
        /// Number of positions.
        positions: usize,
        /// Number of joint index sets.
        joints: usize,
        /// Number of weight sets.
        weights: usize,
    },
    /// A weight is negative, NaN or infinite.
    #[error("vertex {vertex} has a negative or non-finite skin weight")]
    InvalidWeight {
        /// The render vertex.
        vertex: usize,
    },
    /// A weighted joint index is not a joint of the skeleton.
    #[error("vertex {vertex} is weighted to joint {joint}, the skin has {joint_count} joints")]
    JointIndexOutOfRange {
        /// The render vertex.
        vertex: usize,
        /// The joint index.
        joint: usize,
        /// Joints in the skin.
        joint_count: usize,
    },
    /// All of a vertex' weights are zero: nothing moves it.
    #[error("vertex {vertex} has no skin weight")]
    UnweightedVertex {
        /// The render vertex.
        vertex: usize,
    },
    /// The skinning matrices are singular or not finite at the reference pose.
    #[error("the skinning matrices are degenerate (zero or non-finite scale)")]
    DegenerateSkinning,
    /// The mesh itself is invalid.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A constrained vertex is out of range.
    #[error("constrained vertex {vertex} is out of range for {vertex_count} welded vertices")]
    VertexOutOfRange {
        /// The vertex.
        vertex: u32,
        /// Welded vertex count.
        vertex_count: usize,
    },
    /// A constrained joint is out of range.
    #[error("constrained joint {joint} is out of range for {joint_count} joints")]
    JointOutOfRange {
        /// The joint.
        joint: usize,
        /// Joint count.
        joint_count: usize,
    },
    /// A handle transform is NaN/infinite or its rotation is not unit length.
    #[error("a handle transform is not finite (or its rotation is not unit)")]
    NonFiniteTarget,
    /// An effector or stiffness weight outside [0, 1] (or NaN).
    #[error("a constraint weight is {weight}, outside [0, 1]")]
    InvalidConstraintWeight {
        /// The weight given.
        weight: f64,
    },
    /// The solve was given constraints whose sets differ from the precomputed ones.
    #[error("constraint sets changed since the solver was built; build it again")]
    ConstraintSetChanged,
    /// A [`Balance`] that cannot be used: no support point, a non-finite one, a zero or
    /// non-finite gravity, a negative or non-finite margin, or masses of the wrong count or
    /// not finite and non-negative.
    #[error("the balance constraint is invalid: {0}")]
    InvalidBalance(&'static str),
    /// A [`Contact`] or [`Floor`] that cannot be used: a non-finite or non-unit ground
    /// normal, a non-finite point, planted positions not one per patch vertex, a zero `up`
    /// axis, or a negative band.
    #[error("a ground contact is invalid: {0}")]
    InvalidContact(&'static str),
    /// The solve produced a non-finite pose (nothing is returned).
    #[error("the solve produced a non-finite pose")]
    NonFiniteResult,
}

/// Largest change of a bone's world length (distance from a joint to its parent) between two
/// poses, in skeleton-space units. 0 for a skeleton posed by rotations only.
pub fn max_bone_length_error(skeleton: &Skeleton, a: &SkeletonPose, b: &SkeletonPose) -> f64 {
    let (ga, gb) = (skeleton.global_transforms(a), skeleton.global_transforms(b));
    let mut worst = 0.0f64;
    for (j, joint) in skeleton.joints().iter().enumerate() {
        if let Some(p) = joint.parent {
            let la = ga[j].translation.distance(ga[p].translation);
            let lb = gb[j].translation.distance(gb[p].translation);
            worst = worst.max((la - lb).abs());
        }
    }
    worst
}

/// The angle (radians, in [0, π]) of the rotation from `a` to `b`: `q` and `-q` are the same
/// rotation. Stable near zero, where `2 acos |a · b|` loses half its digits.
pub fn rotation_angle(a: glam::DQuat, b: glam::DQuat) -> f64 {
    let (a, b) = (a.normalize(), b.normalize());
    let b = if a.dot(b) < 0.0 { -b } else { b };
    4.0 * (a - b).length().atan2((a + b).length())
}
