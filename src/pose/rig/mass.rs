//! The mass model: a skinned character's mass spread over its surface, each welded vertex
//! carrying a third of the bind-pose area of the triangles around it ([`vertex_masses`]),
//! and the centre of mass of a posed character ([`centre_of_mass`]).

use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::skeleton::SkeletonPose;
use glam::DVec3;

/// Mass per welded vertex of `model`: a third of the bind-pose area of each triangle around it.
pub fn vertex_masses(model: &SkinnedModel) -> Vec<f64> {
    let bind = model.bind_positions();
    let mut mass = vec![0.0; bind.len()];
    for t in model.topology().triangles() {
        let [a, b, c] = t.map(|v| bind[v as usize]);
        let third = (b - a).cross(c - a).length() / 6.0;
        if third.is_finite() {
            for v in t {
                mass[*v as usize] += third;
            }
        }
    }
    mass
}

/// The centre of mass of `model` skinned by `pose` (`masses` per welded vertex, or the
/// model's [`SkinnedModel::area_masses`]). `None` when the masses sum to zero.
pub fn centre_of_mass(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    masses: Option<&[f64]>,
) -> Option<DVec3> {
    let masses = masses.unwrap_or_else(|| model.area_masses());
    let skinned = model.skin_welded(pose);
    let total: f64 = masses.iter().sum();
    (total > 0.0).then(|| {
        skinned
            .iter()
            .zip(masses)
            .map(|(p, m)| *p * *m)
            .sum::<DVec3>()
            / total
    })
}
