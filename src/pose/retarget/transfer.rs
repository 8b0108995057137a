//! A source pose carried over to the target skeleton: joint rotations in a common world frame
//! relative to each skeleton's rest, bones re-aimed where the rest poses differ, the root
//! motion scaled by the legs' ratio. No contacts here (see `bake.rs`).
//!
//! For a target joint following source joint `s` (or a point between two source joints of a
//! chain), with the source's world rotation now `Rₛ` and at rest `Rₛ⁰`:
//!
//! * the source's world change `D = Rₛ · Rₛ⁰⁻¹`, brought into the target's axes by the
//!   alignment `A` of the two rest poses' up and forward: `A · D · A⁻¹`;
//! * the target's rest bone turned onto the source's rest bone (shortest arc) first: `C`, so
//!   an A-pose target follows a T-pose source's arm *directions*, not its rotations;
//! * the target joint's world rotation `A·D·A⁻¹ · C · Rₜ⁰`, and its local rotation from its
//!   parent's new world rotation. Bone lengths are the target's (only the root moves).
//!
//! A clip on its own skeleton comes back as it is: `A`, `C` are identities and `D` carries
//! over unchanged.

use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::pose::retarget::mapping::SkeletonMap;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose, rotation_of};

/// How the root motion is scaled onto the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RootMotion {
    /// Scale the horizontal motion by the legs' ratio (else 1:1 in world units).
    pub scale_horizontal: bool,
    /// Scale the height over the ground by the legs' ratio (else 1:1 in world units).
    pub scale_vertical: bool,
}

impl Default for RootMotion {
    fn default() -> Self {
        Self {
            scale_horizontal: true,
            scale_vertical: true,
        }
    }
}

/// Where one target joint reads its motion: between source joints `a` and `b` at `w`, with
/// its rest bone turned onto the source's by `correction` (world, target axes).
#[derive(Debug, Clone, Copy)]
struct Follow {
    a: usize,
    b: usize,
    w: f64,
    correction: DQuat,
}

/// The rotation carry-over of one source skeleton onto one target skeleton (see the module
/// docs).
#[derive(Debug, Clone)]
pub struct PoseTransfer {
    source: Skeleton,
    target: Skeleton,
    target_rest: SkeletonPose,
    map: SkeletonMap,
    /// Source world → target world (rotation only).
    align: DQuat,
    follow: Vec<Option<Follow>>,
    source_rest_rotations: Vec<DQuat>,
    target_rest_rotations: Vec<DQuat>,
    /// Target leg length over source leg length.
    leg_ratio: f64,
    /// The source's and the target's foot height over their ground, along their up.
    source_foot_height: f64,
    target_foot_height: f64,
    root_motion: RootMotion,
}

fn world_rotations(globals: &[DAffine3]) -> Vec<DQuat> {
    globals.iter().map(|g| rotation_of(&g.matrix3)).collect()
}

/// An orthonormal basis (left, up, forward) from an up and a forward.
fn basis((up, forward): (DVec3, DVec3)) -> DMat3 {
    let up = up.normalize_or(DVec3::Y);
    let forward = (forward - up * forward.dot(up)).normalize_or(DVec3::Z);
    DMat3::from_cols(up.cross(forward), up, forward)
}

/// Parameters along a chain: each joint's distance from the first, over the chain's length
/// (by index when the chain has no length).
fn chain_params(globals: &[DAffine3], chain: &[usize]) -> Vec<f64> {
    let mut along = vec![0.0];
    for w in chain.windows(2) {
        let d = globals[w[0]]
            .translation
            .distance(globals[w[1]].translation);
        along.push(along.last().copied().unwrap_or(0.0) + d);
    }
    let total = along.last().copied().unwrap_or(0.0);
    if total > 1e-12 {
        along.iter().map(|a| a / total).collect()
    } else if chain.len() > 1 {
        (0..chain.len())
            .map(|k| k as f64 / (chain.len() - 1) as f64)
            .collect()
    } else {
        vec![0.0]
    }
}

/// The rest direction of the bone leaving joint `j` towards `next` (the chain's next joint),
/// else towards its first child; `None` for a leaf.
fn bone_direction(
    skeleton: &Skeleton,
    globals: &[DAffine3],
    j: usize,
    next: Option<usize>,
) -> Option<DVec3> {
    let to = next.or_else(|| skeleton.children(j).first().copied())?;
    (globals[to].translation - globals[j].translation).try_normalize()
}

/// The height along `up` of the lowest of the map's feet in `globals`: the source's feet
/// (`side` 0) or the target's (1). Infinite when the map has no feet.
fn lowest_foot(map: &SkeletonMap, globals: &[DAffine3], up: DVec3, side: usize) -> f64 {
    map.feet
        .iter()
        .map(|f| {
            globals[if side == 0 { f.0 } else { f.1 }]
                .translation
                .dot(up)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The length of the legs: the mean over the feet of the chain from its first joint to the foot.
fn leg_length(map: &SkeletonMap, globals: &[DAffine3], which: usize) -> Option<f64> {
    let lengths: Vec<f64> = map
        .feet
        .iter()
        .filter_map(|foot| {
            let foot = if which == 0 { foot.0 } else { foot.1 };
            let chain = map.chains.iter().find(|c| {
                let joints = if which == 0 { &c.source } else { &c.target };
                joints.last() == Some(&foot)
            })?;
            let joints = if which == 0 {
                &chain.source
            } else {
                &chain.target
            };
            Some(
                joints
                    .windows(2)
                    .map(|w| {
                        globals[w[0]]
                            .translation
                            .distance(globals[w[1]].translation)
                    })
                    .sum(),
            )
        })
        .filter(|l: &f64| *l > 1e-12)
        .collect();
    (!lengths.is_empty()).then(|| lengths.iter().sum::<f64>() / lengths.len() as f64)
}

impl PoseTransfer {
    /// Prepares the carry-over: the alignment of the two rest poses, each target joint's
    /// source point along its chain and its rest-bone correction, the legs' ratio.
    pub fn new(
        (source, source_rest): (&Skeleton, &SkeletonPose),
        (target, target_rest): (&Skeleton, &SkeletonPose),
        map: SkeletonMap,
        root_motion: RootMotion,
    ) -> Self {
        let sg = source.global_transforms(source_rest);
        let tg = target.global_transforms(target_rest);
        let align =
            DQuat::from_mat3(&(basis(map.axes[1]) * basis(map.axes[0]).transpose())).normalize();
        let mut follow = vec![None; target.len()];
        for chain in &map.chains {
            let (sp, tp) = (
                chain_params(&sg, &chain.source),
                chain_params(&tg, &chain.target),
            );
            for (k, &j) in chain.target.iter().enumerate() {
                let t = tp[k];
                let i = sp.iter().rposition(|&s| s <= t + 1e-12).unwrap_or(0);
                let (a, b, w) = if i + 1 < sp.len() {
                    let span = sp[i + 1] - sp[i];
                    let w = if span > 1e-12 {
                        ((t - sp[i]) / span).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    (chain.source[i], chain.source[i + 1], w)
                } else {
                    (chain.source[i], chain.source[i], 0.0)
                };
                let source_dir = if a != b {
                    (sg[b].translation - sg[a].translation).try_normalize()
                } else {
                    bone_direction(source, &sg, a, None)
                };
                let target_dir = bone_direction(target, &tg, j, chain.target.get(k + 1).copied());
                let correction = match (source_dir, target_dir) {
                    (Some(s), Some(t)) => DQuat::from_rotation_arc(t, align * s),
                    _ => DQuat::IDENTITY,
                };
                follow[j] = Some(Follow {
                    a,
                    b,
                    w,
                    correction,
                });
            }
        }
        // The root (the hips) turns as the source's does, relative to each rest. It is in no
        // chain (its bones go to the spine, each thigh, a tail: no one direction to re-aim),
        // and a root left at rest would hold the whole body at the rest's attitude.
        let (root_s, root_t) = map.root;
        if follow[root_t].is_none() {
            follow[root_t] = Some(Follow {
                a: root_s,
                b: root_s,
                w: 0.0,
                correction: DQuat::IDENTITY,
            });
        }
        let (up_s, up_t) = (
            map.axes[0].0.normalize_or(DVec3::Y),
            map.axes[1].0.normalize_or(DVec3::Y),
        );
        let (ls, lt) = (leg_length(&map, &sg, 0), leg_length(&map, &tg, 1));
        let hips_height = |g: &[DAffine3], root: usize, up: DVec3| {
            let lowest = g
                .iter()
                .map(|x| x.translation.dot(up))
                .fold(f64::INFINITY, f64::min);
            (g[root].translation.dot(up) - lowest).max(1e-9)
        };
        let leg_ratio = match (ls, lt) {
            (Some(s), Some(t)) => t / s,
            _ => hips_height(&tg, map.root.1, up_t) / hips_height(&sg, map.root.0, up_s),
        };
        let source_foot_height = if map.feet.is_empty() {
            sg.iter()
                .map(|x| x.translation.dot(up_s))
                .fold(f64::INFINITY, f64::min)
        } else {
            lowest_foot(&map, &sg, up_s, 0)
        };
        let target_foot_height = if map.feet.is_empty() {
            tg.iter()
                .map(|x| x.translation.dot(up_t))
                .fold(f64::INFINITY, f64::min)
        } else {
            lowest_foot(&map, &tg, up_t, 1)
        };
        Self {
            source_rest_rotations: world_rotations(&sg),
            target_rest_rotations: world_rotations(&tg),
            source: source.clone(),
            target: target.clone(),
            target_rest: target_rest.clone(),
            map,
            align,
            follow,
            leg_ratio,
            source_foot_height,
            target_foot_height,
            root_motion,
        }
    }

    /// The map it carries over by.
    pub fn map(&self) -> &SkeletonMap {
        &self.map
    }

    /// Target leg length over source leg length (the root motion's scale).
    pub fn leg_ratio(&self) -> f64 {
        self.leg_ratio
    }

    /// Source world → target world (the alignment of the two rest poses' axes).
    pub fn align(&self) -> DQuat {
        self.align
    }

    /// The world rotations of the source's and the target's root (hips) at rest.
    pub fn rest_root_rotations(&self) -> (DQuat, DQuat) {
        (
            self.source_rest_rotations[self.map.root.0],
            self.target_rest_rotations[self.map.root.1],
        )
    }

    /// A horizontal velocity of the source's world (its ground's, under a clip made in place:
    /// [`crate::pose::retarget::SourceContacts::treadmill`]) in the target's world: turned into
    /// its axes and scaled as the root's horizontal motion is.
    pub fn carry_ground_velocity(&self, velocity: DVec3) -> DVec3 {
        let up_s = self.map.axes[0].0.normalize_or(DVec3::Y);
        let horizontal = velocity - up_s * velocity.dot(up_s);
        let scale = if self.root_motion.scale_horizontal {
            self.leg_ratio
        } else {
            1.0
        };
        self.align * horizontal * scale
    }

    /// The target's rest pose.
    pub fn target_rest(&self) -> &SkeletonPose {
        &self.target_rest
    }

    /// Sets the source's foot height over its ground (along its up) that the target's rest
    /// foot height matches: the clip's planted height (the bake measures it), else the rest
    /// pose's lowest foot.
    pub fn set_source_foot_height(&mut self, height: f64) {
        if height.is_finite() {
            self.source_foot_height = height;
        }
    }

    /// The source's foot height over its ground (along its up): see
    /// [`PoseTransfer::set_source_foot_height`].
    pub fn source_foot_height(&self) -> f64 {
        self.source_foot_height
    }

    /// The source skeleton.
    pub fn source(&self) -> &Skeleton {
        &self.source
    }

    /// The target skeleton.
    pub fn target(&self) -> &Skeleton {
        &self.target
    }

    /// The target pose for `source_pose`. The target's root goes where the source's is, in
    /// the target's axes, scaled by the legs' ratio: horizontally about the world origin, and
    /// its height over the ground — then, with the vertical motion scaled and feet in the map,
    /// lifted or lowered so that the target's lowest foot is as high over its ground as the
    /// source's, scaled (the hips' height scaled alone puts the feet right only for legs that
    /// hang straight below the hips joint: the way from hips to thigh is not scaled, and a
    /// quadruped's hind paws went 1 % of its size into the ground on legs made 30 % longer).
    pub fn transfer(&self, source_pose: &SkeletonPose) -> SkeletonPose {
        let sg = self.source.global_transforms(source_pose);
        let deltas: Vec<DQuat> = sg
            .iter()
            .zip(&self.source_rest_rotations)
            .map(|(g, r0)| (rotation_of(&g.matrix3) * r0.inverse()).normalize())
            .collect();
        let mut pose = self.target_rest.clone();
        let joints = self.target.joints();
        let mut world: Vec<DQuat> = Vec::with_capacity(joints.len());
        for (j, joint) in joints.iter().enumerate() {
            let parent = match joint.parent {
                Some(p) => world[p],
                None => rotation_of(&joint.parent_frame.matrix3),
            };
            let rotation = match self.follow[j] {
                Some(f) => {
                    let (da, db) = (deltas[f.a], deltas[f.b]);
                    let db = if da.dot(db) < 0.0 { -db } else { db };
                    let d = da.slerp(db, f.w);
                    let q = self.align * d * self.align.inverse() * f.correction;
                    (q * self.target_rest_rotations[j]).normalize()
                }
                None => (parent * self.target_rest.local[j].rotation).normalize(),
            };
            pose.local[j].rotation = (parent.inverse() * rotation).normalize();
            world.push(rotation);
        }
        // The root: its horizontal position and its height over the ground, both scaled.
        let (root_s, root_t) = self.map.root;
        let up_s = self.map.axes[0].0.normalize_or(DVec3::Y);
        let up_t = self.map.axes[1].0.normalize_or(DVec3::Y);
        let at = sg[root_s].translation;
        let horizontal = self.align * (at - up_s * at.dot(up_s));
        let height = at.dot(up_s) - self.source_foot_height;
        let scale = |on: bool| if on { self.leg_ratio } else { 1.0 };
        let world_root = horizontal * scale(self.root_motion.scale_horizontal)
            + up_t * (self.target_foot_height + height * scale(self.root_motion.scale_vertical));
        let globals = self.target.global_transforms(&pose);
        let parent_global = match joints[root_t].parent {
            Some(p) => globals[p],
            None => joints[root_t].parent_frame,
        };
        let local = parent_global.inverse().transform_point3(world_root);
        if local.is_finite() {
            pose.local[root_t].translation = local;
        }
        if self.root_motion.scale_vertical && !self.map.feet.is_empty() {
            // The root's height scaled by the legs is right only for legs hanging straight
            // below it; lift the body so the lowest foot is as high over the ground as the
            // source's, scaled.
            let placed = self.target.global_transforms(&pose);
            let wanted = self.target_foot_height
                + (lowest_foot(&self.map, &sg, up_s, 0) - self.source_foot_height) * self.leg_ratio;
            let lift = wanted - lowest_foot(&self.map, &placed, up_t, 1);
            let local = parent_global
                .inverse()
                .transform_point3(world_root + up_t * lift);
            if local.is_finite() {
                pose.local[root_t].translation = local;
            }
        }
        pose
    }
}
