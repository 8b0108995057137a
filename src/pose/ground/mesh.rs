//! [`TriangleGround`]: any triangle mesh (terrain, stairs, a bent plank baked into a mesh) as
//! the [`Ground`] a character stands on, cast along gravity.
//!
//! A uniform grid across gravity lists, per cell, the triangles whose shadow overlaps it, so a
//! cast tests only the few under it. A cast along the ground's own gravity — every cast the
//! pose layer makes: contacts and the floor under the skin — reads each candidate as its
//! shadow: the barycentric coordinates of the ray's foot in the triangle's projection across
//! gravity and the depth interpolated at them (a handful of multiplications, prepared once
//! per triangle). A cast along any other direction tests every triangle with Möller–Trumbore.
//! Both decide alike: a projected area below 1e-14 is edge-on, barycentric coordinates are
//! accepted within 1e-12 of the triangle's edges.

use glam::{DVec2, DVec3};

use crate::pose::ground::Ground;
use crate::pose::ground::GroundPlane;

/// A triangle mesh as ground, with a uniform grid across gravity: a cast tests the triangles
/// whose shadow overlaps its cell (terrain, stairs, a bent plank baked into a mesh).
#[derive(Debug, Clone)]
pub struct TriangleGround {
    /// Each triangle's corners (a cast along another direction than the grid's reads these).
    corners: Vec<[DVec3; 3]>,
    /// Each triangle seen along the grid's gravity (a cast along it reads these).
    shadows: Vec<Shadow>,
    down: DVec3,
    axes: (DVec3, DVec3),
    origin: DVec2,
    cell: f64,
    size: (usize, usize),
    /// Triangle indices per cell, cell after cell (`starts` has one more entry than cells).
    cells: Vec<u32>,
    starts: Vec<u32>,
    /// Per cell, the highest corner (elevation against gravity) of its triangles (`-∞` for
    /// none): [`Ground::highest_within`] reads these.
    tops: Vec<f64>,
}

/// A triangle seen along gravity: its first corner and two edges across gravity, the inverse
/// of the edges' cross product (0: seen edge-on), its first corner's depth along gravity and
/// how the depth changes along each edge, and its normal facing against gravity.
#[derive(Debug, Clone, Copy)]
struct Shadow {
    a: DVec2,
    e1: DVec2,
    e2: DVec2,
    inverse_area: f64,
    depth: f64,
    depth_along: DVec2,
    normal: DVec3,
}

/// Below this (doubled, signed) projected area a triangle is seen edge-on: Möller–Trumbore's
/// determinant is the same number.
const EDGE_ON: f64 = 1e-14;
/// How far outside its edges (in barycentric coordinates) a cast still hits a triangle.
const EDGE_SLACK: f64 = 1e-12;

impl Shadow {
    /// The triangle `[a, b, c]` seen along `down`, across `axes`.
    fn new([a, b, c]: [DVec3; 3], down: DVec3, axes: (DVec3, DVec3)) -> Self {
        let flat = |p: DVec3| across(p, axes);
        let (e1, e2) = (flat(b) - flat(a), flat(c) - flat(a));
        let area = e1.perp_dot(e2);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        Self {
            a: flat(a),
            e1,
            e2,
            inverse_area: if area.abs() < EDGE_ON {
                0.0
            } else {
                1.0 / area
            },
            depth: a.dot(down),
            depth_along: DVec2::new((b - a).dot(down), (c - a).dot(down)),
            normal: if normal.dot(down) > 0.0 {
                -normal
            } else {
                normal
            },
        }
    }

    /// The depth along gravity at `f` (across gravity), if `f` is over the triangle.
    fn depth_at(&self, f: DVec2) -> Option<f64> {
        if self.inverse_area == 0.0 {
            return None;
        }
        let s = f - self.a;
        let u = s.perp_dot(self.e2) * self.inverse_area;
        if !(-EDGE_SLACK..=1.0 + EDGE_SLACK).contains(&u) {
            return None;
        }
        let v = self.e1.perp_dot(s) * self.inverse_area;
        if v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
            return None;
        }
        Some(self.depth + u * self.depth_along.x + v * self.depth_along.y)
    }
}

impl TriangleGround {
    /// The ground made of `triangles` over `positions`, cast along `gravity`. Triangles with
    /// an index out of range or a non-finite corner are left out.
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>, gravity: DVec3) -> Self {
        let down = gravity.try_normalize().unwrap_or(DVec3::NEG_Y);
        let x = down.any_orthonormal_vector();
        let axes = (x, down.cross(x));
        let flat = |p: DVec3| across(p, axes);
        let triangles: Vec<[u32; 3]> = triangles
            .into_iter()
            .filter(|t| {
                t.iter()
                    .all(|&v| positions.get(v as usize).is_some_and(|p| p.is_finite()))
            })
            .collect();
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for t in &triangles {
            for &v in t {
                let p = flat(positions[v as usize]);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if triangles.is_empty() {
            lo = DVec2::ZERO;
            hi = DVec2::ONE;
        }
        // About two triangles per cell.
        let area = ((hi.x - lo.x) * (hi.y - lo.y)).max(1e-12);
        let cell = (area / (triangles.len().max(1) as f64 / 2.0))
            .sqrt()
            .max(1e-9);
        let size = (
            (((hi.x - lo.x) / cell).ceil() as usize).clamp(1, 4096),
            (((hi.y - lo.y) / cell).ceil() as usize).clamp(1, 4096),
        );
        let cell = ((hi.x - lo.x) / size.0 as f64)
            .max((hi.y - lo.y) / size.1 as f64)
            .max(1e-9);
        let index = |p: DVec2| {
            let c = ((p - lo) / cell).floor();
            (
                (c.x.max(0.0) as usize).min(size.0 - 1),
                (c.y.max(0.0) as usize).min(size.1 - 1),
            )
        };
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); size.0 * size.1];
        for (k, t) in triangles.iter().enumerate() {
            let pts = t.map(|v| flat(positions[v as usize]));
            let (a, b) = (
                index(pts[0].min(pts[1]).min(pts[2])),
                index(pts[0].max(pts[1]).max(pts[2])),
            );
            for i in a.0..=b.0 {
                for j in a.1..=b.1 {
                    per_cell[j * size.0 + i].push(k as u32);
                }
            }
        }
        let corners: Vec<[DVec3; 3]> = triangles
            .iter()
            .map(|t| t.map(|v| positions[v as usize]))
            .collect();
        let shadows = corners
            .iter()
            .map(|c| Shadow::new(*c, down, axes))
            .collect();
        let mut starts = Vec::with_capacity(per_cell.len() + 1);
        let mut cells = Vec::new();
        starts.push(0);
        for c in per_cell {
            cells.extend(c);
            starts.push(cells.len() as u32);
        }
        let tops = starts
            .windows(2)
            .map(|w| {
                cells[w[0] as usize..w[1] as usize]
                    .iter()
                    .flat_map(|&k| corners[k as usize].iter())
                    .map(|c| -c.dot(down))
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect();
        Self {
            corners,
            shadows,
            down,
            axes,
            origin: lo,
            cell,
            size,
            cells,
            starts,
            tops,
        }
    }

    /// `p` across this ground's gravity.
    fn flat(&self, p: DVec3) -> DVec2 {
        across(p, self.axes)
    }

    /// The grid cell over `f` (across gravity), if it is over the ground's extent.
    fn cell_of(&self, f: DVec2) -> Option<usize> {
        let (i, j) = self.cell_ij(f);
        (i >= 0 && j >= 0 && (i as usize) < self.size.0 && (j as usize) < self.size.1)
            .then(|| j as usize * self.size.0 + i as usize)
    }

    /// The grid column and row over `f` (across gravity), negative before the grid's first.
    /// (Truncation, not `floor`: without SSE4.1 `floor` is a call, and this is asked once a
    /// cast and once a vertex.)
    fn cell_ij(&self, f: DVec2) -> (i64, i64) {
        let index = |x: f64| if x < 0.0 { -1 } else { x as i64 };
        let c = (f - self.origin) / self.cell;
        (index(c.x), index(c.y))
    }

    /// A cast along this ground's gravity: the shadows of the triangles in the cell under
    /// `from`.
    fn cast_along_gravity(&self, from: DVec3, max: f64) -> Option<GroundPlane> {
        let f = self.flat(from);
        let c = self.cell_of(f)?;
        let cell = &self.cells[self.starts[c] as usize..self.starts[c + 1] as usize];
        let start = from.dot(self.down);
        let mut best: Option<(f64, usize)> = None;
        for &k in cell {
            let shadow = &self.shadows[k as usize];
            if let Some(depth) = shadow.depth_at(f) {
                let t = depth - start;
                if (0.0..=max).contains(&t) && best.is_none_or(|(bt, _)| t < bt) {
                    best = Some((t, k as usize));
                }
            }
        }
        best.map(|(t, k)| GroundPlane {
            point: from + self.down * t,
            normal: self.shadows[k].normal,
        })
    }

    /// A cast along any direction: every triangle, by Möller–Trumbore.
    fn cast_every_triangle(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        let mut best: Option<(f64, GroundPlane)> = None;
        for &[a, b, c] in &self.corners {
            if let Some(t) = ray_triangle(from, down, a, b, c)
                && t <= max
                && best.as_ref().is_none_or(|(bt, _)| t < *bt)
            {
                let n = (b - a).cross(c - a).normalize_or_zero();
                let n = if n.dot(down) > 0.0 { -n } else { n };
                best = Some((
                    t,
                    GroundPlane {
                        point: from + down * t,
                        normal: n,
                    },
                ));
            }
        }
        best.map(|(_, hit)| hit)
    }
}

impl Ground for TriangleGround {
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        if !from.is_finite() {
            return None;
        }
        // The grid is across this ground's gravity; another direction tests every triangle.
        if down.dot(self.down) > 1.0 - 1e-9 {
            self.cast_along_gravity(from, max)
        } else {
            self.cast_every_triangle(from, down, max)
        }
    }

    /// The highest corner of the triangles in the grid cells the square about `centre` of
    /// half-side `radius` touches (along this ground's gravity only: `None` for another), read
    /// from each cell's highest corner kept at construction.
    fn highest_within(&self, centre: DVec3, radius: f64, down: DVec3) -> Option<f64> {
        if !(centre.is_finite() && radius.is_finite()) || down.dot(self.down) <= 1.0 - 1e-9 {
            return None;
        }
        let f = self.flat(centre);
        let (lo, hi) = (
            self.cell_ij(f - DVec2::splat(radius)),
            self.cell_ij(f + DVec2::splat(radius)),
        );
        let last = (self.size.0 as i64 - 1, self.size.1 as i64 - 1);
        if hi.0 < 0 || hi.1 < 0 || lo.0 > last.0 || lo.1 > last.1 {
            return Some(f64::NEG_INFINITY);
        }
        let range = |a: i64, b: i64, last: i64| (a.max(0) as usize)..=(b.min(last) as usize);
        let mut highest = f64::NEG_INFINITY;
        for j in range(lo.1, hi.1, last.1) {
            let row = &self.tops[j * self.size.0..(j + 1) * self.size.0];
            for i in range(lo.0, hi.0, last.0) {
                highest = highest.max(row[i]);
            }
        }
        Some(highest)
    }
}

/// `p`'s coordinates along `axes` (two unit vectors across gravity).
fn across(p: DVec3, axes: (DVec3, DVec3)) -> DVec2 {
    DVec2::new(p.dot(axes.0), p.dot(axes.1))
}

/// Möller–Trumbore: the distance along `dir` from `o` to triangle `abc`, if hit (either side;
/// `dir` need not be unit, the distance is in its lengths). The crate's one ray–triangle test:
/// ground casts and picking a posed character both use it.
pub(crate) fn ray_triangle(o: DVec3, dir: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < EDGE_ON {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(-EDGE_SLACK..=1.0 + EDGE_SLACK).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t >= 0.0).then_some(t)
}

/// Two levels, for tests: y = 0 for x < `edge`, y = 0.3 beyond, as two quads reaching `half`
/// either side of the edge and of z = 0.
#[cfg(test)]
pub(crate) fn two_levels(edge: f64, half: f64) -> TriangleGround {
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let (a, b) = (edge - half, edge + half);
    let positions = vec![
        p(a, 0.0, -half),
        p(edge, 0.0, -half),
        p(edge, 0.0, half),
        p(a, 0.0, half),
        p(edge, 0.3, -half),
        p(b, 0.3, -half),
        p(b, 0.3, half),
        p(edge, 0.3, half),
    ];
    let triangles = vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]];
    TriangleGround::new(positions, triangles, DVec3::NEG_Y)
}

/// The triangles of an `(n + 1) × (n + 1)` grid of points laid out row after row (point
/// `(i, j)` at `i (n + 1) + j`), two per square, for tests.
#[cfg(test)]
pub(crate) fn grid_triangles(n: usize) -> Vec<[u32; 3]> {
    let at = |i: usize, j: usize| (i * (n + 1) + j) as u32;
    let mut triangles = Vec::with_capacity(2 * n * n);
    for i in 0..n {
        for j in 0..n {
            triangles.push([at(i, j), at(i, j + 1), at(i + 1, j)]);
            triangles.push([at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]);
        }
    }
    triangles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn casts_down_find_the_step_under_them_and_miss_beyond_the_ground() {
        let g = two_levels(1.0, 3.0);
        let hit = g
            .cast_down(DVec3::new(0.0, 2.0, 0.5), DVec3::NEG_Y, 5.0)
            .unwrap();
        assert!(hit.point.distance(DVec3::new(0.0, 0.0, 0.5)) < 1e-12);
        assert!(hit.normal.distance(DVec3::Y) < 1e-12);
        let hit = g
            .cast_down(DVec3::new(2.5, 2.0, -1.0), DVec3::NEG_Y, 5.0)
            .unwrap();
        assert!((hit.point.y - 0.3).abs() < 1e-12);
        assert_eq!(
            g.cast_down(DVec3::new(9.0, 2.0, 0.0), DVec3::NEG_Y, 5.0),
            None
        );
        assert_eq!(
            g.cast_down(DVec3::new(0.0, 2.0, 0.0), DVec3::NEG_Y, 1.0),
            None
        );
        assert_eq!(g.cast_down(DVec3::NAN, DVec3::NEG_Y, 1.0), None);
    }

    /// A rough terrain: a jittered grid of heights with terraces (walls seen edge-on), a
    /// tilted gravity, overhanging triangles above it. Casts along gravity through the grid
    /// and its triangles' shadows find what Möller–Trumbore over every triangle finds.
    #[test]
    fn a_cast_along_gravity_finds_what_every_triangle_finds() {
        // A small deterministic generator (no dependency for one test).
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 12;
        let mut positions = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let terrace = ((i / 4) as f64) * 0.5;
                positions.push(DVec3::new(
                    i as f64 + 0.3 * random(),
                    terrace + 0.4 * random(),
                    j as f64 + 0.3 * random(),
                ));
            }
        }
        let mut triangles = grid_triangles(n);
        // Overhangs: small triangles floating above the terrain.
        for _ in 0..20 {
            let base = positions.len() as u32;
            let c = DVec3::new(n as f64 * random(), 3.0 + random(), n as f64 * random());
            for _ in 0..3 {
                positions.push(c + DVec3::new(random() - 0.5, 0.2 * random(), random() - 0.5));
            }
            triangles.push([base, base + 1, base + 2]);
        }
        let gravity = DVec3::new(0.05, -1.0, -0.03).normalize();
        let ground = TriangleGround::new(positions, triangles, gravity);
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..4000 {
            let from = DVec3::new(
                -1.0 + (n as f64 + 2.0) * random(),
                2.0 + 4.0 * random(),
                -1.0 + (n as f64 + 2.0) * random(),
            );
            let max = 6.0 * random();
            let fast = ground.cast_down(from, gravity, max);
            let every = ground.cast_every_triangle(from, gravity, max);
            match (fast, every) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert!(a.point.distance(b.point) < 1e-9, "{a:?} against {b:?}");
                    assert!(a.normal.distance(b.normal) < 1e-9, "{a:?} against {b:?}");
                }
                (None, None) => misses += 1,
                (a, b) => panic!("from {from}: {a:?} along gravity, {b:?} over every triangle"),
            }
        }
        // Both outcomes were exercised.
        assert!(hits > 1000 && misses > 500, "{hits} hits, {misses} misses");
    }
}
