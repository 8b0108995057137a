//! The humanoid limits preset ([`JointLimits::humanoid`]): limits for every joint whose name
//! has a humanoid role ([`crate::pose::rig::humanoid`]), measured from the rest pose.

use crate::pose::constraints::limits::{JointLimit, JointLimits};
use crate::pose::rig::humanoid::{HumanoidRole, humanoid_role, split_name};
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};
use glam::{DQuat, DVec3};

impl JointLimits {
    /// The humanoid preset: limits for every joint whose name has a humanoid role (see
    /// [`crate::pose::rig::humanoid`]), measured from `rest`. Returns the limits and, for each limited
    /// joint, its name and role, so an app can show what was recognised.
    pub fn humanoid(
        skeleton: &Skeleton,
        rest: &SkeletonPose,
    ) -> (Self, Vec<(String, HumanoidRole)>) {
        let mut limits = JointLimits::new(skeleton, rest);
        let globals = skeleton.global_transforms(rest);
        let frame =
            |j: usize| -> DQuat { crate::pose::rig::skeleton::rotation_of(&globals[j].matrix3) };
        let root_frame = skeleton.joints().first().map_or(DQuat::IDENTITY, |j| {
            crate::pose::rig::skeleton::rotation_of(&j.parent_frame.matrix3)
        });
        let forward = root_frame * DVec3::Z;
        let mut found = Vec::new();
        // Rigs named after joints (`shoulder_l`, `elbow_l`) rather than bones: a "shoulder"
        // with no upper-arm joint on its side is the upper arm itself.
        let roles: Vec<Option<HumanoidRole>> = skeleton
            .joints()
            .iter()
            .map(|j| humanoid_role(&j.name))
            .collect();
        let side_of = |j: usize| split_name(&skeleton.joints()[j].name).1;
        let has_upper_arm = |side| {
            (0..roles.len()).any(|k| roles[k] == Some(HumanoidRole::UpperArm) && side_of(k) == side)
        };
        for (j, joint) in skeleton.joints().iter().enumerate() {
            let Some(mut role) = roles[j] else {
                continue;
            };
            if role == HumanoidRole::Clavicle && !has_upper_arm(side_of(j)) {
                role = HumanoidRole::UpperArm;
            }
            // The bone's world direction at rest: towards its first child.
            let bone = skeleton
                .children(j)
                .first()
                .map(|&c| globals[c].translation - globals[j].translation)
                .filter(|d| d.length_squared() > 1e-18)
                .map_or(frame(j) * DVec3::Y, DVec3::normalize);
            let hinge = |axis_world: DVec3| {
                let axis = frame(j).inverse() * axis_world.normalize_or(DVec3::X);
                JointLimit::hinge_deg(axis, -5.0, 150.0)
            };
            use HumanoidRole::*;
            let limit = match role {
                Spine => JointLimit::cone_deg((30.0, 30.0), (-30.0, 30.0)),
                Neck => JointLimit::cone_deg((45.0, 45.0), (-60.0, 60.0)),
                Head => JointLimit::cone_deg((40.0, 40.0), (-45.0, 45.0)),
                Clavicle => JointLimit::cone_deg((20.0, 20.0), (-10.0, 10.0)),
                UpperArm => JointLimit::cone_deg((100.0, 100.0), (-90.0, 90.0)),
                Elbow => hinge(bone.cross(forward)),
                Wrist => JointLimit::cone_deg((70.0, 45.0), (-30.0, 30.0)),
                Hip => JointLimit::cone_deg((90.0, 60.0), (-45.0, 45.0)),
                Knee => hinge(forward.cross(bone)),
                Ankle => JointLimit::cone_deg((40.0, 30.0), (-20.0, 20.0)),
                Toes => JointLimit::cone_deg((40.0, 10.0), (-5.0, 5.0)),
            };
            if limits.set(j, limit).is_ok() {
                found.push((joint.name.clone(), role));
            }
        }
        (limits, found)
    }
}
