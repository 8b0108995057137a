//! Writing the pose onto the joints in `PostUpdate`, after animation: held, or blended over
//! what the clip wrote ([`super::super::PoseBlend`]).

use bevy::prelude::*;

use super::super::blend::BlendMemory;
use super::super::convert::bevy_transform;
use super::super::{PoseBlend, Poseable, PosedSkeleton};
use crate::pose::{SkeletonPose, blend_pose};

/// What [`apply_poses`] reads and writes of a character.
type AppliedCharacter = (
    &'static Poseable,
    Ref<'static, PosedSkeleton>,
    Option<Ref<'static, PoseBlend>>,
    &'static mut BlendMemory,
);

/// Writes each character's pose to its joints: blended over the animation with a
/// [`PoseBlend`] (every frame), else every frame with `hold_pose` or when it changed.
pub(super) fn apply_poses(
    mut characters: Query<AppliedCharacter>,
    mut joints: Query<&mut Transform>,
) {
    for (poseable, posed, blend, mut memory) in &mut characters {
        let memory = memory.bypass_change_detection();
        let Some(blend) = blend else {
            memory.clear();
            if poseable.hold_pose || posed.is_changed() {
                write_pose(&posed.joints, &posed.pose, &mut joints, None);
            }
            continue;
        };
        let current: Vec<Option<Transform>> = posed
            .joints
            .iter()
            .map(|&j| joints.get(j).ok().copied())
            .collect();
        memory.read_animation(&current);
        let animated = memory.animated_pose();
        let skeleton = posed.model.skeleton();
        if blend.is_changed() || memory.mask.is_none() && blend.mask.is_some() {
            memory.mask = blend
                .mask
                .as_ref()
                .map(|m| m.selects(skeleton, &posed.joints));
            memory.reference = None;
        }
        let reference = memory
            .reference
            .get_or_insert_with(|| blend.reference_pose(skeleton));
        let out = blend_pose(
            &animated,
            &posed.pose,
            reference,
            blend.mode.into(),
            f64::from(blend.weight),
            memory.mask.as_deref(),
        );
        write_pose(&posed.joints, &out, &mut joints, Some(&mut memory.written));
    }
}

/// Writes local transforms to the joint entities (skipping invalid ones); `written` records
/// what each joint holds afterwards.
fn write_pose(
    entities: &[Entity],
    pose: &SkeletonPose,
    joints: &mut Query<&mut Transform>,
    mut written: Option<&mut Vec<Transform>>,
) {
    for (k, (&j, t)) in entities.iter().zip(&pose.local).enumerate() {
        if !t.is_valid() {
            continue;
        }
        let Ok(mut transform) = joints.get_mut(j) else {
            continue;
        };
        let new = bevy_transform(t);
        if *transform != new {
            *transform = new;
        }
        if let Some(slot) = written.as_deref_mut().and_then(|w| w.get_mut(k)) {
            *slot = new;
        }
    }
}
