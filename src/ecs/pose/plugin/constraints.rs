//! What a character's solve is asked: the constraint-set key that decides when handles are
//! rebased, and the conversion of handles, joint handles, effectors and limits into the pose
//! core's constraints.

use std::sync::Arc;

use bevy::prelude::*;

use super::super::{
    PoseAnchor, PoseEffector, PoseEffectorKind, PoseJointHandle, PoseLimits, PosedSkeleton,
};
use crate::deform::{Handle as CoreHandle, RigidTransform, centroid};
use crate::ecs::DeformHandle;
use crate::ecs::space::rotation_of_space;
use crate::pose::{
    CentroidEffector, Effector, EffectorGoal, JointHandle, JointLimits, LimitError, SkeletonPose,
};

/// Which handles and pins a solver was built for.
#[derive(Debug, Clone, Default)]
pub(super) struct SetKey {
    pub(super) handles: Vec<(Entity, Vec<u32>)>,
    pub(super) joint_handles: Vec<(Entity, Entity)>,
    pub(super) pins: Vec<Entity>,
    pub(super) anchor: PoseAnchor,
    pub(super) position_only: Vec<Entity>,
    pub(super) effectors: Vec<(Entity, Entity)>,
}

impl SetKey {
    /// True when the handles and pins now are the ones this key was made from (compared in
    /// place: this runs every frame).
    pub(super) fn matches(
        &self,
        handles: &[(Entity, Mut<DeformHandle>, Mut<Transform>)],
        joint_handles: &[(Entity, Mut<PoseJointHandle>, Mut<Transform>)],
        pins: &[Entity],
    ) -> bool {
        self.pins == pins
            && self.handles.len() == handles.len()
            && self
                .handles
                .iter()
                .zip(handles)
                .all(|((e, v), (f, h, _))| e == f && *v == h.vertices)
            && self.joint_handles.len() == joint_handles.len()
            && self
                .joint_handles
                .iter()
                .zip(joint_handles)
                .all(|((e, j), (f, h, _))| e == f && *j == h.joint)
    }
}

/// Rebases the handles of a character to `reference`: vertex handles' pivots to the world
/// centroid of their skinned vertices, joint handles' rests to the joint's world transform;
/// each `Transform` to its rest.
pub(super) fn rebase(
    posed: &PosedSkeleton,
    reference: &SkeletonPose,
    handles: &mut [(Entity, Mut<DeformHandle>, Mut<Transform>)],
    joint_handles: &mut [(Entity, Mut<PoseJointHandle>, Mut<Transform>)],
) {
    let model = &posed.model;
    let skinned = posed.to_world(model.skin_render(reference));
    for (_, h, t) in handles.iter_mut() {
        let c = centroid(&skinned, &h.vertices);
        h.pivot = Some(c.as_vec3());
        **t = Transform::from_translation(c.as_vec3());
    }
    let globals: Vec<glam::DAffine3> = model
        .skeleton()
        .global_transforms(reference)
        .iter()
        .map(|g| posed.placement * *g)
        .collect();
    for (_, h, t) in joint_handles.iter_mut() {
        let Some(j) = posed.joint_index(h.joint) else {
            continue;
        };
        let (_, rotation, translation) = globals[j].to_scale_rotation_translation();
        let rest = Transform::from_translation(translation.as_vec3())
            .with_rotation(rotation.as_quat().normalize());
        h.rest = Some(rest);
        **t = rest;
    }
}

/// The character's limits, resolved against its skeleton (cached until `PoseLimits` changes).
pub(crate) fn resolve_limits(
    posed: &PosedSkeleton,
    source: Option<&Ref<PoseLimits>>,
    cached: &mut Option<Arc<JointLimits>>,
) -> Result<Option<Arc<JointLimits>>, LimitError> {
    let Some(source) = source else {
        *cached = None;
        return Ok(None);
    };
    if let Some(limits) = cached.as_ref().filter(|_| !source.is_changed()) {
        return Ok(Some(limits.clone()));
    }
    let skeleton = posed.model.skeleton();
    let rest = skeleton.bind_pose();
    let limits = match &**source {
        PoseLimits::Humanoid => Arc::new(JointLimits::humanoid(skeleton, &rest).0),
        PoseLimits::Ron(text) => Arc::new(JointLimits::from_ron(text, skeleton, &rest)?),
        PoseLimits::Custom(limits) => limits.clone(),
    };
    *cached = Some(limits.clone());
    Ok(Some(limits))
}

/// The vertex handles of a character: rigid ones, and position-only ones as centroid
/// effectors (the centroid of the welded vertices, where it was in the reference pose, moved
/// by the handle's translation).
pub(super) fn vertex_handles(
    posed: &PosedSkeleton,
    reference: Option<&SkeletonPose>,
    handles: &[(Entity, Mut<DeformHandle>, Mut<Transform>)],
    followers: &[Entity],
) -> (Vec<CoreHandle>, Vec<CentroidEffector>) {
    let model = &posed.model;
    let follows = |e: &Entity| followers.binary_search(e).is_ok();
    let centroids = handles
        .iter()
        .filter(|(e, _, _)| follows(e))
        .filter_map(|(_, h, t)| {
            let vertices = model.topology().welded_set(&h.vertices);
            let at_reference = posed
                .placement
                .transform_point3(model.skinned_centroid(reference?, &vertices));
            let moved = (t.translation - h.pivot?).as_dvec3();
            Some(CentroidEffector {
                vertices,
                target: at_reference + moved,
                weight: 1.0,
            })
        })
        .collect();
    let rigid = handles
        .iter()
        .filter(|(e, _, _)| !follows(e))
        .map(|(_, h, t)| CoreHandle {
            vertices: model.topology().welded_set(&h.vertices),
            transform: h.rigid_transform(t),
        })
        .collect();
    (rigid, centroids)
}

/// A joint handle as the core takes it: the motion from its rest to its `Transform`.
pub(super) fn joint_handle(
    posed: &PosedSkeleton,
    h: &PoseJointHandle,
    t: &Transform,
) -> Option<JointHandle> {
    let joint = posed.joint_index(h.joint)?;
    let rest = h.rest?;
    let rotation = (t.rotation * rest.rotation.inverse())
        .as_dquat()
        .normalize();
    let transform = RigidTransform::new(
        rotation,
        (t.translation - rest.translation).as_dvec3(),
        rest.translation.as_dvec3(),
    );
    Some(JointHandle { joint, transform })
}

/// A [`PoseEffector`] as the core takes it, its goal read from its `GlobalTransform`.
pub(super) fn core_effector(
    posed: &PosedSkeleton,
    effector: &PoseEffector,
    global: &GlobalTransform,
) -> Option<Effector> {
    let joint = posed.joint_index(effector.joint)?;
    let point = global.translation().as_dvec3();
    let goal = match effector.kind {
        PoseEffectorKind::Position => EffectorGoal::Position(point),
        PoseEffectorKind::Orientation => {
            EffectorGoal::Orientation(rotation_of_space(&global.affine()).as_dquat())
        }
        PoseEffectorKind::Aim { axis, up } => EffectorGoal::Aim {
            axis: axis.as_dvec3(),
            target: point,
            up: up.map(|u| (u.as_dvec3(), glam::DVec3::Y)),
        },
    };
    Some(Effector {
        joint,
        goal,
        weight: f64::from(effector.weight),
    })
}
