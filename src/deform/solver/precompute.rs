//! Precompute: a constraint set's free vertices, their elimination order and factor.

use std::sync::Arc;
use web_time::Instant;

use faer::Side;
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky,
};
use glam::DVec3;

use super::layout::{Layout, cell_kinds, pin_unanchored_components};
use super::system::{FreeLaplacians, LazyFactor, LazySource, numeric};
use super::{
    ArapSolver, ConstraintError, Factorization, FillOrdering, NEXT_SOLVER_ID, NOT_FREE,
    PrecomputeStats, Role, SolveError, SolverSettings,
};
use crate::deform::constraints::Constraints;
use crate::deform::factor::LowerFactor;
use crate::deform::ordering::{dissect, minimum_degree};
use crate::deform::topology::Topology;

impl ArapSolver {
    /// Elimination of the constrained vertices and the Cholesky factorization of the cotangent
    /// Laplacian (the iterations' system). The uniform Laplacian (the initial guess's) is
    /// factored by the first solve from [`InitialGuess::Laplacian`](super::InitialGuess::Laplacian). The mesh's layout in
    /// memory (renumbering, weights, rest sums) is built by the topology's first solver and
    /// shared by all after it, and so is the whole mesh's fill-reducing order (restricted to
    /// each set's free vertices; made by the first set with at least half the vertices free,
    /// or by [`Topology::prepare_elimination_order`]), so a new constraint set costs work in
    /// proportion to its free vertices, little more.
    pub fn precompute(
        topology: Arc<Topology>,
        constraints: &Constraints,
        settings: SolverSettings,
    ) -> Result<Self, SolveError> {
        let t0 = Instant::now();
        let n = topology.vertex_count();
        let roles = constrained_roles(constraints, &settings, n)?;
        // The mesh in the solver's order (built by the topology's first solver), then every
        // per-vertex array in that order.
        let layout = topology
            .derived(settings.weights, |t| Layout::new(t, settings.weights))
            .unwrap_or_else(|| std::sync::Arc::new(Layout::new(&topology, settings.weights)));
        let mut roles = layout.gather(&roles);
        let pinned = pin_unanchored_components(&layout, &mut roles);
        let mut free_index = vec![NOT_FREE; n];
        let mut free: Vec<u32> = (0..n as u32)
            .filter(|&i| roles[i as usize] == Role::Free)
            .collect();
        for (f, &i) in free.iter().enumerate() {
            free_index[i as usize] = f as u32;
        }
        let cells = cell_kinds(&layout, &roles, &free_index);
        let nf = free.len();
        let parallel = settings.threading.parallel_for(nf);
        let mut stats = PrecomputeStats {
            free_vertices: nf,
            parallel_iterations: parallel,
            unconstrained_component_vertices: pinned,
            assembly_s: t0.elapsed().as_secs_f64(),
            ..Default::default()
        };
        let (cot_factor, uniform) = if nf == 0 {
            (LowerFactor::default(), LazyFactor::default())
        } else {
            let t1 = Instant::now();
            let (order, split) =
                fill_order(&topology, &settings, parallel, &layout, &free, &free_index);
            // The solves work in elimination order: the free list takes that order, and the
            // matrices are assembled in it, so faer needs no permutation of its own.
            free = order.iter().map(|&f| free[f as usize]).collect();
            for (k, &i) in free.iter().enumerate() {
                free_index[i as usize] = k as u32;
            }
            let laplacians = FreeLaplacians {
                offsets: &layout.offsets,
                nbrs: &layout.nbrs,
                weights: &layout.weights,
                free: &free,
                free_index: &free_index,
                inertia: settings.inertia,
            };
            factor(&laplacians, settings.factorization, split, t1, &mut stats)?
        };
        Ok(Self {
            id: NEXT_SOLVER_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            topology,
            settings,
            constraints: constraints.clone(),
            roles,
            layout,
            free,
            free_index,
            cells,
            cot_factor,
            uniform,
            parallel,
            stats,
            columns: Default::default(),
        })
    }
}

/// Each welded vertex's role under `constraints`, free vertices outside the settings' region
/// of interest held fixed.
fn constrained_roles(
    constraints: &Constraints,
    settings: &SolverSettings,
    n: usize,
) -> Result<Vec<Role>, SolveError> {
    let mut roles = constraints.roles(n)?;
    constraints.check_values()?;
    if let Some(roi) = &settings.region_of_interest {
        if roi.len() != n {
            return Err(ConstraintError::RegionLength {
                got: roi.len(),
                expected: n,
            }
            .into());
        }
        for (r, inside) in roles.iter_mut().zip(roi) {
            if !inside && *r == Role::Free {
                *r = Role::Fixed;
            }
        }
    }
    Ok(roles)
}

/// The free vertices' elimination order (indices into `free`) and its top-level split: the
/// whole mesh's order restricted to them when it exists or is worth making (at least half the
/// vertices free), else this set ordered afresh on the graph of its free vertices. Solves that
/// run on one thread (`parallel` false) gain nothing from two halves: they take minimum
/// degree, which fills less and costs less to find.
fn fill_order(
    topology: &Topology,
    settings: &SolverSettings,
    parallel: bool,
    layout: &Layout,
    free: &[u32],
    free_index: &[u32],
) -> (Vec<u32>, Option<(usize, usize)>) {
    let (n, nf) = (topology.vertex_count(), free.len());
    let _ = parallel;
    let ordering = settings.ordering;
    let whole = match ordering {
        FillOrdering::Halves if 2 * nf >= n => Some(topology.elimination_order()),
        FillOrdering::Halves => topology.elimination_order_if_made(),
        FillOrdering::MinimumDegree => None,
    };
    if let Some(whole) = whole {
        let d = whole.restricted(|w| {
            let f = free_index[layout.to_solver[w as usize] as usize];
            (f != NOT_FREE).then_some(f)
        });
        return (d.order, d.split);
    }
    let (offsets, nbrs) = (&layout.offsets[..], &layout.nbrs[..]);
    let mut graph_offsets = Vec::with_capacity(nf + 1);
    let mut graph = Vec::new();
    graph_offsets.push(0u32);
    for &i in free {
        let ring = &nbrs[offsets[i as usize] as usize..offsets[i as usize + 1] as usize];
        graph.extend(
            ring.iter()
                .map(|&j| free_index[j as usize])
                .filter(|&fj| fj != NOT_FREE),
        );
        graph_offsets.push(graph.len() as u32);
    }
    match ordering {
        FillOrdering::Halves => {
            let coords: Vec<DVec3> = free.iter().map(|&i| layout.rest[i as usize]).collect();
            let d = dissect(&graph_offsets, &graph, &coords);
            (d.order, d.split)
        }
        FillOrdering::MinimumDegree => (minimum_degree(&graph_offsets, &graph), None),
    }
}

/// Factors the cotangent Laplacian of the free vertices (in elimination order) and prepares
/// the uniform one to be factored on first use; `stats` takes the timings and sizes.
fn factor(
    laplacians: &FreeLaplacians,
    factorization: Factorization,
    split: Option<(usize, usize)>,
    t1: Instant,
    stats: &mut PrecomputeStats,
) -> Result<(LowerFactor, LazyFactor), SolveError> {
    let nf = laplacians.free.len();
    let upper = laplacians.upper();
    let threshold = match factorization {
        Factorization::Auto => SupernodalThreshold::AUTO,
        Factorization::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
        Factorization::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
    };
    // faer's symbolic analysis reads the upper triangle (with the identity ordering); the
    // lower one, with the values, is built meanwhile.
    let (symbolic, system) = rayon::join(
        || {
            let pattern =
                SymbolicSparseColMatRef::new_checked(nf, nf, &upper.col_ptr, None, &upper.rows);
            factorize_symbolic_cholesky(
                pattern,
                Side::Upper,
                SymmetricOrdering::Identity,
                CholeskySymbolicParams {
                    supernodal_flop_ratio_threshold: threshold,
                    ..Default::default()
                },
            )
        },
        || laplacians.lower(),
    );
    let symbolic = symbolic.map_err(|e| SolveError::Factorization(format!("{e:?}")))?;
    let pattern = SymbolicSparseColMatRef::new_checked(nf, nf, &system.col_ptr, None, &system.rows);
    stats.symbolic_s = t1.elapsed().as_secs_f64();
    stats.supernodal = matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_));
    let t2 = Instant::now();
    let cot = numeric(&symbolic, pattern, &system.cotangent, split)?;
    stats.numeric_s = t2.elapsed().as_secs_f64();
    stats.parallel_solves = cot.is_split();
    stats.factor_nonzeros = cot.nonzeros();
    let uniform = LazyFactor {
        source: Some(LazySource {
            symbolic,
            col_ptr: system.col_ptr,
            rows: system.rows,
            values: system.uniform,
            split,
        }),
        factor: Default::default(),
    };
    Ok((cot, uniform))
}
