//! Why a skinned model, pose or pose solve was rejected.

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
