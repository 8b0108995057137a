//! The skinning-space ARAP solver: rigid bones as the unknowns.

use std::sync::Arc;
use std::time::Instant;

use glam::{DAffine3, DMat3, DMat4, DQuat, DVec3, DVec4};

mod block_cholesky;
mod energy;
mod gauss_newton;
mod setup;
mod shape_rest;

use super::PoseError;
use super::effectors::{
    CentroidEffector, Effector, ExtraInputs, ExtraTerms, Param, ReferenceStiffness,
};
use super::limits::JointLimits;
use super::model::SkinnedModel;
use super::skeleton::{JointTransform, SkeletonPose};
use crate::deform::constraints::same_keys;
use crate::deform::{Handle, RigidTransform};
use energy::ClusterFit;
use gauss_newton::{BlockPattern, HessianScratch, solve_damped};
use setup::{check_indices, joint_frames, nonzero_blocks, set_sums};

/// A joint driven to a rigid motion of where it was in the reference pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointHandle {
    /// Joint index in the skeleton.
    pub joint: usize,
    /// Motion applied to the joint's reference world transform (pivot usually the joint's
    /// reference position).
    pub transform: RigidTransform,
}

/// What a pose solve must respect. Vertex indices are *welded* (map render indices with
/// `model.topology().welded_set(..)`). Targets are rigid motions of where the vertices (or
/// joints) were in the reference pose given to [`PoseSolver::new`]. The *sets* fix the
/// precompute; the transforms may change every solve.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseConstraints {
    /// Vertex sets moved rigidly (grab the hand's vertices).
    pub handles: Vec<Handle>,
    /// Vertices kept where they were in the reference pose.
    pub fixed_vertices: Vec<u32>,
    /// Joints kept where they were in the reference pose, position and orientation (pin the
    /// feet).
    pub fixed_joints: Vec<usize>,
    /// Joints moved rigidly (grab the hand joint).
    pub joint_handles: Vec<JointHandle>,
    /// Effectors on joints: positions, orientations, aims, each blended in by a weight (see
    /// [`super::effectors`]). They may change freely between solves.
    pub effectors: Vec<Effector>,
    /// Centroids of vertex sets to world points.
    pub centroid_effectors: Vec<CentroidEffector>,
    /// A per-joint pull towards a reference pose ("preferred angles").
    pub stiffness: Option<ReferenceStiffness>,
    /// Joint limits every step respects ([`super::limits`]); `None` = every joint free.
    pub limits: Option<Arc<JointLimits>>,
    /// The pose whose shape the ARAP energy keeps (`None`: the bind pose). With it, the
    /// energy is tilted so this pose is at rest: a solve with nothing pulling leaves it as it
    /// is, and effectors bend the body away from it (an additive layer sets it to the
    /// animation under it; see `shape_rest.rs`). The energies in [`PoseSolveStats`] are then
    /// relative to it and may be negative.
    pub shape_rest: Option<SkeletonPose>,
}

impl PoseConstraints {
    fn same_sets(&self, other: &PoseConstraints) -> bool {
        self.fixed_vertices == other.fixed_vertices
            && self.fixed_joints == other.fixed_joints
            && same_keys(&self.handles, &other.handles, |h| &h.vertices)
            && same_keys(&self.joint_handles, &other.joint_handles, |h| &h.joint)
    }
}

/// Settings of a [`PoseSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolverSettings {
    /// Stiffness of vertex constraints relative to the mesh's mean ARAP stiffness per vertex.
    /// Constraints are soft (a skeleton cannot always reach every target); at the default a
    /// reachable target is met to ~1e-4 of the model size.
    pub constraint_stiffness: f64,
    /// Stiffness of a joint constraint, in vertex constraints: a pinned joint weighs as much
    /// as this many pinned vertices, with its orientation measured at the model's size
    /// (points one bounding diagonal from the joint), so a pin holds against a handle pulling
    /// on a long lever.
    pub joint_stiffness: f64,
}

impl Default for PoseSolverSettings {
    fn default() -> Self {
        Self {
            constraint_stiffness: 1e4,
            joint_stiffness: 1000.0,
        }
    }
}

/// Per-solve options (the same shape as [`crate::deform::SolveOptions`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolveOptions {
    /// Maximum local/global iterations.
    pub max_iterations: u32,
    /// Stop when the relative energy decrease of one iteration falls below this (0 = never).
    pub tolerance: f64,
}

impl Default for PoseSolveOptions {
    fn default() -> Self {
        Self {
            max_iterations: 10,
            tolerance: 1e-6,
        }
    }
}

/// Statistics of one pose solve.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseSolveStats {
    /// Iterations done.
    pub iterations: u32,
    /// Objective of the start pose (ARAP with the start's cluster rotations + constraint
    /// penalties), normalised by the rest energy scale `Σ w‖e‖²`.
    pub initial_energy: f64,
    /// Normalised objective after each iteration; never rises.
    pub energies: Vec<f64>,
    /// Trial bone steps that raised the energy (and were shortened or re-damped).
    pub rejected_steps: u32,
    /// Seconds fitting cluster rotations.
    pub local_s: f64,
    /// Seconds in the bone steps (Gauss–Newton systems, damped solves, trial poses).
    pub global_s: f64,
    /// Of `global_s`, seconds building the Gauss–Newton systems.
    pub system_s: f64,
    /// Total seconds.
    pub total_s: f64,
    /// The cancel callback stopped the iterations early (the result is the last completed
    /// iteration).
    pub cancelled: bool,
}

/// A solved pose.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseSolution {
    /// The skeleton pose: local transforms, bones at their reference lengths.
    pub pose: SkeletonPose,
    /// Best-fit rotation of each cluster (warm-start data).
    pub cluster_rotations: Vec<DQuat>,
    /// The Levenberg–Marquardt damping the solve ended with (warm-start data).
    pub damping: f64,
    /// With a [`PoseConstraints::shape_rest`]: each cluster's best-fit rotation at that rest
    /// pose (warm-start data for the next solve's tilt, whose rest moves little from frame
    /// to frame); empty without one.
    pub shape_rest_rotations: Vec<DQuat>,
    /// Statistics.
    pub stats: PoseSolveStats,
}

/// Where a pose solve starts.
#[derive(Debug, Clone, Copy)]
pub enum PoseStart<'a> {
    /// From this pose (the character's current pose, or the reference pose); cluster
    /// rotations are fitted to it.
    Pose(&'a SkeletonPose),
    /// From a previous solution: its pose, cluster rotations and step damping (use for every
    /// frame of a drag).
    Warm(&'a PoseSolution),
    /// From `pose`, with the cluster rotations and damping of `last` as first guesses: for a
    /// start that moved a little since that solution (an additive layer starts every frame
    /// from the clip's new pose plus the layer). The rotations are refined by Newton steps
    /// instead of fitted from scratch.
    Near {
        /// The pose the solve starts from.
        pose: &'a SkeletonPose,
        /// A solution of the same solver from a pose close to `pose`.
        last: &'a PoseSolution,
    },
}

impl<'a> PoseStart<'a> {
    /// Where a solve after `last` (a solution of the same solver, if any) starts: on from
    /// `last` ([`PoseStart::Warm`]); or, when `pose` is a new start (`moved`), at `pose`
    /// seeded by `last` ([`PoseStart::Near`]); at `pose` without a `last`.
    pub fn following(last: Option<&'a PoseSolution>, pose: &'a SkeletonPose, moved: bool) -> Self {
        match (last, moved) {
            (Some(last), false) => Self::Warm(last),
            (Some(last), true) => Self::Near { pose, last },
            (None, _) => Self::Pose(pose),
        }
    }
}

/// Levenberg–Marquardt damping of a cold start (relative to the Hessian's diagonal).
const INITIAL_DAMPING: f64 = 1e-4;

/// A vertex set's precomputed sums for a rigid target: `Σ M_iᵀ p_iᵀ`, `Σ M_iᵀ`, `Σ p_i`,
/// `Σ ‖p_i‖²` with `p_i` the reference positions.
#[derive(Debug, Clone)]
struct SetSums {
    mp: Vec<f64>,
    m: Vec<f64>,
    p: DVec3,
    pp: f64,
    count: f64,
}

/// A factorized pose problem for one skinned model and one constraint set.
///
/// **How the result stays a skeleton.** The unknowns are not free affine joint transforms
/// but rigid bones: a world-space rotation increment per joint (about the joint's origin)
/// and a translation per root joint. Non-root joints keep their local translations (and
/// scales), so every bone keeps its length and every child stays attached to its parent by
/// construction. Each iteration fits one rotation per weight cluster (local step), then
/// takes one Gauss–Newton step on the bone rotations against the reduced energy, with a
/// backtracking line search so the energy never rises (global step). Both steps cost
/// O(joints² + clusters · joints), independent of the vertex count.
#[derive(Debug, Clone)]
pub struct PoseSolver {
    model: Arc<SkinnedModel>,
    constraints: PoseConstraints,
    reference_globals: Vec<DAffine3>,
    /// The non-zero 4 × 4 blocks `(k, l, Q_kl)` of `Q` plus the constraint penalties (the
    /// dense 4J × 4J matrix is only assembled in [`PoseSolver::new`]).
    q_blocks: Vec<(usize, usize, DMat4)>,
    /// The bone parameters solved for.
    params: Vec<(usize, ParamKind)>,
    handle_sums: Vec<SetSums>,
    fixed_b: Vec<f64>,
    fixed_c: f64,
    joint_u: Vec<[DVec4; 4]>,
    /// The non-zero rows of every cluster's `K_c` (row index, row), cluster after cluster
    /// (a cluster's vertices are skinned by a few joints: most of its 4J rows are zero).
    cluster_rows: Vec<(u32, DVec3)>,
    /// Where each cluster's rows start in `cluster_rows` (one more entry than clusters).
    cluster_row_start: Vec<usize>,
    vertex_weight: f64,
    joint_weight: f64,
    length_scale: f64,
}

impl PoseSolver {
    /// Precomputes the constraint penalties for `constraints` with targets relative to
    /// `reference` (usually the pose the character is in when the grab starts).
    pub fn new(
        model: Arc<SkinnedModel>,
        constraints: &PoseConstraints,
        reference: &SkeletonPose,
        settings: PoseSolverSettings,
    ) -> Result<Self, PoseError> {
        let skeleton = model.skeleton();
        skeleton.check_pose(reference)?;
        check_indices(constraints, model.topology().vertex_count(), skeleton.len())?;
        let joints = skeleton.len();
        let dim = 4 * joints;
        let reference_positions = model.skin_welded(reference);
        let reference_globals = skeleton.global_transforms(reference);
        let vertex_weight = settings.constraint_stiffness * model.mean_degree.max(1e-12);
        let joint_weight = vertex_weight * settings.joint_stiffness;
        let length_scale = model.topology().bounding_diagonal().max(1e-12);
        let mut q = model.q.clone();
        let mut sums = |vertices: &[u32]| {
            set_sums(
                &model,
                &reference_positions,
                vertices,
                vertex_weight,
                &mut q,
            )
        };
        let handle_sums: Vec<SetSums> = constraints
            .handles
            .iter()
            .map(|h| sums(&h.vertices))
            .collect();
        let fixed = sums(&constraints.fixed_vertices);
        let mut fixed_b = vec![0.0; dim * 3];
        let fixed_c = set_target(
            &fixed,
            &RigidTransform::IDENTITY,
            vertex_weight,
            &mut fixed_b,
        );
        let joint_u = joint_frames(skeleton, length_scale);
        for &j in constraints
            .fixed_joints
            .iter()
            .chain(constraints.joint_handles.iter().map(|h| &h.joint))
        {
            let u = &joint_u[j];
            for r in 0..4 {
                for c in 0..4 {
                    q[(4 * j + r) * dim + 4 * j + c] += joint_weight * u[r].dot(u[c]);
                }
            }
        }
        let (block_nonzero, q_blocks) = nonzero_blocks(&q, joints);
        let params = parameters_for(skeleton, &block_nonzero);
        let (cluster_rows, cluster_row_start) = sparse_cluster_rows(&model);
        Ok(Self {
            cluster_rows,
            cluster_row_start,
            params,
            model,
            constraints: constraints.clone(),
            q_blocks,
            reference_globals,
            handle_sums,
            fixed_b,
            fixed_c,
            joint_u,
            vertex_weight,
            joint_weight,
            length_scale,
        })
    }

    /// The model.
    pub fn model(&self) -> &Arc<SkinnedModel> {
        &self.model
    }

    /// The constraints the solver was built for.
    pub fn constraints(&self) -> &PoseConstraints {
        &self.constraints
    }

    /// True when `constraints` has the same sets as the ones precomputed (only transforms
    /// differ), so [`PoseSolver::solve`] accepts it.
    pub fn accepts(&self, constraints: &PoseConstraints) -> bool {
        self.constraints.same_sets(constraints)
    }

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
        let extras = self.extra_terms(constraints);
        let limits = constraints.limits.as_deref();
        let (mut rotations, mut damping, mut exact) = match warm {
            Some(w) if w.cluster_rotations.len() == clusters => {
                (w.cluster_rotations.clone(), w.damping, false)
            }
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
        let c0 = self.model.c0.max(1e-300);
        let mut pose = start.clone();
        if let Some(limits) = limits {
            limits.project(&mut pose);
        }
        let mut current = self.posed(pose);
        let mut stats = PoseSolveStats::default();
        let mut b = vec![0.0; b_pen.len()];
        let mut scratch = HessianScratch::take();
        let mut last = f64::NAN;
        for it in 0..options.max_iterations {
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
                b: &b,
                constant: self.model.c0 + c_pen,
                extras: &extras,
            };
            let f0 = self.energy(&current, &objective);
            if it == 0 {
                stats.initial_energy = f0 / c0;
                last = f0;
            }
            // Levenberg–Marquardt: damp the Gauss–Newton step until it lowers the energy.
            let (mut h, mut g) = self.gauss_newton_system(&current, &b, &mut scratch);
            if !extras.is_empty() {
                let params = self.param_list();
                extras.add_system(&current.globals, &current.skin, &params, &mut h, &mut g);
            }
            if let Some(limits) = limits {
                self.restrict_hinges(limits, &current.globals, &mut h, &mut g);
            }
            // The effector terms may couple joints the shape energy does not: read their
            // blocks off the matrix; else the system's own pattern (hinges add none).
            let pattern = if extras.is_empty() {
                scratch.pattern()
            } else {
                std::rc::Rc::new(BlockPattern::of(&h, g.len()))
            };
            stats.system_s += t.elapsed().as_secs_f64();
            let step = DampedSystem {
                h: &h,
                g: &g,
                f0,
                pattern: &pattern,
            };
            let accepted = self.damped_step(
                &current,
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
                    current = next;
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
        let pose = current.pose;
        if !pose.local.iter().all(|t| t.is_valid()) {
            return Err(PoseError::NonFiniteResult);
        }
        stats.total_s = started.elapsed().as_secs_f64();
        Ok(PoseSolution {
            pose,
            cluster_rotations: rotations,
            damping,
            shape_rest_rotations,
            stats,
        })
    }

    /// The effector and stiffness terms of `constraints`, with targets blended from the
    /// reference pose this solver was built for.
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
        super::effectors::validate(
            skeleton,
            self.model.topology().vertex_count(),
            &constraints.effectors,
            &constraints.centroid_effectors,
            constraints.stiffness.as_ref(),
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

    /// A pose with its global and skinning transforms and the stacked skinning matrix.
    fn posed(&self, pose: SkeletonPose) -> Posed {
        let skeleton = self.model.skeleton();
        let globals = skeleton.global_transforms(&pose);
        let skin = skinning(&globals, skeleton);
        let x = self.model.stack(&skin);
        let qx = self.q_times(&x);
        Posed {
            pose,
            globals,
            skin,
            x,
            qx,
        }
    }

    /// The energy of a posed skeleton.
    fn energy(&self, posed: &Posed, objective: &Objective) -> f64 {
        self.objective(&posed.x, &posed.qx, objective.b, objective.constant)
            + objective.extras.energy(&posed.globals, &posed.skin)
    }

    /// One Levenberg–Marquardt step from `current`: a rejected step is first shortened along
    /// its direction (cheap: no new factorization), then re-solved with more damping. The
    /// accepted pose and its energy, or `None` after twelve rejections.
    fn damped_step(
        &self,
        current: &Posed,
        system: &DampedSystem,
        objective: &Objective,
        limits: Option<&JointLimits>,
        damping: &mut f64,
        stats: &mut PoseSolveStats,
    ) -> Option<(Posed, f64)> {
        for _ in 0..12 {
            let step = solve_damped(system.h, system.g, *damping, system.pattern);
            for (k, length) in [1.0, 0.5].into_iter().enumerate() {
                let mut candidate = retract(&current.pose, &current.globals, &step, length, self);
                if let Some(limits) = limits {
                    limits.project(&mut candidate);
                }
                let candidate = self.posed(candidate);
                let f = self.energy(&candidate, objective);
                if f.is_finite() && f <= system.f0 {
                    *damping = if k == 0 {
                        (*damping / 2.0).max(1e-9)
                    } else {
                        *damping * 2.0
                    };
                    return Some((candidate, f));
                }
                stats.rejected_steps += 1;
            }
            *damping *= 4.0;
        }
        None
    }

    fn extra_terms<'a>(&'a self, constraints: &'a PoseConstraints) -> ExtraTerms<'a> {
        let skeleton = self.model.skeleton();
        let reference_skinning = skinning(&self.reference_globals, skeleton);
        ExtraTerms::new(
            skeleton,
            &ExtraInputs {
                effectors: &constraints.effectors,
                centroids: &constraints.centroid_effectors,
                stiffness: constraints.stiffness.as_ref(),
                reference_globals: &self.reference_globals,
                reference_skinning: &reference_skinning,
                influences: self.model.influences(),
                relative_inertia: self.model.relative_inertia(),
                bind: self.model.bind_positions(),
                joint_weight: self.joint_weight,
                vertex_weight: self.vertex_weight,
                length_scale: self.length_scale,
            },
        )
    }

    /// The bone parameters as the effector terms see them.
    fn param_list(&self) -> Vec<Param> {
        self.params
            .iter()
            .map(|&(j, kind)| match kind {
                ParamKind::Rotation => Param::Rotation(j),
                ParamKind::Translation => Param::Translation(j),
            })
            .collect()
    }

    /// The linear (`B`, 4J × 3) and constant terms of the constraint penalties for the
    /// current targets.
    fn penalty_terms(&self, constraints: &PoseConstraints) -> (Vec<f64>, f64) {
        let mut b = self.fixed_b.clone();
        let mut c = self.fixed_c;
        for (h, s) in constraints.handles.iter().zip(&self.handle_sums) {
            c += set_target(s, &h.transform, self.vertex_weight, &mut b);
        }
        let dim = 4 * self.model.skeleton().len();
        let fixed = self
            .constraints
            .fixed_joints
            .iter()
            .map(|&j| (j, RigidTransform::IDENTITY));
        let moved = constraints
            .joint_handles
            .iter()
            .map(|h| (h.joint, h.transform));
        for (j, t) in fixed.chain(moved) {
            let g = self.reference_globals[j];
            // Rigid motion p ↦ pivot + R(p − pivot) + T as an affine: R p + (pivot − R pivot + T).
            let motion = DAffine3::from_mat3_translation(
                DMat3::from_quat(t.rotation),
                t.pivot - t.rotation * t.pivot + t.translation,
            );
            let target = motion * g;
            let v = affine_rows(&target); // 3 × 4 rows of G*
            // V = G* D; B_j += λ U Vᵀ; const += λ‖V‖².
            let vd: [DVec4; 3] = std::array::from_fn(|r| {
                DVec4::new(
                    v[r][0] * self.length_scale,
                    v[r][1] * self.length_scale,
                    v[r][2] * self.length_scale,
                    v[r][3],
                )
            });
            let u = &self.joint_u[j];
            for r in 0..4 {
                for col in 0..3 {
                    b[(4 * j + r) * 3 + col] += self.joint_weight * u[r].dot(vd[col]);
                }
            }
            c += self.joint_weight * vd.iter().map(|r| r.length_squared()).sum::<f64>();
        }
        debug_assert_eq!(dim * 3, b.len());
        (b, c)
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum ParamKind {
    Rotation,
    Translation,
}

/// The bone parameters: a rotation per joint, a translation per root — only for joints whose
/// subtree moves something (a weighted vertex or a constrained joint); the others would be
/// zero rows of the system.
fn parameters_for(skeleton: &super::Skeleton, block_nonzero: &[bool]) -> Vec<(usize, ParamKind)> {
    let n = skeleton.len();
    let mut active: Vec<bool> = (0..n).map(|j| block_nonzero[j * n + j]).collect();
    for j in (0..n).rev() {
        if let Some(p) = skeleton.joints()[j].parent {
            active[p] |= active[j];
        }
    }
    // Children before parents, root translations last: the order the block Cholesky
    // eliminates in, so that a joint's elimination fills in only among its ancestors.
    let mut out: Vec<(usize, ParamKind)> = (0..n)
        .rev()
        .filter(|&j| active[j])
        .map(|j| (j, ParamKind::Rotation))
        .collect();
    out.extend(
        (0..n)
            .filter(|&j| active[j] && skeleton.joints()[j].parent.is_none())
            .map(|j| (j, ParamKind::Translation)),
    );
    out
}

/// A pose with what the energy and its derivatives read of it.
struct Posed {
    pose: SkeletonPose,
    globals: Vec<DAffine3>,
    skin: Vec<DAffine3>,
    /// The stacked skinning matrices `X` and `Q X`.
    x: Vec<f64>,
    qx: Vec<f64>,
}

/// The non-zero rows of each cluster's `K_c` in the model's dense `k` (clusters × 4J × 3),
/// and where each cluster's start.
fn sparse_cluster_rows(model: &SkinnedModel) -> (Vec<(u32, DVec3)>, Vec<usize>) {
    let dim = 4 * model.skeleton().len();
    let mut rows = Vec::new();
    let mut start = vec![0];
    for c in 0..model.cluster_count() {
        let k = &model.k[c * dim * 3..][..dim * 3];
        rows.extend(
            k.chunks_exact(3)
                .enumerate()
                .map(|(row, v)| (row as u32, DVec3::new(v[0], v[1], v[2])))
                .filter(|(_, v)| *v != DVec3::ZERO),
        );
        start.push(rows.len());
    }
    (rows, start)
}

/// What an iteration's energy is made of besides the pose: the linear term of the rotation
/// fit and penalties, its constant, and the effector, limit and stiffness terms.
struct Objective<'a> {
    b: &'a [f64],
    constant: f64,
    extras: &'a ExtraTerms<'a>,
}

/// An iteration's Gauss–Newton system and the energy it starts from.
struct DampedSystem<'a> {
    h: &'a [f64],
    g: &'a [f64],
    f0: f64,
    /// Where `h`'s Cholesky factor has non-zero blocks.
    pattern: &'a BlockPattern,
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

/// Applies `t · step` to `pose`: rotation increments (world space, about each joint) become
/// local rotation changes; root translations move the roots.
fn retract(
    pose: &SkeletonPose,
    globals: &[DAffine3],
    step: &[DVec3],
    t: f64,
    solver: &PoseSolver,
) -> SkeletonPose {
    let skeleton = solver.model.skeleton();
    let mut out = pose.clone();
    for (p, &(j, kind)) in solver.params.iter().enumerate() {
        let d = step[p] * t;
        let local: &mut JointTransform = &mut out.local[j];
        match kind {
            ParamKind::Rotation => {
                let qp = skeleton.parent_rotation(globals, j);
                let inc = qp.inverse() * DQuat::from_scaled_axis(d) * qp;
                local.rotation = (inc * local.rotation).normalize();
            }
            ParamKind::Translation => {
                let lin = skeleton.parent_linear(globals, j);
                if lin.determinant().abs() > 1e-300 {
                    local.translation += lin.inverse() * d;
                }
            }
        }
    }
    out
}

fn skinning(globals: &[DAffine3], skeleton: &super::Skeleton) -> Vec<DAffine3> {
    globals
        .iter()
        .zip(skeleton.joints())
        .map(|(g, j)| *g * j.inverse_bind)
        .collect()
}

/// Rows of an affine as a 4 × 4 matrix (last row 0 0 0 1).
fn affine_rows(a: &DAffine3) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for (r, row) in m.iter_mut().enumerate().take(3) {
        for (c, v) in row.iter_mut().enumerate().take(3) {
            *v = a.matrix3.col(c)[r];
        }
        row[3] = a.translation[r];
    }
    m[3][3] = 1.0;
    m
}

/// Adds `λ Σ M_iᵀ t_iᵀ` for targets `t_i = motion(p_i)` to `b`; returns `λ Σ ‖t_i‖²`.
fn set_target(s: &SetSums, motion: &RigidTransform, weight: f64, b: &mut [f64]) -> f64 {
    if s.count == 0.0 {
        return 0.0;
    }
    let r = DMat3::from_quat(motion.rotation);
    let c = motion.pivot - r * motion.pivot + motion.translation;
    // Σ M_iᵀ (R p_i + c)ᵀ = (Σ M_iᵀ p_iᵀ) Rᵀ + (Σ M_iᵀ) cᵀ
    for (row, m) in s.m.iter().enumerate() {
        let mp = DVec3::new(s.mp[row * 3], s.mp[row * 3 + 1], s.mp[row * 3 + 2]);
        let v = r * mp + c * *m;
        b[row * 3] += weight * v.x;
        b[row * 3 + 1] += weight * v.y;
        b[row * 3 + 2] += weight * v.z;
    }
    weight * (s.pp + 2.0 * c.dot(r * s.p) + s.count * c.length_squared())
}
