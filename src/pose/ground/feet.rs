//! Which joints a character stands on (feet, paws, a single base) and the skin patch under
//! each: [`lowest_joints`], [`sole_patch`].

use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::skeleton::SkeletonPose;
use glam::DVec3;

/// A sole's thickness, as a share of the model's size (its bounding diagonal): a foot's patch
/// is its skin within this of its lowest vertex ([`sole_patch`] as the tracker uses it).
pub(crate) const SOLE_THICKNESS: f64 = 0.02;

/// The length of `v` across gravity (`down`, unit).
pub(crate) fn horizontal(v: DVec3, down: DVec3) -> f64 {
    (v - down * v.dot(down)).length()
}

/// The joints a character stands on in `pose`: those whose most-weighted vertices reach within
/// `tolerance` (world units) of the lowest skinned vertex along `down` (feet, paws, the base
/// of a one-joint prop), lowest first.
///
/// A joint above another chosen joint of its own leg whose skin stays more than a sole's
/// thickness (2 % of the model's size) higher is the leg over a foot — a
/// quadruped's raised hock, a shin — not a foot, and is left out: planted, it would be laid
/// on the ground it does not reach, against the foot under it. A heel and its toes (a biped's
/// foot and toe joints), both down, are both kept.
pub fn lowest_joints(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    down: DVec3,
    tolerance: f64,
) -> Vec<usize> {
    let skinned = model.skin_welded(pose);
    let mut deepest = vec![f64::NEG_INFINITY; model.skeleton().len()];
    for (v, inf) in model.influences().iter().enumerate() {
        let main = inf.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|i| i.0);
        if let Some(j) = main {
            deepest[j as usize] = deepest[j as usize].max(skinned[v].dot(down));
        }
    }
    let lowest = deepest.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let joints: Vec<usize> = (0..deepest.len())
        .filter(|&j| deepest[j] > f64::NEG_INFINITY && deepest[j] >= lowest - tolerance)
        .collect();
    let thickness = SOLE_THICKNESS * model.topology().bounding_diagonal();
    let skeleton = model.skeleton();
    let over_a_lower_foot = |j: usize| {
        joints
            .iter()
            .any(|&d| d != j && skeleton.descends_from(d, j) && deepest[d] > deepest[j] + thickness)
    };
    let mut feet: Vec<usize> = joints
        .iter()
        .copied()
        .filter(|&j| !over_a_lower_foot(j))
        .collect();
    feet.sort_by(|a, b| deepest[*b].total_cmp(&deepest[*a]));
    feet
}

/// The skin patch under `joint` in `pose`: its most-weighted vertices within `thickness` (world
/// units) of its lowest one along `down` (a sole).
pub fn sole_patch(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    joint: usize,
    down: DVec3,
    thickness: f64,
) -> Vec<u32> {
    let skinned = model.skin_welded(pose);
    let carried: Vec<u32> = model
        .influences()
        .iter()
        .enumerate()
        .filter(|(_, inf)| {
            inf.iter()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .is_some_and(|i| i.0 as usize == joint && i.1 > 0.0)
        })
        .map(|(v, _)| v as u32)
        .collect();
    let lowest = carried
        .iter()
        .map(|&v| skinned[v as usize].dot(down))
        .fold(f64::NEG_INFINITY, f64::max);
    carried
        .into_iter()
        .filter(|&v| skinned[v as usize].dot(down) >= lowest - thickness)
        .collect()
}
