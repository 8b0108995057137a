//! The coarse grid of casts under a [`Floor`](super::floor::Floor), and what it remembers
//! between casts ([`FloorMemory`]).
//!
//! The grid's nodes lie on a lattice fixed in the ground's space: `spacing` apart along two
//! axes across gravity that depend on gravity alone, the footprint covered by the nodes from
//! the lattice line below its lowest corner. A node's cast is then the same question frame
//! after frame while the footprint moves over it, and a [`FloorMemory`] answers it again
//! without casting:
//! - a node remembers one cast over a generous window of heights (from `band` above the
//!   window a floor asks for down to `band` below it); it answers a later window inside that
//!   one when the surface it found is not above the later window's top (then nothing lies
//!   between that top and the surface), and a miss answers every window inside it;
//! - a cell remembers how high the ground rises over it ([`Ground::highest_within`]): the
//!   same square every time.
//!
//! Anything else (a window reaching past the remembered one, a surface above the window's
//! top: an overhang, or ground above the skin's lowest vertex) is cast again, exactly as a
//! floor without memory casts it.

use glam::DVec3;

use crate::pose::ground::Ground;
use crate::pose::ground::GroundPlane;
use crate::pose::ground::floor::FloorSampling;

/// The grid of coarse casts over the footprint of a set of points, across gravity, on the
/// ground's lattice.
pub(super) struct CoarseGrid {
    pub(super) down: DVec3,
    axes: (DVec3, DVec3),
    /// The lattice index of the grid's first node along each axis.
    first: (i64, i64),
    spacing: f64,
    /// Nodes along each axis: at least two, so every cell has its four nodes ([`Self::around`]).
    pub(super) size: (usize, usize),
    /// The lowest point's height against gravity.
    pub(super) lowest: f64,
}

impl CoarseGrid {
    /// At most this many nodes along an axis: a sampling finer than the footprint allows is
    /// coarsened by powers of two (so a character's lattice stays the same while its
    /// footprint changes a little).
    const MAX_NODES: usize = 64;

    pub(super) fn new(positions: &[DVec3], sampling: &FloorSampling) -> Option<Self> {
        let down = sampling.down.try_normalize()?;
        let finite =
            sampling.band.is_finite() && sampling.near.is_finite() && sampling.spacing.is_finite();
        if !(finite && sampling.band > 0.0 && sampling.spacing > 0.0) {
            return None;
        }
        let x = down.any_orthonormal_vector();
        let axes = (x, down.cross(x));
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        let mut lowest = f64::INFINITY;
        for p in positions.iter().filter(|p| p.is_finite()) {
            let (a, b) = (p.dot(axes.0), p.dot(axes.1));
            lo = (lo.0.min(a), lo.1.min(b));
            hi = (hi.0.max(a), hi.1.max(b));
            lowest = lowest.min(-p.dot(down));
        }
        if !lowest.is_finite() {
            return None;
        }
        let extent = (hi.0 - lo.0).max(hi.1 - lo.1);
        let mut spacing = sampling.spacing;
        while extent / spacing > (Self::MAX_NODES - 2) as f64 {
            spacing *= 2.0;
        }
        // The lattice lines at or below the footprint's lowest corner, and the nodes past its
        // highest.
        let first = |along: f64| (along / spacing).floor();
        let (f0, f1) = (first(lo.0), first(lo.1));
        let nodes = |from: f64, to: f64| ((to / spacing).ceil() - from).max(0.0) as usize + 1;
        Some(Self {
            down,
            axes,
            first: (f0 as i64, f1 as i64),
            spacing,
            size: (nodes(f0, hi.0).max(2), nodes(f1, hi.1).max(2)),
            lowest,
        })
    }

    pub(super) fn nodes(&self) -> usize {
        self.size.0 * self.size.1
    }

    /// Node `k` at height `height` against gravity (its position depends on its lattice index
    /// alone, whatever grid it is in).
    pub(super) fn node(&self, k: usize, height: f64) -> DVec3 {
        let (i, j) = (k % self.size.0, k / self.size.0);
        let along = |first: i64, n: usize| (first + n as i64) as f64 * self.spacing;
        self.axes.0 * along(self.first.0, i) + self.axes.1 * along(self.first.1, j)
            - self.down * height
    }

    /// The cell `p` is over: its first node's `(i, j)`. (Truncation of a number not below
    /// 0 is its floor, without the call `floor` is without SSE4.1: this is asked per vertex.)
    pub(super) fn cell_ij(&self, p: DVec3) -> (usize, usize) {
        let cell = |along: f64, first: i64, n: usize| {
            ((along / self.spacing - first as f64).max(0.0) as usize).min(n.saturating_sub(2))
        };
        (
            cell(p.dot(self.axes.0), self.first.0, self.size.0),
            cell(p.dot(self.axes.1), self.first.1, self.size.1),
        )
    }

    /// The centre of the cell whose first node is node `k` (at height 0).
    pub(super) fn cell_centre(&self, k: usize) -> DVec3 {
        self.node(k, 0.0) + (self.axes.0 + self.axes.1) * (0.5 * self.spacing)
    }

    /// Half the side of a square about a cell's centre that holds the cell (and the
    /// footprint's edge beyond it, where a vertex on the edge is counted to the last cell).
    pub(super) fn cell_radius(&self) -> f64 {
        self.spacing
    }

    /// The four nodes around the cell whose first node is `(i, j)` (a grid has at least two
    /// nodes along each axis).
    pub(super) fn around(&self, (i, j): (usize, usize)) -> [usize; 4] {
        let k = j * self.size.0 + i;
        [k, k + 1, k + self.size.0, k + self.size.0 + 1]
    }
}

/// What a floor's grid of casts found on one ground, kept from one [`Floor::cast_remembering`]
/// to the next so a character that stays or walks over the same ground casts only the nodes
/// that are new under it (see the module docs). One per character; [`FloorMemory::forget`]
/// it when the ground changes (a moved or rebuilt ground answers differently, and the memory
/// cannot tell).
///
/// [`Floor::cast_remembering`]: super::floor::Floor::cast_remembering
#[derive(Debug, Clone, Default)]
pub struct FloorMemory {
    /// The lattice the memory is on: gravity and spacing (another forgets everything).
    lattice: Option<(DVec3, f64)>,
    /// The lattice index of the window's first node, and its nodes along each axis.
    first: (i64, i64),
    size: (usize, usize),
    /// Per node of the window, its cast.
    nodes: Vec<Option<NodeCast>>,
    /// Per cell of the window (by its first node), how high the ground rises over it.
    rises: Vec<Option<Option<f64>>>,
}

/// One node's cast: down from `from` to `to` (heights against gravity), and what it hit with
/// the hit's height.
#[derive(Debug, Clone, Copy)]
struct NodeCast {
    from: f64,
    to: f64,
    hit: Option<(GroundPlane, f64)>,
}

impl FloorMemory {
    /// Forgets every cast (the ground changed).
    pub fn forget(&mut self) {
        *self = Self::default();
    }

    /// Moves the window onto `grid`'s nodes, keeping what it knows of the nodes in both.
    pub(super) fn fit(&mut self, grid: &CoarseGrid) {
        let lattice = (grid.down, grid.spacing);
        if self.lattice != Some(lattice) {
            *self = Self {
                lattice: Some(lattice),
                ..Self::default()
            };
        }
        if (self.first, self.size) == (grid.first, grid.size) {
            return;
        }
        let mut nodes = vec![None; grid.nodes()];
        let mut rises = vec![None; grid.nodes()];
        for (k, (node, rise)) in nodes.iter_mut().zip(&mut rises).enumerate() {
            let (i, j) = (k % grid.size.0, k / grid.size.0);
            let old = (
                grid.first.0 + i as i64 - self.first.0,
                grid.first.1 + j as i64 - self.first.1,
            );
            let inside = |at: i64, n: usize| at >= 0 && (at as usize) < n;
            if inside(old.0, self.size.0) && inside(old.1, self.size.1) {
                let o = old.1 as usize * self.size.0 + old.0 as usize;
                (*node, *rise) = (self.nodes[o], self.rises[o]);
            }
        }
        (self.first, self.size, self.nodes, self.rises) = (grid.first, grid.size, nodes, rises);
    }

    /// The ground's plane first below node `k` of `grid` (the window [`fit`](Self::fit)
    /// to it) from height `top` down to `bottom`, remembered or cast; and whether it was
    /// cast.
    pub(super) fn node_plane(
        &mut self,
        (grid, k): (&CoarseGrid, usize),
        (top, bottom): (f64, f64),
        ground: &dyn Ground,
    ) -> (Option<GroundPlane>, bool) {
        let answer = |cast: &NodeCast| match cast.hit {
            _ if cast.from < top || cast.to > bottom => None,
            None => Some(None),
            Some((plane, height)) if height <= top => Some((height >= bottom).then_some(plane)),
            Some(_) => None,
        };
        if let Some(plane) = self.nodes[k].as_ref().and_then(answer) {
            return (plane, false);
        }
        // A generous window, to answer the next frames' too.
        let margin = top - bottom;
        let (from, to) = (top + 0.5 * margin, bottom - 0.5 * margin);
        let hit = plane_below(ground, grid.node(k, from), grid.down, from - to)
            .map(|plane| (plane, -plane.point.dot(grid.down)));
        let cast = NodeCast { from, to, hit };
        self.nodes[k] = Some(cast);
        match answer(&cast) {
            Some(plane) => (plane, true),
            // Ground above `top` here: the cast a floor without memory makes.
            None => (
                plane_below(ground, grid.node(k, top), grid.down, margin),
                true,
            ),
        }
    }

    /// How high the ground rises over the cell whose first node is node `k` of `grid`
    /// (`None`: the ground cannot say), remembered or asked.
    pub(super) fn rise(
        &mut self,
        (grid, k): (&CoarseGrid, usize),
        ground: &dyn Ground,
    ) -> Option<f64> {
        *self.rises[k].get_or_insert_with(|| {
            ground.highest_within(grid.cell_centre(k), grid.cell_radius(), grid.down)
        })
    }
}

/// The ground's plane first below `from` along `down` within `max`, if it is usable (a
/// non-finite or degenerate hit is a miss).
pub(super) fn plane_below(
    ground: &dyn Ground,
    from: DVec3,
    down: DVec3,
    max: f64,
) -> Option<GroundPlane> {
    ground
        .cast_down(from, down, max)
        .and_then(|hit| GroundPlane::new(hit.point, hit.normal))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::ground::floor::{Floor, FloorCastStats};
    use crate::pose::ground::mesh::{TriangleGround, grid_triangles};

    /// A terrain of `n × n` unit squares: rolling hills with terraces (walls 0.45 high every
    /// 4 units along x) under a gravity tilted off -y.
    fn terrace_terrain(n: usize, gravity: DVec3) -> TriangleGround {
        let height =
            |x: f64, z: f64| 0.45 * (x / 4.0).floor() + 0.3 * (0.7 * x).sin() * (0.5 * z).cos();
        let mut positions = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let (x, z) = (i as f64, j as f64);
                positions.push(DVec3::new(x, height(x, z), z));
            }
        }
        TriangleGround::new(positions, grid_triangles(n), gravity)
    }

    /// Two floors agree: the same vertices, each with planes that agree at it to 1e-9.
    fn assert_same_floor(a: &Floor, b: &Floor, positions: &[DVec3]) {
        let (Floor::Under(a), Floor::Under(b)) = (a, b) else {
            panic!("cast floors are per vertex")
        };
        assert_eq!(
            a.iter().map(|(v, _)| *v).collect::<Vec<_>>(),
            b.iter().map(|(v, _)| *v).collect::<Vec<_>>()
        );
        for ((v, pa), (_, pb)) in a.iter().zip(b) {
            let p = positions[*v as usize];
            assert!(
                (pa.height(p) - pb.height(p)).abs() < 1e-9,
                "vertex {v}: {pa:?} against {pb:?}"
            );
            assert!(
                pa.normal.distance(pb.normal) < 1e-9,
                "vertex {v}: {pa:?} against {pb:?}"
            );
        }
    }

    /// A body walking over a terraced terrain, its legs swinging: the floor cast with a
    /// memory kept from step to step is the floor cast afresh at every step, and after the
    /// first step the memory answers most of the grid. (Fails if a remembered cast answers a
    /// window it does not cover, or if the lattice moves with the body.)
    #[test]
    fn a_remembered_floor_is_the_floor_cast_afresh() {
        let gravity = DVec3::new(0.04, -1.0, 0.02).normalize();
        let ground = terrace_terrain(24, gravity);
        let sampling = FloorSampling {
            down: gravity,
            band: 0.4,
            near: 0.1,
            spacing: 0.25,
        };
        let mut memory = FloorMemory::default();
        let (mut remembered, mut cast) = (0, 0);
        for step in 0..60 {
            let t = step as f64 * 0.15;
            // A body 2 × 1 over the ground, legs reaching down and swinging.
            let mut body = Vec::new();
            for k in 0..200 {
                let (u, w) = ((k % 20) as f64 / 19.0, (k / 20) as f64 / 9.0);
                let x = 2.0 + t + 2.0 * u;
                let z = 8.0 + w + 0.2 * (0.3 * t).sin();
                let ground_y = 0.45 * (x / 4.0).floor() + 0.3;
                let leg = if k % 7 == 0 {
                    0.9 + 0.2 * (t + u).sin()
                } else {
                    0.0
                };
                body.push(DVec3::new(x, ground_y + 0.9 - leg, z));
            }
            let (fresh, _) = Floor::cast(&body, &ground, &sampling);
            let (kept, stats): (Floor, FloorCastStats) =
                Floor::cast_remembering(&body, &ground, &sampling, &mut memory);
            assert_same_floor(&kept, &fresh, &body);
            assert!(
                !matches!(&kept, Floor::Under(u) if u.is_empty()),
                "step {step}"
            );
            if step > 0 {
                (remembered, cast) = (
                    remembered + stats.grid_nodes_remembered,
                    cast + stats.grid_casts,
                );
            }
        }
        assert!(
            remembered > 4 * cast,
            "{remembered} remembered, {cast} cast"
        );
    }

    /// A node whose ground rises above the window a floor asks for (a level just above the
    /// skin's lowest vertex + band): the remembered generous cast saw that level, and the
    /// node is cast again as a floor without memory casts it — no plane there. Another
    /// gravity or spacing forgets the memory; `forget` does.
    #[test]
    fn ground_above_the_window_is_cast_again_and_another_lattice_forgets() {
        // y = 0 for x < 1, y = 0.15 beyond.
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let positions = vec![
            p(-2.0, 0.0, -2.0),
            p(1.0, 0.0, -2.0),
            p(1.0, 0.0, 2.0),
            p(-2.0, 0.0, 2.0),
            p(1.0, 0.15, -2.0),
            p(4.0, 0.15, -2.0),
            p(4.0, 0.15, 2.0),
            p(1.0, 0.15, 2.0),
        ];
        let triangles = vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]];
        let ground = TriangleGround::new(positions, triangles, DVec3::NEG_Y);
        let sampling = FloorSampling {
            down: DVec3::NEG_Y,
            band: 0.1,
            near: 0.05,
            spacing: 0.5,
        };
        // The lowest vertex at 0.02 over the lower level: the window's top is 0.12, under
        // the upper level.
        let skin = [p(0.0, 0.02, 0.0), p(2.0, 0.5, 0.0), p(2.0, 0.17, 0.5)];
        let mut memory = FloorMemory::default();
        for _ in 0..2 {
            let (kept, _) = Floor::cast_remembering(&skin, &ground, &sampling, &mut memory);
            let (fresh, _) = Floor::cast(&skin, &ground, &sampling);
            assert_same_floor(&kept, &fresh, &skin);
        }
        let (_, stats) = Floor::cast_remembering(&skin, &ground, &sampling, &mut memory);
        assert!(
            stats.grid_casts > 0,
            "the upper level's nodes cast again: {stats:?}"
        );
        let coarser = FloorSampling {
            spacing: 1.0,
            ..sampling
        };
        let (_, stats) = Floor::cast_remembering(&skin, &ground, &coarser, &mut memory);
        assert_eq!(stats.grid_nodes_remembered, 0, "{stats:?}");
        let (_, stats) = Floor::cast_remembering(&skin, &ground, &coarser, &mut memory);
        assert!(stats.grid_nodes_remembered > 0, "{stats:?}");
        memory.forget();
        let (_, stats) = Floor::cast_remembering(&skin, &ground, &coarser, &mut memory);
        assert_eq!(stats.grid_nodes_remembered, 0, "{stats:?}");
    }
}
