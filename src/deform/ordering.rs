//! Fill-reducing elimination order for the Cholesky factor: geometric dissection on top,
//! approximate minimum degree below.
//!
//! A surface mesh cut by a plane falls apart along a curve of vertices. Splitting near the
//! median coordinate of the longest bounding-box side and eliminating the cut vertices last
//! leaves the factor with independent pieces, which the triangular solves run on separate
//! threads. Inside each piece faer's approximate minimum degree orders the vertices: on
//! these meshes it makes less fill than cutting all the way down.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::amd;
use glam::DVec3;

use super::io::bounding_box;
use rayon::prelude::*;

/// Pieces at most this big are never cut.
const LEAF: usize = 64;

/// An elimination order of a graph.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Dissection {
    /// `order[k]` is the vertex eliminated `k`-th.
    pub order: Vec<u32>,
    /// `(a, b)`: positions `0..a` and `a..b` of `order` share no edge and no fill; `b..` is
    /// the top-level separator. `None` when the graph was too small to split.
    pub split: Option<(usize, usize)>,
}

impl Dissection {
    /// This order restricted to a subset of the vertices, renumbered by `local` (`None` for
    /// the vertices left out): an elimination order of the induced subgraph. Halves that
    /// shared no edge still share none; a split that leaves a half empty is dropped.
    pub(crate) fn restricted(&self, local: impl Fn(u32) -> Option<u32>) -> Dissection {
        let mut order = Vec::new();
        let mut kept_before = Vec::with_capacity(self.order.len() + 1);
        for &v in &self.order {
            kept_before.push(order.len());
            order.extend(local(v));
        }
        kept_before.push(order.len());
        let split = self
            .split
            .map(|(a, b)| (kept_before[a], kept_before[b]))
            .filter(|&(a, b)| a > 0 && b > a);
        Dissection { order, split }
    }
}

/// A memory order for the vertices at `coords`: along a Z-order (Morton) curve through their
/// bounding box, so mesh neighbours sit close in memory. `order[k]` is the vertex stored
/// `k`-th.
pub(crate) fn spatial_order(coords: &[DVec3]) -> Vec<u32> {
    let (lo, hi) = bounding_box(coords);
    // 21 bits per axis; a flat box gets the same scale on every axis.
    let scale = ((1u64 << 21) - 1) as f64 / (hi - lo).max_element().max(f64::MIN_POSITIVE);
    let mut keyed: Vec<(u64, u32)> = coords
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let q = ((*p - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(((1u64 << 21) - 1) as f64));
            let code = spread_bits(q.x as u64)
                | spread_bits(q.y as u64) << 1
                | spread_bits(q.z as u64) << 2;
            (code, i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The low 21 bits of `x` spread to every third bit.
fn spread_bits(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The longest of the three sides `extent` of a box.
fn longest(extent: DVec3) -> usize {
    if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    }
}

/// Orders the graph with CSR adjacency `offsets`/`adjacency` (symmetric, local indices) and
/// vertex positions `coords`: one plane cut into two independent halves and a separator,
/// then minimum degree inside each half (both halves at once, on two threads).
pub(crate) fn dissect(offsets: &[u32], adjacency: &[u32], coords: &[DVec3]) -> Dissection {
    let n = coords.len();
    let graph = Graph { offsets, adjacency };
    let all: Vec<u32> = (0..n as u32).collect();
    if n <= LEAF {
        return Dissection {
            order: graph.minimum_degree(&all),
            split: None,
        };
    }
    let (first, second, separator) = graph.cut(coords);
    let (mut order, second) = rayon::join(
        || graph.minimum_degree(&first),
        || graph.minimum_degree(&second),
    );
    let a = order.len();
    order.extend_from_slice(&second);
    let b = order.len();
    order.extend_from_slice(&separator);
    Dissection {
        order,
        split: Some((a, b)),
    }
}

/// The whole graph with CSR adjacency `offsets`/`adjacency` in approximate-minimum-degree
/// order: `order[k]` is the vertex eliminated `k`-th.
pub(crate) fn minimum_degree(offsets: &[u32], adjacency: &[u32]) -> Vec<u32> {
    let all: Vec<u32> = (0..offsets.len() as u32 - 1).collect();
    Graph { offsets, adjacency }.minimum_degree(&all)
}

struct Graph<'a> {
    offsets: &'a [u32],
    adjacency: &'a [u32],
}

impl Graph<'_> {
    fn neighbours(&self, v: u32) -> &[u32] {
        &self.adjacency[self.offsets[v as usize] as usize..self.offsets[v as usize + 1] as usize]
    }

    /// Splits the graph by a plane across the longest side of its bounding box into two
    /// halves with no edge between them and the separator (the boundary of one half). Of a
    /// few cut positions around the median, the one with the smallest separator wins: the
    /// separator's size drives the fill it adds. The cut positions are found by selection,
    /// not by sorting.
    fn cut(&self, coords: &[DVec3]) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
        const PERCENTILES: [usize; 5] = [40, 45, 50, 55, 60];
        let (lo, hi) = bounding_box(coords);
        let axis = longest(hi - lo);
        let n = coords.len();
        // By (coordinate, index): a strict total order, so each cut is one key.
        let order = |a: &u32, b: &u32| {
            coords[*a as usize][axis]
                .total_cmp(&coords[*b as usize][axis])
                .then(a.cmp(b))
        };
        let mut scratch: Vec<u32> = (0..n as u32).collect();
        let mut cuts = [0u32; PERCENTILES.len()];
        let mut done = 0;
        for (cut, percent) in cuts.iter_mut().zip(PERCENTILES) {
            let at = n * percent / 100;
            scratch[done..].select_nth_unstable_by(at - done, order);
            *cut = scratch[at];
            done = at;
        }
        // `v` is below cut `c` iff `bucket[v] <= c` (the number of cut keys at or under it).
        let bucket: Vec<u8> = (0..n as u32)
            .into_par_iter()
            .map(|v| cuts.iter().filter(|c| order(c, &v).is_le()).count() as u8)
            .collect();
        let below = |v: u32, c: usize| bucket[v as usize] as usize <= c;
        let on_boundary = |v: u32, c: usize| {
            let side = below(v, c);
            self.neighbours(v).iter().any(|&w| below(w, c) != side)
        };
        // Boundary vertices below and above each cut.
        const CUTS: usize = PERCENTILES.len();
        let counts = (0..n as u32)
            .into_par_iter()
            .fold(
                || [[0usize; 2]; CUTS],
                |mut acc, v| {
                    for (c, count) in acc.iter_mut().enumerate() {
                        if on_boundary(v, c) {
                            count[!below(v, c) as usize] += 1;
                        }
                    }
                    acc
                },
            )
            .reduce(
                || [[0usize; 2]; CUTS],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(b) {
                        x[0] += y[0];
                        x[1] += y[1];
                    }
                    a
                },
            );
        let mut best: Option<(usize, bool, usize)> = None; // (separator size, low side, cut)
        for (c, &[low, high]) in counts.iter().enumerate() {
            let candidate = if low <= high {
                (low, true, c)
            } else {
                (high, false, c)
            };
            if best.is_none_or(|b| candidate.0 < b.0) {
                best = Some(candidate);
            }
        }
        let (_, low_side, c) = best.unwrap_or((0, true, CUTS / 2));
        // 0: first half, 1: second half, 2: separator.
        let class: Vec<u8> = (0..n as u32)
            .into_par_iter()
            .map(|v| {
                let side = below(v, c);
                if side == low_side && on_boundary(v, c) {
                    2
                } else {
                    (!side) as u8
                }
            })
            .collect();
        let mut first = Vec::with_capacity(n / 2);
        let mut second = Vec::with_capacity(n / 2);
        let mut separator = Vec::new();
        for (v, &k) in (0..n as u32).zip(&class) {
            match k {
                0 => first.push(v),
                1 => second.push(v),
                _ => separator.push(v),
            }
        }
        (first, second, separator)
    }

    /// `piece` in faer's approximate-minimum-degree order of its induced subgraph (in the
    /// given order if that fails, which costs fill, never correctness).
    fn minimum_degree(&self, piece: &[u32]) -> Vec<u32> {
        let m = piece.len();
        let mut local = vec![u32::MAX; self.offsets.len() - 1];
        for (k, &v) in piece.iter().enumerate() {
            local[v as usize] = k as u32;
        }
        let mut col_ptr = Vec::with_capacity(m + 1);
        let mut rows = Vec::new();
        col_ptr.push(0u32);
        // AMD orders the pattern of A + Aᵀ: the strict lower triangle is all it needs, and
        // half the entries to symmetrise.
        for (k, &v) in piece.iter().enumerate() {
            let start = rows.len();
            for &w in self.neighbours(v) {
                let l = local[w as usize];
                if l != u32::MAX && l > k as u32 {
                    rows.push(l);
                }
            }
            rows[start..].sort_unstable();
            col_ptr.push(rows.len() as u32);
        }
        let mut perm = vec![0u32; m];
        let mut perm_inv = vec![0u32; m];
        let ordered = MemBuffer::try_new(amd::order_scratch::<u32>(m, rows.len()))
            .ok()
            .and_then(|mut mem| {
                let pattern = SymbolicSparseColMatRef::new_checked(m, m, &col_ptr, None, &rows);
                amd::order(
                    &mut perm,
                    &mut perm_inv,
                    pattern,
                    amd::Control::default(),
                    MemStack::new(&mut mem),
                )
                .ok()
            })
            .is_some();
        if ordered {
            perm.iter().map(|&k| piece[k as usize]).collect()
        } else {
            piece.to_vec()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` grid graph in the plane.
    fn grid(w: u32, h: u32) -> (Vec<u32>, Vec<u32>, Vec<DVec3>) {
        let id = |x: u32, y: u32| y * w + x;
        let mut offsets = vec![0];
        let mut adjacency = Vec::new();
        let mut coords = Vec::new();
        for y in 0..h {
            for x in 0..w {
                coords.push(DVec3::new(x as f64, y as f64, 0.0));
                if x > 0 {
                    adjacency.push(id(x - 1, y));
                }
                if x + 1 < w {
                    adjacency.push(id(x + 1, y));
                }
                if y > 0 {
                    adjacency.push(id(x, y - 1));
                }
                if y + 1 < h {
                    adjacency.push(id(x, y + 1));
                }
                offsets.push(adjacency.len() as u32);
            }
        }
        (offsets, adjacency, coords)
    }

    #[test]
    fn order_is_a_permutation_with_independent_halves() {
        let (offsets, adjacency, coords) = grid(40, 25);
        let d = dissect(&offsets, &adjacency, &coords);
        let mut seen = d.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..1000).collect::<Vec<u32>>());
        let (a, b) = d.split.expect("a 1000-vertex grid is split");
        assert!(a > 300 && b - a > 300, "unbalanced halves {a} {b}");
        // Separator of a 40×25 grid cut across its long side: one column of 25.
        assert_eq!(1000 - b, 25);
        let mut half = vec![0u8; 1000];
        for (k, &v) in d.order.iter().enumerate() {
            half[v as usize] = if k < a {
                1
            } else if k < b {
                2
            } else {
                3
            };
        }
        for v in 0..1000usize {
            for &w in &adjacency[offsets[v] as usize..offsets[v + 1] as usize] {
                let pair = (half[v], half[w as usize]);
                assert!(
                    pair != (1, 2) && pair != (2, 1),
                    "edge {v}-{w} joins the halves"
                );
            }
        }
    }

    #[test]
    fn a_restricted_order_orders_the_subset_with_independent_halves() {
        let (offsets, adjacency, coords) = grid(40, 25);
        let d = dissect(&offsets, &adjacency, &coords);
        // Keep a disc in the middle (straddling the cut) and renumber it.
        let inside = |v: u32| coords[v as usize].distance(DVec3::new(20.0, 12.0, 0.0)) < 9.0;
        let mut local = vec![None; 1000];
        let mut kept = 0u32;
        for v in 0..1000u32 {
            if inside(v) {
                local[v as usize] = Some(kept);
                kept += 1;
            }
        }
        let r = d.restricted(|v| local[v as usize]);
        let mut seen = r.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..kept).collect::<Vec<u32>>());
        let (a, b) = r.split.expect("the disc straddles the cut");
        // The restricted order is the whole order's, filtered.
        let filtered: Vec<u32> = d.order.iter().filter_map(|&v| local[v as usize]).collect();
        assert_eq!(r.order, filtered);
        let mut half = vec![0u8; kept as usize];
        for (k, &v) in r.order.iter().enumerate() {
            half[v as usize] = 1 + (k >= a) as u8 + (k >= b) as u8;
        }
        for v in (0..1000u32).filter(|&v| inside(v)) {
            for &w in &adjacency[offsets[v as usize] as usize..offsets[v as usize + 1] as usize] {
                let (Some(lv), Some(lw)) = (local[v as usize], local[w as usize]) else {
                    continue;
                };
                let pair = (half[lv as usize], half[lw as usize]);
                assert!(
                    pair != (1, 2) && pair != (2, 1),
                    "edge {v}-{w} joins the halves"
                );
            }
        }
        // A subset within one half: no split.
        let left = |v: u32| (coords[v as usize].x < 5.0).then_some(v);
        assert_eq!(d.restricted(left).split, None);
    }

    #[test]
    fn spatial_order_is_a_permutation_keeping_neighbours_close() {
        // A 64 × 64 grid, its vertices given in a scrambled order.
        let (_, _, grid_coords) = grid(64, 64);
        let scramble = |v: usize| (v * 1031) % 4096;
        let mut coords = vec![DVec3::ZERO; 4096];
        for (v, p) in grid_coords.iter().enumerate() {
            coords[scramble(v)] = *p;
        }
        let order = spatial_order(&coords);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..4096).collect::<Vec<u32>>());
        // Row-major storage would put every vertex 64 slots from its upper neighbour; here
        // most vertical neighbours share a few cache lines.
        let mut slot = vec![0i64; 4096];
        for (k, &v) in order.iter().enumerate() {
            slot[v as usize] = k as i64;
        }
        let mut close = 0;
        for y in 0..63 {
            for x in 0..64 {
                let d = slot[scramble(y * 64 + x)] - slot[scramble((y + 1) * 64 + x)];
                close += (d.abs() <= 16) as usize;
            }
        }
        let fraction = close as f64 / (63.0 * 64.0);
        assert!(
            fraction >= 0.7,
            "{fraction} of vertical neighbours within 16 slots"
        );
    }

    #[test]
    fn spatial_order_of_degenerate_clouds_is_a_permutation() {
        for coords in [
            vec![],
            vec![DVec3::splat(3.0)],
            vec![DVec3::splat(-1.0); 100],
            (0..100).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect(),
            vec![
                DVec3::new(1e300, -1e300, 0.0),
                DVec3::new(-1e300, 1e300, 1e-300),
            ],
        ] {
            let mut order = spatial_order(&coords);
            order.sort_unstable();
            assert_eq!(order, (0..coords.len() as u32).collect::<Vec<_>>());
        }
        // Points along a line keep their order along it.
        let line: Vec<DVec3> = (0..50)
            .map(|i| DVec3::new(0.0, 49.0 - i as f64, 0.0))
            .collect();
        assert_eq!(spatial_order(&line), (0..50).rev().collect::<Vec<u32>>());
    }

    #[test]
    fn tiny_graphs_are_not_split() {
        let (offsets, adjacency, coords) = grid(3, 3);
        let d = dissect(&offsets, &adjacency, &coords);
        assert_eq!(d.order.len(), 9);
        assert_eq!(d.split, None);
    }
}
