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
//! ([`super::PoseSolution::balance_boost`]), so over a few frames the margin is met without a
//! still stiffer term (which three iterations a frame would not converge).
//!
//! **Walking.** A walk balances itself dynamically: a trot stands on two paws between its
//! steps, the centre of mass beside the line between them. Held statically over those two
//! paws, the body would fight its clip (and the paws slide). [`Balance::lean`] lets the centre
//! of mass out of the polygon by as much as the clip carries it out (the character plugin sets
//! it from the clip under an additive layer): balance then keeps what the clip does on flat
//! ground, and corrects what the terrain and the pose add.

use glam::{DVec2, DVec3};

use super::model::SkinnedModel;
use super::skeleton::SkeletonPose;

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

/// Mass per welded vertex of `model`: a third of the bind-pose area of each triangle around it.
pub fn vertex_masses(model: &SkinnedModel) -> Vec<f64> {
    let bind = model.bind_positions();
    let mut mass = vec![0.0; bind.len()];
    for t in model.topology().triangles() {
        let [a, b, c] = t.map(|v| bind[v as usize]);
        let third = (b - a).cross(c - a).length() / 6.0;
        if third.is_finite() {
            for v in t {
                mass[*v as usize] += third;
            }
        }
    }
    mass
}

/// The centre of mass of `model` skinned by `pose` (`masses` per welded vertex, or the
/// model's [`SkinnedModel::area_masses`]). `None` when the masses sum to zero.
pub fn centre_of_mass(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    masses: Option<&[f64]>,
) -> Option<DVec3> {
    let masses = masses.unwrap_or_else(|| model.area_masses());
    let skinned = model.skin_welded(pose);
    let total: f64 = masses.iter().sum();
    (total > 0.0).then(|| {
        skinned
            .iter()
            .zip(masses)
            .map(|(p, m)| *p * *m)
            .sum::<DVec3>()
            / total
    })
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
    /// space; `None` while `point` is in that region.
    pub fn violation(&self, point: DVec3, margin: f64) -> Option<DVec3> {
        let p = self.flatten(point);
        let (nearest, inside) = self.nearest(p);
        let margin = if self.corners.len() >= 3 { margin } else { 0.0 };
        let d = p.distance(nearest);
        let signed = if inside { d } else { -d };
        if signed >= margin {
            return None;
        }
        // Outward direction across the nearest boundary feature.
        let outward = match (inside, (p - nearest).try_normalize()) {
            (false, Some(n)) => n,
            (true, Some(n)) => -n,
            (_, None) => self.edge_normal_near(p)?,
        };
        let v = outward * (margin - signed);
        Some(self.axes.0 * v.x + self.axes.1 * v.y)
    }

    /// `point` in the plane across gravity.
    fn flatten(&self, point: DVec3) -> DVec2 {
        DVec2::new(point.dot(self.axes.0), point.dot(self.axes.1))
    }

    /// The nearest point of the polygon's boundary (or of the point / segment) to `p`, and
    /// whether `p` is inside a polygon.
    fn nearest(&self, p: DVec2) -> (DVec2, bool) {
        let c = &self.corners;
        match c.len() {
            0 => (p, false),
            1 => (c[0], false),
            2 => (closest_on_segment(p, c[0], c[1]), false),
            n => {
                let mut best = (c[0], f64::INFINITY);
                let mut inside = true;
                for k in 0..n {
                    let (a, b) = (c[k], c[(k + 1) % n]);
                    if (b - a).perp_dot(p - a) < 0.0 {
                        inside = false;
                    }
                    let q = closest_on_segment(p, a, b);
                    let d = q.distance_squared(p);
                    if d < best.1 {
                        best = (q, d);
                    }
                }
                (best.0, inside)
            }
        }
    }

    /// The outward normal of the polygon edge nearest `p` (for a point exactly on the
    /// boundary); `None` for a point or segment.
    fn edge_normal_near(&self, p: DVec2) -> Option<DVec2> {
        let c = &self.corners;
        if c.len() < 3 {
            return None;
        }
        (0..c.len())
            .map(|k| (c[k], c[(k + 1) % c.len()]))
            .min_by(|x, y| {
                let dx = closest_on_segment(p, x.0, x.1).distance_squared(p);
                let dy = closest_on_segment(p, y.0, y.1).distance_squared(p);
                dx.total_cmp(&dy)
            })
            .and_then(|(a, b)| {
                let e = b - a;
                DVec2::new(e.y, -e.x).try_normalize()
            })
    }
}

/// The point of segment `a`–`b` nearest `p`.
fn closest_on_segment(p: DVec2, a: DVec2, b: DVec2) -> DVec2 {
    let e = b - a;
    let len = e.length_squared();
    if len == 0.0 {
        return a;
    }
    a + e * ((p - a).dot(e) / len).clamp(0.0, 1.0)
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
}
