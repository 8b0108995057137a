//! The floor: every skin vertex near the ground kept above it, in the same solve as the
//! contacts, the limits and the effectors (a one-sided term per vertex, see
//! [`crate::pose::ground::contact`]).
//!
//! A [`Floor`] is either one plane for the whole body ([`Floor::Plane`]: a flat floor; the
//! solve picks the vertices within its band of it in the pose it starts from) or a plane per
//! vertex ([`Floor::Under`]), sampled from any [`Ground`] by [`Floor::cast`]: terrain, hills
//! and steps, where a single plane under the root is centimetres off under the far paws.
//!
//! [`Floor::cast`] costs a coarse grid of casts over the body's footprint plus one cast per
//! vertex that comes close to the ground:
//! 1. the footprint (the skin across gravity) is covered by a grid of casts `spacing` apart,
//!    each giving the ground's plane at a node (the nodes lie on a lattice fixed in the
//!    ground's space, so [`Floor::cast_remembering`] answers the nodes a [`FloorMemory`]
//!    already cast — a character standing or walking casts only the nodes new under it);
//! 2. a vertex's coarse ground is the highest of the planes of the four nodes around it (at a
//!    step's edge the upper level wins: the floor errs on the side of lifting);
//! 3. a vertex within `band` of its coarse ground is in the floor; within `near` of it, the
//!    ground right under it is cast (one ray each: the exact triangle, the step's own edge),
//!    and the coarse plane is its fallback when that cast misses;
//! 4. a vertex further up is cast under too when the ground rises somewhere over its cell more
//!    than `near` above the coarse ground and to within `near` of the vertex
//!    ([`Ground::highest_within`]: a ridge or a rail between two nodes, a step's edge), and is
//!    in the floor if that ground is within `band`.
//!
//! The floor is built from the pose a solve starts from, so `band` has to cover the motion of
//! a solve (a paw that starts far above and ends below is in it).
//!
//! A ground that cannot bound its height over a cell (the default of
//! [`Ground::highest_within`]: closures, custom grounds) is trusted at the nodes alone: a
//! ridge or rail narrower than `spacing` and taller than `near` between two nodes is then not
//! under a vertex more than `near` above the coarse ground (a vertex can end inside it).
//! [`crate::pose::TriangleGround`] and the scene's ground of meshes bound it.

use glam::DVec3;

use crate::deform::bounding_box;
use crate::pose::ground::Ground;
use crate::pose::ground::GroundPlane;
use crate::pose::ground::floor_grid::{CoarseGrid, plane_below};

pub use crate::pose::ground::floor_grid::FloorMemory;

/// Every skin vertex near the ground kept above it (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub enum Floor {
    /// One plane: the vertices within `band` of it (or below it) in the pose a solve starts
    /// from are kept above it in that solve.
    Plane {
        /// The floor.
        plane: GroundPlane,
        /// Vertices within this height of the floor are its active set (world units: more
        /// than a solve's motion).
        band: f64,
    },
    /// Each listed welded vertex kept above its own plane of the ground ([`Floor::cast`]).
    Under(Vec<(u32, GroundPlane)>),
}

/// How [`Floor::cast`] samples the ground (world units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorSampling {
    /// Gravity (normalised by the cast).
    pub down: DVec3,
    /// Vertices within this height of the ground are in the floor.
    pub band: f64,
    /// Vertices within this height of the coarse ground get a cast of their own.
    pub near: f64,
    /// Spacing of the coarse grid of casts across the footprint.
    pub spacing: f64,
}

impl FloorSampling {
    /// The sampling for a character of `size` (its bounding diagonal): a band of `band` ×
    /// size, a grid 6 % of the size apart, exact casts within 5 % of the size.
    pub fn for_size(size: f64, band: f64, down: DVec3) -> Self {
        Self {
            down,
            band: band * size,
            near: 0.05 * size,
            spacing: 0.06 * size,
        }
    }
}

/// What a [`Floor::cast`] did: how many rays, how many vertices it keeps.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FloorCastStats {
    /// Casts on the coarse grid.
    pub grid_casts: usize,
    /// Nodes of the coarse grid answered from a [`FloorMemory`] without a cast.
    pub grid_nodes_remembered: usize,
    /// Casts under single vertices.
    pub vertex_casts: usize,
    /// Vertices in the floor.
    pub vertices: usize,
}

impl Floor {
    /// The floor under the skin `positions` (welded, in the pose a solve starts from, in the
    /// ground's space) on `ground` (see the module docs). Vertices over no ground are left
    /// out; non-finite hits are ignored. The floor is empty for no positions or a sampling
    /// that is not finite and positive.
    pub fn cast(
        positions: &[DVec3],
        ground: &dyn Ground,
        sampling: &FloorSampling,
    ) -> (Self, FloorCastStats) {
        Self::cast_remembering(positions, ground, sampling, &mut FloorMemory::default())
    }

    /// [`Floor::cast`], answering the grid's casts from `memory` where it can and keeping
    /// the new ones in it (see [`FloorMemory`]): the same floor, cast for the nodes new under
    /// the skin only. `memory` has to be of this `ground` ([`FloorMemory::forget`] it when
    /// the ground changes).
    pub fn cast_remembering(
        positions: &[DVec3],
        ground: &dyn Ground,
        sampling: &FloorSampling,
        memory: &mut FloorMemory,
    ) -> (Self, FloorCastStats) {
        let mut stats = FloorCastStats::default();
        let Some(grid) = CoarseGrid::new(positions, sampling) else {
            return (Floor::Under(Vec::new()), stats);
        };
        memory.fit(&grid);
        let down = grid.down;
        let cast = |from: DVec3, max: f64| plane_below(ground, from, down, max);
        // The coarse planes, from the top of the band above the lowest vertex.
        let top = grid.lowest + sampling.band;
        let window = (top, top - 2.0 * sampling.band);
        let nodes: Vec<Option<GroundPlane>> = (0..grid.nodes())
            .map(|k| {
                let (plane, cast) = memory.node_plane((&grid, k), window, ground);
                stats.grid_casts += usize::from(cast);
                stats.grid_nodes_remembered += usize::from(!cast);
                plane
            })
            .collect();
        // Each node's plane as its normal and offset (a height `n·p - offset`); a node over
        // no ground is infinitely far below every vertex.
        let offsets: Vec<(DVec3, f64)> = nodes
            .iter()
            .map(|n| {
                n.map_or((DVec3::ZERO, f64::NEG_INFINITY), |g| {
                    (g.normal, g.normal.dot(g.point))
                })
            })
            .collect();
        let mut under = Vec::with_capacity(positions.len());
        for (v, p) in positions.iter().enumerate() {
            if !p.is_finite() {
                continue;
            }
            // The highest of the surrounding nodes' planes at this vertex (the first of equals).
            let cell = grid.cell_ij(*p);
            let (mut nearest, mut height) = (None, f64::INFINITY);
            for k in grid.around(cell) {
                let (normal, offset) = offsets[k];
                let h = normal.dot(*p) - offset;
                if h < height {
                    (nearest, height) = (Some(k), h);
                }
            }
            let coarse = nearest.and_then(|k| nodes[k]);
            // Well above the coarse ground: unless the ground rises between the nodes more
            // than `near` over the coarse ground (a ridge, a step's edge; lower rises are
            // what `near` is for) and to within `near` of this vertex.
            let far = coarse.is_some() && height >= sampling.near;
            let rise_under = far && {
                let (i, j) = cell;
                let rise = memory.rise((&grid, j * grid.size.0 + i), ground);
                let elevation = -p.dot(down);
                rise.is_some_and(|top| {
                    top > elevation - height + sampling.near && elevation < top + sampling.near
                })
            };
            if far && !rise_under && height >= sampling.band {
                continue;
            }
            let exact = (!far || rise_under)
                .then(|| {
                    stats.vertex_casts += 1;
                    cast(*p - down * sampling.band, 2.0 * sampling.band)
                })
                .flatten();
            match (exact, coarse) {
                // Cast for a rise between the nodes: kept if the ground under it is near.
                (Some(plane), _) if rise_under && plane.height(*p) >= sampling.band => {}
                (Some(plane), _) => under.push((v as u32, plane)),
                (None, Some(plane)) if height < sampling.band => under.push((v as u32, plane)),
                (None, _) => {}
            }
        }
        stats.vertices = under.len();
        (Floor::Under(under), stats)
    }

    /// How far the vertex deepest under its plane is below it, of `positions` (welded, as the
    /// floor was cast for): negative when one is under, `+∞` for an empty floor. A vertex
    /// the floor lists but `positions` does not have is skipped.
    pub fn deepest(&self, positions: &[DVec3]) -> f64 {
        match self {
            Floor::Plane { plane, .. } => positions
                .iter()
                .map(|p| plane.height(*p))
                .fold(f64::INFINITY, f64::min),
            Floor::Under(under) => under
                .iter()
                .filter_map(|(v, plane)| positions.get(*v as usize).map(|p| plane.height(*p)))
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// Whether a vertex of `positions` (welded, in the ground's space) may be more than
    /// `depth` under `ground`: `false` only when each is certainly less deep — above the
    /// ground's own bound over its column ([`Ground::highest_within`], asked once for the
    /// whole footprint and then per vertex below that), or else above the ground a cast
    /// under it finds (from `band` above, as [`Floor::cast`] casts a vertex). Much cheaper
    /// than casting the floor to read [`Floor::deepest`]: after a solve most skin is above
    /// every ground near it and needs no cast. A ground that cannot bound its height
    /// answers `true` (cast the floor to know).
    pub fn may_be_under(
        positions: &[DVec3],
        ground: &dyn Ground,
        sampling: &FloorSampling,
        depth: f64,
    ) -> bool {
        if positions.is_empty() {
            return false;
        }
        let Some(down) = sampling.down.try_normalize() else {
            return true;
        };
        let (lo, hi) = bounding_box(positions);
        // A square about the box's centre as wide as the box's diagonal holds its footprint.
        let Some(top) = ground.highest_within((lo + hi) * 0.5, 0.5 * (hi - lo).length(), down)
        else {
            return true;
        };
        let band = sampling.band;
        positions
            .iter()
            .filter(|p| p.is_finite())
            .map(|p| (*p, -p.dot(down)))
            .filter(|(_, elevation)| elevation + depth < top)
            .any(|(p, elevation)| match ground.highest_within(p, 0.0, down) {
                Some(over) if over <= elevation + depth => false,
                None => true,
                Some(_) => plane_below(ground, p - down * band, down, 2.0 * band)
                    .is_some_and(|plane| plane.height(p) < -depth),
            })
    }

    /// This floor with the planes of `earlier` (a floor cast for the same skin before it
    /// moved) that meet a plane of this one in a valley: a vertex the ground under it has
    /// changed for keeps its earlier plane too where the two planes are each on or above the
    /// other at its surface point (a riser's foot, a terrace's inner corner — the ground
    /// there is the higher of the two, and the skin has to be above both), not where they
    /// meet in a ridge (a step's edge, where the ground is the lower of the two). A vertex
    /// pushed out of one face of a valley is then not pushed into the other, pass after
    /// pass. Only per-vertex floors merge; anything else is returned as it is.
    pub fn with_valleys_of(self, earlier: &Floor) -> Floor {
        let (mut under, before) = match (self, earlier) {
            (Floor::Under(under), Floor::Under(before)) => (under, before),
            (floor, _) => return floor,
        };
        let mut by_vertex: Vec<(u32, usize)> = before
            .iter()
            .enumerate()
            .map(|(k, (v, _))| (*v, k))
            .collect();
        by_vertex.sort_unstable();
        let valley = |a: &GroundPlane, b: &GroundPlane| {
            a.normal != b.normal && a.height(b.point) >= 0.0 && b.height(a.point) >= 0.0
        };
        for n in 0..under.len() {
            let (v, plane) = under[n];
            let first = by_vertex.partition_point(|&(u, _)| u < v);
            for &(_, k) in by_vertex[first..].iter().take_while(|&&(u, _)| u == v) {
                let old = before[k].1;
                if valley(&plane, &old) {
                    under.push((v, old));
                }
            }
        }
        Floor::Under(under)
    }

    /// Whether the numbers can be used (vertex indices are checked by the solver).
    pub(crate) fn is_valid(&self) -> bool {
        let usable = |g: &GroundPlane| {
            g.point.is_finite() && g.normal.is_finite() && (g.normal.length() - 1.0).abs() < 1e-6
        };
        match self {
            Floor::Plane { plane, band } => usable(plane) && band.is_finite() && *band >= 0.0,
            Floor::Under(under) => under.iter().all(|(_, g)| usable(g)),
        }
    }

    /// The planes of the floor, to map them into another frame.
    pub(crate) fn planes_mut(&mut self) -> Box<dyn Iterator<Item = &mut GroundPlane> + '_> {
        match self {
            Floor::Plane { plane, .. } => Box::new(std::iter::once(plane)),
            Floor::Under(under) => Box::new(under.iter_mut().map(|(_, g)| g)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::ground::mesh::TriangleGround;

    /// Two levels (y = 0 for x < 0, 0.3 beyond), a sampling for them, and a skin of two paws
    /// just above each level and a vertex high above.
    fn step_scene() -> (TriangleGround, FloorSampling, Vec<DVec3>) {
        let ground = crate::pose::ground::mesh::two_levels(0.0, 3.0);
        let sampling = FloorSampling {
            down: DVec3::NEG_Y,
            band: 0.5,
            near: 0.1,
            spacing: 0.4,
        };
        let skin = vec![
            DVec3::new(-0.5, 0.02, 0.0),
            DVec3::new(0.5, 0.32, 0.0),
            DVec3::new(0.0, 1.5, 0.0),
        ];
        (ground, sampling, skin)
    }

    #[test]
    fn each_vertex_near_the_ground_gets_the_level_under_it_and_far_ones_are_left_out() {
        // The two paws and the high vertex, and one vertex sunk into the upper level.
        let (ground, sampling, mut positions) = step_scene();
        positions.push(DVec3::new(1.0, 0.2, 0.5));
        let (floor, stats) = Floor::cast(&positions, &ground, &sampling);
        let Floor::Under(under) = floor else {
            panic!("a cast floor is per vertex")
        };
        let level = |v: u32| under.iter().find(|(u, _)| *u == v).map(|(_, g)| g.point.y);
        assert!((level(0).unwrap() - 0.0).abs() < 1e-12, "{under:?}");
        assert!((level(1).unwrap() - 0.3).abs() < 1e-12);
        assert_eq!(level(2), None, "1.2 above the ground: not in the floor");
        assert!(
            (level(3).unwrap() - 0.3).abs() < 1e-12,
            "a sunk vertex is kept"
        );
        assert_eq!(stats.vertices, 3);
        assert!(
            stats.vertex_casts >= 2 && stats.grid_casts >= 4,
            "{stats:?}"
        );
        // A vertex over no ground is left out; no positions give an empty floor.
        let (floor, _) = Floor::cast(&[DVec3::new(9.0, 0.0, 0.0)], &ground, &sampling);
        assert_eq!(floor, Floor::Under(Vec::new()));
        let (floor, _) = Floor::cast(&[], &ground, &sampling);
        assert_eq!(floor, Floor::Under(Vec::new()));
    }

    /// `may_be_under`: skin above both levels is seen to be so (the lower level's paw over a
    /// cell the upper level also crosses, by its cast); a vertex sunk into the upper level by
    /// more than the depth is found, one sunk by less is not; a ground that cannot bound its
    /// height always answers that it may be. (Fails if the bound alone decides: the paw over
    /// the step's cell is under that cell's top.)
    #[test]
    fn skin_under_the_ground_is_found_without_casting_a_floor() {
        let (ground, sampling, mut skin) = step_scene();
        assert_eq!(ground.highest_within(skin[0], 0.0, DVec3::NEG_Y), Some(0.3));
        assert!(!Floor::may_be_under(&skin, &ground, &sampling, 0.01));
        skin.push(DVec3::new(1.0, 0.29, 0.5));
        assert!(!Floor::may_be_under(&skin, &ground, &sampling, 0.02));
        assert!(Floor::may_be_under(&skin, &ground, &sampling, 0.005));
        skin[3].y = 0.1;
        assert!(Floor::may_be_under(&skin, &ground, &sampling, 0.02));
        let plane = GroundPlane::new(DVec3::ZERO, DVec3::Y).unwrap();
        assert!(Floor::may_be_under(&skin[..3], &plane, &sampling, 0.01));
        assert!(!Floor::may_be_under(&[], &ground, &sampling, 0.01));
    }

    /// `with_valleys_of`: a vertex whose ground changed from a riser's foot to the riser
    /// keeps the level too (a valley: each plane above the other at its point); one whose
    /// ground changed across a step's edge does not (a ridge); an unchanged plane is not
    /// doubled, and a vertex the new floor does not list gets nothing.
    #[test]
    fn planes_meeting_in_a_valley_are_kept_and_ridges_are_not() {
        let plane = |p: DVec3, n: DVec3| GroundPlane::new(p, n).unwrap();
        let level = plane(DVec3::ZERO, DVec3::Y);
        // A riser rising from x = 1 towards +x, its foot on the level.
        let riser = plane(DVec3::new(1.5, 0.5, 0.0), DVec3::new(-1.0, 1.0, 0.0));
        // A step's top at y = 1 from x = 2 on: its edge meets the riser in a ridge.
        let top = plane(DVec3::new(2.5, 1.0, 0.0), DVec3::Y);
        // A slope far up: above the level, but the level's point is under it.
        let far_up = plane(DVec3::new(10.0, 2.0, 0.0), DVec3::new(0.1, 1.0, 0.0));
        let earlier = Floor::Under(vec![
            (0, level),
            (1, riser),
            (2, level),
            (3, level),
            (4, far_up),
        ]);
        let now = Floor::Under(vec![(0, riser), (1, top), (2, level), (4, level)]);
        let Floor::Under(merged) = now.with_valleys_of(&earlier) else {
            panic!("a per-vertex floor stays one")
        };
        assert_eq!(merged.len(), 5, "{merged:?}");
        assert_eq!(merged[4], (0, level), "the riser's foot keeps the level");
        let flat = Floor::Plane {
            plane: level,
            band: 1.0,
        };
        assert_eq!(flat.clone().with_valleys_of(&earlier), flat);
    }

    /// `deepest`: the vertex deepest under its own plane (a listed vertex the positions lack
    /// skipped); every position under one plane; +∞ for nothing.
    #[test]
    fn the_deepest_vertex_is_read_under_its_own_plane() {
        let plane = |y: f64| GroundPlane::new(DVec3::Y * y, DVec3::Y).unwrap();
        let under = Floor::Under(vec![(0, plane(0.0)), (1, plane(0.5)), (7, plane(9.0))]);
        let positions = [DVec3::new(0.0, 0.1, 0.0), DVec3::new(1.0, 0.3, 0.0)];
        assert!((under.deepest(&positions) + 0.2).abs() < 1e-12);
        let flat = Floor::Plane {
            plane: plane(0.2),
            band: 1.0,
        };
        assert!((flat.deepest(&positions) + 0.1).abs() < 1e-12);
        assert_eq!(Floor::Under(Vec::new()).deepest(&positions), f64::INFINITY);
    }
}
