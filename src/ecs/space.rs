//! Space math the ECS folders share (input controls and pose effectors): one home, outside
//! every folder, so no folder imports another for it.

use bevy::prelude::*;

/// The rotation of an affine space: the rotation nearest to its linear part (the polar
/// factor), whatever its scale — uniform (0.01 for centimetre rigs), non-uniform, or sheared by
/// a scaled parent. `Quat::from_mat3a` is only defined for pure rotations; on a scaled matrix
/// it turns a 34° drag into 39° (scale 2) or a −90° turn into 2.3° (scale 0.01). A degenerate
/// space (zero or non-finite scale) has no rotation: the identity.
pub fn rotation_of_space(space: &bevy::math::Affine3A) -> Quat {
    let m = glam::DMat3::from_cols(
        space.matrix3.x_axis.as_dvec3(),
        space.matrix3.y_axis.as_dvec3(),
        space.matrix3.z_axis.as_dvec3(),
    );
    // The polar factor does not depend on the scale; normalising keeps Jacobi's tolerances
    // meaningful at any size.
    let norm =
        (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt();
    if !norm.is_finite() || norm < 1e-30 {
        return Quat::IDENTITY;
    }
    let q = crate::deform::best_rotation_exact(&(m * norm.recip())).as_quat();
    if q.is_finite() {
        q.normalize()
    } else {
        Quat::IDENTITY
    }
}
