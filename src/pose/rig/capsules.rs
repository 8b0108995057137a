//! Capsules that follow a skinned character's bones, fitted to its skin: for physics to meet
//! the posed body (`ecs::physics::PosedColliders` with the `avian` feature).
//!
//! Each joint that carries skin gets one capsule in its own space (rigid with the joint): from
//! the joint to its first child (a leaf joint: toward the centroid of its skin, as far as the
//! skin reaches), its radius the
//! 75th percentile of the distances of the vertices weighted at least `min_weight` to the
//! joint from that segment — inside the skin's outer bumps, around its bulk.

use glam::DVec3;

use crate::deform::synth::capsule;
use crate::pose::rig::model::SkinnedModel;

/// A capsule rigid with a joint, in the joint's space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoneCapsule {
    /// Skeleton index of the joint.
    pub joint: usize,
    /// One end (joint space).
    pub a: DVec3,
    /// The other end (joint space).
    pub b: DVec3,
    /// Radius (joint space units).
    pub radius: f64,
}

/// The capsules of `model`'s bones: one per joint with at least three vertices weighted
/// `min_weight` or more to it, none of zero radius.
pub fn fit_bone_capsules(model: &SkinnedModel, min_weight: f64) -> Vec<BoneCapsule> {
    let skeleton = model.skeleton();
    let rest = skeleton.bind_pose();
    let mut carried: Vec<Vec<DVec3>> = vec![Vec::new(); skeleton.len()];
    for (p, influences) in model.bind_positions().iter().zip(model.influences()) {
        for &(j, w) in influences {
            let j = j as usize;
            if w >= min_weight && j < skeleton.len() {
                carried[j].push(skeleton.joints()[j].inverse_bind.transform_point3(*p));
            }
        }
    }
    let mut capsules = Vec::new();
    for (joint, points) in carried.iter().enumerate() {
        if points.len() < 3 {
            continue;
        }
        let b = match skeleton.children(joint).first() {
            Some(&child) => rest.local[child].translation,
            None => {
                // A leaf: toward the centroid of its skin, as far as the skin reaches.
                let towards =
                    (points.iter().sum::<DVec3>() / points.len() as f64).normalize_or_zero();
                let reach = points.iter().map(|p| p.dot(towards)).fold(0.0, f64::max);
                towards * reach
            }
        };
        let a = DVec3::ZERO;
        let mut distances: Vec<f64> = points.iter().map(|p| capsule(*p, a, b, 0.0)).collect();
        distances.sort_by(f64::total_cmp);
        let radius = distances[(distances.len() - 1) * 3 / 4];
        if radius > 0.0 && radius.is_finite() && b.is_finite() {
            capsules.push(BoneCapsule {
                joint,
                a,
                b,
                radius,
            });
        }
    }
    capsules
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rig::synth_rig;

    #[test]
    fn a_bar_rigs_capsules_follow_its_bones_with_its_radius() {
        let rig = synth_rig::bar_rig(4, 16, 40);
        let model = rig.model().unwrap();
        let capsules = fit_bone_capsules(&model, 0.5);
        assert_eq!(capsules.len(), 4, "{capsules:?}");
        for c in &capsules {
            assert!((c.radius - 0.1).abs() < 0.01, "the bar's radius: {c:?}");
            // Along the bone: +Y in the joint's space, a quarter of the bar long.
            let length = (c.b - c.a).length();
            assert!(
                c.b.x.abs() < 1e-9 && c.b.z.abs() < 1e-9 && length > 0.1,
                "{c:?}"
            );
        }
    }
}
