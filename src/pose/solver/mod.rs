//! The skinning-space ARAP solver: rigid bones as the unknowns. Read top-down:
//!
//! | file | what it holds |
//! |---|---|
//! | `mod.rs` | the API: settings, options, solutions, where a solve starts, [`PoseSolver::new`] (the precompute); the constraints are [`crate::pose::constraints`] |
//! | `params.rs` | the unknowns: a rotation per joint, a translation per root (`Param`) |
//! | `setup.rs` | the precompute's pieces: index checks, vertex-set sums, joint frames, the block pattern |
//! | `solve.rs` | [`PoseSolver::solve`]: the local/global loop (cluster rotations, then one damped Gauss–Newton step), the iterations past the budget for the ground and the holds |
//! | `step.rs` | the Levenberg–Marquardt step: damping, trial steps, the retraction onto the skeleton |
//! | `gauss_newton.rs` | the Gauss–Newton system in the bone parameters and its damped solve |
//! | `damped_step.rs` | one damped solve with the factor, low-rank parts and hinges |
//! | `hinges.rs` | joint limits inside the step (hinges restrict it; cones and twist are projected in `step.rs`) |
//! | `energy/` | the shape energy and the quadratic penalties: `arap.rs`, `penalties.rs`, `holds.rs`, `shape_rest.rs` |
//! | `terms/` | the extra (non-quadratic) terms: effectors, stiffness and balance in `mod.rs`, their residuals and energy in `residuals.rs`, their Jacobians in `jacobians.rs`; the ground's contact and floor terms in `ground.rs`, summed in groups (`floor_groups.rs`) and by moments (`moments.rs`), the raised floor (`raised_floor.rs`); their Gauss–Newton system (`system.rs`) |
//! | `linalg/` | the block-sparse Cholesky factor and the low-rank (Woodbury) parts |

use std::sync::Arc;

use glam::{DAffine3, DMat4, DQuat, DVec3, DVec4};

mod damped_step;
mod energy;
mod gauss_newton;
mod hinges;
mod linalg;
mod params;
mod setup;
mod solve;
mod step;
mod terms;

use crate::pose::solver::energy::penalties::{SetSums, set_target};
use crate::pose::solver::params::{Param, movers_of_joints, parameters_for};

use crate::deform::RigidTransform;
use crate::pose::constraints::PoseConstraints;
use crate::pose::error::PoseError;
use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::skeleton::SkeletonPose;
use crate::pose::solver::setup::{check_indices, joint_frames, nonzero_blocks, set_sums};

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
    /// Iterations past `max_iterations` a solve may take while a vertex kept above the
    /// ground (a contact's patch, the floor) is still through it by more than
    /// [`THROUGH_THE_GROUND`] of the model's size, or a planted patch's vertex is farther
    /// than [`OFF_THE_HOLD`] from its held point: a solve does not end with the skin in the
    /// ground or a planted foot sliding because its budget ran out (0: stop at
    /// `max_iterations` regardless). It also stops there when an iteration improves by less
    /// than `tolerance`.
    pub ground_iterations: u32,
}

/// How far (a share of the model's size) a vertex kept above the ground may still be through
/// it when a solve stops at `max_iterations` ([`PoseSolveOptions::ground_iterations`]).
pub const THROUGH_THE_GROUND: f64 = 1e-3;

/// How far (a share of the model's size) a planted contact's patch vertex may still be from
/// the point it is held at when a solve stops at `max_iterations`
/// ([`PoseSolveOptions::ground_iterations`]).
pub const OFF_THE_HOLD: f64 = 1e-3;

/// The contact skin, a share of the model's size: the one-sided terms that keep skin above
/// the ground act from this height above it (the penalty balances a push at a depth, so a
/// pushed vertex comes to rest on the surface, not under it), and a planted patch vertex is
/// held this far above the point where it touched, along the ground's normal.
pub const CONTACT_SKIN: f64 = 1e-3;

impl Default for PoseSolveOptions {
    fn default() -> Self {
        Self {
            max_iterations: 10,
            tolerance: 1e-6,
            ground_iterations: 6,
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
    /// How much further inside the support polygon than [`Balance::required_inside`] the next
    /// warm solve asks for the centre of mass (world units, warm-start data; 0 without
    /// balance). A penalty leaves the centre of mass out of its region by as much as the body
    /// pushes against it; each solve moves the boost by how far it ended short of (or past)
    /// what balance asks, so over a few frames that is met without a stiffer term (a
    /// multiplier of the method of augmented Lagrangians). It is learned for one support: a
    /// solve over other support points (a foot planted or lifted, a walk) starts again from 0.
    ///
    /// [`Balance::required_inside`]: crate::pose::ground::balance::Balance::required_inside
    pub balance_boost: f64,
    /// Which support (points and gravity, hashed) [`PoseSolution::balance_boost`] was learned
    /// over (warm-start data; 0 without balance).
    pub balance_support: u64,
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
    params: Vec<Param>,
    /// Per joint, the parameters (indices into `params`) that move it.
    joint_movers: Vec<Vec<u32>>,
    /// Each joint's position in the bind pose.
    bind_origins: Vec<DVec3>,
    /// The centre of mass of the skin at its area masses as per-joint sums, once balance is
    /// asked for (the same every solve: a model's thousands of vertices summed once).
    area_mass_sums: std::sync::OnceLock<Vec<(usize, DVec4)>>,
    /// The `Q` blocks with the last planted patches' holds (`energy/holds.rs`).
    held_blocks: crate::pose::solver::energy::holds::HeldBlocks,
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
        let joint_movers = movers_of_joints(skeleton, &params);
        let bind_origins = skeleton.bind_origins();
        let (cluster_rows, cluster_row_start) = sparse_cluster_rows(&model);
        Ok(Self {
            cluster_rows,
            cluster_row_start,
            params,
            joint_movers,
            bind_origins,
            area_mass_sums: std::sync::OnceLock::new(),
            held_blocks: Default::default(),
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
