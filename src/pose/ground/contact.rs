//! Contacts with the ground, solved with everything else in the pose solve.
//!
//! A [`Contact`] is a patch of skin (welded vertices: a sole, a palm, a knee) carried by a
//! joint, and the ground under it: a [`GroundPlane`] (a ray-cast hit, or a plane fitted to
//! several, [`GroundPlane::fit`]).
//!
//! * **Free** (`planted: None`): the patch may not go below the ground. Each of its vertices is
//!   an inequality `n · (x − p) ≥ 0`, a one-sided term (zero above the ground, the squared
//!   depth times a stiff weight below it) in the same damped Gauss–Newton steps as the
//!   effectors and the projected joint limits — not a clamp after the solve, which would break
//!   them.
//! * **Planted** ([`Contact::plant`]): the patch is locked where it touched — each vertex held
//!   at its point on the ground, so it neither sinks nor slides — and the joint's bind-pose
//!   `up` axis turns to the ground's normal as far as the joint's limits allow (the limits are
//!   hard: on a slope steeper than the ankle turns, the sole meets the ground with its edge).
//!   The game releases a contact ([`Contact::release`]) when the pose lifts it past a release
//!   height ([`Contact::lifted`]) or when it wants.
//! * A [`crate::pose::ground::floor::Floor`] keeps *every* skin vertex near the ground above it: the vertices near
//!   the ground in the pose a solve starts from become one-sided terms of that solve (an
//!   active set renewed every solve: a character dragged down into the floor does not sink).

use crate::pose::ground::{Ground, GroundPlane};
use crate::pose::rig::skeleton::rotation_of;
use glam::{DQuat, DVec3};

/// A patch of skin and the ground under it (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// The joint that carries the patch (a foot's ankle): its `up` turns to a planted
    /// contact's ground.
    pub joint: usize,
    /// Welded vertices of the patch (e.g. the lowest vertices the foot's joint carries).
    pub patch: Vec<u32>,
    /// The ground under the patch.
    pub ground: GroundPlane,
    /// While planted: where each patch vertex is held (world space, on the ground).
    pub planted: Option<Vec<DVec3>>,
    /// The joint's axis, in its bind-pose frame, that a planted contact turns to the
    /// ground's normal (a foot's up; `None`: no turn).
    pub up: Option<DVec3>,
    /// How far above the ground the planted points still are (world units): a patch planted
    /// above the ground (a foot over a lower step) is held where it touched down and lowered
    /// onto the ground by [`Contact::descend`], so the body is not yanked down in one solve
    /// (the other planted patches would slide under the pull).
    pub landing: f64,
    /// While a planted patch is still turning onto its ground ([`Contact::plant_rolling`]):
    /// about which held point, and the turn left.
    pub rolling: Option<Rolling>,
}

/// A planted patch still turning onto its ground: it touched down tilted (a paw toe first)
/// and rolls flat about the point that touched, a bounded turn per update
/// ([`Contact::roll`]), its joint's turn to the normal left to the holds meanwhile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rolling {
    /// The held point it turns about (an index into the patch): the lowest when it touched.
    pub pivot: usize,
    /// The turn still to make, about the pivot.
    pub left: DQuat,
}

impl Contact {
    /// A free contact of `patch` (carried by `joint`) over `ground`, turning the joint's
    /// bind-pose `+Y` to the ground when planted.
    pub fn new(joint: usize, patch: Vec<u32>, ground: GroundPlane) -> Self {
        Self {
            joint,
            patch,
            ground,
            planted: None,
            up: Some(DVec3::Y),
            landing: 0.0,
            rolling: None,
        }
    }

    /// Plants the contact where the patch is now (`positions`: the patch's vertices, world
    /// space, in patch order). The patch is laid on the ground as a rigid piece: turned about
    /// its lowest vertex so that `current_up` (the joint's `up` axis as the pose carries it now;
    /// `None`: no turn) meets the ground's normal, then moved along the normal until its
    /// lowest vertex touches. Each vertex is held there: the sole lies on the ground where it
    /// touched, curved or flat, and does not slide.
    pub fn plant(&mut self, positions: &[DVec3], current_up: Option<DVec3>) {
        self.lay(positions, current_up, false, f64::INFINITY);
    }

    /// Plants the contact as [`Contact::plant`] does, but a patch that is above the ground is
    /// held at its height for now ([`Contact::landing`]; lower it with [`Contact::descend`]):
    /// a foot coming down on a lower step while the others stand.
    pub fn plant_landing(&mut self, positions: &[DVec3], current_up: Option<DVec3>) {
        self.lay(positions, current_up, true, f64::INFINITY);
    }

    /// Plants the contact as [`Contact::plant_landing`] does, but turned onto the ground by
    /// at most `max_turn` (radians) now: the rest of the turn is [`Contact::rolling`], made by
    /// [`Contact::roll`] update after update, about the point that touched. A paw the walk
    /// puts down toe first (tilted 14° at the median, 53° at the 90th percentile in the
    /// crowd) was laid flat at once, its held points up to 7 % of its size from where it was,
    /// and the solve snapped it there in a frame.
    pub fn plant_rolling(&mut self, positions: &[DVec3], current_up: Option<DVec3>, max_turn: f64) {
        self.lay(positions, current_up, true, max_turn.max(0.0));
    }

    /// Turns a rolling patch ([`Contact::rolling`]) by at most `max_turn` (radians) about its
    /// pivot; returns whether it turned.
    pub fn roll(&mut self, max_turn: f64) -> bool {
        let (Some(rolling), Some(planted)) = (self.rolling, &mut self.planted) else {
            self.rolling = None;
            return false;
        };
        // (A turn or pivot that is not usable ends the roll where it is.)
        let Some(&pivot) = planted
            .get(rolling.pivot)
            .filter(|_| rolling.left.is_finite())
        else {
            self.rolling = None;
            return false;
        };
        let (now, left) = split_turn(rolling.left, max_turn.max(0.0));
        for p in planted.iter_mut() {
            *p = pivot + now * (*p - pivot);
        }
        self.rolling = left.map(|left| Rolling { left, ..rolling });
        true
    }

    fn lay(
        &mut self,
        positions: &[DVec3],
        current_up: Option<DVec3>,
        landing: bool,
        max_turn: f64,
    ) {
        let full = current_up
            .and_then(|u| u.try_normalize())
            .map_or(DQuat::IDENTITY, |u| {
                DQuat::from_rotation_arc(u, self.ground.normal)
            });
        let Some((pivot_index, &pivot)) = positions.iter().enumerate().min_by(|a, b| {
            self.ground
                .height(*a.1)
                .total_cmp(&self.ground.height(*b.1))
        }) else {
            self.planted = Some(Vec::new());
            self.rolling = None;
            return;
        };
        let (turn, left) = split_turn(full, max_turn);
        self.rolling = left.map(|left| Rolling {
            pivot: pivot_index,
            left,
        });
        let laid: Vec<DVec3> = positions
            .iter()
            .map(|p| pivot + turn * (*p - pivot))
            .collect();
        let lowest = laid
            .iter()
            .map(|p| self.ground.height(*p))
            .fold(f64::INFINITY, f64::min);
        self.landing = if landing {
            positions
                .iter()
                .map(|p| self.ground.height(*p))
                .fold(f64::INFINITY, f64::min)
                .max(0.0)
        } else {
            0.0
        };
        let lift = self.ground.normal * (self.landing - lowest);
        self.planted = Some(laid.into_iter().map(|p| p + lift).collect());
    }

    /// Lowers a planted patch that is still landing by at most `step` (world units) towards
    /// the ground; returns the height left.
    pub fn descend(&mut self, step: f64) -> f64 {
        let drop = self.landing.min(step.max(0.0));
        if let Some(planted) = &mut self.planted
            && drop > 0.0
        {
            for p in planted.iter_mut() {
                *p -= self.ground.normal * drop;
            }
            self.landing -= drop;
        }
        self.landing
    }

    /// Raises a planted patch that lies partly under `ground` out of it, along gravity
    /// (`down`, unit), as one piece: every planted point by the depth of the deepest (casts
    /// from `reach` above each point, `2 × reach` long). Returns that depth (0: nothing under).
    ///
    /// [`Contact::plant`] lays the patch on one plane, the ground under its centre; where the
    /// ground under the patch is not that plane (a paw half on a terrace and half on the slope
    /// rising from it), part of the patch was held inside the ground, the floor pushed those
    /// vertices out and the hold pulled them back in: a walking crowd's planted paws stood
    /// 1–1.6 % of their size in the terrain. Raised as one piece the patch keeps the shape its
    /// joint carries (raising only the points under the ground bent it, and the sole, which
    /// cannot bend, went under between them); it rests on its highest ground. Misses and
    /// non-finite hits change nothing.
    pub fn raise_onto(&mut self, ground: &dyn Ground, down: DVec3, reach: f64) -> f64 {
        let Some(planted) = &mut self.planted else {
            return 0.0;
        };
        let depth = planted
            .iter()
            .filter_map(|p| {
                let hit = ground.cast_down(*p - down * reach, down, 2.0 * reach)?;
                let depth = (hit.point - *p).dot(-down);
                depth.is_finite().then_some(depth)
            })
            .fold(0.0f64, f64::max);
        if depth > 0.0 {
            for p in planted.iter_mut() {
                *p -= down * depth;
            }
        }
        depth
    }

    /// Carries the contact by a similarity (`moved`: a rotation, a uniform scale and a
    /// translation; e.g. into a character's space after it moved): its ground, its planted
    /// points and the turn a rolling patch has left. A ground the map does not keep usable
    /// (a singular `moved`) stays as it was.
    pub fn move_by(&mut self, moved: &glam::DAffine3) {
        if let Some(g) = GroundPlane::new(
            moved.transform_point3(self.ground.point),
            moved.matrix3 * self.ground.normal,
        ) {
            self.ground = g;
        }
        for p in self.planted.iter_mut().flatten() {
            *p = moved.transform_point3(*p);
        }
        if let Some(r) = &mut self.rolling {
            let turn = rotation_of(&moved.matrix3);
            r.left = (turn * r.left * turn.inverse()).normalize();
        }
    }

    /// Releases a planted contact (it may then only not go below the ground).
    pub fn release(&mut self) {
        self.planted = None;
        self.landing = 0.0;
        self.rolling = None;
    }

    /// Whether the patch (`positions`, as for [`Contact::plant`]) is entirely more than
    /// `height` above the ground: the pose lifted it, release it.
    pub fn lifted(&self, positions: &[DVec3], height: f64) -> bool {
        !positions.is_empty() && positions.iter().all(|p| self.ground.height(*p) > height)
    }

    /// Whether the numbers can be used (indices are checked by the solver).
    pub(crate) fn is_valid(&self) -> bool {
        self.ground.point.is_finite()
            && self.landing.is_finite()
            && self.rolling.is_none_or(|r| r.left.is_finite())
            && self.ground.normal.is_finite()
            && (self.ground.normal.length() - 1.0).abs() < 1e-6
            && self
                .planted
                .as_ref()
                .is_none_or(|p| p.len() == self.patch.len() && p.iter().all(|x| x.is_finite()))
            && self
                .up
                .is_none_or(|u| u.is_finite() && u.length_squared() > 1e-18)
    }
}

/// `turn` split into at most `max` radians now and the rest (`None`: nothing left), about
/// the same axis.
fn split_turn(turn: DQuat, max: f64) -> (DQuat, Option<DQuat>) {
    let angle = DQuat::IDENTITY.angle_between(turn);
    if angle.is_nan() || angle <= max {
        return (turn, None);
    }
    let now = DQuat::IDENTITY.slerp(turn, max / angle);
    (now, Some(now.inverse() * turn))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_fitted_to_hits_on_a_slope_has_the_slope_normal_facing_up() {
        let normal = DVec3::new(0.5, 1.0, 0.0).normalize();
        let plane = GroundPlane::new(DVec3::ZERO, normal).unwrap();
        let hits: Vec<DVec3> = (0..9)
            .map(|k| {
                let p = DVec3::new((k % 3) as f64, 3.0, (k / 3) as f64 * 0.7);
                plane.project(p)
            })
            .collect();
        let fitted = GroundPlane::fit(&hits, DVec3::Y).unwrap();
        assert!(fitted.normal.distance(normal) < 1e-9, "{}", fitted.normal);
        assert!(fitted.height(DVec3::ZERO).abs() < 1e-9);
        // On a line: no plane.
        let line: Vec<DVec3> = (0..4).map(|k| DVec3::X * k as f64).collect();
        assert_eq!(GroundPlane::fit(&line, DVec3::Y), None);
        assert_eq!(GroundPlane::new(DVec3::ZERO, DVec3::ZERO), None);
        assert_eq!(GroundPlane::new(DVec3::NAN, DVec3::Y), None);
    }

    #[test]
    fn planting_puts_the_patch_on_the_ground_and_lifting_is_measured_from_it() {
        let ground = GroundPlane::new(DVec3::new(0.0, 1.0, 0.0), DVec3::Y).unwrap();
        let mut c = Contact::new(0, vec![0, 1], ground);
        // Laid as it is: its lowest vertex moved onto the ground, the rest with it.
        c.plant(
            &[DVec3::new(0.0, 1.2, 0.0), DVec3::new(1.0, 0.9, 0.0)],
            None,
        );
        let planted = c.planted.clone().unwrap();
        assert!(planted[0].distance(DVec3::new(0.0, 1.3, 0.0)) < 1e-12);
        assert!(planted[1].distance(DVec3::new(1.0, 1.0, 0.0)) < 1e-12);
        assert_eq!(c.landing, 0.0);
        // Planted 0.25 above the ground: held there, then lowered 0.1 at a time onto it.
        c.plant_landing(
            &[DVec3::new(0.0, 1.25, 0.0), DVec3::new(1.0, 1.25, 0.0)],
            None,
        );
        assert!((c.landing - 0.25).abs() < 1e-12);
        assert!((c.planted.as_ref().unwrap()[1].y - 1.25).abs() < 1e-12);
        assert!((c.descend(0.1) - 0.15).abs() < 1e-12);
        assert!((c.planted.as_ref().unwrap()[1].y - 1.15).abs() < 1e-12);
        c.descend(0.1);
        assert_eq!(c.descend(0.1), 0.0);
        assert!((c.planted.as_ref().unwrap()[0].y - 1.0).abs() < 1e-12);
        // Turned flat: a patch tilted by 30° about z comes down level, touching at its lowest.
        let tilt = glam::DQuat::from_rotation_z(0.5);
        let patch = [DVec3::new(-0.1, 1.5, 0.0), DVec3::new(0.1, 1.5, 0.0)].map(|p| tilt * p);
        c.plant(&patch, Some(tilt * DVec3::Y));
        let planted = c.planted.clone().unwrap();
        for p in &planted {
            assert!((p.y - 1.0).abs() < 1e-12, "{p}");
        }
        assert!((planted[0].distance(planted[1]) - 0.2).abs() < 1e-12);
        assert!(!c.lifted(&[DVec3::new(0.0, 1.05, 0.0)], 0.1));
        assert!(c.lifted(&[DVec3::new(0.0, 1.2, 0.0)], 0.1));
    }

    /// A patch put down tilted 50° turns onto the ground 20° at a time about the point that
    /// touched: 20° at planting, 20° and the last 10° in two rolls, then none; its shape kept,
    /// its pivot where it touched, level at the end; carried by a turn, the turn left is too.
    #[test]
    fn a_patch_planted_tilted_rolls_flat_about_the_point_that_touched() {
        let ground = GroundPlane::new(DVec3::ZERO, DVec3::Y).unwrap();
        let tilt = DQuat::from_rotation_z(50f64.to_radians());
        let patch = [DVec3::new(-0.1, 0.0, 0.0), DVec3::new(0.1, 0.0, 0.0)]
            .map(|p| tilt * p + DVec3::new(0.0, 0.2, 0.0));
        let up = tilt * DVec3::Y;
        let max = 20f64.to_radians();
        let level = |c: &Contact| {
            let p = c.planted.as_ref().unwrap();
            let along = (p[1] - p[0]).normalize();
            along.angle_between(DVec3::X).to_degrees()
        };
        let mut c = Contact::new(0, vec![0, 1], ground);
        c.plant_rolling(&patch, Some(up), max);
        let pivot = c.planted.as_ref().unwrap()[0];
        assert!(
            (level(&c) - 30.0).abs() < 1e-9,
            "turned 20° of 50: {}",
            level(&c)
        );
        assert_eq!(c.rolling.map(|r| r.pivot), Some(0), "about the lower end");
        // Carried by a quarter turn about the vertical and moved: the turn left is carried too.
        let mut carried = c.clone();
        let moved = glam::DAffine3::from_rotation_translation(
            DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2),
            DVec3::new(3.0, 0.0, 1.0),
        );
        carried.move_by(&moved);
        while carried.roll(max) {}
        let held = carried.planted.as_ref().unwrap();
        assert!(
            (held[1] - held[0]).y.abs() < 1e-9,
            "carried, it still rolls level"
        );
        assert!(c.roll(max));
        assert!((level(&c) - 10.0).abs() < 1e-9, "{}", level(&c));
        assert!(c.roll(max));
        assert!(level(&c) < 1e-9 && c.rolling.is_none(), "{}", level(&c));
        assert!(!c.roll(max), "nothing left to turn");
        let held = c.planted.as_ref().unwrap();
        assert!(held[0].distance(pivot) < 1e-12, "the pivot stays");
        assert!(
            (held[0].distance(held[1]) - 0.2).abs() < 1e-12,
            "the shape is kept"
        );
        // Without a limit it is laid flat at once, as `plant_landing` lays it.
        let mut flat = Contact::new(0, vec![0, 1], ground);
        flat.plant_rolling(&patch, Some(up), f64::INFINITY);
        assert!(flat.rolling.is_none() && level(&flat) < 1e-9);
        // A turn left that is not a number ends the roll, the held points untouched.
        let mut broken = Contact::new(0, vec![0, 1], ground);
        broken.plant_rolling(&patch, Some(up), max);
        let before = broken.planted.clone();
        broken.rolling.as_mut().unwrap().left = DQuat::from_xyzw(f64::NAN, 0.0, 0.0, 1.0);
        assert!(!broken.is_valid(), "a NaN turn is not a usable contact");
        assert!(!broken.roll(max));
        assert_eq!(broken.planted, before);
        assert!(broken.rolling.is_none() && broken.is_valid());
    }
}
