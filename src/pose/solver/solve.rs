//! [`PoseSolver::solve`]: the local/global loop. Each iteration fits one rotation per weight
//! cluster (the local step, `arap.rs`), builds the Gauss–Newton system in the bone parameters
//! with the effector, stiffness and hinge terms (`gauss_newton.rs`, `terms/`,
//! `hinges.rs`), and takes one damped step that lowers the energy (`step.rs`).

use std::borrow::Cow;

use web_time::Instant;

use glam::{DAffine3, DQuat, DVec4};

use crate::deform::RigidTransform;
use crate::pose::constraints::PoseConstraints;
use crate::pose::error::PoseError;
use crate::pose::ground::GroundPlane;
use crate::pose::ground::floor::Floor;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};
use crate::pose::rig::skin::{VertexSkins, mass_sums};
use crate::pose::solver::damped_step::{damping_weights, diagonal_of};
use crate::pose::solver::energy::arap::{ClusterFit, q_times_into};
use crate::pose::solver::energy::holds::QBlocks;
use crate::pose::solver::gauss_newton::HessianScratch;
use crate::pose::solver::linalg::low_rank;
use crate::pose::solver::step::{DampedSystem, Objective};
use crate::pose::solver::terms::{ExtraInputs, ExtraTerms, validate, validate_ground};
use crate::pose::solver::{
    OFF_THE_HOLD, PoseSolution, PoseSolveOptions, PoseSolveStats, PoseSolver, PoseStart,
    THROUGH_THE_GROUND,
};

/// The smallest share of the energy a step is tried for, whatever the tolerance: the energy
/// is a sum of terms up to ~10¹⁰ times its last digit, and two evaluations of poses a
/// rounding apart differ by ~10⁻¹⁰ of it. Steps promising less (measured: the humanoid's
/// settle tried up to 24 of them an iteration, each rejected on rounding) are not taken.
const ENERGY_RESOLUTION: f64 = 1e-9;
/// Levenberg–Marquardt damping of a cold start (relative to the Hessian's diagonal).
const INITIAL_DAMPING: f64 = 1e-4;
/// The largest [`PoseSolution::balance_boost`], as a share of the model's size: a support the
/// body cannot get over does not wind the boost up without end.
const MAX_BALANCE_BOOST: f64 = 0.1;

/// A pose with what the energy and its derivatives read of it.
pub(super) struct Posed {
    pub(super) pose: SkeletonPose,
    pub(super) globals: Vec<DAffine3>,
    pub(super) skin: Vec<DAffine3>,
    /// The stacked skinning matrices `X` and `Q X`.
    pub(super) x: Vec<f64>,
    pub(super) qx: Vec<f64>,
    /// Each vertex kept above the ground: its height above the ground's skin, as the last
    /// energy of this pose found it ([`ExtraTerms::energy`]).
    pub(super) gaps: Vec<f64>,
    /// The extra terms' energy of this pose, once an energy was taken of it: the shape part
    /// changes with each iteration's cluster rotations, the extra terms' does not (an
    /// accepted trial's is the next iteration's first).
    pub(super) extras_energy: Option<f64>,
}

/// The deepest a vertex kept above the ground is in it, with `gaps` its heights above its
/// plane raised by `raised` (0 past its end; positive when every vertex is above).
fn deepest(gaps: &[f64], raised: &[f64]) -> f64 {
    gaps.iter()
        .enumerate()
        .map(|(k, g)| g + raised.get(k).copied().unwrap_or(0.0))
        .fold(f64::INFINITY, f64::min)
}

impl PoseSolver {
    /// Solves for the pose from `start`. `cancel` is polled between iterations.
    pub fn solve(
        &self,
        constraints: &PoseConstraints,
        options: &PoseSolveOptions,
        start: PoseStart<'_>,
        cancel: &dyn Fn() -> bool,
    ) -> Result<PoseSolution, PoseError> {
        let started = Instant::now();
        self.check_solve(constraints, &start)?;
        let clusters = self.model.cluster_count();
        let (start, warm) = match start {
            PoseStart::Pose(p) => (p, None),
            PoseStart::Warm(s) => (&s.pose, Some(s)),
            PoseStart::Near { pose, last } => (pose, Some(last)),
        };
        let support = constraints.balance.as_ref().map_or(0, |b| b.support_key());
        let boost = warm
            .filter(|w| w.balance_support == support)
            .map_or(0.0, |w| w.balance_boost);
        let mut extras = self.extra_terms(constraints, start, boost);
        let limits = constraints.limits.as_deref();
        // A warm start keeps the cluster rotations but not the damping the last solve ended
        // with: raised by that solve's landscape (a foot planting, the floor), carried over it
        // throttled every step of the next (a walking crowd's 3-iteration solves moved ~1 % of
        // the Gauss–Newton step, and swinging paws went through the ground).
        let (mut rotations, mut damping, mut exact) = match warm {
            Some(w) if w.cluster_rotations.len() == clusters => (
                w.cluster_rotations.clone(),
                w.damping.min(INITIAL_DAMPING),
                false,
            ),
            _ => (vec![DQuat::IDENTITY; clusters], INITIAL_DAMPING, true),
        };
        let (mut b_pen, mut c_pen) = self.penalty_terms(constraints);
        let mut shape_rest_rotations = Vec::new();
        if let Some(rest) = &constraints.shape_rest {
            let guess = warm
                .map(|w| &w.shape_rest_rotations[..])
                .filter(|r| r.len() == clusters);
            let (tilt, constant, fitted) = self.shape_tilt(rest, guess);
            shape_rest_rotations = fitted;
            for (b, t) in b_pen.iter_mut().zip(tilt) {
                *b += t;
            }
            c_pen += constant;
        }
        let q_blocks = self.with_holds(&constraints.contacts, &mut b_pen, &mut c_pen);
        let c0 = self.model.c0.max(1e-300);
        let mut pose = start.clone();
        if let Some(limits) = limits {
            limits.project(&mut pose);
        }
        let mut current = self.posed(pose, &q_blocks);
        // The buffers of the last replaced or rejected trial pose, for the next trial.
        let mut spare: Option<Posed> = None;
        let mut stats = PoseSolveStats::default();
        let mut b = vec![0.0; b_pen.len()];
        let mut scratch = HessianScratch::take();
        let mut last = f64::NAN;
        // Past the budget only while the skin is through the ground or a planted patch is off
        // its holds.
        let size = self.length_scale;
        // How far each vertex kept above the ground has its plane raised (`raised_floor.rs`).
        let mut raised = Vec::new();
        for it in 0..options
            .max_iterations
            .saturating_add(options.ground_iterations)
        {
            if it >= options.max_iterations {
                let through = deepest(&current.gaps, &raised) < -THROUGH_THE_GROUND * size;
                let off = self.farthest_off_hold(&constraints.contacts, &current.skin);
                if !through && off <= OFF_THE_HOLD * size {
                    break;
                }
                // A vertex the ground's penalty leaves in the ground: its plane raised by its
                // depth (the method of multipliers, `raised_floor.rs`).
                if through && extras.raise_floor(&current.gaps, &mut raised) {
                    last = f64::NAN;
                    current.extras_energy = None;
                }
            }
            if cancel() {
                stats.cancelled = true;
                break;
            }
            let t = Instant::now();
            let fit = if exact {
                ClusterFit::Exact
            } else {
                ClusterFit::Newton(4)
            };
            self.local_step(&current.x, &mut rotations, fit);
            exact = false;
            stats.local_s += t.elapsed().as_secs_f64();
            let t = Instant::now();
            b.copy_from_slice(&b_pen);
            self.add_rotation_terms(&rotations, &mut b);
            let objective = Objective {
                q_blocks: &q_blocks,
                b: &b,
                constant: self.model.c0 + c_pen,
                extras: &extras,
            };
            let f0 = self.energy(&mut current, &objective);
            if it == 0 {
                stats.initial_energy = f0 / c0;
                last = f0;
            }
            // Levenberg–Marquardt: damp the Gauss–Newton step until it lowers the energy.
            let (mut h, mut g) = self.gauss_newton_system(&current, &objective, &mut scratch);
            // The coordinates the effector, floor and balance terms act on (their diagonal
            // grew): the damping's floor tells them from the others ([`damping_weights`]).
            let n = g.len();
            let before = diagonal_of(&h, n);
            // Balance's Jacobian reads every joint: kept apart as rank-one parts (`low_rank.rs`).
            let mut low_rank = Vec::new();
            if !extras.is_empty() {
                extras.add_system(
                    (&current.globals, &current.skin, &current.gaps),
                    &self.params,
                    (&mut h, &mut low_rank),
                    &mut g,
                );
            }
            let mut diagonal = diagonal_of(&h, n);
            low_rank::add_diagonal(&low_rank, &mut diagonal);
            let acted_on: Vec<bool> = (0..n)
                .map(|i| diagonal[i] > before[i] + 1e-9 * diagonal[i])
                .collect();
            if let Some(limits) = limits {
                self.restrict_hinges(limits, &current.globals, (&mut h, &mut low_rank), &mut g);
                diagonal = diagonal_of(&h, n);
                low_rank::add_diagonal(&low_rank, &mut diagonal);
            }
            // The effector terms may couple joints the shape energy does not: read their
            // blocks off the matrix; else the system's own pattern (hinges add none).
            let pattern = if extras.is_empty() {
                scratch.pattern()
            } else {
                scratch.pattern_of(&h, g.len())
            };
            let weights = damping_weights(&diagonal, &self.params, &acted_on);
            stats.system_s += t.elapsed().as_secs_f64();
            let step = DampedSystem {
                h: &h,
                low_rank: &low_rank,
                g: &g,
                f0,
                no_progress: (options.tolerance * 0.1).max(ENERGY_RESOLUTION) * f0.abs(),
                pattern: &pattern,
                weights: &weights,
            };
            let accepted = self.damped_step(
                (&current, &mut spare),
                &step,
                &objective,
                limits,
                &mut damping,
                &mut stats,
            );
            stats.global_s += t.elapsed().as_secs_f64();
            scratch.return_matrix(h);
            let f = match accepted {
                Some((next, f)) => {
                    spare = Some(std::mem::replace(&mut current, next));
                    f
                }
                None => f0,
            };
            stats.iterations += 1;
            stats.energies.push(f / c0);
            let decrease = (last - f) / last.abs().max(1e-300);
            last = f;
            if decrease < options.tolerance && it > 0 {
                break;
            }
        }
        scratch.keep();
        let balance_boost = self.next_balance_boost(constraints, &extras, &current, boost);
        let pose = current.pose;
        if !pose.local.iter().all(|t| t.is_valid()) {
            return Err(PoseError::NonFiniteResult);
        }
        stats.total_s = started.elapsed().as_secs_f64();
        Ok(PoseSolution {
            pose,
            cluster_rotations: rotations,
            damping,
            balance_boost,
            balance_support: support,
            shape_rest_rotations,
            stats,
        })
    }

    /// The balance boost for the next warm solve: this one's, moved by how far the centre of
    /// mass ended past what balance asks (down) or short of it (up), within
    /// [0, [`MAX_BALANCE_BOOST`] × size].
    fn next_balance_boost(
        &self,
        constraints: &PoseConstraints,
        extras: &ExtraTerms,
        solved: &Posed,
        boost: f64,
    ) -> f64 {
        let balance = constraints.balance.as_ref().filter(|b| b.weight > 0.0);
        match (balance, extras.balance_inside(&solved.skin)) {
            (Some(b), Some(inside)) if inside.is_finite() && boost.is_finite() => {
                (boost + b.required_inside() - inside)
                    .clamp(0.0, MAX_BALANCE_BOOST * self.length_scale)
            }
            _ => 0.0,
        }
    }

    /// A solve of `constraints` from `start` is possible: the same constraint sets, finite
    /// targets, valid effectors and a start pose of this skeleton.
    fn check_solve(
        &self,
        constraints: &PoseConstraints,
        start: &PoseStart,
    ) -> Result<(), PoseError> {
        if !self.accepts(constraints) {
            return Err(PoseError::ConstraintSetChanged);
        }
        if !targets_valid(constraints) {
            return Err(PoseError::NonFiniteTarget);
        }
        let skeleton = self.model.skeleton();
        validate(
            skeleton,
            self.model.topology().vertex_count(),
            &constraints.effectors,
            &constraints.centroid_effectors,
            constraints.stiffness.as_ref(),
        )?;
        validate_ground(
            constraints,
            skeleton.len(),
            self.model.topology().vertex_count(),
        )?;
        let pose = match start {
            PoseStart::Pose(p) | PoseStart::Near { pose: p, .. } => p,
            PoseStart::Warm(s) => &s.pose,
        };
        skeleton.check_pose(pose)?;
        if let Some(rest) = &constraints.shape_rest {
            skeleton.check_pose(rest)?;
        }
        Ok(())
    }

    /// A pose with its global and skinning transforms, the stacked skinning matrix `X` and
    /// `Q X` (`q_blocks`: the solve's `Q`).
    pub(super) fn posed(&self, pose: SkeletonPose, q_blocks: &QBlocks) -> Posed {
        let mut posed = self.posed_unrefreshed(pose);
        self.refresh(&mut posed, q_blocks);
        posed
    }

    /// A pose with empty buffers, to be [`PoseSolver::refresh`]ed.
    pub(super) fn posed_unrefreshed(&self, pose: SkeletonPose) -> Posed {
        Posed {
            pose,
            globals: Vec::new(),
            skin: Vec::new(),
            x: Vec::new(),
            qx: Vec::new(),
            gaps: Vec::new(),
            extras_energy: None,
        }
    }

    /// Recomputes what `posed` derives from its pose, in its own buffers (a trial step reuses
    /// a rejected or replaced one's: no allocation per trial).
    pub(super) fn refresh(&self, posed: &mut Posed, q_blocks: &QBlocks) {
        let skeleton = self.model.skeleton();
        skeleton.global_transforms_into(&posed.pose, &mut posed.globals);
        posed.skin.clear();
        posed.skin.extend(
            posed
                .globals
                .iter()
                .zip(skeleton.joints())
                .map(|(g, j)| *g * j.inverse_bind),
        );
        self.model.stack_into(&posed.skin, &mut posed.x);
        q_times_into(q_blocks, &posed.x, &mut posed.qx);
        posed.extras_energy = None;
    }

    /// The energy of a posed skeleton (its vertices' heights above the ground and its extra
    /// terms' energy noted in it: taken again of the same pose and terms, only the shape part
    /// is summed again).
    pub(super) fn energy(&self, posed: &mut Posed, objective: &Objective) -> f64 {
        let extras = match posed.extras_energy {
            Some(e) => e,
            None => {
                let e = objective
                    .extras
                    .energy(&posed.globals, &posed.skin, &mut posed.gaps);
                posed.extras_energy = Some(e);
                e
            }
        };
        self.objective(&posed.x, &posed.qx, objective.b, objective.constant) + extras
    }

    /// The effector and stiffness terms of `constraints`, with targets blended from the
    /// reference pose this solver was built for (balance asking `balance_boost` further
    /// inside).
    fn extra_terms<'a>(
        &'a self,
        constraints: &'a PoseConstraints,
        start: &SkeletonPose,
        balance_boost: f64,
    ) -> ExtraTerms<'a> {
        let skeleton = self.model.skeleton();
        let reference_skinning = skinning(&self.reference_globals, skeleton);
        let start_skinning = skinning(&skeleton.global_transforms(start), skeleton);
        let balance = constraints.balance.as_ref().filter(|b| b.weight > 0.0);
        // The centre of mass as per-joint sums: the area masses' kept, given masses' summed.
        let skin = (self.model.bind_positions(), self.model.influences());
        let joints = skeleton.len();
        let mass_sums: Option<Cow<[(usize, DVec4)]>> = balance.map(|b| match b.masses.as_deref() {
            Some(masses) => Cow::Owned(mass_sums(joints, skin, masses)),
            None => Cow::Borrowed(
                &self
                    .area_mass_sums
                    .get_or_init(|| mass_sums(joints, skin, self.model.area_masses()))[..],
            ),
        });
        // The floor's active set: the vertices near or below it where this solve starts.
        let floor: Cow<[(u32, GroundPlane)]> = match &constraints.floor {
            None => Cow::Borrowed(&[]),
            Some(Floor::Plane { plane, band }) => self
                .model
                .skin_welded(start)
                .iter()
                .enumerate()
                .filter(|(_, p)| plane.height(**p) < *band)
                .map(|(v, _)| (v as u32, *plane))
                .collect(),
            Some(Floor::Under(under)) => Cow::Borrowed(under),
        };
        // The vertices' skins, made by the first solve that keeps vertices above a ground.
        let grounded = !constraints.contacts.is_empty() || !floor.is_empty();
        let vertex_skins = match grounded {
            true => self.model.vertex_skins(),
            false => VertexSkins::NONE,
        };
        ExtraTerms::new(
            (skeleton, &self.joint_movers, &self.bind_origins),
            vertex_skins,
            &ExtraInputs {
                balance: balance.zip(mass_sums.as_deref()),
                balance_boost,
                contacts: &constraints.contacts,
                floor: &floor,
                effectors: &constraints.effectors,
                centroids: &constraints.centroid_effectors,
                stiffness: constraints.stiffness.as_ref(),
                reference_globals: &self.reference_globals,
                reference_skinning: &reference_skinning,
                start_skinning: &start_skinning,
                influences: self.model.influences(),
                relative_inertia: self.model.relative_inertia(),
                bind: self.model.bind_positions(),
                joint_weight: self.joint_weight,
                vertex_weight: self.vertex_weight,
                length_scale: self.length_scale,
            },
        )
    }
}

/// Every handle's target is a finite rigid transform.
fn targets_valid(constraints: &PoseConstraints) -> bool {
    let valid = |t: &RigidTransform| t.is_valid();
    constraints.handles.iter().all(|h| valid(&h.transform))
        && constraints
            .joint_handles
            .iter()
            .all(|h| valid(&h.transform))
}

/// Each joint's skinning transform: its global transform times its inverse bind.
pub(super) fn skinning(globals: &[DAffine3], skeleton: &Skeleton) -> Vec<DAffine3> {
    globals
        .iter()
        .zip(skeleton.joints())
        .map(|(g, j)| *g * j.inverse_bind)
        .collect()
}
