//! The blend layer: a [`Poseable`](super::Poseable) character's pose blended over the
//! animation that plays on its joints, by a weight, in override or additive mode, optionally
//! on a mask of joints. The per-joint math is [`crate::pose::animation::blend`]; the system is in
//! [`PoseSystems::Apply`](super::PoseSystems::Apply) (`PostUpdate`, after `AnimationSystems`,
//! before transform propagation).

use bevy::ecs::entity::MapEntities;
use bevy::prelude::*;

use super::PosedSkeleton;
use super::convert::joint_transform;
use crate::pose::{BlendMode, Skeleton, SkeletonPose, additive_layer_for};

/// Blends a [`Poseable`](super::Poseable) character's pose ([`super::PosedSkeleton::pose`])
/// over what the animation put on its joints this frame. Without it, the pose replaces the
/// joints ([`super::Poseable::hold_pose`]).
///
/// - `weight` 0 is the clip, 1 the pose; animate it (a system, a curve, a tween) to fade a
///   pose in and out.
/// - [`PoseBlendMode::Override`] mixes the animated and the posed local transforms.
/// - [`PoseBlendMode::Additive`] adds the pose's difference from `reference` (the bind pose
///   when `None`) on top of the animation: the walk cycle keeps walking, bent as posed. In
///   this mode handles and effectors are solved against the pose on screen (the animation plus
///   the layer) and re-solved while the animation moves, so a look-at keeps looking while the
///   character walks; the solved pose is stored as the layer that gives it over the current
///   animation.
/// - `mask`: only these joints take the blend; the others keep the clip.
///
/// The animation this blends over is read from the joints each frame: what a playing (or
/// paused) `AnimationPlayer` wrote. When nothing writes them, the last animated values are
/// kept, so the blend never feeds on its own output.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Default)]
pub struct PoseBlend {
    /// In [0, 1]: 0 = the clip, 1 = the pose.
    pub weight: f32,
    /// Override or additive.
    pub mode: PoseBlendMode,
    /// Joints that take the blend (all when `None`).
    #[entities]
    pub mask: Option<JointMask>,
    /// Additive mode's reference pose (local transforms in the skeleton's joint order); the
    /// bind pose when `None`.
    #[reflect(ignore)]
    pub reference: Option<SkeletonPose>,
}

impl Default for PoseBlend {
    fn default() -> Self {
        Self {
            weight: 1.0,
            mode: PoseBlendMode::Override,
            mask: None,
            reference: None,
        }
    }
}

impl PoseBlend {
    /// Override blend by `weight`.
    pub fn overriding(weight: f32) -> Self {
        Self {
            weight,
            ..Default::default()
        }
    }

    /// Additive blend by `weight` over the bind pose.
    pub fn additive(weight: f32) -> Self {
        Self {
            weight,
            mode: PoseBlendMode::Additive,
            ..Default::default()
        }
    }

    /// The additive reference for `skeleton`: `reference` when it fits the skeleton, else the
    /// bind pose.
    pub fn reference_pose(&self, skeleton: &Skeleton) -> SkeletonPose {
        self.reference
            .clone()
            .filter(|r| skeleton.check_pose(r).is_ok())
            .unwrap_or_else(|| skeleton.bind_pose())
    }

    /// The same blend on a mask of joints.
    pub fn with_mask(mut self, mask: JointMask) -> Self {
        self.mask = Some(mask);
        self
    }
}

/// How a [`PoseBlend`] combines the pose with the animation.
#[derive(Reflect, Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum PoseBlendMode {
    /// Mix from the animated local transforms to the posed ones (slerp/lerp).
    #[default]
    Override,
    /// The pose's difference from the reference pose, applied on top of the animation.
    Additive,
}

impl From<PoseBlendMode> for BlendMode {
    fn from(mode: PoseBlendMode) -> Self {
        match mode {
            PoseBlendMode::Override => BlendMode::Override,
            PoseBlendMode::Additive => BlendMode::Additive,
        }
    }
}

/// The joints a [`PoseBlend`] acts on: by entity and by name (the glTF node name), with
/// their descendants when `include_children` is set. Names the skeleton lacks select nothing.
#[derive(Reflect, MapEntities, Debug, Clone, Default, PartialEq)]
pub struct JointMask {
    /// Joint entities.
    #[entities]
    pub joints: Vec<Entity>,
    /// Joint names.
    pub names: Vec<String>,
    /// Also every joint below a selected one.
    pub include_children: bool,
}

impl JointMask {
    /// Joints by name (e.g. `["b_Neck_04"]`), with or without their children.
    pub fn names<S: Into<String>>(
        names: impl IntoIterator<Item = S>,
        include_children: bool,
    ) -> Self {
        Self {
            joints: Vec::new(),
            names: names.into_iter().map(Into::into).collect(),
            include_children,
        }
    }

    /// Per joint of `skeleton` (joint entities in `joints`, same order): whether it is
    /// selected.
    pub fn selects(&self, skeleton: &Skeleton, joints: &[Entity]) -> Vec<bool> {
        let mut out: Vec<bool> = skeleton
            .joints()
            .iter()
            .zip(joints)
            .map(|(joint, entity)| self.joints.contains(entity) || self.names.contains(&joint.name))
            .collect();
        out.resize(skeleton.len(), false);
        if self.include_children {
            // Parents come before their children.
            for (j, joint) in skeleton.joints().iter().enumerate() {
                if joint.parent.is_some_and(|p| out[p]) {
                    out[j] = true;
                }
            }
        }
        out
    }
}

/// What the blend layer remembers between frames (part of the character's internal state,
/// see `state.rs`).
#[derive(Component, Debug, Default)]
pub(super) struct BlendMemory {
    /// The animated local transforms the blend last read (per joint).
    pub(super) animated: Vec<Transform>,
    /// What the blend last wrote (per joint): a joint still holding it was not animated since.
    pub(super) written: Vec<Transform>,
    /// The resolved mask (per joint) and the reference pose, rebuilt when the blend changes.
    pub(super) mask: Option<Vec<bool>>,
    pub(super) reference: Option<SkeletonPose>,
    /// The animation moved a joint in the last blend (an additive layer re-solves then).
    pub(super) moved: bool,
}

impl BlendMemory {
    /// Reads this frame's animated transforms from the joints' current ones (`current[j]`),
    /// keeping the remembered value of a joint that still holds what the blend wrote.
    pub(super) fn read_animation(&mut self, current: &[Option<Transform>]) {
        self.animated.resize(current.len(), Transform::IDENTITY);
        self.written
            .resize(current.len(), Transform::from_scale(Vec3::NAN));
        self.moved = false;
        for (j, now) in current.iter().enumerate() {
            let animated = self.animated_now(j, *now);
            if animated != self.animated[j] {
                self.animated[j] = animated;
                self.moved = true;
            }
        }
    }

    /// This frame's animated pose as [`BlendMemory::read_animation`] would read it from the
    /// joints' current transforms, without remembering it (an in-frame solve reads it before
    /// the blend does).
    pub(super) fn peek_animation(&self, current: &[Option<Transform>]) -> SkeletonPose {
        SkeletonPose {
            local: current
                .iter()
                .enumerate()
                .map(|(j, now)| joint_transform(&self.animated_now(j, *now)))
                .collect(),
        }
    }

    /// Joint `j`'s animated transform given its current one: the current one, unless it is
    /// what the blend wrote (the animation did not touch the joint) or missing.
    fn animated_now(&self, j: usize, now: Option<Transform>) -> Transform {
        let kept = self.animated.get(j).copied().unwrap_or(Transform::IDENTITY);
        match now {
            Some(now) if Some(&now) != self.written.get(j) => now,
            _ => kept,
        }
    }

    /// The remembered animated pose, as a skeleton pose.
    pub(super) fn animated_pose(&self) -> SkeletonPose {
        SkeletonPose {
            local: self.animated.iter().map(joint_transform).collect(),
        }
    }

    /// Forgets everything (the blend was removed or the character re-prepared).
    pub(super) fn clear(&mut self) {
        *self = Self::default();
    }
}

/// The additive layer that shows `full` over `animated` (the animation the blend last read,
/// or this frame's for a solve inside the frame).
pub(super) fn additive_layer(
    posed: &PosedSkeleton,
    (memory, animated): (&BlendMemory, &SkeletonPose),
    blend: &PoseBlend,
    full: &SkeletonPose,
) -> SkeletonPose {
    let skeleton = posed.model.skeleton();
    let reference = memory
        .reference
        .clone()
        .unwrap_or_else(|| blend.reference_pose(skeleton));
    let local = full
        .local
        .iter()
        .enumerate()
        .map(
            |(j, f)| match (animated.local.get(j), reference.local.get(j)) {
                (Some(a), Some(r)) => additive_layer_for(a, f, r),
                _ => *f,
            },
        )
        .collect();
    SkeletonPose { local }
}
