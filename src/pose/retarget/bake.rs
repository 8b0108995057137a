//! A whole clip retargeted through the pose solver: each frame carried over (`transfer.rs`),
//! then solved with the target's feet held where they landed while the source's foot is
//! planted, every skin vertex kept above the ground, and the carried-over pose as the shape's
//! rest (so nothing else pulls the body away from it).

use std::sync::Arc;

use glam::DVec3;

use crate::pose::animation::clip::{KeyInterpolation, PoseClip, PoseKey};
use crate::pose::constraints::PoseConstraints;
use crate::pose::constraints::effectors::{Effector, EffectorGoal, ReferenceStiffness};
use crate::pose::ground::feet::sole_patch;
use crate::pose::ground::floor::{Floor, FloorSampling};
use crate::pose::ground::{Ground, GroundPlane};
use crate::pose::retarget::RetargetError;
use crate::pose::retarget::contacts::{ContactThresholds, SourceContacts, detect_contacts};
use crate::pose::retarget::mapping::SkeletonMap;
use crate::pose::retarget::transfer::{PoseTransfer, RootMotion};
use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose, rotation_of};
use crate::pose::solver::{
    PoseSolution, PoseSolveOptions, PoseSolver, PoseSolverSettings, PoseStart,
};

/// How a clip is retargeted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetargetSettings {
    /// How the root motion is scaled.
    pub root_motion: RootMotion,
    /// Keep the source's contacts and the skin above the ground through the pose solver
    /// (off: the carried-over poses as they are).
    pub contacts: bool,
    /// When a source foot counts as planted.
    pub thresholds: ContactThresholds,
    /// Iterations per frame's solve.
    pub iterations: u32,
    /// The pull of every joint towards its carried-over rotation (the solver's reference
    /// stiffness): without it a leg held at the hips and the foot may swivel about the line
    /// between them, and a toe may flip to lift its tip.
    pub stiffness: f64,
}

impl Default for RetargetSettings {
    fn default() -> Self {
        Self {
            root_motion: RootMotion::default(),
            contacts: true,
            thresholds: ContactThresholds::default(),
            iterations: 8,
            stiffness: 1.0,
        }
    }
}

/// A clip retargeted onto the target.
#[derive(Debug, Clone)]
pub struct RetargetedClip {
    /// The target's clip (a key per source key).
    pub clip: PoseClip,
    /// The target's poses carried over before the contacts were kept (for comparison).
    pub carried: Vec<SkeletonPose>,
    /// The source's contacts, per foot of the map and frame.
    pub source_contacts: SourceContacts,
    /// Frames whose solve failed (their carried-over pose was kept).
    pub failed_solves: usize,
}

/// A source skeleton retargeted onto a target character (see the module docs of
/// [`crate::pose::retarget`]).
pub struct Retargeter {
    transfer: PoseTransfer,
    model: Arc<SkinnedModel>,
    solver: PoseSolver,
    settings: RetargetSettings,
    size: f64,
    /// Per foot of the map, the target's sole (welded vertices), found at rest.
    soles: Vec<Vec<u32>>,
    /// The source's rest pose.
    source_rest: SkeletonPose,
}

impl Retargeter {
    /// Prepares the retarget of `source` (skeleton and rest pose) onto the character `model`
    /// at rest pose `target_rest`, by `map`.
    pub fn new(
        source: (&Skeleton, &SkeletonPose),
        model: Arc<SkinnedModel>,
        target_rest: &SkeletonPose,
        map: SkeletonMap,
        settings: RetargetSettings,
    ) -> Result<Self, RetargetError> {
        source.0.check_pose(source.1)?;
        model.skeleton().check_pose(target_rest)?;
        let transfer = PoseTransfer::new(
            source,
            (model.skeleton(), target_rest),
            map,
            settings.root_motion,
        );
        let solver = PoseSolver::new(
            model.clone(),
            &PoseConstraints::default(),
            target_rest,
            PoseSolverSettings::default(),
        )?;
        let size = model.topology().bounding_diagonal();
        let down = -transfer.map().axes[1].0.normalize_or(DVec3::Y);
        let soles = transfer
            .map()
            .feet
            .iter()
            .map(|&(_, foot)| sole_patch(&model, target_rest, foot, down, 0.01 * size))
            .collect();
        Ok(Self {
            soles,
            source_rest: source.1.clone(),
            transfer,
            model,
            solver,
            settings,
            size,
        })
    }

    /// The rotation carry-over (map, legs' ratio).
    pub fn transfer(&self) -> &PoseTransfer {
        &self.transfer
    }

    /// How it retargets.
    pub fn settings(&self) -> &RetargetSettings {
        &self.settings
    }

    /// The source's rest pose.
    pub fn source_rest(&self) -> &SkeletonPose {
        &self.source_rest
    }

    /// The flat ground the target stands on at rest: through its lowest skin vertex, normal
    /// along the target's up.
    pub fn rest_ground(&self) -> GroundPlane {
        let up = self.transfer.map().axes[1].0.normalize_or(DVec3::Y);
        let skin = self.model.skin_welded(self.transfer.target_rest());
        let lowest = skin
            .iter()
            .copied()
            .min_by(|a, b| a.dot(up).total_cmp(&b.dot(up)))
            .unwrap_or(DVec3::ZERO);
        GroundPlane {
            point: lowest,
            normal: up,
        }
    }

    /// Retargets `clip` (poses of the source skeleton) onto the target, on `ground` (the
    /// target's rest ground, [`Retargeter::rest_ground`], for a flat floor).
    pub fn bake(
        &self,
        clip: &PoseClip,
        ground: &dyn Ground,
    ) -> Result<RetargetedClip, RetargetError> {
        let keys = clip.keys();
        if keys.is_empty() {
            return Err(RetargetError::EmptyClip);
        }
        let map = self.transfer.map();
        let source = self.transfer.source();
        let frames: Vec<SkeletonPose> = keys.iter().map(|k| k.pose.clone()).collect();
        let frame_time = if keys.len() > 1 {
            f64::from(keys[keys.len() - 1].time - keys[0].time) / (keys.len() - 1) as f64
        } else {
            1.0 / 30.0
        };
        let source_up = map.axes[0].0.normalize_or(DVec3::Y);
        let source_feet: Vec<usize> = map.feet.iter().map(|f| f.0).collect();
        let leg = source_leg(source, &frames[0], map);
        let contacts = detect_contacts(
            source,
            &frames,
            frame_time,
            &source_feet,
            source_up,
            leg,
            &self.settings.thresholds,
        );
        let mut transfer = self.transfer.clone();
        if let Some(low) = contacts.planted_height.iter().copied().reduce(f64::min) {
            transfer.set_source_foot_height(low);
        }
        let carried: Vec<SkeletonPose> = frames.iter().map(|p| transfer.transfer(p)).collect();
        let mut out = Vec::with_capacity(keys.len());
        let mut failed = 0;
        if self.settings.contacts {
            // Under a clip made in place the ground moves, and a planted foot's hold with it.
            let ground_step = self.ground_step(&contacts);
            let mut holds: Vec<Option<DVec3>> = vec![None; map.feet.len()];
            let mut last: Option<PoseSolution> = None;
            for (f, pose) in carried.iter().enumerate() {
                if f > 0 {
                    holds.iter_mut().flatten().for_each(|h| *h += ground_step);
                }
                let planted: Vec<bool> = contacts.planted.iter().map(|p| p[f]).collect();
                match self.solve_frame(pose, &planted, &mut holds, ground, last.as_ref()) {
                    Ok(solution) => {
                        out.push(solution.pose.clone());
                        last = Some(solution);
                    }
                    Err(_) => {
                        failed += 1;
                        out.push(pose.clone());
                    }
                }
            }
        } else {
            out = carried.clone();
        }
        let clip = PoseClip::from_keys(
            keys.iter()
                .zip(out)
                .map(|(k, pose)| PoseKey {
                    time: k.time,
                    pose,
                    interpolation: KeyInterpolation::Linear,
                })
                .collect(),
        )?;
        Ok(RetargetedClip {
            clip,
            carried,
            source_contacts: contacts,
            failed_solves: failed,
        })
    }

    /// How far the target's ground moves from one frame to the next under a clip made in
    /// place (zero under one that travels): the source's treadmill carried over.
    fn ground_step(&self, contacts: &SourceContacts) -> DVec3 {
        self.transfer.carry_ground_velocity(contacts.treadmill) * contacts.frame_time
    }

    /// One frame: the carried-over `pose` solved with the planted feet held (a foot's hold is
    /// set where it is when its source foot plants, on the ground) and the skin above the
    /// ground.
    pub(super) fn solve_frame(
        &self,
        pose: &SkeletonPose,
        planted: &[bool],
        holds: &mut [Option<DVec3>],
        ground: &dyn Ground,
        last: Option<&PoseSolution>,
    ) -> Result<PoseSolution, RetargetError> {
        let map = self.transfer.map();
        let up = map.axes[1].0.normalize_or(DVec3::Y);
        let globals = self.model.skeleton().global_transforms(pose);
        let skin = self.model.skin_welded(pose);
        let mut effectors = Vec::new();
        for (k, &(_, foot)) in map.feet.iter().enumerate() {
            if !planted[k] {
                holds[k] = None;
                continue;
            }
            // Held where it planted across the ground, at the height the carried-over pose
            // gives it now (a paw shifting its weight rises and sinks as the source's does),
            // raised by as much as its sole is below the ground (the proportions' error).
            let at = globals[foot].translation;
            let planted_at = *holds[k].get_or_insert(at);
            let lowest = self.soles[k]
                .iter()
                .map(|&v| skin[v as usize])
                .map(|p| {
                    ground
                        .cast_down(p + up * self.size, -up, 4.0 * self.size)
                        .map_or(0.0, |hit| (p - hit.point).dot(up))
                })
                .fold(f64::INFINITY, f64::min);
            let raise = if lowest.is_finite() {
                (-lowest).max(0.0)
            } else {
                0.0
            };
            let hold = planted_at - up * planted_at.dot(up) + up * (at.dot(up) + raise);
            effectors.push(Effector {
                joint: foot,
                goal: EffectorGoal::Position(hold),
                weight: 1.0,
            });
            // The foot (and its toes) turn as the source's do (a heel-to-toe roll), where it
            // stands: the floor does not flip a toe to lift its tip.
            let skeleton = self.model.skeleton();
            for j in std::iter::once(foot).chain(skeleton.children(foot).iter().copied()) {
                effectors.push(Effector {
                    joint: j,
                    goal: EffectorGoal::Orientation(rotation_of(&globals[j].matrix3)),
                    weight: 1.0,
                });
            }
        }
        let root = map.root.1;
        effectors.push(Effector {
            joint: root,
            goal: EffectorGoal::Position(globals[root].translation),
            weight: 1.0,
        });
        let sampling = FloorSampling::for_size(self.size, 0.1, -up);
        let (floor, _) = Floor::cast(&skin, ground, &sampling);
        let constraints = PoseConstraints {
            effectors,
            stiffness: (self.settings.stiffness > 0.0)
                .then(|| ReferenceStiffness::uniform(pose.clone(), self.settings.stiffness)),
            floor: Some(floor),
            shape_rest: Some(pose.clone()),
            ..PoseConstraints::default()
        };
        let options = PoseSolveOptions {
            max_iterations: self.settings.iterations,
            ..PoseSolveOptions::default()
        };
        let start = match last {
            Some(last) => PoseStart::Near { pose, last },
            None => PoseStart::Pose(pose),
        };
        let solution = self
            .solver
            .solve(&constraints, &options, start, &|| false)?;
        if solution.pose.local.iter().all(|t| t.is_valid()) {
            Ok(solution)
        } else {
            Err(RetargetError::NonFiniteSolve)
        }
    }
}

/// The source's leg length in `pose` (its chains to the feet), or 1.
pub(super) fn source_leg(skeleton: &Skeleton, pose: &SkeletonPose, map: &SkeletonMap) -> f64 {
    let g = skeleton.global_transforms(pose);
    let lengths: Vec<f64> = map
        .feet
        .iter()
        .filter_map(|&(foot, _)| {
            let chain = map.chains.iter().find(|c| c.source.last() == Some(&foot))?;
            Some(
                chain
                    .source
                    .windows(2)
                    .map(|w| g[w[0]].translation.distance(g[w[1]].translation))
                    .sum::<f64>(),
            )
        })
        .filter(|l| *l > 1e-12)
        .collect();
    if lengths.is_empty() {
        1.0
    } else {
        lengths.iter().sum::<f64>() / lengths.len() as f64
    }
}

/// How well a retargeted clip keeps the source's motion and its contacts (the benchmark's and
/// the tests' measures).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RetargetQuality {
    /// The largest horizontal move of a target foot joint from one frame to the next while its
    /// source foot is planted in both, over the target's height: against its ground, which
    /// moves under a clip made in place ([`SourceContacts::treadmill`]).
    pub foot_slide_max: f64,
    /// The deepest target skin vertex below the ground, over the model's size (0 when none is
    /// below).
    pub penetration_max: f64,
    /// The 95th percentile, over frames and mapped limb segments, of the angle between the
    /// target's segment and the source's, each measured in its hips' frame (degrees).
    pub limb_direction_error_deg_p95: f64,
    /// The largest change of a target bone's length against the rest pose (world units over
    /// the target's size).
    pub bone_length_error_max: f64,
}

impl Retargeter {
    /// Measures `poses` (the target's, one per source frame) against the source's `frames`
    /// and `contacts` on `ground`.
    pub fn quality(
        &self,
        frames: &[SkeletonPose],
        poses: &[SkeletonPose],
        contacts: &SourceContacts,
        ground: &dyn Ground,
    ) -> RetargetQuality {
        let map = self.transfer.map();
        let (source, target) = (self.transfer.source(), self.model.skeleton());
        let up = map.axes[1].0.normalize_or(DVec3::Y);
        let rest = self.transfer.target_rest();
        let height = {
            let skin = self.model.skin_welded(rest);
            let hs = skin.iter().map(|p| p.dot(up));
            hs.clone().fold(f64::NEG_INFINITY, f64::max) - hs.fold(f64::INFINITY, f64::min)
        }
        .max(1e-12);
        let mut q = RetargetQuality::default();
        let tg: Vec<_> = poses.iter().map(|p| target.global_transforms(p)).collect();
        let horizontal = |v: DVec3| v - up * v.dot(up);
        let ground_step = self.ground_step(contacts);
        for (k, &(_, foot)) in map.feet.iter().enumerate() {
            for f in 1..poses.len().min(contacts.planted[k].len()) {
                if contacts.planted[k][f] && contacts.planted[k][f - 1] {
                    let moved = horizontal(
                        tg[f][foot].translation - tg[f - 1][foot].translation - ground_step,
                    )
                    .length();
                    q.foot_slide_max = q.foot_slide_max.max(moved / height);
                }
            }
        }
        let gr = target.global_transforms(rest);
        for pose in poses {
            let skin = self.model.skin_welded(pose);
            for p in skin {
                let depth = ground
                    .cast_down(p + up * self.size, -up, 4.0 * self.size)
                    .map_or(0.0, |hit| (hit.point - p).dot(up));
                q.penetration_max = q.penetration_max.max(depth / self.size);
            }
            let gp = target.global_transforms(pose);
            for (j, joint) in target.joints().iter().enumerate() {
                // The root (hips) moves by design; every other bone keeps its length.
                if let Some(p) = joint.parent.filter(|_| j != map.root.1) {
                    let rest_length = gr[j].translation.distance(gr[p].translation);
                    let length = gp[j].translation.distance(gp[p].translation);
                    q.bone_length_error_max = q
                        .bone_length_error_max
                        .max((length - rest_length).abs() / self.size);
                }
            }
        }
        // Limb directions with each hips' turn since rest taken out, in the target's axes.
        let align = self.transfer.align();
        let (hips_s0, hips_t0) = self.transfer.rest_root_rotations();
        let mut angles = Vec::new();
        for (f, pose) in frames.iter().enumerate().take(poses.len()) {
            let sg = source.global_transforms(pose);
            let turn_s = rotation_of(&sg[map.root.0].matrix3) * hips_s0.inverse();
            let turn_t = rotation_of(&tg[f][map.root.1].matrix3) * hips_t0.inverse();
            for chain in &map.chains {
                if chain.source.len() < 2 || chain.target.len() != chain.source.len() {
                    continue;
                }
                for k in 0..chain.source.len() - 1 {
                    let ds = sg[chain.source[k + 1]].translation - sg[chain.source[k]].translation;
                    let dt =
                        tg[f][chain.target[k + 1]].translation - tg[f][chain.target[k]].translation;
                    let (Some(ds), Some(dt)) = (ds.try_normalize(), dt.try_normalize()) else {
                        continue;
                    };
                    let in_s = align * (turn_s.inverse() * ds);
                    let in_t = turn_t.inverse() * dt;
                    angles.push(in_s.angle_between(in_t).to_degrees());
                }
            }
        }
        angles.sort_by(f64::total_cmp);
        q.limb_direction_error_deg_p95 = angles
            .get((angles.len() * 95 / 100).min(angles.len().saturating_sub(1)))
            .copied()
            .unwrap_or(0.0);
        q
    }
}
