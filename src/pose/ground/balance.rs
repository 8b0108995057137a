//! Balance: the character's centre of mass kept over its support polygon inside the pose solve.
//!
//! **Mass model.** A skinned character's mass is spread over its surface: each welded vertex
//! carries a third of the area of the triangles around it in the bind pose (a shell of uniform
//! density; [`vertex_masses`]). Where that is wrong for a rig (a heavy armour plate, a light
//! cape), [`Balance::masses`] gives a mass per welded vertex instead. The centre of mass is
//! then `Σ mᵢ xᵢ / Σ mᵢ` over the skinned vertices: linear in the joints' skinning transforms,
//! so the solver differentiates it exactly as it does a centroid effector.
//!
//! **Support polygon.** The points the character stands on ([`Balance::support`]: the planted
//! contacts' sole vertices, in world space) seen along gravity: their convex hull in the plane
//! across gravity. Three or more points not on one line make a polygon; fewer (one foot on a
//! point, contacts on a line) a point or a segment, which the centre of mass must be over.
//!
//! **In the solve.** The centre of mass, projected along gravity, must lie at least
//! [`Balance::margin`] inside the polygon (on the point or segment when it is degenerate). The
//! term is one-sided: zero while the centre of mass is inside, the squared distance to the
//! allowed region, times a weight well above an effector's, once it leaves it. It is part of
//! the same damped Gauss–Newton steps as the effectors and the joint limits, so the body
//! counterbalances — the hips and the other limbs move — and an effector pulling the body over
//! gives only as much as balance needs. A penalty leaves the centre of mass out of its region
//! by as much as the body pushes against it; a warm solve asks the next for that much more
//! ([`crate::pose::solver::PoseSolution::balance_boost`]), so over a few frames the margin is met without a
//! still stiffer term (which three iterations a frame would not converge).
//!
//! **Walking.** A walk balances itself dynamically: a trot stands on two paws between its
//! steps, the centre of mass beside the line between them. Held statically over those two
//! paws, the body would fight its clip (and the paws slide). [`Balance::lean`] lets the centre
//! of mass out of the polygon by as much as the clip carries it out (the character plugin sets
//! it from the clip under an additive layer): balance then keeps what the clip does on flat
//! ground, and corrects what the terrain and the pose add.

use glam::{DVec2, DVec3};

/// Keep the centre of mass over the support polygon (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Balance {
    /// The points the character stands on, world space (e.g. the planted soles' vertices).
    pub support: Vec<DVec3>,
    /// The direction of gravity, world space (any length but zero; e.g. `-Y`).
    pub gravity: DVec3,
    /// How far inside the polygon the centre of mass must stay, world units (ignored when the
    /// support is a point or a segment).
    pub margin: f64,
    /// How far the centre of mass may lean out of the polygon past the margin, world units
    /// (≥ 0; 0 for static balance): balance asks for `margin − lean` inside. A walk's two-paw
    /// phases (see the module docs).
    pub lean: f64,
    /// Weight in [0, 1], as effectors': 0 is no balance; 1 holds the centre of mass a thousand
    /// times as firmly as a position effector of weight 1 holds its joint.
    pub weight: f64,
    /// Mass per welded vertex (`None`: area per vertex, [`SkinnedModel::area_masses`]).
    pub masses: Option<Vec<f64>>,
}

impl Balance {
    /// Balance over `support` with gravity along −Y, no margin, full weight and the area mass
    /// model.
    pub fn over(support: Vec<DVec3>) -> Self {
        Self {
            support,
            gravity: DVec3::NEG_Y,
            margin: 0.0,
            lean: 0.0,
            weight: 1.0,
            masses: None,
        }
    }

    /// How far inside the polygon balance asks the centre of mass to be: the margin less the
    /// lean (negative: outside by at most that much).
    pub fn required_inside(&self) -> f64 {
        self.margin - self.lean
    }

    /// A hash of the support points and gravity: equal for the same support.
    pub(crate) fn support_key(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut hasher = std::hash::DefaultHasher::new();
        for p in self.support.iter().chain([&self.gravity]) {
            p.to_array().map(f64::to_bits).hash(&mut hasher);
        }
        hasher.finish()
    }

    /// Whether the numbers can be used: finite support points (at least one), a finite
    /// non-zero gravity, a finite non-negative margin and lean, masses finite and
    /// non-negative.
    pub(crate) fn is_valid(&self, vertex_count: usize) -> bool {
        !self.support.is_empty()
            && self.support.iter().all(|p| p.is_finite())
            && self.gravity.is_finite()
            && self.gravity.length_squared() > 0.0
            && self.margin.is_finite()
            && self.margin >= 0.0
            && self.lean.is_finite()
            && self.lean >= 0.0
            && self.masses.as_ref().is_none_or(|m| {
                m.len() == vertex_count && m.iter().all(|x| x.is_finite() && *x >= 0.0)
            })
    }
}

/// The support seen along gravity: a convex polygon, a segment or a point in the plane across
/// gravity.
#[derive(Debug, Clone, PartialEq)]
pub struct SupportPolygon {
    /// Gravity's direction (unit).
    down: DVec3,
    /// A basis of the plane across gravity.
    axes: (DVec3, DVec3),
    /// Hull corners in that plane, counter-clockwise (1: a point, 2: a segment).
    corners: Vec<DVec2>,
}

impl SupportPolygon {
    /// The hull of `points` seen along `gravity` (non-zero, finite; `points` finite and not
    /// empty, as [`Balance`] checks).
    pub fn new(points: &[DVec3], gravity: DVec3) -> Self {
        let down = gravity.normalize();
        let x = down.any_orthonormal_vector();
        let axes = (x, down.cross(x));
        let flat: Vec<DVec2> = points
            .iter()
            .map(|p| DVec2::new(p.dot(axes.0), p.dot(axes.1)))
            .collect();
        Self {
            down,
            axes,
            corners: convex_hull(flat),
        }
    }

    /// Gravity's direction (unit).
    pub fn down(&self) -> DVec3 {
        self.down
    }

    /// The hull's corners in the plane across gravity, counter-clockwise.
    pub fn corners(&self) -> &[DVec2] {
        &self.corners
    }

    /// The hull's corners back in world space, at the height (along gravity) of `at`.
    pub fn corners_at(&self, at: DVec3) -> Vec<DVec3> {
        let h = self.down * at.dot(self.down);
        self.corners
            .iter()
            .map(|c| self.axes.0 * c.x + self.axes.1 * c.y + h)
            .collect()
    }

    /// Signed distance of `point`, projected along gravity, inside the polygon's boundary
    /// (negative outside; for a point or segment, minus the distance to it).
    pub fn signed_distance(&self, point: DVec3) -> f64 {
        let p = self.flatten(point);
        let (nearest, inside) = self.nearest(p);
        let d = p.distance(nearest);
        if inside { d } else { -d }
    }

    /// The horizontal vector from the region allowed to the centre of mass (at least `margin`
    /// inside a polygon; on a point or segment) to `point` projected along gravity, world
    /// space; `None` while `point` is in that region. (For many points against one margin,
    /// make the region once: [`SupportPolygon::allowed`].)
    pub fn violation(&self, point: DVec3, margin: f64) -> Option<DVec3> {
        self.allowed(margin).violation(point)
    }

    /// The region the centre of mass is allowed in, seen along gravity: the polygon shrunk by
    /// `margin` (the intersection of its edges' half-planes moved inwards; as deep inside as
    /// the polygon goes when it is narrower than twice the margin), or grown by `-margin`
    /// when that is negative (a lean); a point or segment itself (the margin ignored).
    pub fn allowed(&self, margin: f64) -> AllowedRegion {
        let whole = |grow: f64| AllowedRegion {
            polygon: self.clone(),
            grow,
        };
        if self.corners.len() < 3 || !margin.is_finite() || margin == 0.0 {
            return whole(0.0);
        }
        if margin < 0.0 {
            return whole(-margin);
        }
        let shrunk = |by: f64| {
            shrink(&self.corners, by).map(|corners| AllowedRegion {
                polygon: Self {
                    corners,
                    ..self.clone()
                },
                grow: 0.0,
            })
        };
        if let Some(region) = shrunk(margin) {
            return region;
        }
        // Narrower than twice the margin: the deepest region found by bisection.
        let (mut inside, mut outside) = (0.0, margin);
        for _ in 0..40 {
            let mid = 0.5 * (inside + outside);
            if shrink(&self.corners, mid).is_some() {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        shrunk(inside).unwrap_or_else(|| whole(0.0))
    }

    /// `point` in the plane across gravity.
    fn flatten(&self, point: DVec3) -> DVec2 {
        DVec2::new(point.dot(self.axes.0), point.dot(self.axes.1))
    }

    /// The nearest point of the polygon's boundary (or of the point / segment) to `p`, and
    /// whether `p` is inside a polygon.
    fn nearest(&self, p: DVec2) -> (DVec2, bool) {
        let (nearest, inside, _) = self.nearest_feature(p);
        (nearest, inside)
    }

    /// [`SupportPolygon::nearest`], and whether the nearest point is a corner (an end of its
    /// edge, the point, an end of the segment).
    fn nearest_feature(&self, p: DVec2) -> (DVec2, bool, bool) {
        let c = &self.corners;
        match c.len() {
            0 => (p, false, false),
            1 => (c[0], false, true),
            2 => {
                let (q, t) = closest_on_segment_at(p, c[0], c[1]);
                (q, false, t <= 0.0 || t >= 1.0)
            }
            n => {
                let mut best = (c[0], f64::INFINITY, false);
                let mut inside = true;
                for k in 0..n {
                    let (a, b) = (c[k], c[(k + 1) % n]);
                    if (b - a).perp_dot(p - a) < 0.0 {
                        inside = false;
                    }
                    let (q, t) = closest_on_segment_at(p, a, b);
                    let d = q.distance_squared(p);
                    if d < best.1 {
                        best = (q, d, t <= 0.0 || t >= 1.0);
                    }
                }
                (best.0, inside, best.2)
            }
        }
    }
}

/// Where the centre of mass may be, seen along gravity ([`SupportPolygon::allowed`]): a convex
/// polygon, segment or point and how far outside it is still allowed. Its distance is smooth
/// (the squared distance to a convex region has a continuous gradient): the residual turns
/// round the region's corners instead of jumping from one edge's normal to the next.
#[derive(Debug, Clone, PartialEq)]
pub struct AllowedRegion {
    /// The region before growing (the support itself, or shrunk by a margin).
    polygon: SupportPolygon,
    /// How far outside `polygon` is still allowed (a lean; ≥ 0).
    grow: f64,
}

impl AllowedRegion {
    /// The horizontal vector from the region to `point` projected along gravity, world space;
    /// `None` while `point` is in it.
    pub fn violation(&self, point: DVec3) -> Option<DVec3> {
        self.residual(point).map(|(r, _)| r)
    }

    /// The directions the residual at `point` changes along as the centre of mass moves, each
    /// with its Gauss–Newton share: across the region's edge (one), or, past a corner, along
    /// the way to the corner (share 1) and across it (`(1 − grow / distance)²`: the rounded
    /// corner of a grown region turns less); none while `point` is in the region.
    pub fn directions(&self, point: DVec3) -> Vec<(DVec3, f64)> {
        let Some((r, corner)) = self.residual(point) else {
            return Vec::new();
        };
        let Some(out) = r.try_normalize() else {
            return Vec::new();
        };
        let mut directions = vec![(out, 1.0)];
        if let Some(distance) = corner {
            let share = (1.0 - self.grow / distance).powi(2);
            directions.push((self.polygon.down.cross(out), share));
        }
        directions
    }

    /// While `point` is in the region: the horizontal direction (world space, unit) in which
    /// it is nearest to leaving it and how far it may go that way before it does; `None` out
    /// of the region, or exactly on its boundary or on a point or segment support (no single
    /// way out).
    pub fn way_out(&self, point: DVec3) -> Option<(DVec3, f64)> {
        let p = self.polygon.flatten(point);
        let (nearest, inside, _) = self.polygon.nearest_feature(p);
        let (way, slack) = if inside && self.polygon.corners.len() >= 3 {
            let way = nearest - p;
            (way, way.length() + self.grow)
        } else {
            let way = p - nearest;
            (way, self.grow - way.length())
        };
        if slack < 0.0 {
            return None;
        }
        let out = way.try_normalize()?;
        let axes = self.polygon.axes;
        Some((axes.0 * out.x + axes.1 * out.y, slack))
    }

    /// The residual at `point` and, past a corner, the distance to it.
    fn residual(&self, point: DVec3) -> Option<(DVec3, Option<f64>)> {
        let p = self.polygon.flatten(point);
        let (nearest, inside, at_corner) = self.polygon.nearest_feature(p);
        if inside && self.polygon.corners.len() >= 3 {
            return None;
        }
        let way = p - nearest;
        let distance = way.length();
        if distance <= self.grow || distance == 0.0 {
            return None;
        }
        let v = way * ((distance - self.grow) / distance);
        let axes = self.polygon.axes;
        Some((axes.0 * v.x + axes.1 * v.y, at_corner.then_some(distance)))
    }
}

/// The point of segment `a`–`b` nearest `p`, and where along it (0 at `a`, 1 at `b`).
fn closest_on_segment_at(p: DVec2, a: DVec2, b: DVec2) -> (DVec2, f64) {
    let e = b - a;
    let len = e.length_squared();
    if len == 0.0 {
        return (a, 0.0);
    }
    let t = ((p - a).dot(e) / len).clamp(0.0, 1.0);
    (a + e * t, t)
}

/// The convex polygon `corners` (counter-clockwise) with each edge moved `by` inwards: the
/// intersection of the moved half-planes (Sutherland–Hodgman), as a hull; `None` when nothing
/// is left.
fn shrink(corners: &[DVec2], by: f64) -> Option<Vec<DVec2>> {
    let n = corners.len();
    let mut kept = corners.to_vec();
    for k in 0..n {
        let (a, b) = (corners[k], corners[(k + 1) % n]);
        let e = b - a;
        let length = e.length();
        if length == 0.0 {
            continue;
        }
        let inside = |x: DVec2| e.perp_dot(x - a) / length - by;
        let mut clipped = Vec::with_capacity(kept.len() + 1);
        for i in 0..kept.len() {
            let (p, q) = (kept[i], kept[(i + 1) % kept.len()]);
            let (sp, sq) = (inside(p), inside(q));
            if sp >= 0.0 {
                clipped.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                clipped.push(p + (q - p) * (sp / (sp - sq)));
            }
        }
        kept = clipped;
        if kept.is_empty() {
            return None;
        }
    }
    Some(convex_hull(kept))
}

/// Convex hull, counter-clockwise, without collinear points (Andrew's monotone chain): one
/// point or two for degenerate input.
fn convex_hull(mut points: Vec<DVec2>) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup_by(|a, b| a.distance_squared(*b) <= 1e-24);
    if points.len() <= 2 {
        return points;
    }
    let turn = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(points.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let ordered: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in ordered {
            while hull.len() >= start + 2
                && turn(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    if hull.len() < 3 {
        // All on one line: its two ends.
        let (first, last) = (points[0], points[points.len() - 1]);
        return vec![first, last];
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> SupportPolygon {
        let pts = [
            DVec3::new(-1.0, 0.0, -1.0),
            DVec3::new(1.0, 0.0, -1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(-1.0, 0.0, 1.0),
            DVec3::new(0.2, 0.0, 0.3),
        ];
        SupportPolygon::new(&pts, DVec3::NEG_Y)
    }

    #[test]
    fn a_square_and_the_point_inside_it_make_a_four_corner_hull() {
        assert_eq!(square().corners().len(), 4);
    }

    #[test]
    fn distances_are_signed_and_taken_across_gravity() {
        let s = square();
        // Height along gravity does not matter.
        assert!((s.signed_distance(DVec3::new(0.5, 7.0, 0.0)) - 0.5).abs() < 1e-12);
        assert!((s.signed_distance(DVec3::new(3.0, -2.0, 0.0)) + 2.0).abs() < 1e-12);
    }

    #[test]
    fn the_violation_points_out_of_the_region_the_margin_leaves() {
        let s = square();
        assert_eq!(s.violation(DVec3::new(0.0, 1.0, 0.0), 0.2), None);
        let v = s.violation(DVec3::new(0.9, 1.0, 0.0), 0.2).unwrap();
        assert!((v - DVec3::new(0.1, 0.0, 0.0)).length() < 1e-12, "{v}");
        let v = s.violation(DVec3::new(1.5, 1.0, 0.0), 0.2).unwrap();
        assert!((v - DVec3::new(0.7, 0.0, 0.0)).length() < 1e-12, "{v}");
    }

    #[test]
    fn collinear_and_single_supports_degenerate_to_a_segment_and_a_point() {
        let line = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
        ];
        let s = SupportPolygon::new(&line, DVec3::NEG_Y);
        assert_eq!(s.corners().len(), 2);
        // On the segment (margin ignored): no violation; beside it: the way back to it.
        assert_eq!(s.violation(DVec3::new(1.5, 3.0, 0.0), 0.3), None);
        let v = s.violation(DVec3::new(1.0, 3.0, 0.4), 0.3).unwrap();
        assert!((v - DVec3::new(0.0, 0.0, 0.4)).length() < 1e-12, "{v}");
        let one = SupportPolygon::new(&[DVec3::new(1.0, 0.0, 1.0)], DVec3::NEG_Y);
        let v = one.violation(DVec3::new(1.0, 5.0, 2.0), 0.0).unwrap();
        assert!((v - DVec3::Z).length() < 1e-12, "{v}");
    }

    #[test]
    fn past_a_corner_of_the_margin_the_residual_points_from_the_shrunk_corner() {
        // Square of half-size 1, margin 0.2: the region is the square of half-size 0.8. At
        // (0.9, 0.85), inside the band near the corner, the way out of the region is from its
        // corner (0.8, 0.8), not across the nearest edge of the square alone.
        let v = square().violation(DVec3::new(0.9, 1.0, 0.85), 0.2).unwrap();
        assert!((v - DVec3::new(0.1, 0.0, 0.05)).length() < 1e-12, "{v}");
    }

    #[test]
    fn the_residual_turns_without_jumping_across_the_corner_of_the_band() {
        // Along a line across the diagonal in the margin's band, the residual is the way out
        // of a convex region: it moves no faster than the point (measured from the edges, it
        // jumped by ~0.14 from one edge's normal to the other where they are equally near).
        let region = square().allowed(0.2);
        let step = 1e-3;
        let at = |k: i32| {
            let t = f64::from(k) * step;
            let p = DVec3::new(0.95 - t, 0.0, 0.85 + t);
            region.violation(p).unwrap()
        };
        for k in 0..100 {
            let jump = (at(k + 1) - at(k)).length();
            assert!(
                jump <= step * std::f64::consts::SQRT_2 + 1e-12,
                "{k}: {jump}"
            );
        }
    }

    #[test]
    fn a_polygon_narrower_than_its_margin_allows_its_deepest_part() {
        // 2 long and 0.2 wide, margin 0.3: the deepest part is the middle line.
        let strip = SupportPolygon::new(
            &[
                DVec3::new(-1.0, 0.0, -0.1),
                DVec3::new(1.0, 0.0, -0.1),
                DVec3::new(1.0, 0.0, 0.1),
                DVec3::new(-1.0, 0.0, 0.1),
            ],
            DVec3::NEG_Y,
        );
        let region = strip.allowed(0.3);
        let v = region.violation(DVec3::new(0.2, 0.0, 0.05)).unwrap();
        assert!((v - DVec3::new(0.0, 0.0, 0.05)).length() < 1e-6, "{v}");
        assert_eq!(region.violation(DVec3::new(0.5, 0.0, 0.0)), None);
    }

    #[test]
    fn a_lean_grows_the_region_round_its_corners() {
        let region = square().allowed(-0.2);
        assert_eq!(region.violation(DVec3::new(1.15, 0.0, 0.0)), None);
        let v = region.violation(DVec3::new(1.5, 0.0, 0.0)).unwrap();
        assert!((v - DVec3::new(0.3, 0.0, 0.0)).length() < 1e-12, "{v}");
        // Past the corner: from the rounded corner, along the diagonal.
        let v = region.violation(DVec3::new(2.0, 0.0, 2.0)).unwrap();
        let expected = DVec3::new(1.0, 0.0, 1.0) * (1.0 - 0.2 / 2f64.sqrt());
        assert!((v - expected).length() < 1e-12, "{v}");
    }

    #[test]
    fn past_a_corner_the_residual_changes_along_two_directions_across_an_edge_one() {
        let region = square().allowed(-0.2);
        assert!(region.directions(DVec3::ZERO).is_empty());
        let edge = region.directions(DVec3::new(1.5, 0.0, 0.3));
        assert_eq!(edge.len(), 1);
        assert!((edge[0].0 - DVec3::X).length() < 1e-12);
        let corner = region.directions(DVec3::new(2.0, 0.0, 2.0));
        assert_eq!(corner.len(), 2);
        assert!((corner[0].1 - 1.0).abs() < 1e-12);
        // Across the rounded corner the residual turns by (1 − grow / distance) of the way.
        let share = (1.0 - 0.2 / 2f64.sqrt()).powi(2);
        assert!((corner[1].1 - share).abs() < 1e-12, "{}", corner[1].1);
        assert!(corner[0].0.dot(corner[1].0).abs() < 1e-12);
    }

    #[test]
    fn inside_the_region_the_way_out_is_across_its_nearest_edge() {
        let (out, slack) = square()
            .allowed(0.2)
            .way_out(DVec3::new(0.5, 3.0, 0.1))
            .unwrap();
        assert!((out - DVec3::X).length() < 1e-12, "{out}");
        assert!((slack - 0.3).abs() < 1e-12, "{slack}");
        // Leaning: outside the polygon, still inside what the lean allows.
        let (out, slack) = square()
            .allowed(-0.2)
            .way_out(DVec3::new(1.1, 0.0, 0.0))
            .unwrap();
        assert!((out - DVec3::X).length() < 1e-12, "{out}");
        assert!((slack - 0.1).abs() < 1e-12, "{slack}");
        assert_eq!(
            square().allowed(0.2).way_out(DVec3::new(0.9, 0.0, 0.0)),
            None
        );
    }
}
