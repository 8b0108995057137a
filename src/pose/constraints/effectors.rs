//! Effectors and reference stiffness: the pose solver's constraints beyond vertex handles and
//! joint pins, each a weighted least-squares term in the bone parameters.
//!
//! * [`EffectorGoal::Position`]: a joint's origin to a world point, its orientation free (plant
//!   a foot and let the ankle turn);
//! * [`EffectorGoal::Orientation`]: a joint's world rotation, its position free;
//! * [`EffectorGoal::Aim`]: a joint's local axis points at a world point (a head looking at
//!   something), with an optional up axis;
//! * [`CentroidEffector`]: the centroid of a vertex set to a world point;
//! * [`ReferenceStiffness`]: per joint, a pull towards a reference pose's local rotation (the
//!   animation's current pose, or the bind pose), so joints nothing pulls on stay where they
//!   were — Unreal's "preferred angles".
//!
//! **Weights.** A weight `w` in [0, 1] blends a constraint in: its target moves from where the
//! joint (or centroid) is in the solver's reference pose towards the goal by `w`, and its
//! strength fades in over `w` ∈ [0, ¼]. So `w = 0` is exactly the solve without the
//! constraint, `w = 1` meets a reachable goal, and `w = ½` asks for the halfway target.
//! A pinned joint ([`crate::pose::constraints::PoseConstraints::fixed_joints`]) and a joint handle are a position
//! and an orientation effector of weight 1 at once, kept in the solver's quadratic form.

use crate::pose::rig::mirror::Mirror;
use crate::pose::rig::skeleton::rotation_of;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};
use glam::{DAffine3, DMat3, DQuat, DVec3};

/// What an effector asks of its joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EffectorGoal {
    /// The joint's origin at this world point.
    Position(DVec3),
    /// The joint's world rotation.
    Orientation(DQuat),
    /// The joint's local `axis` points at the world point `target`; with `up`, its local
    /// `up.0` turns towards the world direction `up.1` about the aim.
    Aim {
        /// The aiming axis in the joint's frame (e.g. the head's forward).
        axis: DVec3,
        /// The point to look at, world space.
        target: DVec3,
        /// Optional (local up axis, world up direction).
        up: Option<(DVec3, DVec3)>,
    },
}

/// A goal for one joint, blended in by `weight` (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effector {
    /// Joint index in the skeleton.
    pub joint: usize,
    /// What it asks.
    pub goal: EffectorGoal,
    /// Weight in [0, 1].
    pub weight: f64,
}

/// The centroid of a set of welded vertices to a world point, blended in by `weight`.
#[derive(Debug, Clone, PartialEq)]
pub struct CentroidEffector {
    /// Welded vertex indices of the model.
    pub vertices: Vec<u32>,
    /// Where their centroid should be, world space.
    pub target: DVec3,
    /// Weight in [0, 1].
    pub weight: f64,
}

/// A pull of each joint's local rotation (and each root's translation) towards `pose`.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceStiffness {
    /// The reference (the animation's current pose, or the bind pose).
    pub pose: SkeletonPose,
    /// Per joint, in [0, 1]: 1 holds a joint as firmly as one constrained vertex at the
    /// model's size; 0 leaves it free.
    pub per_joint: Vec<f64>,
    /// How `per_joint` is scaled joint by joint.
    pub weighting: StiffnessWeighting,
}

/// How a [`ReferenceStiffness`] weighs its joints against each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StiffnessWeighting {
    /// `per_joint` as it is: turning the hips costs what turning the neck costs.
    #[default]
    Uniform,
    /// `per_joint` times the share of the body the joint's rotation carries
    /// ([`crate::pose::rig::model::SkinnedModel::relative_inertia`]): the stiffness measured in how far the mesh
    /// moves, so a pull is met by the light joints near it before the heavy ones (a look-at
    /// turns the neck, not the hips).
    Inertia,
}

impl ReferenceStiffness {
    /// The same stiffness `k` on every joint.
    pub fn uniform(pose: SkeletonPose, k: f64) -> Self {
        let per_joint = vec![k; pose.local.len()];
        Self {
            pose,
            per_joint,
            weighting: StiffnessWeighting::Uniform,
        }
    }

    /// Stiffness `k` weighted by the share of the body each joint carries
    /// ([`StiffnessWeighting::Inertia`]).
    pub fn by_inertia(pose: SkeletonPose, k: f64) -> Self {
        Self {
            weighting: StiffnessWeighting::Inertia,
            ..Self::uniform(pose, k)
        }
    }
}

/// The pose's reference-relative check used by tests and benches: where each joint is.
pub fn joint_positions(skeleton: &Skeleton, pose: &SkeletonPose) -> Vec<DVec3> {
    skeleton
        .global_transforms(pose)
        .iter()
        .map(|g| g.translation)
        .collect()
}

impl Mirror {
    /// The effector that mirrors `effector` onto the partner of its joint, for a skeleton whose
    /// root's parent space is `frame` (world ← character): points reflected across the plane,
    /// rotations and local axes turned by the rest-pose correction. `None` for an unpaired
    /// joint (its mirror image is itself).
    pub fn mirror_effector(&self, effector: &Effector, frame: &DAffine3) -> Option<Effector> {
        let partner = *self.partner.get(effector.joint)?;
        if partner == effector.joint {
            return None;
        }
        let reflect_point = |p: DVec3| self.reflect_point(p, frame);
        let frame_rotation = DMat3::from_quat(rotation_of(&frame.matrix3));
        let c = self.correction[partner];
        let goal = match effector.goal {
            EffectorGoal::Position(p) => EffectorGoal::Position(reflect_point(p)),
            EffectorGoal::Orientation(q) => {
                let r = frame_rotation.transpose() * DMat3::from_quat(q);
                let mirrored = frame_rotation * (self.reflection * r * c);
                EffectorGoal::Orientation(rotation_of(&mirrored))
            }
            EffectorGoal::Aim { axis, target, up } => EffectorGoal::Aim {
                axis: c.transpose() * axis,
                target: reflect_point(target),
                up: up.map(|(local, world)| {
                    let world_in_frame = frame_rotation.transpose() * world;
                    (
                        c.transpose() * local,
                        frame_rotation * (self.reflection * world_in_frame),
                    )
                }),
            },
        };
        Some(Effector {
            joint: partner,
            goal,
            weight: effector.weight,
        })
    }
}
