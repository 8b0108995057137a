//! The mesh in the solvers' memory order, shared by every constraint set of a topology;
//! which cells a set fits; pinning of components no constraint reaches.

use glam::DVec3;
use rayon::prelude::*;

use super::NOT_FREE;
use crate::deform::constraints::Role;
use crate::deform::ordering::spatial_order;
use crate::deform::topology::{RowPiece, Topology, WeightMode, join_rows};

/// The mesh renumbered in a spatial (Z-order curve) order, so the neighbours a local step or a
/// right-hand side reads sit close in memory: on meshes whose file order is scattered
/// (subdivided, edited) this halves the time of those steps. Depends only on the topology and
/// the weight mode, so the topology keeps it for every solver after the first.
#[derive(Debug)]
pub(crate) struct Layout {
    /// Solver index → welded index.
    pub(super) to_welded: Vec<u32>,
    /// Welded index → solver index.
    pub(super) to_solver: Vec<u32>,
    pub(super) offsets: Vec<u32>,
    pub(super) nbrs: Vec<u32>,
    pub(super) weights: Vec<f64>,
    pub(super) rest: Vec<DVec3>,
    /// `Σ_j w_ij (p_i − p_j)` per cell.
    pub(super) weighted_rest_sum: Vec<DVec3>,
    /// `Σ_j w_ij |p_i − p_j|²` per cell.
    pub(super) cell_rest_sq: Vec<f64>,
    /// Sum of `cell_rest_sq`: the energy's normalisation.
    pub(super) rest_norm: f64,
}

/// A memory order for the mesh: its own when neighbours already sit close (generated grids,
/// ring-by-ring bars: mean index distance within a few rows of a √n × √n grid), else a
/// Z-order curve.
fn memory_order(topology: &Topology) -> Vec<u32> {
    let n = topology.vertex_count();
    let (offsets_w, nbrs_w) = (topology.offsets(), topology.neighbor_list());
    let spread = (0..n)
        .into_par_iter()
        .map(|i| {
            nbrs_w[offsets_w[i] as usize..offsets_w[i + 1] as usize]
                .iter()
                .map(|&j| (i as u64).abs_diff(j as u64))
                .sum::<u64>()
        })
        .sum::<u64>() as f64
        / nbrs_w.len().max(1) as f64;
    if spread <= 2.0 * (n as f64).sqrt() {
        (0..n as u32).collect()
    } else {
        spatial_order(topology.positions())
    }
}

impl Layout {
    pub(super) fn new(topology: &Topology, mode: WeightMode) -> Self {
        let weights = topology.weights(mode);
        let (offsets_w, nbrs_w) = (topology.offsets(), topology.neighbor_list());
        let to_welded = memory_order(topology);
        let mut to_solver = vec![0u32; to_welded.len()];
        for (k, &w) in to_welded.iter().enumerate() {
            to_solver[w as usize] = k as u32;
        }
        // Rows renumbered, in parallel chunks. Their order within a row does not matter
        // (the matrices are assembled, sorted, from them later).
        let pieces: Vec<RowPiece> = to_welded
            .par_chunks(4096)
            .map(|rows| {
                let (mut lengths, mut nbrs, mut wts) = (Vec::new(), Vec::new(), Vec::new());
                for &w in rows {
                    let range = offsets_w[w as usize] as usize..offsets_w[w as usize + 1] as usize;
                    nbrs.extend(nbrs_w[range.clone()].iter().map(|&j| to_solver[j as usize]));
                    wts.extend_from_slice(&weights[range.clone()]);
                    lengths.push(range.len() as u32);
                }
                (lengths, nbrs, wts)
            })
            .collect();
        let (offsets, nbrs, weights) = join_rows(&pieces);
        let rest: Vec<DVec3> = to_welded
            .iter()
            .map(|&w| topology.positions()[w as usize])
            .collect();
        let (weighted_rest_sum, cell_rest_sq): (Vec<DVec3>, Vec<f64>) = (0..rest.len())
            .into_par_iter()
            .map(|i| {
                let (mut sum, mut sq) = (DVec3::ZERO, 0.0);
                for e in offsets[i] as usize..offsets[i + 1] as usize {
                    let d = rest[i] - rest[nbrs[e] as usize];
                    sum += weights[e] * d;
                    sq += weights[e] * d.length_squared();
                }
                (sum, sq)
            })
            .unzip();
        let rest_norm = cell_rest_sq.iter().sum();
        Self {
            to_solver,
            to_welded,
            offsets,
            nbrs,
            weights,
            rest,
            weighted_rest_sum,
            cell_rest_sq,
            rest_norm,
        }
    }

    /// Welded order → solver order.
    pub(super) fn gather<T: Copy>(&self, welded: &[T]) -> Vec<T> {
        self.to_welded.iter().map(|&w| welded[w as usize]).collect()
    }

    /// Solver order → welded order.
    pub(super) fn scatter<T: Copy + Default>(&self, solver: &[T]) -> Vec<T> {
        let mut out = vec![T::default(); solver.len()];
        for (&w, &v) in self.to_welded.iter().zip(solver) {
            out[w as usize] = v;
        }
        out
    }
}

/// What a vertex's cell (the vertex and its one-ring) does in a solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum CellKind {
    /// A free vertex in the one-ring: its rotation is fitted at every iteration.
    Active,
    /// Only constrained vertices, some of them moved by a handle or target: fitted once per
    /// solve.
    Constant,
    /// Only fixed vertices, which stay at rest: the rotation is the identity and the energy
    /// zero, with nothing to fit (most of the mesh when a region of interest is solved).
    Rest,
}

/// The [`CellKind`] of every vertex (solver order). Adjacency is symmetric, so a cell is
/// active exactly when its vertex or a neighbour is free.
pub(super) fn cell_kinds(layout: &Layout, roles: &[Role], free_index: &[u32]) -> Vec<CellKind> {
    (0..roles.len())
        .into_par_iter()
        .map(|i| {
            let ring = &layout.nbrs[layout.offsets[i] as usize..layout.offsets[i + 1] as usize];
            let ring_and_self = || ring.iter().map(|&j| j as usize).chain([i]);
            if ring_and_self().any(|j| free_index[j] != NOT_FREE) {
                CellKind::Active
            } else if ring_and_self().all(|j| roles[j] == Role::Fixed) {
                CellKind::Rest
            } else {
                CellKind::Constant
            }
        })
        .collect()
}

/// Fixes the free vertices of every connected component (through non-zero weights) that
/// reaches no constrained vertex: they keep their rest pose, and the system stays
/// non-singular. Returns how many vertices were fixed.
pub(super) fn pin_unanchored_components(layout: &Layout, roles: &mut [Role]) -> usize {
    let (offsets, nbrs, weights) = (&layout.offsets, &layout.nbrs, &layout.weights);
    let n = roles.len();
    let mut pinned = 0usize;
    let mut seen = vec![false; n];
    let mut stack = Vec::new();
    let mut comp = Vec::new();
    for s in 0..n {
        if seen[s] || roles[s] != Role::Free {
            continue;
        }
        comp.clear();
        let mut anchored = false;
        seen[s] = true;
        stack.push(s as u32);
        while let Some(i) = stack.pop() {
            comp.push(i);
            let i = i as usize;
            for e in offsets[i] as usize..offsets[i + 1] as usize {
                if weights[e] == 0.0 {
                    continue;
                }
                let j = nbrs[e] as usize;
                if roles[j] != Role::Free {
                    anchored = true;
                } else if !seen[j] {
                    seen[j] = true;
                    stack.push(j as u32);
                }
            }
        }
        if !anchored {
            pinned += comp.len();
            for &v in &comp {
                roles[v as usize] = Role::Fixed;
            }
        }
    }
    pinned
}
