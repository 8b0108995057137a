//! How much of the body each joint's rotation carries: the weight [`crate::pose::constraints::effectors::ReferenceStiffness`]
//! gives each joint under [`crate::pose::constraints::effectors::StiffnessWeighting::Inertia`].
//!
//! Turning a joint by a small angle `δ` moves every vertex of its subtree by `δ` times its
//! distance from the joint, so the squared displacement it causes is `δ² · I_j` with
//! `I_j = Σ_v w_v ‖p_v − o_j‖²` over the vertices its subtree skins (skin weights `w_v`,
//! bind pose): the subtree's moment of inertia about the joint, unit mass per vertex. A
//! stiffness weighted by it holds the hips (which carry the whole body) far more firmly than
//! the neck, so a look-at turns the neck and head first — as a stiffness measured in how far
//! the mesh moves from the reference would — instead of sharing the turn equally with every
//! ancestor (the hips included, with the legs swinging off the animation).

use glam::DVec3;

use crate::pose::rig::skeleton::{Skeleton, VertexInfluences};

/// Per joint, `I_j / mean(I)` over the joints that carry any vertex (0 for the others): 1 on
/// average, ≫ 1 for the hips, ≪ 1 for a finger tip.
pub(crate) fn relative_inertia(
    skeleton: &Skeleton,
    bind: &[DVec3],
    influences: &[VertexInfluences],
) -> Vec<f64> {
    let joints = skeleton.joints();
    let origins = skeleton.bind_origins();
    let mut inertia = vec![0.0; joints.len()];
    for (p, skin) in bind.iter().zip(influences) {
        for &(joint, w) in skin.iter().filter(|(_, w)| *w > 0.0) {
            let mut at = Some(joint as usize);
            while let Some(a) = at.filter(|&a| a < joints.len()) {
                inertia[a] += w * p.distance_squared(origins[a]);
                at = joints[a].parent;
            }
        }
    }
    let carrying: Vec<f64> = inertia.iter().copied().filter(|&i| i > 0.0).collect();
    let mean = carrying.iter().sum::<f64>() / carrying.len().max(1) as f64;
    if !(mean.is_finite() && mean > 0.0) {
        return vec![1.0; joints.len()];
    }
    inertia.iter().map(|i| i / mean).collect()
}
