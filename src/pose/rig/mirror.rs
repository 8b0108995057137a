//! Mirroring poses across a character's symmetry plane, with left/right joints paired by name.
//!
//! Pairs are found by name ([`crate::pose::rig::humanoid::split_name`]): two joints pair when their names
//! differ only in the side they name (`Left`/`Right` anywhere, `.L`/`.R`, `_l`/`_r`, `L_`/`R_`,
//! VRM's `J_Bip_L_`/`J_Bip_R_`, case-insensitive; exporters' instance numbers such as the Fox's
//! `_015`/`_019` ignored). A joint with no partner mirrors onto itself.
//!
//! The plane is `x = 0` of the skeleton root's parent space (glTF characters face +Z with +X
//! to their left), or another axis ([`Mirror::with_axis`]). Mirroring works on world
//! rotations and needs no convention about the joints' local axes: a joint's mirrored world
//! rotation is `M · R_partner · C`, with `M` the reflection and `C = R⁰_partnerᵀ M R⁰_joint`
//! fixed by the rest pose, so mirroring the rest pose gives the rest pose and mirroring twice
//! gives the pose back exactly.

use std::collections::HashMap;

use glam::{DAffine3, DMat3, DVec3};

use crate::deform::RigidTransform;

use crate::pose::rig::humanoid::{Side, split_name};
use crate::pose::rig::skeleton::rotation_of;
use crate::pose::rig::skeleton::{JointTransform, Skeleton, SkeletonPose};

/// Left/right pairs and the rest-pose corrections of a skeleton (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Mirror {
    pub(crate) partner: Vec<usize>,
    pub(crate) parents: Vec<Option<usize>>,
    pub(crate) reflection: DMat3,
    pub(crate) correction: Vec<DMat3>,
}

/// Index of each joint's mirror partner (itself when unpaired), by name.
pub fn mirror_partners(skeleton: &Skeleton) -> Vec<usize> {
    let split: Vec<(String, Option<Side>)> = skeleton
        .joints()
        .iter()
        .map(|j| split_name(&j.name))
        .collect();
    let mut by_base: HashMap<(&str, Side), usize> = HashMap::new();
    for (j, (base, side)) in split.iter().enumerate() {
        if let Some(side) = side {
            by_base.entry((base.as_str(), *side)).or_insert(j);
        }
    }
    split
        .iter()
        .enumerate()
        .map(|(j, (base, side))| {
            let other = match side {
                Some(Side::Left) => Side::Right,
                Some(Side::Right) => Side::Left,
                None => return j,
            };
            by_base.get(&(base.as_str(), other)).copied().unwrap_or(j)
        })
        .collect()
}

/// World rotations (in the root's parent space) of every joint, composed from local rotations.
fn world_rotations(parents: &[Option<usize>], pose: &SkeletonPose) -> Vec<DMat3> {
    let mut out: Vec<DMat3> = Vec::with_capacity(parents.len());
    for (j, parent) in parents.iter().enumerate() {
        let local = DMat3::from_quat(pose.local[j].rotation);
        out.push(parent.map_or(local, |p| out[p] * local));
    }
    out
}

impl Mirror {
    /// Pairs and corrections for mirroring across `x = 0`, taken from `rest` (a pose the
    /// character is symmetric in, usually the bind pose).
    pub fn new(skeleton: &Skeleton, rest: &SkeletonPose) -> Self {
        Self::with_axis(skeleton, rest, DVec3::X)
    }

    /// As [`Mirror::new`], across the plane through the origin normal to `axis` (in the root's
    /// parent space).
    pub fn with_axis(skeleton: &Skeleton, rest: &SkeletonPose, axis: DVec3) -> Self {
        let n = axis.normalize_or(DVec3::X);
        let reflection = DMat3::IDENTITY - 2.0 * DMat3::from_cols(n * n.x, n * n.y, n * n.z);
        let parents: Vec<Option<usize>> = skeleton.joints().iter().map(|j| j.parent).collect();
        let partner = mirror_partners(skeleton);
        let rest_world = world_rotations(&parents, rest);
        let correction = (0..partner.len())
            .map(|j| rest_world[partner[j]].transpose() * reflection * rest_world[j])
            .collect();
        Self {
            partner,
            parents,
            reflection,
            correction,
        }
    }

    /// The vertices mirroring `vertices`: for each, the one of `positions` (the welded
    /// vertices where the character is symmetric, usually skinned in the bind pose, world
    /// space) nearest to its reflection across the plane of `frame` (world ← character).
    /// Sorted, without repeats; `None` when the mirrored set meets the original (a set on the
    /// plane, the head say, mirrors onto itself) or an index is out of range.
    pub fn mirror_vertices(
        &self,
        positions: &[DVec3],
        vertices: &[u32],
        frame: &DAffine3,
    ) -> Option<Vec<u32>> {
        let mut out = Vec::with_capacity(vertices.len());
        for &v in vertices {
            let at = self.reflect_point(*positions.get(v as usize)?, frame);
            let nearest = positions
                .iter()
                .enumerate()
                .map(|(i, p)| (i, p.distance_squared(at)))
                .min_by(|a, b| a.1.total_cmp(&b.1))?
                .0;
            out.push(nearest as u32);
        }
        out.sort_unstable();
        out.dedup();
        let meets = out.iter().any(|v| vertices.contains(v));
        (!meets).then_some(out)
    }

    /// `point` (world) reflected across the plane of `frame` (world ← character).
    pub fn reflect_point(&self, point: DVec3, frame: &DAffine3) -> DVec3 {
        frame.transform_point3(self.reflection * frame.inverse().transform_point3(point))
    }

    /// The rigid motion (world) that mirrors `motion` across the plane of `frame`: the
    /// pivot reflected, the translation and the rotation conjugated by the reflection.
    pub fn mirror_motion(&self, motion: &RigidTransform, frame: &DAffine3) -> RigidTransform {
        let f = DMat3::from_quat(rotation_of(&frame.matrix3));
        let m = f * self.reflection * f.transpose();
        RigidTransform {
            rotation: rotation_of(&(m * DMat3::from_quat(motion.rotation) * m)),
            translation: m * motion.translation,
            pivot: self.reflect_point(motion.pivot, frame),
        }
    }

    /// Each joint's partner (itself when unpaired).
    pub fn partners(&self) -> &[usize] {
        &self.partner
    }

    /// The number of left/right pairs.
    pub fn pair_count(&self) -> usize {
        self.partner
            .iter()
            .enumerate()
            .filter(|(j, p)| *p > j)
            .count()
    }

    /// `pose` mirrored across the plane: each joint takes its partner's mirrored world
    /// rotation; bones keep their lengths (non-root local translations as in `pose`'s joint,
    /// which the rest pose makes symmetric); roots' translations are reflected. A pose of
    /// the wrong length comes back unchanged.
    pub fn mirror(&self, pose: &SkeletonPose) -> SkeletonPose {
        if pose.local.len() != self.partner.len() {
            return pose.clone();
        }
        let world = world_rotations(&self.parents, pose);
        let mirrored: Vec<DMat3> = (0..world.len())
            .map(|j| self.reflection * world[self.partner[j]] * self.correction[j])
            .collect();
        let local = (0..world.len())
            .map(|j| {
                let m =
                    self.parents[j].map_or(mirrored[j], |p| mirrored[p].transpose() * mirrored[j]);
                let rotation = rotation_of(&m);
                let own = pose.local[j];
                let translation = match self.parents[j] {
                    None => self.reflection * pose.local[self.partner[j]].translation,
                    Some(_) => own.translation,
                };
                JointTransform {
                    translation,
                    rotation,
                    scale: own.scale,
                }
            })
            .collect();
        SkeletonPose { local }
    }
}
