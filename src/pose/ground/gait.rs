//! The gait's own foot-down phases, read from the animation a pose layer is added to.
//!
//! A character walking by a clip plants a foot when the clip puts it down and lifts it when
//! the clip lifts it — not when the foot happens to come near the terrain (mid-swing over a
//! hill) or trails behind. The clip was authored on flat ground: its floor is the level of the
//! lowest skin vertex in the pose the character was first stood in (character space), and a
//! patch's height in the clip above that floor is its phase:
//! * at most [`GaitPhases::touch`] above it: the clip has the foot down (a free patch may plant);
//! * more than [`GaitPhases::lift`] above it: the clip lifts the foot (a planted patch is released).
//!
//! Where the foot is planted is still decided on the terrain (the patch as the pose carries it,
//! laid on the ground under it); the phases only decide when. Used by
//! [`crate::pose::ground::tracker::ContactTracker::update_guided`].

use glam::DVec3;

use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::skeleton::SkeletonPose;

/// When the clip has a foot down or up (see the module docs), in world units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaitPhases {
    /// The clip's floor: the lowest skin vertex's height against gravity in the pose the
    /// character was first stood in.
    pub floor: f64,
    /// A patch at most this high above the clip's floor is down.
    pub touch: f64,
    /// A patch entirely more than this high above the clip's floor is lifted.
    pub lift: f64,
}

impl GaitPhases {
    /// The phases of a character of `size` (bounding diagonal) first stood in `skinned`
    /// (welded skin positions): down within 1.5 % of the size of the floor, lifted beyond
    /// 2.5 % (the Fox's walk: ±0.6 % in stance, 4–6 % at the top of a swing).
    pub fn new(skinned: &[DVec3], down: DVec3, size: f64) -> Self {
        let floor = skinned
            .iter()
            .filter(|p| p.is_finite())
            .map(|p| -p.dot(down))
            .fold(f64::INFINITY, f64::min);
        Self {
            floor: if floor.is_finite() { floor } else { 0.0 },
            touch: 0.015 * size,
            lift: 0.025 * size,
        }
    }

    /// Each patch's lowest vertex above the clip's floor in `animation` (the clip's pose, no
    /// layer), one per patch; `None` when the pose does not fit the model.
    pub fn heights(
        &self,
        model: &SkinnedModel,
        animation: &SkeletonPose,
        patches: &[&[u32]],
        down: DVec3,
    ) -> Option<Vec<f64>> {
        if animation.local.len() != model.skeleton().len() {
            return None;
        }
        // Only the patches' vertices are skinned (a few dozen of the mesh), in one pass.
        let count = model.bind_positions().len();
        let vertices: Vec<u32> = patches
            .iter()
            .flat_map(|patch| patch.iter().copied())
            .filter(|&v| (v as usize) < count)
            .collect();
        let mut skinned = model.skin_vertices(animation, &vertices).into_iter();
        Some(
            patches
                .iter()
                .map(|patch| {
                    patch
                        .iter()
                        .filter(|&&v| (v as usize) < count)
                        .filter_map(|_| skinned.next())
                        .map(|p| -p.dot(down) - self.floor)
                        .fold(f64::INFINITY, f64::min)
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rig::model::{ModelSettings, SkinnedModel};
    use crate::pose::rig::synth_rig::bar_rig;

    #[test]
    fn a_patch_raised_by_the_clip_reads_its_height_above_the_clip_floor() {
        let rig = bar_rig(3, 8, 16);
        let model = SkinnedModel::new(
            rig.skeleton.clone(),
            &rig.mesh,
            &rig.rest,
            ModelSettings::default(),
        )
        .unwrap();
        let rest = model.skin_welded(&rig.rest);
        let phases = GaitPhases::new(&rest, DVec3::NEG_Y, 1.0);
        let bottom = rig.vertices_where(&model, |p| p.y < 0.05);
        let top = rig.vertices_where(&model, |p| p.y > 0.95);
        let at_rest = phases
            .heights(&model, &rig.rest, &[&bottom, &top], DVec3::NEG_Y)
            .unwrap();
        assert!(at_rest[0].abs() < 1e-12, "{at_rest:?}");
        assert!(at_rest[1] > 0.9);
        // The clip lifts the whole bar 0.1: the bottom patch reads 0.1 up (lifted).
        let mut lifted = rig.rest.clone();
        lifted.local[0].translation += DVec3::Y * 0.1;
        let h = phases
            .heights(&model, &lifted, &[&bottom], DVec3::NEG_Y)
            .unwrap();
        assert!((h[0] - 0.1).abs() < 1e-9 && h[0] > phases.lift, "{h:?}");
        // A pose of another skeleton does not fit.
        let short = SkeletonPose {
            local: lifted.local[..1].to_vec(),
        };
        assert_eq!(
            phases.heights(&model, &short, &[&bottom], DVec3::NEG_Y),
            None
        );
    }
}
