//! Welded mesh topology and cotangent edge weights.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `geodesic.rs` | Distances along the mesh surface (edge paths): grab patches and regions of interest. |
//! | `rebase.rs` | A topology carried over to new rest positions: same weld and adjacency, new weights. |
//! | `weld.rs` | Welding: which coincident render vertices become one solver vertex. |

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::ordering::{Dissection, dissect};

mod geodesic;
mod rebase;
mod weld;

use weld::weld;

/// Errors raised while building a [`Topology`] from render-mesh data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The mesh has no vertices.
    #[error("the mesh has no vertices")]
    NoVertices,
    /// The index buffer length is not a multiple of three.
    #[error("index count {0} is not a multiple of 3 (triangle lists only)")]
    IndexCountNotTriangles(usize),
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle index {index} is out of range for {vertex_count} vertices")]
    IndexOutOfRange {
        /// The offending index.
        index: u32,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition {
        /// Index of the offending (render) vertex.
        vertex: usize,
    },
    /// More vertices than a `u32` index can address.
    #[error("the mesh has {0} vertices, more than u32 indices can address")]
    TooManyVertices(usize),
    /// New rest positions for a topology do not match its render vertex count.
    #[error("{got} positions given for a mesh of {expected} render vertices")]
    VertexCountChanged {
        /// Render vertices of the topology.
        expected: usize,
        /// Positions given.
        got: usize,
    },
    /// The index buffer given to rebase a topology is not the one it was built from.
    #[error("the triangles differ from the ones the topology was built from")]
    TrianglesChanged,
}

/// How edge weights are derived from the rest mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WeightMode {
    /// `max(0, ½(cot α + cot β))`: negative weights clamped to zero (default; keeps the
    /// iteration monotone on real meshes).
    #[default]
    ClampedCotangent,
    /// `½(cot α + cot β)` as is. Can make the system indefinite on obtuse meshes.
    RawCotangent,
    /// Every edge weighs 1.
    Uniform,
}

/// Which coincident vertices [`Topology`] merges.
///
/// Render meshes (glTF, OBJ) duplicate vertices at UV and normal seams; solving on the split
/// copies tears the surface along the seam. But two vertices can also share a position
/// without being a seam: a pinch point, a hand modelled resting on a hip, two closed parts
/// that touch. Gluing those makes the surfaces bend together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WeldPolicy {
    /// Weld coincident vertices only where that closes a split seam (default): a vertex is
    /// welded when it lies on a *boundary* edge of the index topology (an edge of one
    /// triangle) that has a twin — another boundary edge between the same two positions. A
    /// closed surface has no boundary edges, so coincident vertices of touching closed parts
    /// stay apart, and so do open borders that merely touch at a point.
    #[default]
    Seams,
    /// Weld every pair of vertices at bit-identical positions.
    AllCoincident,
    /// Weld nothing: the index topology as given.
    None,
}

/// Welded triangle-mesh connectivity with per-edge cotangent weights, in CSR form.
///
/// Coincident vertices are merged as [`WeldPolicy`] says (seams only, by default), and the map
/// from render vertex to welded vertex is kept. All vertex indices used by the solver are
/// *welded* indices.
#[derive(Debug, Clone)]
pub struct Topology {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    render_to_welded: Vec<u32>,
    offsets: Vec<u32>,
    neighbors: Vec<u32>,
    cotangent: Vec<f64>,
    /// Data other modules derive once per [`WeightMode`] and share between every constraint
    /// set (the solver's memory layout), type-erased so the topology does not know them.
    derived: [std::sync::OnceLock<DerivedData>; 3],
    /// Fill-reducing elimination order of the whole mesh (welded indices), made once and
    /// restricted to each constraint set's free vertices; shared with rebased copies (same
    /// graph).
    elimination: std::sync::Arc<std::sync::OnceLock<Dissection>>,
}

/// Positions and triangles that make a mesh: some vertices, all finite, every index in range.
fn check_mesh(positions: &[DVec3], triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    if positions.is_empty() {
        return Err(MeshError::NoVertices);
    }
    if positions.len() > u32::MAX as usize / 2 {
        return Err(MeshError::TooManyVertices(positions.len()));
    }
    if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
        return Err(MeshError::NonFinitePosition { vertex });
    }
    for t in triangles {
        for &i in t {
            if i as usize >= positions.len() {
                return Err(MeshError::IndexOutOfRange {
                    index: i,
                    vertex_count: positions.len(),
                });
            }
        }
    }
    Ok(())
}

/// The cotangent-weighted rows of the welded mesh, in a few pieces of consecutive rows.
///
/// Half-cotangent of each corner, per triangle in parallel. Then every corner's two edges are
/// scattered, in triangle order, into its vertex's raw row, and the rows are merged in
/// parallel: duplicates are summed in raw order, so both ends of an edge add the same
/// contributions in the same (triangle) order and `w_ij == w_ji` exactly.
fn cotangent_rows(welded: &[DVec3], tris: &[[u32; 3]]) -> Vec<RowPiece> {
    let n = welded.len();
    let corners: Vec<[f64; 3]> = tris
        .par_iter()
        .map(|t| half_cotangents(t.map(|i| welded[i as usize])))
        .collect();
    let mut starts = vec![0usize; n + 1];
    for t in tris {
        for &v in t {
            starts[v as usize + 1] += 2;
        }
    }
    for i in 0..n {
        starts[i + 1] += starts[i];
    }
    let mut raw = vec![(0u32, 0.0f64); starts[n]];
    let mut fill = starts[..n].to_vec();
    for (t, half_cot) in tris.iter().zip(&corners) {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            // Edge (a, b) is opposite the corner at c; edge (a, c) the corner at b.
            let at = fill[a as usize];
            raw[at] = (b, half_cot[(k + 2) % 3]);
            raw[at + 1] = (c, half_cot[(k + 1) % 3]);
            fill[a as usize] += 2;
        }
    }
    // A few groups of rows, merged in parallel, each with a marker array over all vertices
    // (4 bytes per vertex per group: the group count is capped).
    let groups = rayon::current_num_threads().clamp(1, 4);
    let per_group = n.div_ceil(groups).max(1);
    (0..n.div_ceil(per_group))
        .into_par_iter()
        .map(|g| merge_rows(&raw, &starts, g * per_group..n.min((g + 1) * per_group), n))
        .collect()
}

/// Merges the raw rows `rows` (duplicate neighbours summed, each row sorted).
fn merge_rows(
    raw: &[(u32, f64)],
    starts: &[usize],
    rows: std::ops::Range<usize>,
    n: usize,
) -> RowPiece {
    // Every edge but a boundary one appears twice: half the raw entries, and a little more,
    // holds the rows.
    let guess = (starts[rows.end] - starts[rows.start]) * 5 / 8;
    let mut lengths = Vec::with_capacity(rows.len());
    let (mut nbrs, mut wts) = (Vec::with_capacity(guess), Vec::with_capacity(guess));
    // `slot_of[j]`: where neighbour `j` sits in the row being merged.
    let mut slot_of = vec![u32::MAX; n];
    for i in rows {
        let before = nbrs.len();
        for &(j, w) in &raw[starts[i]..starts[i + 1]] {
            let slot = &mut slot_of[j as usize];
            if *slot == u32::MAX {
                *slot = nbrs.len() as u32;
                nbrs.push(j);
                wts.push(w);
            } else {
                wts[*slot as usize] += w;
            }
        }
        let row = before..nbrs.len();
        for &j in &nbrs[row.clone()] {
            slot_of[j as usize] = u32::MAX;
        }
        sort_row(&mut nbrs[row.clone()], &mut wts[row.clone()]);
        lengths.push(row.len() as u32);
    }
    (lengths, nbrs, wts)
}

/// Data derived from a topology by another module ([`Topology::derived`]).
type DerivedData = std::sync::Arc<dyn std::any::Any + Send + Sync>;

/// CSR rows built piece by piece (in parallel): `(row lengths, neighbours, weights)`.
pub(crate) type RowPiece = (Vec<u32>, Vec<u32>, Vec<f64>);

/// Joins row pieces, given in row order, into CSR `(offsets, neighbours, weights)`.
pub(crate) fn join_rows(pieces: &[RowPiece]) -> (Vec<u32>, Vec<u32>, Vec<f64>) {
    (
        row_offsets(pieces.iter().map(|p| &p.0[..])),
        pieces.iter().map(|p| &p.1[..]).collect::<Vec<_>>().concat(),
        pieces.iter().map(|p| &p.2[..]).collect::<Vec<_>>().concat(),
    )
}

/// CSR row offsets (starting at 0) from row lengths given piece by piece, in row order.
pub(crate) fn row_offsets<'a>(lengths: impl Iterator<Item = &'a [u32]>) -> Vec<u32> {
    let mut offsets = vec![0u32];
    for piece in lengths {
        for &len in piece {
            offsets.push(offsets[offsets.len() - 1] + len);
        }
    }
    offsets
}

/// Half the cotangent of each corner of the triangle `p` (0 for a corner that is not clearly
/// non-degenerate, NaN included). The cross product of the two sides at a corner is twice
/// the area at every corner, so one square root serves all three.
fn half_cotangents(p: [DVec3; 3]) -> [f64; 3] {
    let twice_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
    let half_inverse = 0.5 / twice_area;
    std::array::from_fn(|k| {
        let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
        // sin = 2A / (|u| |v|), compared squared.
        let clear = twice_area * twice_area
            > DEGENERATE_SINE * DEGENERATE_SINE * u.length_squared() * v.length_squared();
        if clear { u.dot(v) * half_inverse } else { 0.0 }
    })
}

/// Sorts a row by neighbour (neighbours are distinct), carrying the weights along.
fn sort_row(nbrs: &mut [u32], wts: &mut [f64]) {
    if nbrs.len() > 32 {
        let mut pairs: Vec<(u32, f64)> = nbrs.iter().copied().zip(wts.iter().copied()).collect();
        pairs.sort_unstable_by_key(|&(j, _)| j);
        for ((n, w), (j, v)) in nbrs.iter_mut().zip(wts.iter_mut()).zip(pairs) {
            (*n, *w) = (j, v);
        }
        return;
    }
    // Insertion sort: rows of ordinary meshes are short.
    for a in 1..nbrs.len() {
        let (j, w) = (nbrs[a], wts[a]);
        let mut b = a;
        while b > 0 && nbrs[b - 1] > j {
            nbrs[b] = nbrs[b - 1];
            wts[b] = wts[b - 1];
            b -= 1;
        }
        nbrs[b] = j;
        wts[b] = w;
    }
}

/// Below this ratio of `|u × v|` to `|u|·|v|` a corner angle counts as degenerate (0 or 180°)
/// and contributes no cotangent weight.
const DEGENERATE_SINE: f64 = 1e-12;

impl Topology {
    /// Builds the topology of a triangle list given in render order (`f32` positions, flat
    /// `u32` index buffer, as in a Bevy `Mesh`). Split seams are welded ([`WeldPolicy::Seams`]).
    pub fn from_render_mesh(positions: &[Vec3], indices: &[u32]) -> Result<Self, MeshError> {
        if !indices.len().is_multiple_of(3) {
            return Err(MeshError::IndexCountNotTriangles(indices.len()));
        }
        let positions: Vec<DVec3> = positions.iter().map(|p| p.as_dvec3()).collect();
        let triangles: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        Self::new(&positions, &triangles)
    }

    /// Builds the topology from `f64` positions and triangles, welding split seams
    /// ([`WeldPolicy::Seams`]); triangles that become degenerate (repeated corner) are dropped.
    pub fn new(positions: &[DVec3], triangles: &[[u32; 3]]) -> Result<Self, MeshError> {
        Self::with_weld(positions, triangles, WeldPolicy::Seams)
    }

    /// As [`Topology::new`], merging coincident vertices as `policy` says.
    pub fn with_weld(
        positions: &[DVec3],
        triangles: &[[u32; 3]],
        policy: WeldPolicy,
    ) -> Result<Self, MeshError> {
        check_mesh(positions, triangles)?;
        let (welded, render_to_welded) = weld(positions, triangles, policy);
        let tris: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| render_to_welded[i as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();

        let pieces = cotangent_rows(&welded, &tris);
        let (offsets, neighbors, cotangent) = join_rows(&pieces);
        Ok(Topology {
            positions: welded,
            triangles: tris,
            render_to_welded,
            offsets,
            neighbors,
            cotangent,
            derived: Default::default(),
            elimination: Default::default(),
        })
    }

    /// Computes the whole mesh's fill-reducing elimination order now, e.g. on a loading
    /// thread. Solvers restrict it to their free vertices instead of ordering each constraint
    /// set afresh; without this call the first solver with at least half the vertices free
    /// makes it.
    pub fn prepare_elimination_order(&self) {
        self.elimination_order();
    }

    /// The whole mesh's elimination order, made on first use.
    pub(crate) fn elimination_order(&self) -> &Dissection {
        self.elimination
            .get_or_init(|| dissect(&self.offsets, &self.neighbors, &self.positions))
    }

    /// The whole mesh's elimination order, if it has been made.
    pub(crate) fn elimination_order_if_made(&self) -> Option<&Dissection> {
        self.elimination.get()
    }

    /// What `build` derives from this mesh under `mode`, built by the first caller and shared
    /// after it (the solver keeps its memory layout here). One type per mode: a caller asking
    /// for another type than the one stored gets `None`.
    pub(crate) fn derived<T: std::any::Any + Send + Sync>(
        &self,
        mode: WeightMode,
        build: impl FnOnce(&Self) -> T,
    ) -> Option<std::sync::Arc<T>> {
        let slot = match mode {
            WeightMode::ClampedCotangent => 0,
            WeightMode::RawCotangent => 1,
            WeightMode::Uniform => 2,
        };
        self.derived[slot]
            .get_or_init(|| std::sync::Arc::new(build(self)))
            .clone()
            .downcast::<T>()
            .ok()
    }

    /// Number of welded vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Welded rest positions.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Welded, non-degenerate triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// For each render vertex, the welded vertex it maps to.
    pub fn render_to_welded(&self) -> &[u32] {
        &self.render_to_welded
    }

    /// Sorted welded neighbours of vertex `i`.
    pub fn neighbors(&self, i: usize) -> &[u32] {
        &self.neighbors[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// CSR row offsets into [`Topology::neighbor_list`] (length `vertex_count + 1`).
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }

    /// All neighbour lists, concatenated (CSR column indices).
    pub fn neighbor_list(&self) -> &[u32] {
        &self.neighbors
    }

    /// Raw cotangent weight `½(cot α + cot β)` per CSR entry (may be negative).
    pub fn raw_cotangents(&self) -> &[f64] {
        &self.cotangent
    }

    /// Edge weights per CSR entry for the chosen mode.
    pub fn weights(&self, mode: WeightMode) -> Vec<f64> {
        match mode {
            WeightMode::ClampedCotangent => self.cotangent.iter().map(|w| w.max(0.0)).collect(),
            WeightMode::RawCotangent => self.cotangent.clone(),
            WeightMode::Uniform => vec![1.0; self.cotangent.len()],
        }
    }

    /// Fraction of edges whose raw cotangent weight is negative.
    pub fn negative_weight_fraction(&self) -> f64 {
        if self.cotangent.is_empty() {
            return 0.0;
        }
        self.cotangent.iter().filter(|w| **w < 0.0).count() as f64 / self.cotangent.len() as f64
    }

    /// The welded vertices of a set of render vertices, sorted and without repeats (render
    /// indices out of range are skipped; [`crate::deform::Constraints::from_render`] rejects
    /// them instead).
    pub fn welded_set(&self, render: &[u32]) -> Vec<u32> {
        let mut out: Vec<u32> = render
            .iter()
            .filter_map(|&i| self.render_to_welded.get(i as usize).copied())
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Scatters per-welded-vertex values back to render order.
    pub fn to_render<T: Copy>(&self, welded: &[T]) -> Vec<T> {
        self.render_to_welded
            .iter()
            .map(|&w| welded[w as usize])
            .collect()
    }

    /// Length of the rest bounding-box diagonal.
    pub fn bounding_diagonal(&self) -> f64 {
        let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (hi - lo).length()
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;

    fn quad() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        (
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn square_cotangents_match_right_angles() {
        let (p, t) = quad();
        let topo = Topology::new(&p, &t).unwrap();
        // Diagonal 0-2: opposite corners are both 90°, cot = 0.
        let s = topo.slot(0, 2);
        assert!(topo.raw_cotangents()[s].abs() < 1e-12);
        // Edge 0-1: one triangle, opposite angle 45°, weight ½·cot 45° = 0.5.
        let s = topo.slot(0, 1);
        assert!((topo.raw_cotangents()[s] - 0.5).abs() < 1e-12);
        assert_eq!(topo.neighbors(0), &[1, 2, 3]);
    }

    #[test]
    fn welds_split_vertices_and_keeps_map() {
        let (mut p, _) = quad();
        p.push(p[0]);
        p.push(p[2]);
        let t = vec![[0, 1, 2], [4, 5, 3]];
        let topo = Topology::new(&p, &t).unwrap();
        assert_eq!(topo.vertex_count(), 4);
        assert_eq!(topo.render_to_welded(), &[0, 1, 2, 3, 0, 2]);
        assert_eq!(topo.neighbors(0), &[1, 2, 3]);
    }

    #[test]
    fn zero_area_triangles_give_finite_weights() {
        let p = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ];
        let topo = Topology::new(&p, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        assert!(topo.raw_cotangents().iter().all(|w| w.is_finite()));
    }

    #[test]
    fn rejects_bad_input() {
        let (p, _) = quad();
        assert_eq!(
            Topology::new(&p, &[[0, 1, 9]]).unwrap_err(),
            MeshError::IndexOutOfRange {
                index: 9,
                vertex_count: 4
            }
        );
        let mut bad = p.clone();
        bad[2].y = f64::NAN;
        assert_eq!(
            Topology::new(&bad, &[[0, 1, 2]]).unwrap_err(),
            MeshError::NonFinitePosition { vertex: 2 }
        );
        assert_eq!(Topology::new(&[], &[]).unwrap_err(), MeshError::NoVertices);
        assert_eq!(
            Topology::from_render_mesh(&[Vec3::ZERO; 3], &[0, 1]).unwrap_err(),
            MeshError::IndexCountNotTriangles(2)
        );
    }

    #[test]
    fn isolated_vertices_have_no_neighbors() {
        let (mut p, t) = quad();
        p.push(DVec3::splat(5.0));
        let topo = Topology::new(&p, &t).unwrap();
        assert!(topo.neighbors(4).is_empty());
    }

    /// Every edge weight from the definition: the sum, over triangles holding the edge, of
    /// half the cotangent of the opposite corner (computed with `atan2`, independently of
    /// `half_cotangent`).
    fn reference_weights(p: &[DVec3], t: &[[u32; 3]]) -> HashMap<(u32, u32), f64> {
        let mut w = HashMap::new();
        for tri in t {
            for k in 0..3 {
                let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let (u, v) = (p[a as usize] - p[c as usize], p[b as usize] - p[c as usize]);
                let angle = u.cross(v).length().atan2(u.dot(v));
                let half_cot = 0.5 / angle.tan();
                *w.entry((a.min(b), a.max(b))).or_insert(0.0) += half_cot;
            }
        }
        w
    }

    /// Every stored weight of `topo` (built from `p`, `t`) equals its mirror `w_ji` bit for
    /// bit and the definition to 1e-12, and every edge of the definition is stored both ways.
    fn assert_weights_match_definition(topo: &Topology, p: &[DVec3], t: &[[u32; 3]]) {
        let reference = reference_weights(p, t);
        let mut checked = 0;
        for i in 0..topo.vertex_count() {
            for (slot, &j) in topo.neighbors(i).iter().enumerate() {
                let w = topo.raw_cotangents()[topo.offsets()[i] as usize + slot];
                let back = topo.raw_cotangents()[topo.slot(j, i as u32)];
                assert_eq!(w.to_bits(), back.to_bits(), "w[{i}][{j}] != w[{j}][{i}]");
                let expected = reference[&(j.min(i as u32), j.max(i as u32))];
                assert!(
                    (w - expected).abs() < 1e-12,
                    "edge {i}-{j}: {w} vs {expected}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 2 * reference.len());
    }

    #[test]
    fn weights_match_the_definition_and_are_exactly_symmetric() {
        // A bent strip plus a fin on one of its edges: three triangles share edge 2-3
        // (non-manifold), and the strip's vertices have irregular valence.
        let mut p: Vec<DVec3> = (0..6)
            .flat_map(|i| {
                let x = i as f64 * 0.7;
                [
                    DVec3::new(x, 0.0, 0.1 * x * x),
                    DVec3::new(x + 0.3, 1.0, 0.2 * x),
                ]
            })
            .collect();
        p.push(DVec3::new(0.8, 0.5, 1.3));
        let mut t = Vec::new();
        for i in 0..5u32 {
            let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            t.push([a, c, b]);
            t.push([b, c, d]);
        }
        t.push([2, 3, 12]);
        let topo = Topology::new(&p, &t).unwrap();
        assert_weights_match_definition(&topo, &p, &t);
        assert_eq!(topo.neighbors(12), &[2, 3]);
        assert_eq!(topo.neighbors(2).len(), 5);
    }

    #[test]
    fn high_valence_rows_are_sorted_and_exact() {
        // A closed fan of 50 triangles (the centre's raw row has 100 entries), its rim
        // vertices numbered out of angular order.
        let rim = 50u32;
        let label = |k: u32| (k * 7) % rim + 1;
        let mut p = vec![DVec3::new(0.0, 0.0, 0.3); rim as usize + 1];
        for k in 0..rim {
            let a = std::f64::consts::TAU * k as f64 / rim as f64;
            p[label(k) as usize] = DVec3::new(a.cos(), a.sin(), 0.1 * (3.0 * a).sin());
        }
        let t: Vec<[u32; 3]> = (0..rim)
            .map(|k| [0, label(k), label((k + 1) % rim)])
            .collect();
        let topo = Topology::new(&p, &t).unwrap();
        assert_eq!(topo.neighbors(0), (1..=rim).collect::<Vec<u32>>());
        assert_weights_match_definition(&topo, &p, &t);
    }
}
