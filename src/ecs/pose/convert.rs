//! Conversions between Bevy's transforms and the pose core's (f32 → f64), one home for the
//! stages that need them.

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

/// A joint's local `Transform` as the core's (its rotation normalised).
pub(super) fn joint_transform(t: &Transform) -> JointTransform {
    JointTransform {
        translation: t.translation.as_dvec3(),
        rotation: t.rotation.as_dquat().normalize(),
        scale: t.scale.as_dvec3(),
    }
}
