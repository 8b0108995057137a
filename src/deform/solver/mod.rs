//! The ARAP solver: precompute (weights, elimination, Cholesky factorization) and
//! warm-startable local/global iterations.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `budget.rs` | [`SlicedSolve`]: one solve spread over several calls, each running at most a budget of iterations — how a frame bounds its solving where the solve cannot leave the frame's thread (the web: Bevy's task pools run on the browser's main thread). |
//! | `contacts.rs` | Free vertices kept above an [`Obstacle`]: after each global step, the free positions are projected onto the half-spaces of the vertices that went below, in the norm of the factored Laplacian `L`. |
//! | `iterate.rs` | The iterations of a solve: plain or Anderson-accelerated local/global, and L-BFGS on the energy. |
//! | `layout.rs` | The mesh in the solvers' memory order, shared by every constraint set of a topology; which cells a set fits; pinning of components no constraint reaches. |
//! | `newton.rs` | Truncated Newton on the ARAP energy: each step solves `H d = −g` by conjugate gradients preconditioned with the factored Laplacian (stopping at negative curvature, Steihaug), then line-searches `d`. |
//! | `precompute.rs` | Precompute: a constraint set's free vertices, their elimination order and factor. |
//! | `solve.rs` | A solve: the starting state, the iterations of the chosen acceleration, the result. |
//! | `system.rs` | The free vertices' Laplacian systems: assembly in elimination order and numeric factorization (now, or on first use). |

use std::sync::Arc;

use super::constraints::{ConstraintError, Constraints, Role};
use super::factor::LowerFactor;
use super::rotation::{add_outer, fit_rotation_warm};
use super::topology::{MeshError, Topology, WeightMode};
use glam::{DMat3, DQuat, DVec3};

mod budget;
mod contacts;
mod iterate;
mod layout;
mod newton;
mod precompute;
mod solve;
mod system;
use super::lbfgs::Lbfgs;
use super::parallel::{Threading, for_chunks, sum_chunks_pair, zip_chunks};
pub use budget::{SliceProgress, SlicedSolve};
use layout::CellKind;
pub(crate) use layout::Layout;
use system::LazyFactor;

/// Source of [`ArapSolver`] ids.
static NEXT_SOLVER_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Which faer Cholesky variant computes the factor. Either way the factor is then compacted
/// into the solver's own compressed-column layout, so this choice only changes how long the
/// factorization takes, never the result or the speed of the iterations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Factorization {
    /// Let faer decide from the flop ratio (default).
    #[default]
    Auto,
    /// Column-by-column factorization: cheapest on small meshes.
    Simplicial,
    /// Dense supernodes: faster factorization on large meshes.
    Supernodal,
}

/// Fill-reducing elimination order of the free vertices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FillOrdering {
    /// One geometric cut into two independent halves, each ordered by approximate minimum
    /// degree (default). The factor holds 9–16 % more non-zeros than with minimum degree on
    /// the whole system (benchmark meshes), but the triangular solves run on two threads.
    #[default]
    Halves,
    /// faer's approximate minimum degree; the solves run on one thread.
    MinimumDegree,
}

/// Settings fixed for the lifetime of a factorization.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SolverSettings {
    /// Edge weights of the ARAP energy.
    pub weights: WeightMode,
    /// Optional region of interest (one flag per welded vertex). Vertices outside it are not
    /// unknowns: they stay at their rest position, which keeps the system small on big meshes.
    pub region_of_interest: Option<Vec<bool>>,
    /// Cholesky variant (affects the factorization time only: the iterations always solve
    /// with the factor compacted to compressed columns).
    pub factorization: Factorization,
    /// Fill-reducing ordering.
    pub ordering: FillOrdering,
    /// Where the loops of the iterations run (the positions are the same either way).
    pub threading: Threading,
    /// Weight of each free vertex's pull toward an inertial target
    /// ([`ArapSolver::solve_inertial`]), added to the system's diagonal: `m / (k h²)` for a
    /// vertex mass `m`, an ARAP stiffness `k` and a time step `h` ([`crate::deform::dynamics`]).
    /// 0 (the default): the static problem.
    pub inertia: f64,
}

/// Per-solve options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    /// Maximum local/global iterations.
    pub max_iterations: u32,
    /// Stop when the relative energy decrease of one iteration falls below this (0 = never).
    pub tolerance: f64,
    /// How the iterations are accelerated beyond plain local/global.
    pub acceleration: Acceleration,
}

/// Acceleration of the local/global iteration. Every accelerated iterate is checked against the
/// energy and replaced by the plain local/global step when it does not lower it, so the energy
/// never rises whichever is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Acceleration {
    /// Plain local/global (Sorkine & Alexa 2007): one rotation fit and one back-substitution per
    /// iteration.
    #[default]
    None,
    /// Anderson acceleration (Peng et al. 2018) combining the last `depth` iterates (3 is a good
    /// value). It pays off in long solves from a cold start.
    Anderson {
        /// Previous iterates combined.
        depth: usize,
    },
    /// L-BFGS on the energy with the factored Laplacian as the initial inverse Hessian (Liu,
    /// Bouaziz & Kavan 2017), line-searched: per iteration one back-substitution, one rotation
    /// fit per line-search trial and one gradient pass.
    Lbfgs {
        /// Curvature pairs kept.
        depth: usize,
    },
    /// Truncated Newton: per iteration, conjugate gradients on the exact Hessian (rotation
    /// fits differentiated) preconditioned by the factored Laplacian, up to `max_cg`
    /// back-substitutions, then a line search. Far fewer iterations than the others on soft
    /// modes, each costing several back-substitutions ([`SolveStats::back_substitutions`]).
    Newton {
        /// Conjugate-gradient steps per iteration at most.
        max_cg: u32,
    },
}

impl Acceleration {
    /// Anderson acceleration of `depth` iterates, or plain local/global when `depth` is 0.
    pub fn anderson(depth: usize) -> Self {
        match depth {
            0 => Self::None,
            depth => Self::Anderson { depth },
        }
    }
}

impl Default for SolveOptions {
    fn default() -> Self {
        Self {
            max_iterations: 10,
            tolerance: 1e-3,
            acceleration: Acceleration::None,
        }
    }
}

/// Where the iterations start.
#[derive(Debug, Clone, Copy)]
pub enum InitialGuess<'a> {
    /// The paper's detail-preserving uniform Laplacian solve (use when an edit starts).
    Laplacian,
    /// The rest pose with identity rotations.
    Rest,
    /// The previous solution (warm start: use for every frame of a drag).
    Warm(&'a Solution),
}

/// Why a precompute or solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// Invalid mesh.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Invalid constraints.
    #[error(transparent)]
    Constraint(#[from] ConstraintError),
    /// The system is not positive definite (raw cotangent weights on an obtuse mesh).
    #[error("the system matrix is not positive definite (try clamped cotangent weights)")]
    NotPositiveDefinite,
    /// The solve was given constraints whose vertex sets differ from the factorized ones.
    #[error("constraint vertex sets changed since precompute; precompute again")]
    ConstraintSetChanged,
    /// A warm-start solution does not belong to this mesh.
    #[error("warm-start solution has {got} vertices, the mesh has {expected}")]
    WarmStartMismatch {
        /// Vertices in the given solution.
        got: usize,
        /// Vertices in the mesh.
        expected: usize,
    },
    /// The cancel callback asked to stop.
    #[error("solve cancelled")]
    Cancelled,
    /// The result contained NaN or infinity (nothing is returned).
    #[error("the solve produced non-finite positions")]
    NonFinite,
    /// Allocation or factorization bookkeeping failed.
    #[error("sparse factorization failed: {0}")]
    Factorization(String),
}

/// Statistics of one precompute.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PrecomputeStats {
    /// Number of unknown vertices.
    pub free_vertices: usize,
    /// Vertices kept at rest because their connected component has no constraint.
    pub unconstrained_component_vertices: usize,
    /// Whether faer chose (or was told to use) the supernodal variant.
    pub supernodal: bool,
    /// Non-zeros of the Cholesky factor as the iterations store it.
    pub factor_nonzeros: usize,
    /// Seconds finding the free vertices (and, for a topology's first solver, building the
    /// vertex layout every later one shares).
    pub assembly_s: f64,
    /// Seconds ordering (restricting the whole mesh's order, or building the free graph and
    /// ordering it), assembling both matrices in elimination order and analysing the factor's
    /// structure.
    pub symbolic_s: f64,
    /// Seconds in the numeric factorization of the cotangent Laplacian (and compacting it to
    /// the solve layout).
    pub numeric_s: f64,
    /// Whether the triangular solves run on two threads (independent halves in the
    /// elimination order).
    pub parallel_solves: bool,
    /// Whether the iterations' loops run on rayon's pool ([`SolverSettings::threading`]).
    pub parallel_iterations: bool,
}

/// Statistics of one solve.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SolveStats {
    /// Local/global iterations done.
    pub iterations: u32,
    /// Normalised energy of the initial guess (not available for warm starts).
    pub initial_energy: Option<f64>,
    /// Normalised energy after each iteration (solver weights).
    pub energies: Vec<f64>,
    /// Seconds computing the initial guess.
    pub init_s: f64,
    /// Seconds in local steps (rotation fits).
    pub local_s: f64,
    /// Seconds assembling right-hand sides.
    pub rhs_s: f64,
    /// Seconds in triangular solves.
    pub global_s: f64,
    /// Seconds in the acceleration: Anderson extrapolation, L-BFGS directions, Newton CG.
    pub acceleration_s: f64,
    /// Extrapolated iterates that did not lower the energy and were replaced by the plain
    /// local/global step (each costs one extra local step).
    pub rejected_extrapolations: u32,
    /// Back-substitutions with the factored Laplacian (one per plain, Anderson or L-BFGS
    /// iteration, more for Newton and for rejected line searches): the comparable unit of
    /// work across accelerations.
    pub back_substitutions: u32,
    /// Total seconds.
    pub total_s: f64,
    /// The cancel callback stopped the iterations early (the result is the last completed
    /// iteration).
    pub cancelled: bool,
    /// Free vertices held on the obstacle's surface at the end
    /// ([`ArapSolver::solve_above`]; 0 without one).
    pub contacts: usize,
}

impl SolveStats {
    /// Final energy (after the last iteration, or of the initial guess).
    pub fn final_energy(&self) -> f64 {
        self.energies
            .last()
            .copied()
            .or(self.initial_energy)
            .unwrap_or(0.0)
    }
}

/// Result of a solve, in welded vertex order.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Deformed positions.
    pub positions: Vec<DVec3>,
    /// Best-fit rotation of each vertex' cell (rotate normals and tangents with these).
    pub rotations: Vec<DQuat>,
    /// Statistics.
    pub stats: SolveStats,
    /// The L-BFGS curvature pairs the solve ended with ([`Acceleration::Lbfgs`]): a solve
    /// warm-started from this solution by the same solver continues with them.
    pub(crate) history: CarriedHistory,
}

/// L-BFGS curvature pairs and the solver (precompute) they belong to. Compares equal always: it
/// is a cache, not part of the result.
#[derive(Debug, Clone, Default)]
pub(crate) struct CarriedHistory(Option<(u64, Lbfgs)>);

impl PartialEq for CarriedHistory {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Solution {
    /// The rest pose as a solution (identity rotations).
    pub fn rest(topology: &Topology) -> Self {
        Self {
            positions: topology.positions().to_vec(),
            rotations: vec![DQuat::IDENTITY; topology.vertex_count()],
            stats: SolveStats::default(),
            history: CarriedHistory::default(),
        }
    }
}

const NOT_FREE: u32 = u32::MAX;
const CHUNK: usize = 512;

/// A factorized ARAP problem for one mesh and one set of constrained vertices.
///
/// `precompute` does everything that depends only on the mesh and the constraint *sets*;
/// [`ArapSolver::solve`] then accepts any handle transforms/targets for those sets and only
/// back-substitutes. Constrained vertices are eliminated, so the system is SPD.
///
/// Connected components (of positive-weight edges) containing no constrained vertex would make
/// the system singular; they keep their rest pose, as do isolated vertices.
pub struct ArapSolver {
    /// Unique per precompute (tells whose curvature pairs a warm start carries).
    id: u64,
    topology: Arc<Topology>,
    settings: SolverSettings,
    constraints: Constraints,
    /// The mesh in the solver's memory order (shared by every solver of the topology); every
    /// per-vertex array below follows it.
    layout: Arc<Layout>,
    roles: Vec<Role>,
    /// Free vertices in elimination order.
    free: Vec<u32>,
    free_index: Vec<u32>,
    /// What each vertex's cell does in a solve.
    cells: Vec<CellKind>,
    cot_factor: LowerFactor,
    /// The uniform Laplacian, factored by the first solve that starts from it (a warm-started
    /// interaction never does, and a new grab should not wait for it).
    uniform: LazyFactor,
    /// Whether the iterations' loops run on rayon's pool ([`SolverSettings::threading`]).
    parallel: bool,
    stats: PrecomputeStats,
    /// Columns of the inverse system for vertices held on an obstacle.
    columns: std::sync::Mutex<contacts::ColumnCache>,
}

impl std::fmt::Debug for ArapSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ArapSolver")
            .field("vertices", &self.topology.vertex_count())
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl ArapSolver {
    /// The mesh this solver was built for.
    pub fn topology(&self) -> &Arc<Topology> {
        &self.topology
    }

    /// Settings used at precompute.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Factors the uniform Laplacian of the paper's initial guess now rather than in the first
    /// solve that starts from it ([`InitialGuess::Laplacian`]): for benchmarks that time the
    /// precompute with both factorizations, as other ARAP implementations do.
    pub fn factor_initial_guess(&self) -> Result<(), SolveError> {
        self.uniform.get().map(|_| ())
    }

    /// Precompute statistics.
    pub fn precompute_stats(&self) -> &PrecomputeStats {
        &self.stats
    }

    /// True when `constraints` has the vertex sets this solver was factorized for.
    pub fn accepts(&self, constraints: &Constraints) -> bool {
        self.constraints.same_sets(constraints)
    }

    /// Fits rotations for active (`true`) or inactive (`false`) cells; returns their summed
    /// un-normalised energy. Cells at rest get the identity (their energy is zero) unfitted.
    #[allow(clippy::needless_range_loop)] // CSR rows: `e` indexes weights and neighbours alike
    fn local_step(
        &self,
        x: &[DVec3],
        quats: &mut [DQuat],
        mats: &mut [DMat3],
        active: bool,
    ) -> f64 {
        let layout = &self.layout;
        let (rest, offsets, nbrs) = (&layout.rest, &layout.offsets, &layout.nbrs);
        // A time step's iterations stop short of the static minimum anyway (one to three per
        // step): its rotation fits need not go to rounding level.
        let rotation_tolerance = if self.settings.inertia > 0.0 {
            1e-7
        } else {
            1e-10
        };
        sum_chunks_pair(self.parallel, quats, mats, CHUNK, |c, qs, ms| {
            let mut energy = 0.0;
            for k in 0..qs.len() {
                let i = c * CHUNK + k;
                let kind = self.cells[i];
                if (kind == CellKind::Active) != active {
                    continue;
                }
                if kind == CellKind::Rest {
                    qs[k] = DQuat::IDENTITY;
                    ms[k] = DMat3::IDENTITY;
                    continue;
                }
                let mut a = DMat3::ZERO;
                let mut sq = 0.0;
                for e in offsets[i] as usize..offsets[i + 1] as usize {
                    let w = layout.weights[e];
                    if w == 0.0 {
                        continue;
                    }
                    let j = nbrs[e] as usize;
                    let d = x[i] - x[j];
                    add_outer(&mut a, w, d, rest[i] - rest[j]);
                    sq += w * d.length_squared();
                }
                let q = fit_rotation_warm(&a, qs[k], 40, rotation_tolerance);
                let r = DMat3::from_quat(q);
                let tr = r.x_axis.dot(a.x_axis) + r.y_axis.dot(a.y_axis) + r.z_axis.dot(a.z_axis);
                energy += sq + self.layout.cell_rest_sq[i] - 2.0 * tr;
                qs[k] = q;
                ms[k] = r;
            }
            energy
        })
        .max(0.0)
    }

    /// `b_i = Σ_j (w_ij/2)(R_i + R_j)(p_i − p_j) + Σ_{j known} w_ij x_j`, in elimination
    /// order. Computed in the solver's memory order into `by_vertex` (one-rings read from
    /// nearby memory), then gathered: walking the elimination order directly would jump
    /// across the mesh at every vertex.
    #[allow(clippy::needless_range_loop)] // CSR rows: `e` indexes weights and neighbours alike
    fn arap_rhs(&self, x: &[DVec3], mats: &[DMat3], by_vertex: &mut [DVec3], rhs: &mut [DVec3]) {
        let layout = &self.layout;
        let (rest, offsets, nbrs) = (&layout.rest, &layout.offsets, &layout.nbrs);
        for_chunks(self.parallel, by_vertex, CHUNK, |c, out| {
            for (k, b_out) in out.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                if self.free_index[i] == NOT_FREE {
                    continue;
                }
                let mut b = 0.5 * (mats[i] * self.layout.weighted_rest_sum[i]);
                for e in offsets[i] as usize..offsets[i + 1] as usize {
                    let w = layout.weights[e];
                    let j = nbrs[e] as usize;
                    b += (0.5 * w) * (mats[j] * (rest[i] - rest[j]));
                    if self.free_index[j] == NOT_FREE {
                        b += w * x[j];
                    }
                }
                *b_out = b;
            }
        });
        self.gather_free(by_vertex, rhs);
    }

    /// `out_i = Σ_j w_ij (u_i − u_j) − ½ M_i Σ_j w_ij (p_i − p_j) − Σ_j ½ w_ij M_j (p_i − p_j)`
    /// for the free vertices, in elimination order (computed per vertex into `by_vertex`, then
    /// gathered, as [`Self::arap_rhs`]). With `(u, M) = (x, R)` it is the energy's gradient
    /// `L x − b(R)` (a quarter of it); with `(v, dR[v])` its Hessian applied to `v`.
    #[allow(clippy::needless_range_loop)] // CSR rows: `e` indexes weights and neighbours alike
    fn laplacian_minus_rotated(
        &self,
        u: &[DVec3],
        mats: &[DMat3],
        by_vertex: &mut [DVec3],
        out: &mut [DVec3],
    ) {
        let layout = &self.layout;
        let (rest, offsets, nbrs) = (&layout.rest, &layout.offsets, &layout.nbrs);
        for_chunks(self.parallel, by_vertex, CHUNK, |c, chunk| {
            for (k, o) in chunk.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                if self.free_index[i] == NOT_FREE {
                    continue;
                }
                let mut g = -0.5 * (mats[i] * self.layout.weighted_rest_sum[i]);
                for e in offsets[i] as usize..offsets[i + 1] as usize {
                    let w = layout.weights[e];
                    let j = nbrs[e] as usize;
                    g += w * (u[i] - u[j]) - (0.5 * w) * (mats[j] * (rest[i] - rest[j]));
                }
                *o = g;
            }
        });
        self.gather_free(by_vertex, out);
    }

    /// `out[k] = by_vertex[free[k]]`: per-vertex values of the free vertices in elimination
    /// order.
    fn gather_free(&self, by_vertex: &[DVec3], out: &mut [DVec3]) {
        zip_chunks(self.parallel, out, &self.free, CHUNK, |out, free| {
            for (o, &i) in out.iter_mut().zip(free) {
                *o = by_vertex[i as usize];
            }
        });
    }

    /// The covariance `Σ_j w_ij (u_i − u_j)(p_i − p_j)ᵀ` of cell `i` under the field `u`.
    fn cell_covariance(&self, i: usize, u: &[DVec3]) -> DMat3 {
        let layout = &self.layout;
        let mut a = DMat3::ZERO;
        for e in layout.offsets[i] as usize..layout.offsets[i + 1] as usize {
            let j = layout.nbrs[e] as usize;
            add_outer(
                &mut a,
                layout.weights[e],
                u[i] - u[j],
                layout.rest[i] - layout.rest[j],
            );
        }
        a
    }

    /// Uniform Laplacian right-hand side `deg_i p_i − Σ_j p_j + Σ_{j known} x_j`.
    fn uniform_rhs(&self, x: &[DVec3], rhs: &mut [DVec3]) {
        let layout = &self.layout;
        let (rest, offsets, nbrs) = (&layout.rest, &layout.offsets, &layout.nbrs);
        zip_chunks(self.parallel, rhs, &self.free, CHUNK, |rhs, free| {
            for (out, &i) in rhs.iter_mut().zip(free) {
                let i = i as usize;
                let range = offsets[i] as usize..offsets[i + 1] as usize;
                let mut b = range.len() as f64 * rest[i];
                for e in range {
                    let j = nbrs[e] as usize;
                    b -= rest[j];
                    if self.free_index[j] == NOT_FREE {
                        b += x[j];
                    }
                }
                *out = b;
            }
        });
    }

    fn back_substitute(&self, factor: &LowerFactor, rhs: &mut [DVec3], x: &mut [DVec3]) {
        factor.solve_in_place(rhs, self.parallel);
        self.write_free(rhs, x);
    }

    /// Writes free positions given in elimination order into `x`.
    fn write_free(&self, free_positions: &[DVec3], x: &mut [DVec3]) {
        for (&i, v) in self.free.iter().zip(free_positions) {
            x[i as usize] = *v;
        }
    }
}
