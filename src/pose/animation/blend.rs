//! Blending a pose over an animated pose, per joint: the math of the ECS blend layer
//! ([`crate::ecs::PoseBlend`]), on plain local transforms.
//!
//! - **Override**: `out = mix(animated, pose, w)`: translations and scales lerp, rotations
//!   slerp (shortest arc). Weight 0 is the animation, 1 the pose.
//! - **Additive**: the pose's difference from a `reference` pose (the bind pose by default in
//!   the ECS) on top of the animation: `out.rotation = animated.rotation · slerp(1, reference⁻¹ ·
//!   pose, w)`, `out.translation = animated + w (pose − reference)`, `out.scale = animated ·
//!   lerp(1, pose / reference, w)`. A pose equal to the reference leaves the animation as it
//!   is; a walk cycle keeps walking with the pose's bend added.
//!
//! [`additive_layer_for`] inverts the additive blend at weight 1: the layer pose that puts a
//! joint at a given full pose over a given animated pose, so a pose solved in the world
//! (effectors, handles) becomes a layer that follows the animation.

use glam::{DQuat, DVec3};

use crate::pose::rig::skeleton::{JointTransform, SkeletonPose};

/// How a pose is blended over the animation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum BlendMode {
    /// Mix from the animated transforms to the pose's.
    #[default]
    Override,
    /// Add the pose's difference from a reference pose on top of the animation.
    Additive,
}

/// One joint: `animated` blended with `pose` by `weight` (clamped to [0, 1]); `reference` is
/// used by [`BlendMode::Additive`] only.
pub fn blend_joint(
    animated: &JointTransform,
    pose: &JointTransform,
    reference: &JointTransform,
    mode: BlendMode,
    weight: f64,
) -> JointTransform {
    let w = weight.clamp(0.0, 1.0);
    match mode {
        BlendMode::Override => JointTransform {
            translation: animated.translation.lerp(pose.translation, w),
            rotation: animated.rotation.slerp(pose.rotation, w).normalize(),
            scale: animated.scale.lerp(pose.scale, w),
        },
        BlendMode::Additive => {
            let delta = reference.rotation.inverse() * pose.rotation;
            JointTransform {
                translation: animated.translation + (pose.translation - reference.translation) * w,
                rotation: (animated.rotation * DQuat::IDENTITY.slerp(delta, w)).normalize(),
                scale: animated.scale * DVec3::ONE.lerp(ratio(pose.scale, reference.scale), w),
            }
        }
    }
}

/// Every joint of `animated` blended with `pose` (see [`blend_joint`]); joints whose `mask`
/// entry is false keep the animation. All poses must have one joint count (extra joints of
/// `animated` are kept as they are).
pub fn blend_pose(
    animated: &SkeletonPose,
    pose: &SkeletonPose,
    reference: &SkeletonPose,
    mode: BlendMode,
    weight: f64,
    mask: Option<&[bool]>,
) -> SkeletonPose {
    let local = animated
        .local
        .iter()
        .enumerate()
        .map(|(j, a)| {
            let masked_in = mask.is_none_or(|m| m.get(j).copied().unwrap_or(false));
            match (pose.local.get(j), reference.local.get(j)) {
                (Some(p), Some(r)) if masked_in => blend_joint(a, p, r, mode, weight),
                _ => *a,
            }
        })
        .collect();
    SkeletonPose { local }
}

/// The additive layer that puts the joint at `full` over `animated` at weight 1:
/// `blend_joint(animated, additive_layer_for(animated, full, reference), reference, Additive,
/// 1) == full`.
pub fn additive_layer_for(
    animated: &JointTransform,
    full: &JointTransform,
    reference: &JointTransform,
) -> JointTransform {
    JointTransform {
        translation: reference.translation + (full.translation - animated.translation),
        rotation: (reference.rotation * animated.rotation.inverse() * full.rotation).normalize(),
        scale: reference.scale * ratio(full.scale, animated.scale),
    }
}

/// Component-wise `a / b`, 1 where `b` is zero.
fn ratio(a: DVec3, b: DVec3) -> DVec3 {
    DVec3::select(b.cmpeq(DVec3::ZERO), DVec3::ONE, a / b)
}
