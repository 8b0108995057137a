//! Spring bones: chains of joints (tails, ears, hair) that lag, swing and settle after the pose,
//! following the update rule of VRM 1.0's `VRMC_springBone` (read with [`read_vrm_springs`];
//! rigs without the extension: [`SpringRig::from_names`], [`SpringRig::from_ron`]).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `ron_file.rs` | Spring rigs in RON, joints by name, for rigs without a VRM extension ([`SpringRig::from_ron`]). |
//! | `vrm.rs` | Reading VRM 1.0's `VRMC_springBone` extension from a glTF document. |
//!
//! Each joint of a chain but the last carries a bone to the next; the bone's *tail* (the next
//! joint's position) is a point mass integrated in world space (or in the chain's centre
//! joint's space):
//!
//! ```text
//! inertia  = (tail − previous tail) · (1 − drag)
//! stiffness = h · (parent rotation · animated local rotation · bone axis) · stiffness
//! external = h · gravity direction · gravity power
//! next     = tail + inertia + stiffness + external, then put back at the bone's length from
//!            the joint's head, pushed out of every collider (spheres and capsules on joints)
//! ```
//!
//! and the joint turns from its animated rotation by the arc from the bone's animated direction
//! to the tail's. Deviations from the specification, on purpose: the update runs in fixed steps
//! of `h` = 1/60 s ([`SpringSettings::step`]) whatever the frame rate, the parents moving
//! linearly between the frame's start and end, and the frame shows the tails interpolated
//! between the last two steps — a VRM runtime updates once per frame, so its motion depends on
//! the frame rate; this one moves as that runtime does at 60 fps, at any frame rate. Joint
//! limits ([`JointLimits`]) are applied to the turned joints, and a tail inside a collider goes
//! to the nearest point that is both outside it and at its bone's length (VRM pushes it out,
//! then restores the length, which can leave it inside), four passes over the colliders. A
//! frame longer than [`SpringSettings::max_steps`] steps drops the excess time (a hitch); a
//! placement jump beyond [`SpringSettings::teleport_distance`] resets the tails to the
//! animated pose (no whip).

mod ron_file;
mod vrm;

use glam::{DAffine3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::deform::synth::closest_on_segment;
use crate::pose::constraints::limits::JointLimits;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};

pub use crate::pose::springs::ron_file::SpringRonError;
pub use crate::pose::springs::vrm::{VrmSpringError, read_vrm_springs};

/// Rounds of pushing a tail out of the colliders and back to its bone's length per step.
const COLLISION_PASSES: usize = 4;

/// How one joint's bone (to the next joint of its chain) moves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpringJoint {
    /// Skeleton index of the joint.
    pub joint: usize,
    /// Pull back toward the animated direction (VRM `stiffness`, per second).
    pub stiffness: f64,
    /// Share of the velocity lost per step, in [0, 1] (VRM `dragForce`).
    pub drag: f64,
    /// Gravity's pull (VRM `gravityPower`, per second).
    pub gravity_power: f64,
    /// Gravity's direction in world space (VRM `gravityDir`, unit).
    pub gravity_dir: DVec3,
    /// Radius of the tail against colliders (VRM `hitRadius`, world units).
    pub hit_radius: f64,
}

impl SpringJoint {
    /// A joint with the settings VRM exporters use by default (stiffness 1, drag 0.4, no
    /// gravity, hit radius 0.02).
    pub fn new(joint: usize) -> Self {
        Self {
            joint,
            stiffness: 1.0,
            drag: 0.4,
            gravity_power: 0.0,
            gravity_dir: DVec3::NEG_Y,
            hit_radius: 0.02,
        }
    }
}

/// A chain of joints, root first; each joint's bone reaches to the next one, so the last joint
/// is the tail of the chain and its own settings are not used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpringChain {
    /// A name for UIs (VRM's spring name).
    pub name: String,
    /// The joints, root first, each the parent of the next (at least two).
    pub joints: Vec<SpringJoint>,
    /// Indices into [`SpringRig::collider_groups`] that this chain collides with.
    pub collider_groups: Vec<usize>,
    /// The joint whose space the tails move in (VRM `center`), `None` for world space.
    pub center: Option<usize>,
}

/// A collider shape in its joint's space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum SpringColliderShape {
    /// A sphere at `offset`.
    Sphere {
        /// Centre in the joint's space.
        offset: DVec3,
        /// Radius (world units).
        radius: f64,
    },
    /// A capsule from `offset` to `tail`.
    Capsule {
        /// One end in the joint's space.
        offset: DVec3,
        /// The other end in the joint's space.
        tail: DVec3,
        /// Radius (world units).
        radius: f64,
    },
}

/// A collider attached to a joint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpringCollider {
    /// Skeleton index of the joint it moves with.
    pub joint: usize,
    /// Its shape.
    pub shape: SpringColliderShape,
}

/// Time stepping of a [`SpringRig`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpringSettings {
    /// Seconds per step (1/60: what VRM content is tuned for).
    pub step: f64,
    /// Steps per frame at most (a longer frame drops the rest of its time).
    pub max_steps: u32,
    /// A placement move longer than this in one frame (world units) resets the tails.
    pub teleport_distance: f64,
}

impl Default for SpringSettings {
    fn default() -> Self {
        Self {
            step: 1.0 / 60.0,
            max_steps: 8,
            teleport_distance: 1.0,
        }
    }
}

/// The spring chains of one character, its colliders and their groups.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SpringRig {
    /// The chains.
    pub chains: Vec<SpringChain>,
    /// Every collider.
    pub colliders: Vec<SpringCollider>,
    /// Groups of [`SpringRig::colliders`] (indices) that chains refer to.
    pub collider_groups: Vec<Vec<usize>>,
    /// Time stepping.
    pub settings: SpringSettings,
}

/// A spring rig that does not fit its skeleton.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpringError {
    /// A joint index is not in the skeleton.
    #[error("spring chain {chain:?} names joint {joint}, the skeleton has {joints}")]
    JointOutOfRange {
        /// The chain.
        chain: String,
        /// The index.
        joint: usize,
        /// Joints in the skeleton.
        joints: usize,
    },
    /// A chain's joint is not the parent of the next one, or the chain has under two joints.
    #[error("spring chain {chain:?} is not a parent-to-child run of at least two joints")]
    NotAChain {
        /// The chain.
        chain: String,
    },
    /// A setting is not finite, or out of its range.
    #[error(
        "spring chain {chain:?} has a setting out of range (stiffness, gravity power and hit \
         radius ≥ 0, drag in [0, 1], all finite)"
    )]
    InvalidSetting {
        /// The chain (empty for the rig's time stepping).
        chain: String,
    },
    /// A collider is not finite or has no positive radius, names a missing joint, or a group
    /// names a missing collider (or a chain a missing group).
    #[error("spring collider {collider} is invalid (a missing joint or collider, or a radius ≤ 0)")]
    InvalidCollider {
        /// The collider's index (or the group's, for a group that names a missing collider;
        /// or the chain's, for a chain naming a missing group).
        collider: usize,
    },
}

impl SpringRig {
    /// Chains found by joint names: every run of joints whose names contain one of `words`
    /// (case-insensitive: "tail", "ear", "hair", "skirt"), from the first such joint down to
    /// its leaf, each joint with `settings`. Runs that are not a single parent-to-child line
    /// follow the first child.
    pub fn from_names(skeleton: &Skeleton, words: &[&str], settings: SpringJoint) -> Self {
        let words: Vec<String> = words.iter().map(|w| w.to_lowercase()).collect();
        let matches = |j: usize| {
            let name = skeleton.joints()[j].name.to_lowercase();
            words.iter().any(|w| name.contains(w.as_str()))
        };
        let mut chains = Vec::new();
        for j in 0..skeleton.len() {
            let parent_matches = skeleton.joints()[j].parent.is_some_and(matches);
            if !matches(j) || parent_matches {
                continue;
            }
            let mut joints = vec![SpringJoint {
                joint: j,
                ..settings
            }];
            let mut at = j;
            while let Some(&child) = skeleton.children(at).first() {
                joints.push(SpringJoint {
                    joint: child,
                    ..settings
                });
                at = child;
            }
            if joints.len() >= 2 {
                chains.push(SpringChain {
                    name: skeleton.joints()[j].name.clone(),
                    joints,
                    collider_groups: Vec::new(),
                    center: None,
                });
            }
        }
        Self {
            chains,
            ..Default::default()
        }
    }

    /// Checks the rig against `skeleton` (every index in range, chains parent to child,
    /// settings finite).
    pub fn validate(&self, skeleton: &Skeleton) -> Result<(), SpringError> {
        let n = skeleton.len();
        for chain in &self.chains {
            let bad = |joint| SpringError::JointOutOfRange {
                chain: chain.name.clone(),
                joint,
                joints: n,
            };
            if chain.joints.len() < 2 {
                return Err(SpringError::NotAChain {
                    chain: chain.name.clone(),
                });
            }
            for (k, sj) in chain.joints.iter().enumerate() {
                if sj.joint >= n {
                    return Err(bad(sj.joint));
                }
                if k > 0 && skeleton.joints()[sj.joint].parent != Some(chain.joints[k - 1].joint) {
                    return Err(SpringError::NotAChain {
                        chain: chain.name.clone(),
                    });
                }
                let finite = [sj.stiffness, sj.drag, sj.gravity_power, sj.hit_radius]
                    .iter()
                    .all(|v| v.is_finite())
                    && sj.gravity_dir.is_finite();
                let in_range = (0.0..=1.0).contains(&sj.drag)
                    && sj.stiffness >= 0.0
                    && sj.gravity_power >= 0.0
                    && sj.hit_radius >= 0.0;
                if !finite || !in_range {
                    return Err(SpringError::InvalidSetting {
                        chain: chain.name.clone(),
                    });
                }
            }
            if chain.center.is_some_and(|c| c >= n) {
                return Err(bad(chain.center.unwrap_or(0)));
            }
            if let Some(&g) = chain
                .collider_groups
                .iter()
                .find(|&&g| g >= self.collider_groups.len())
            {
                return Err(SpringError::InvalidCollider { collider: g });
            }
        }
        for (k, c) in self.colliders.iter().enumerate() {
            let (radius, points) = match c.shape {
                SpringColliderShape::Sphere { offset, radius } => (radius, [offset, offset]),
                SpringColliderShape::Capsule {
                    offset,
                    tail,
                    radius,
                } => (radius, [offset, tail]),
            };
            let ok = c.joint < n
                && radius.is_finite()
                && radius > 0.0
                && points.iter().all(|p| p.is_finite());
            if !ok {
                return Err(SpringError::InvalidCollider { collider: k });
            }
        }
        for (g, group) in self.collider_groups.iter().enumerate() {
            if group.iter().any(|&c| c >= self.colliders.len()) {
                return Err(SpringError::InvalidCollider { collider: g });
            }
        }
        let s = &self.settings;
        if !(s.step > 0.0 && s.step.is_finite() && s.teleport_distance > 0.0) || s.max_steps == 0 {
            return Err(SpringError::InvalidSetting {
                chain: String::new(),
            });
        }
        Ok(())
    }

    /// Joints of every chain that this rig turns (each chain's joints but its last).
    pub fn driven_joints(&self) -> impl Iterator<Item = usize> + '_ {
        self.chains
            .iter()
            .flat_map(|c| c.joints[..c.joints.len() - 1].iter().map(|j| j.joint))
    }

    /// Joints in all chains, tails included.
    pub fn joint_count(&self) -> usize {
        self.chains.iter().map(|c| c.joints.len()).sum()
    }
}

/// The moving state of a [`SpringRig`]: each bone's tail now and one step before (in its
/// chain's space), the last two steps' tails for display, and how far the steps are ahead of
/// the frame.
#[derive(Debug, Clone, Default)]
pub struct SpringState {
    /// Per chain, per bone: (tail, previous tail).
    tails: Vec<Vec<(DVec3, DVec3)>>,
    /// Per chain, per bone: the tail one step earlier than `tails` (for display between).
    before: Vec<Vec<DVec3>>,
    /// Frame time not yet stepped, seconds: in (−step, 0] after a frame (the last step is at
    /// or just after the frame's time).
    accumulated: f64,
    /// The animated world transforms the last frame ended with (the parents' start for the
    /// next frame's steps), character placement included.
    last_world: Option<Vec<DAffine3>>,
}

impl SpringState {
    /// Forgets the motion: the next [`step_springs`] starts from the animated pose at rest.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Whether the state has started (a first frame was stepped).
    pub fn is_started(&self) -> bool {
        self.last_world.is_some()
    }
}

/// Steps the springs of `rig` by `dt` seconds and turns their joints in `pose` (the animated or
/// posed local transforms on input, the swung ones on output). `placement` puts the
/// character's space into the world (gravity and inertia are the world's); `limits`, when
/// given, are applied to the turned joints. Non-finite input leaves `pose` as it was and resets
/// the state.
pub fn step_springs(
    rig: &SpringRig,
    skeleton: &Skeleton,
    placement: DAffine3,
    pose: &mut SkeletonPose,
    dt: f64,
    limits: Option<&JointLimits>,
    state: &mut SpringState,
) {
    let animated: Vec<DAffine3> = skeleton
        .global_transforms(pose)
        .into_iter()
        .map(|g| placement * g)
        .collect();
    if !(dt.is_finite() && dt >= 0.0 && animated.iter().all(|a| a.is_finite())) {
        state.reset();
        return;
    }
    let settings = rig.settings;
    let teleported = state.last_world.as_ref().is_some_and(|last| {
        let moved = |j: usize| last[j].translation.distance(animated[j].translation);
        rig.chains
            .iter()
            .any(|c| moved(c.joints[0].joint) > settings.teleport_distance)
    });
    if state.tails.len() != rig.chains.len() || teleported || state.last_world.is_none() {
        start_at_rest(rig, &animated, state);
    }
    let start = state.last_world.clone().unwrap_or_else(|| animated.clone());
    // Step until the simulation reaches (or just passes) the frame's time; the frame shows
    // the tails between the last two steps, where its time falls.
    state.accumulated += dt;
    let mut steps = (state.accumulated / settings.step - 1e-9).ceil().max(0.0) as u32;
    if steps > settings.max_steps {
        steps = settings.max_steps;
        state.accumulated = settings.step * f64::from(steps);
    }
    for k in 1..=steps {
        // Where the parents are at this step: along the frame's motion.
        let at = f64::from(k) * settings.step;
        let s = if dt > 0.0 {
            ((at - (state.accumulated - dt)) / dt).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let parents: Vec<DAffine3> = start
            .iter()
            .zip(&animated)
            .map(|(a, b)| interpolate(a, b, s))
            .collect();
        step_once(rig, skeleton, pose, &parents, state);
    }
    state.accumulated -= settings.step * f64::from(steps);
    state.last_world = Some(animated.clone());
    show(rig, skeleton, pose, &animated, state, limits);
}

/// Tails at the animated pose, still.
fn start_at_rest(rig: &SpringRig, animated: &[DAffine3], state: &mut SpringState) {
    state.tails = rig
        .chains
        .iter()
        .map(|c| {
            let space = chain_space(c, animated).inverse();
            c.joints[1..]
                .iter()
                .map(|j| {
                    let p = space.transform_point3(animated[j.joint].translation);
                    (p, p)
                })
                .collect()
        })
        .collect();
    state.before = state
        .tails
        .iter()
        .map(|c| c.iter().map(|t| t.0).collect())
        .collect();
    state.accumulated = 0.0;
    state.last_world = None;
}

/// World ← the space a chain's tails live in.
fn chain_space(chain: &SpringChain, world: &[DAffine3]) -> DAffine3 {
    chain.center.map_or(DAffine3::IDENTITY, |c| world[c])
}

/// Linear motion between two transforms (translation and matrix blended, then the rotation
/// re-orthonormalised through a quaternion slerp).
fn interpolate(a: &DAffine3, b: &DAffine3, s: f64) -> DAffine3 {
    if s >= 1.0 {
        return *b;
    }
    let (sa, ra, ta) = a.to_scale_rotation_translation();
    let (sb, rb, tb) = b.to_scale_rotation_translation();
    DAffine3::from_scale_rotation_translation(sa.lerp(sb, s), ra.slerp(rb, s), ta.lerp(tb, s))
}

/// One step of every chain with the parents at `parents` (world, animated).
fn step_once(
    rig: &SpringRig,
    skeleton: &Skeleton,
    pose: &SkeletonPose,
    parents: &[DAffine3],
    state: &mut SpringState,
) {
    let h = rig.settings.step;
    for (c, chain) in rig.chains.iter().enumerate() {
        let space = chain_space(chain, parents);
        let to_space = space.inverse();
        let colliders = chain_colliders(rig, chain, parents);
        let first = chain.joints[0].joint;
        let mut parent = match skeleton.joints()[first].parent {
            Some(p) => parents[p],
            None => parents[first] * pose.local[first].to_affine().inverse(),
        };
        for (b, pair) in chain.joints.windows(2).enumerate() {
            let (sj, child) = (pair[0], pair[1].joint);
            let animated_local = pose.local[sj.joint].to_affine();
            let head_frame = parent * animated_local;
            let head = head_frame.translation;
            let rest_dir = head_frame.transform_vector3(pose.local[child].translation);
            let length = rest_dir.length();
            let (tail, prev) = state.tails[c][b];
            let (tail_w, prev_w) = (space.transform_point3(tail), space.transform_point3(prev));
            let mut next = tail_w
                + (tail_w - prev_w) * (1.0 - sj.drag)
                + rest_dir.normalize_or_zero() * (h * sj.stiffness)
                + sj.gravity_dir.normalize_or_zero() * (h * sj.gravity_power);
            next = head + (next - head).normalize_or(rest_dir.normalize_or_zero()) * length;
            // Pushed out of each collider and put back at the bone's length, a few times
            // over (VRM does it once: a tail between the two can end up inside).
            for _ in 0..COLLISION_PASSES {
                for (centre_a, centre_b, radius) in &colliders {
                    next = push_out(
                        next,
                        head,
                        length,
                        *centre_a,
                        *centre_b,
                        radius + sj.hit_radius,
                    );
                }
            }
            state.before[c][b] = tail;
            state.tails[c][b] = (to_space.transform_point3(next), tail);
            // The next bone hangs from this one turned to its new tail.
            let turn = DQuat::from_rotation_arc(
                rest_dir.normalize_or_zero(),
                (next - head).normalize_or_zero(),
            );
            parent = turned(head_frame, turn);
        }
    }
}

/// `frame` turned by the world rotation `turn` about its origin.
fn turned(frame: DAffine3, turn: DQuat) -> DAffine3 {
    DAffine3 {
        matrix3: glam::DMat3::from_quat(turn) * frame.matrix3,
        translation: frame.translation,
    }
}

/// The colliders of `chain`'s groups in world space: segment ends and radius (a sphere's
/// ends coincide).
fn chain_colliders(
    rig: &SpringRig,
    chain: &SpringChain,
    world: &[DAffine3],
) -> Vec<(DVec3, DVec3, f64)> {
    chain
        .collider_groups
        .iter()
        .flat_map(|&g| rig.collider_groups[g].iter())
        .map(|&c| {
            let collider = &rig.colliders[c];
            let frame = world[collider.joint];
            match collider.shape {
                SpringColliderShape::Sphere { offset, radius } => {
                    let p = frame.transform_point3(offset);
                    (p, p, radius)
                }
                SpringColliderShape::Capsule {
                    offset,
                    tail,
                    radius,
                } => (
                    frame.transform_point3(offset),
                    frame.transform_point3(tail),
                    radius,
                ),
            }
        })
        .collect()
}

/// `p` pushed out of the capsule `a`–`b` of `radius`, then put back at `length` from `head`.
fn push_out(p: DVec3, head: DVec3, length: f64, a: DVec3, b: DVec3, radius: f64) -> DVec3 {
    let closest = closest_on_segment(p, a, b);
    let away = p - closest;
    let d = away.length();
    if d >= radius || d == 0.0 {
        return p;
    }
    // The tail must stay `length` from the head and `radius` from the collider's centre: on
    // the circle where the two spheres meet, the point nearest the tail. (VRM pushes out, then
    // restores the length, which can leave the tail inside.)
    let axis = closest - head;
    let span = axis.length();
    if span > 0.0 && span < length + radius && span > (length - radius).abs() {
        let along = (span * span + length * length - radius * radius) / (2.0 * span);
        let circle = (length * length - along * along).max(0.0).sqrt();
        let n = axis / span;
        let centre = head + n * along;
        let across = (p - centre) - n * (p - centre).dot(n);
        if let Some(dir) = across.try_normalize() {
            return centre + dir * circle;
        }
    }
    let pushed = closest + away / d * radius;
    head + (pushed - head).normalize_or_zero() * length
}

/// Turns each chain's joints in `pose` toward the tails shown this frame (between the last two
/// steps) from their animated rotations, then applies `limits`.
fn show(
    rig: &SpringRig,
    skeleton: &Skeleton,
    pose: &mut SkeletonPose,
    animated: &[DAffine3],
    state: &SpringState,
    limits: Option<&JointLimits>,
) {
    // `accumulated` is in (−step, 0]: how far the last step is ahead of the frame.
    let alpha = (1.0 + state.accumulated / rig.settings.step).clamp(0.0, 1.0);
    let before = pose.clone();
    for (c, chain) in rig.chains.iter().enumerate() {
        let space = chain_space(chain, animated);
        let first = chain.joints[0].joint;
        let mut parent = match skeleton.joints()[first].parent {
            Some(p) => animated[p],
            None => animated[first] * before.local[first].to_affine().inverse(),
        };
        for (b, pair) in chain.joints.windows(2).enumerate() {
            let (j, child) = (pair[0].joint, pair[1].joint);
            let head_frame = parent * before.local[j].to_affine();
            let head = head_frame.translation;
            let rest_dir = head_frame.transform_vector3(before.local[child].translation);
            let shown = state.before[c][b].lerp(state.tails[c][b].0, alpha);
            let target = space.transform_point3(shown) - head;
            let turn = DQuat::from_rotation_arc(
                rest_dir.normalize_or_zero(),
                target.normalize_or(rest_dir.normalize_or_zero()),
            );
            // The world turn expressed in the joint's local frame: parent⁻¹ · turn · parent.
            let (_, parent_rotation, _) = parent.to_scale_rotation_translation();
            let local_turn = parent_rotation.inverse() * turn * parent_rotation;
            let rotation = (local_turn * before.local[j].rotation).normalize();
            if rotation.is_finite() {
                pose.local[j].rotation = rotation;
            }
            parent *= pose.local[j].to_affine();
        }
    }
    if let Some(limits) = limits {
        limits.project(pose);
    }
}
