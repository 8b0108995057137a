//! The sensor bar as a heading reference: a 6-axis filter knows its tilt from gravity but has
//! nothing to hold its heading (rotation about the vertical), whose error grows with the
//! remaining vertical gyro bias. While the IR camera sees the bar, the bar's direction is a
//! fixed point of the room: [`BarHeading`] turns the filter's estimate about the world
//! vertical so that the bar stays where it was first seen (`docs/PROTOCOL.md` §17.6).
//!
//! The correction is a separate heading offset applied on top of the 6-axis estimate, as VQF
//! does with a magnetometer in its 9-axis mode: the gyro integration, the inclination and the
//! bias estimation underneath are untouched, so the tilt is exactly the 6-axis filter's and
//! losing the bar changes nothing at that instant — the offset simply stops moving.

use glam::{DQuat, DVec3};

/// Radians per degree.
const RAD: f64 = std::f64::consts::PI / 180.0;

/// A heading offset kept by sightings of the sensor bar. See the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct BarHeading {
    /// Time constant of the correction while the bar is in view, s (0.5). The bar's direction
    /// is measured to a few hundredths of a degree, so the only reason not to snap is that a
    /// heading error accumulated out of view should come back as a turn, not a jump.
    pub tau_s: f64,
    /// Fastest correction, deg/s (10): a large error (minutes out of view) is taken out at
    /// this rate.
    pub max_rate_dps: f64,
    /// Smallest horizontal share of the bar's world direction for its heading to count (0.3):
    /// a remote pointing almost straight up or down at the bar measures no heading.
    pub min_horizontal: f64,
    /// Rotation about the world vertical applied to the 6-axis estimate, rad.
    offset: f64,
    /// World heading of the bar (after the offset), latched at the first sighting, rad.
    reference: Option<f64>,
    /// Whether the last report saw the bar with a usable heading.
    in_view: bool,
}

impl Default for BarHeading {
    fn default() -> Self {
        Self {
            tau_s: 0.5,
            max_rate_dps: 10.0,
            min_horizontal: 0.3,
            offset: 0.0,
            reference: None,
            in_view: false,
        }
    }
}

impl BarHeading {
    /// `attitude` (world←body) with the heading offset applied.
    pub fn apply(&self, attitude: DQuat) -> DQuat {
        DQuat::from_rotation_z(self.offset) * attitude
    }

    /// Feeds one report: `attitude` is the 6-axis estimate (world←body, before the offset),
    /// `bar` the body-frame direction to the bar's centre (`None`: not in view), `dt` the time
    /// since the previous report (s; 0 after a dropout: no correction). The first usable
    /// sighting latches where the bar is; later ones pull the heading back to it.
    pub fn observe(&mut self, attitude: DQuat, bar: Option<DVec3>, dt: f64) {
        self.in_view = false;
        let Some(direction) = bar.filter(|b| b.is_finite() && b.length_squared() > 0.25) else {
            return;
        };
        let world = self.apply(attitude) * direction.normalize();
        if world.truncate().length() < self.min_horizontal || !world.is_finite() {
            return;
        }
        self.in_view = true;
        let heading = world.y.atan2(world.x);
        let Some(reference) = self.reference else {
            self.reference = Some(heading);
            return;
        };
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let error = (reference - heading)
            .sin()
            .atan2((reference - heading).cos());
        let gain = if self.tau_s > 0.0 {
            (dt / self.tau_s).min(1.0)
        } else {
            1.0
        };
        let limit = self.max_rate_dps.max(0.0) * RAD * dt;
        let step = (error * gain).clamp(-limit, limit);
        let offset = self.offset + step;
        self.offset = offset.sin().atan2(offset.cos());
    }

    /// Whether the last report saw the bar (with a usable heading).
    pub fn in_view(&self) -> bool {
        self.in_view
    }

    /// The heading offset applied to the 6-axis estimate, degrees.
    pub fn offset_deg(&self) -> f64 {
        self.offset / RAD
    }

    /// Forgets where the bar was (the next sighting latches it again) and keeps the offset:
    /// for a player who moved, or a bar moved to another screen.
    pub fn forget_bar(&mut self) {
        self.reference = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bar straight ahead of a remote pointing along −Y: body direction −Y.
    const AHEAD: DVec3 = DVec3::NEG_Y;

    #[test]
    fn a_heading_error_is_pulled_back_to_where_the_bar_was_first_seen() {
        let mut h = BarHeading::default();
        h.observe(DQuat::IDENTITY, Some(AHEAD), 0.01);
        // The 6-axis estimate drifts 3° in heading while the remote stays put.
        let drifted = DQuat::from_rotation_z(3.0 * RAD);
        for _ in 0..500 {
            h.observe(drifted, Some(AHEAD), 0.01);
        }
        let corrected = h.apply(drifted);
        assert!(
            corrected.angle_between(DQuat::IDENTITY) < 0.01 * RAD,
            "left {}°",
            corrected.angle_between(DQuat::IDENTITY) / RAD
        );
        assert!(h.in_view());
        // Out of view the offset holds: no jump, no further correction.
        let before = h.apply(drifted);
        h.observe(drifted, None, 0.01);
        assert!(!h.in_view());
        assert_eq!(h.apply(drifted), before);
    }

    #[test]
    fn corrections_are_rate_limited_and_ignore_vertical_sightings() {
        let mut h = BarHeading::default();
        h.observe(DQuat::IDENTITY, Some(AHEAD), 0.01);
        let drifted = DQuat::from_rotation_z(30.0 * RAD);
        h.observe(drifted, Some(AHEAD), 0.01);
        assert!(
            (h.offset_deg().abs() - 0.1).abs() < 1e-9,
            "{}",
            h.offset_deg()
        );
        // Pointing straight down at the bar: no heading to measure.
        let mut v = BarHeading::default();
        v.observe(DQuat::IDENTITY, Some(DVec3::Z), 0.01);
        v.observe(drifted, Some(DVec3::Z), 0.01);
        assert!(!v.in_view());
        assert_eq!(v.offset_deg(), 0.0);
        // NaN sightings are ignored.
        v.observe(drifted, Some(DVec3::NAN), 0.01);
        assert_eq!(v.offset_deg(), 0.0);
    }
}
