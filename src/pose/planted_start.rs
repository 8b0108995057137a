//! Where a standing character's solve starts its planted limbs.
//!
//! Under an additive layer a solve starts each frame from the animation's new pose with the
//! last layer added ([`crate::pose::blend_pose`]). For a limb whose foot is planted that start
//! is a poor guess: the layer was solved against last frame's animation, and the clip moves the
//! stance leg on (at its own speed, on flat ground), so the start puts a planted paw 1–2 % of
//! the model's size off the points it is held at, and the solve spends its iterations bringing
//! it back (measured on the walking crowd: median 1.2 % of the size off at the start, 1.35 of
//! its 4.5 iterations a solve past the budget only to meet the holds).
//!
//! [`ContactTracker::carry_planted_limbs`] starts a planted limb where the last solve left it
//! instead — its joints' rotations as solved — and re-aims it at its holds as the character
//! moved since: the limb's top joint turned so that the patch points at the held points, the
//! contact's joint turned back so that the sole keeps its tilt. It only moves the start: the
//! solve still meets the holds, the floor, the limits and balance itself.

use glam::{DQuat, DVec3};

use super::{ContactTracker, SkeletonPose, SkinnedModel};

/// The largest re-aim of a limb's top joint, radians: a hold far from where the limb points (a
/// first frame, a teleport) is left to the solve.
const MAX_REAIM: f64 = 0.35;

impl ContactTracker {
    /// Starts every planted contact's limb (its joint's subtree and the chain above it up to
    /// the first joint with other children, never the root) at its rotations in `last` (the
    /// last solved pose of `model`), re-aimed at the contact's held points (see the module
    /// docs). Returns how many limbs were carried; `start` is left as it was when `last` is
    /// not a finite pose of the same skeleton, or a carried start would not be finite, and a
    /// contact whose patch is not the model's is skipped.
    pub fn carry_planted_limbs(
        &self,
        model: &SkinnedModel,
        last: &SkeletonPose,
        start: &mut SkeletonPose,
    ) -> usize {
        let skeleton = model.skeleton();
        let joints = skeleton.len();
        if last.local.len() != joints
            || start.local.len() != joints
            || !last.local.iter().all(|t| t.is_valid())
        {
            return 0;
        }
        let before = start.clone();
        let vertices = model.bind_positions().len();
        let mut carried = 0;
        for contact in &self.contacts {
            let Some(held) = contact.planted.as_deref() else {
                continue;
            };
            if contact.patch.iter().any(|&v| v as usize >= vertices) {
                continue; // a patch of another model
            }
            let Some(top) = limb_top(skeleton, contact.joint) else {
                continue;
            };
            let mut stack = vec![contact.joint];
            while let Some(j) = stack.pop() {
                start.local[j].rotation = last.local[j].rotation;
                stack.extend_from_slice(skeleton.children(j));
            }
            let mut j = contact.joint;
            while j != top {
                j = skeleton.joints()[j].parent.unwrap_or(top);
                start.local[j].rotation = last.local[j].rotation;
            }
            if held.len() == contact.patch.len() && !held.is_empty() {
                reaim(model, (top, contact.joint), (&contact.patch, held), start);
            }
            carried += 1;
        }
        if !start.local.iter().all(|t| t.is_valid()) {
            *start = before;
            return 0;
        }
        carried
    }
}

/// The top joint of `joint`'s limb: the highest ancestor (or `joint` itself) reached without
/// passing a joint that carries other children too; `None` for a root joint (its limb would be
/// the whole body).
fn limb_top(skeleton: &super::Skeleton, joint: usize) -> Option<usize> {
    let joints = skeleton.joints();
    let mut top = joint;
    joints.get(joint)?.parent?;
    while let Some(parent) = joints[top].parent {
        if joints[parent].parent.is_none() || skeleton.children(parent).len() > 1 {
            break;
        }
        top = parent;
    }
    Some(top)
}

/// Turns the limb's `top` joint about its origin so that the patch's centroid points where its
/// held points' centroid is (at most [`MAX_REAIM`]), and the contact's `joint` back by as much
/// (its sole keeps its tilt).
fn reaim(
    model: &SkinnedModel,
    (top, joint): (usize, usize),
    (patch, held): (&[u32], &[DVec3]),
    start: &mut SkeletonPose,
) {
    let skeleton = model.skeleton();
    let globals = skeleton.global_transforms(start);
    let origin = globals[top].translation;
    let at = model.skinned_centroid(start, patch) - origin;
    let goal = held.iter().sum::<DVec3>() / held.len() as f64 - origin;
    let (Some(from), Some(to)) = (at.try_normalize(), goal.try_normalize()) else {
        return;
    };
    let turn = DQuat::from_rotation_arc(from, to);
    let angle = turn.angle_between(DQuat::IDENTITY);
    if !angle.is_finite() || angle < 1e-9 {
        return;
    }
    let turn = match angle > MAX_REAIM {
        true => DQuat::IDENTITY.slerp(turn, MAX_REAIM / angle),
        false => turn,
    };
    // A world-space turn at a joint is its parent's frame's conjugate of it, locally.
    let parent = skeleton.parent_rotation(&globals, top);
    let local = &mut start.local[top].rotation;
    *local = (parent.inverse() * turn * parent * *local).normalize();
    if joint != top {
        let globals = skeleton.global_transforms(start);
        let parent = skeleton.parent_rotation(&globals, joint);
        let local = &mut start.local[joint].rotation;
        *local = (parent.inverse() * turn.inverse() * parent * *local).normalize();
    }
}
