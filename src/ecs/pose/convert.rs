//! Conversions between Bevy's transforms and the pose core's (f32 → f64), one home for the
//! stages that need them (and the retarget plugin's clips).

use bevy::prelude::*;
use glam::DAffine3;

use crate::pose::JointTransform;

/// A `GlobalTransform` as the core's affine map.
pub(super) fn affine(t: &GlobalTransform) -> DAffine3 {
    let a = t.affine();
    DAffine3::from_mat3_translation(
        glam::Mat3::from(a.matrix3).as_dmat3(),
        Vec3::from(a.translation).as_dvec3(),
    )
}

/// `entity`'s world transform composed from the local transforms up its hierarchy as they
/// are now (`local` gives an entity's transform and parent): `GlobalTransform` is last
/// frame's until propagation runs in `PostUpdate`, so a character moved or animated this frame
/// reads it a frame late. `None` when an ancestor has no `Transform` or the chain is
/// implausibly deep.
pub(super) fn composed_global(
    entity: Entity,
    local: impl Fn(Entity) -> Option<(Transform, Option<Entity>)>,
) -> Option<GlobalTransform> {
    // Composed from the entity upwards (each parent's local transform applied on the left),
    // without collecting the chain: this runs for every effector every frame.
    let mut global = bevy::math::Affine3A::IDENTITY;
    let mut at = Some(entity);
    let mut depth = 0;
    while let Some(e) = at {
        let (transform, parent) = local(e)?;
        global = transform.compute_affine() * global;
        at = parent;
        depth += 1;
        if depth > 512 {
            return None;
        }
    }
    Some(GlobalTransform::from(global))
}

/// The core's joint transform as a Bevy `Transform` (its rotation normalised).
pub(crate) fn bevy_transform(t: &JointTransform) -> Transform {
    Transform {
        translation: t.translation.as_vec3(),
        rotation: t.rotation.as_quat().normalize(),
        scale: t.scale.as_vec3(),
    }
}

/// A joint's local `Transform` as the core's (its rotation normalised).
pub(super) fn joint_transform(t: &Transform) -> JointTransform {
    JointTransform {
        translation: t.translation.as_dvec3(),
        rotation: t.rotation.as_dquat().normalize(),
        scale: t.scale.as_dvec3(),
    }
}
