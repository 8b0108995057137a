//! Surfaces a bend may not pass through (the game's ground under a [`Deformable`] mesh).
//!
//! A solve given an [`Obstacle`] ([`ArapSolver::solve_above`](crate::deform::ArapSolver::solve_above))
//! keeps every free vertex on or above it: after each global step the free positions are
//! projected, in the norm of the factored system, onto the half-spaces of the vertices that
//! went below (an active set of one linear inequality per vertex, along the surface's normal,
//! so a vertex that meets the surface slides along it). Handles and targets are lifted onto
//! the surface before the solve ([`Constraints::lifted_above`](crate::deform::Constraints::lifted_above)):
//! a hand that drags a handle into the floor drags it along the floor.
//!
//! [`Deformable`]: crate::ecs::Deformable

use glam::DVec3;

use crate::deform::constraints::Constraints;

/// Where a vertex meets a surface: a point on it and its unit outward normal (the side the
/// vertex must stay on).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSample {
    /// A point of the surface (under or over the queried point).
    pub point: DVec3,
    /// Unit normal pointing to the allowed side.
    pub normal: DVec3,
}

impl SurfaceSample {
    /// Signed distance of `p` above the sample's tangent plane (negative: below).
    pub fn gap(&self, p: DVec3) -> f64 {
        self.normal.dot(p - self.point)
    }
}

/// A surface the free vertices of a solve stay above, in the mesh's own coordinates.
pub trait Obstacle: Send + Sync {
    /// The surface at `p`'s place across [`Obstacle::up`] (above or below `p`), or `None`
    /// where there is none (the vertex is free there). Non-finite answers are ignored.
    fn surface_at(&self, p: DVec3) -> Option<SurfaceSample>;

    /// The direction handles are lifted along when they are dragged below the surface
    /// (unit, against gravity).
    fn up(&self) -> DVec3;
}

/// An infinite plane: everything below it is solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneObstacle {
    /// A point of the plane.
    pub point: DVec3,
    /// Unit normal, pointing out of the solid.
    pub normal: DVec3,
}

impl PlaneObstacle {
    /// The plane through `point` with normal `normal` (normalised); `None` when the normal is
    /// zero or anything is not finite.
    pub fn new(point: DVec3, normal: DVec3) -> Option<Self> {
        let normal = normal.try_normalize()?;
        point.is_finite().then_some(Self { point, normal })
    }
}

impl Obstacle for PlaneObstacle {
    fn surface_at(&self, _: DVec3) -> Option<SurfaceSample> {
        Some(SurfaceSample {
            point: self.point,
            normal: self.normal,
        })
    }

    fn up(&self) -> DVec3 {
        self.normal
    }
}

/// A height field over a rectangle across `up`: the ground sampled on a grid (e.g. by ray
/// casts into a scene once, then queried for every vertex of every iteration at the cost of
/// a bilinear lookup). Cells with an unknown corner are no ground. Between samples the
/// surface is bilinear, so a vertical step is a slope one cell wide.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightField {
    origin: DVec3,
    axes: [DVec3; 2],
    up: DVec3,
    cell: f64,
    size: [usize; 2],
    heights: Vec<f64>,
}

/// A height field that cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum HeightFieldError {
    /// `up` is zero or not finite.
    #[error("the height field's up direction is zero or not finite")]
    InvalidUp,
    /// The cell size is not positive and finite, or the grid is under 2×2 samples.
    #[error("the height field needs a positive cell size and at least 2×2 samples")]
    InvalidGrid,
}

impl HeightField {
    /// Samples `height(p)` (the surface's coordinate along `up`, `up · surface point`, across
    /// the point `p` of the base plane, or `None`) on `size[0] × size[1]` points spaced `cell`
    /// apart from `origin`, along `along` (made square to `up`) and along `along × up`.
    /// Non-finite heights count as `None`.
    pub fn sample(
        origin: DVec3,
        up: DVec3,
        along: DVec3,
        cell: f64,
        size: [usize; 2],
        mut height: impl FnMut(DVec3) -> Option<f64>,
    ) -> Result<Self, HeightFieldError> {
        let up = up.try_normalize().ok_or(HeightFieldError::InvalidUp)?;
        if !(cell > 0.0 && cell.is_finite()) || size[0] < 2 || size[1] < 2 || !origin.is_finite() {
            return Err(HeightFieldError::InvalidGrid);
        }
        let u = (along - up * up.dot(along))
            .try_normalize()
            .unwrap_or_else(|| up.any_orthonormal_vector());
        let axes = [u, u.cross(up)];
        let mut heights = Vec::with_capacity(size[0] * size[1]);
        for j in 0..size[1] {
            for i in 0..size[0] {
                let p = origin + axes[0] * (i as f64 * cell) + axes[1] * (j as f64 * cell);
                heights.push(height(p).filter(|h| h.is_finite()).unwrap_or(f64::NAN));
            }
        }
        Ok(Self {
            origin,
            axes,
            up,
            cell,
            size,
            heights,
        })
    }

    /// The two axes of the base plane (unit, across `up`).
    pub fn axes(&self) -> [DVec3; 2] {
        self.axes
    }

    /// Samples that found ground.
    pub fn known_samples(&self) -> usize {
        self.heights.iter().filter(|h| !h.is_nan()).count()
    }

    /// Whether `p` lies over the sampled rectangle (across `up`).
    pub fn covers(&self, p: DVec3) -> bool {
        let d = p - self.origin;
        let extent = |k: usize| (self.size[k] - 1) as f64 * self.cell;
        (0..2).all(|k| (0.0..=extent(k)).contains(&d.dot(self.axes[k])))
    }
}

impl Obstacle for HeightField {
    fn surface_at(&self, p: DVec3) -> Option<SurfaceSample> {
        let d = p - self.origin;
        let (s, t) = (
            d.dot(self.axes[0]) / self.cell,
            d.dot(self.axes[1]) / self.cell,
        );
        if !(s.is_finite() && t.is_finite()) {
            return None;
        }
        let (i, j) = (s.floor(), t.floor());
        if i < 0.0 || j < 0.0 {
            return None;
        }
        let (i, j) = (i as usize, j as usize);
        if i + 1 >= self.size[0] || j + 1 >= self.size[1] {
            return None;
        }
        let at = |a: usize, b: usize| self.heights[b * self.size[0] + a];
        let [h00, h10, h01, h11] = [at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)];
        if [h00, h10, h01, h11].iter().any(|h| h.is_nan()) {
            return None;
        }
        let (fs, ft) = (s - i as f64, t - j as f64);
        let h = h00 * (1.0 - fs) * (1.0 - ft)
            + h10 * fs * (1.0 - ft)
            + h01 * (1.0 - fs) * ft
            + h11 * fs * ft;
        // Slopes along the two axes (per unit length) give the normal.
        let dh_ds = ((h10 - h00) * (1.0 - ft) + (h11 - h01) * ft) / self.cell;
        let dh_dt = ((h01 - h00) * (1.0 - fs) + (h11 - h10) * fs) / self.cell;
        let normal = (self.up - self.axes[0] * dh_ds - self.axes[1] * dh_dt).try_normalize()?;
        Some(SurfaceSample {
            point: p + self.up * (h - self.up.dot(p)),
            normal,
        })
    }

    fn up(&self) -> DVec3 {
        self.up
    }
}

/// How far `p` must rise along `up` to be on or above the obstacle (0 when it is; a second
/// look after the first lift, for surfaces that are not planes).
fn lift_onto(obstacle: &dyn Obstacle, up: DVec3, p: DVec3) -> f64 {
    let mut lift = 0.0;
    for _ in 0..2 {
        let q = p + up * lift;
        let Some(s) = obstacle.surface_at(q) else {
            break;
        };
        let rise = s.normal.dot(up);
        let gap = s.gap(q);
        if !(gap.is_finite() && rise > 1e-6) || gap >= 0.0 {
            break;
        }
        lift -= gap / rise;
    }
    lift
}

impl Constraints {
    /// These constraints with their handles and targets out of `obstacle`: each handle rises
    /// along [`Obstacle::up`] until none of its vertices (`rest`: welded rest positions, as the
    /// solver's) is below the surface, each target below it rises onto it. A drag into the
    /// floor becomes a drag along it. Fixed vertices stay where they are.
    pub fn lifted_above(&self, rest: &[DVec3], obstacle: &dyn Obstacle) -> Constraints {
        let up = obstacle.up().try_normalize().unwrap_or(DVec3::Y);
        let mut lifted = self.clone();
        for handle in &mut lifted.handles {
            let lift = handle
                .vertices
                .iter()
                .filter_map(|&v| rest.get(v as usize))
                .map(|&p| lift_onto(obstacle, up, handle.transform.apply(p)))
                .fold(0.0, f64::max);
            handle.transform.translation += up * lift;
        }
        for (_, target) in &mut lifted.targets {
            *target += up * lift_onto(obstacle, up, *target);
        }
        lifted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_height_field_of_a_slope_gives_its_height_and_normal() {
        let up = DVec3::Y;
        let slope = 0.5_f64; // rises 0.5 per unit along the first axis
        let a0 = DVec3::new(1.0, 0.0, 1.0).normalize();
        let origin = DVec3::new(0.0, 0.0, -5.0);
        let field =
            HeightField::sample(origin, up, a0, 0.25, [41, 41], |p| Some(slope * p.dot(a0)))
                .unwrap();
        assert!(field.axes()[0].distance(a0) < 1e-12);
        let p = DVec3::new(0.3, 7.0, -0.8);
        let s = field.surface_at(p).unwrap();
        assert!((s.point.y - slope * p.dot(a0)).abs() < 1e-12, "{s:?}");
        let expected = (up - a0 * slope).normalize();
        assert!(s.normal.distance(expected) < 1e-12, "{s:?}");
        assert!(field.surface_at(DVec3::new(9.0, 0.0, 0.0)).is_none());
        assert_eq!(field.known_samples(), 41 * 41);
    }

    #[test]
    fn cells_without_ground_and_bad_grids_are_refused() {
        // The first sample (at the origin) found nothing: the cell at the origin is no ground.
        let field = HeightField::sample(DVec3::ZERO, DVec3::Z, DVec3::X, 1.0, [3, 3], |p| {
            (p.length() > 0.5).then_some(0.0)
        })
        .unwrap();
        let [a, b] = field.axes();
        assert!(field.surface_at(a * 0.5 + b * 0.5).is_none());
        assert!(field.surface_at(a * 1.5 + b * 1.5).is_some());
        assert_eq!(field.known_samples(), 8);
        assert_eq!(
            HeightField::sample(DVec3::ZERO, DVec3::ZERO, DVec3::X, 1.0, [3, 3], |_| Some(
                0.0
            )),
            Err(HeightFieldError::InvalidUp)
        );
        assert_eq!(
            HeightField::sample(DVec3::ZERO, DVec3::Y, DVec3::X, 0.0, [3, 3], |_| Some(0.0)),
            Err(HeightFieldError::InvalidGrid)
        );
    }
}
