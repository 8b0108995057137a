//! Ground-truth motions that drive the emulator's sensors.

use glam::{DQuat, DVec3};

/// Standard gravity, m/s².
pub const GRAVITY: f64 = 9.80665;

/// A ground-truth motion: orientation (world←body, world Z up, body axes of `PROTOCOL.md`
/// §5.3) and sensor position over time. Angular velocity and acceleration are derived
/// numerically, so any smooth function works.
pub trait Motion: Send + Sync {
    /// Orientation at `t` seconds.
    fn orientation(&self, t: f64) -> DQuat;
    /// Sensor position in metres at `t` seconds.
    fn position(&self, _t: f64) -> DVec3 {
        DVec3::ZERO
    }
}

const H: f64 = 1e-4;

/// Body-frame angular velocity (rad/s, right-hand rule) at `t`.
pub fn body_rate(m: &dyn Motion, t: f64) -> DVec3 {
    let q0 = m.orientation(t - H);
    let q1 = m.orientation(t + H);
    let mut d = q0.inverse() * q1;
    if d.w < 0.0 {
        d = -d;
    }
    let (axis, angle) = d.to_axis_angle();
    if angle.abs() < 1e-15 {
        DVec3::ZERO
    } else {
        axis * (angle / (2.0 * H))
    }
}

/// Specific force in the body frame, in g (what an accelerometer reads: "up" at rest).
pub fn specific_force_g(m: &dyn Motion, t: f64) -> DVec3 {
    let h = 1e-3;
    let a = (m.position(t + h) - 2.0 * m.position(t) + m.position(t - h)) / (h * h);
    let up = a / GRAVITY + DVec3::Z;
    m.orientation(t).inverse() * up
}

/// Held still at one orientation.
#[derive(Debug, Clone, Copy)]
pub struct Still(pub DQuat);

impl Motion for Still {
    fn orientation(&self, _t: f64) -> DQuat {
        self.0
    }
}

/// Constant rotation rate about a body axis, starting at `start`.
#[derive(Debug, Clone, Copy)]
pub struct ConstantRate {
    /// Orientation at t = 0.
    pub start: DQuat,
    /// Body axis (unit).
    pub axis: DVec3,
    /// Rate in rad/s.
    pub rate: f64,
}

impl Motion for ConstantRate {
    fn orientation(&self, t: f64) -> DQuat {
        self.start * DQuat::from_axis_angle(self.axis, self.rate * t)
    }
}

/// A motion from a closure `t → (orientation, position)`.
pub struct FnMotion<F: Fn(f64) -> (DQuat, DVec3) + Send + Sync>(pub F);

impl<F: Fn(f64) -> (DQuat, DVec3) + Send + Sync> Motion for FnMotion<F> {
    fn orientation(&self, t: f64) -> DQuat {
        (self.0)(t).0
    }
    fn position(&self, t: f64) -> DVec3 {
        (self.0)(t).1
    }
}

/// Yaw (about world Z), elevation (nose up) and roll (about the pointing axis) in radians →
/// orientation. The pointing axis is body −Y.
pub fn from_yaw_elevation_roll(yaw: f64, elevation: f64, roll: f64) -> DQuat {
    // Nose (−Y) up = rotation about +X by −elevation (+X rate = nose down, §5.3);
    // positive roll lifts the left side (+X).
    DQuat::from_rotation_z(yaw) * DQuat::from_rotation_x(-elevation) * DQuat::from_rotation_y(-roll)
}

/// A scripted "play" motion for demos: gentle turns and tilts with a looping period.
pub struct DemoMotion;

impl Motion for DemoMotion {
    fn orientation(&self, t: f64) -> DQuat {
        let s = |f: f64, a: f64| a * (std::f64::consts::TAU * f * t).sin();
        from_yaw_elevation_roll(s(0.07, 0.9), s(0.11, 0.5), s(0.05, 0.6))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_rate_is_recovered_in_body_frame() {
        let m = ConstantRate {
            start: DQuat::from_rotation_x(0.7),
            axis: DVec3::Y,
            rate: 1.5,
        };
        let w = body_rate(&m, 3.0);
        assert!((w - DVec3::new(0.0, 1.5, 0.0)).length() < 1e-6, "{w}");
    }

    #[test]
    fn accelerometer_poses_of_protocol_5_3() {
        // Face up: +Z reads +1 g.
        let f = specific_force_g(&Still(DQuat::IDENTITY), 0.0);
        assert!((f - DVec3::Z).length() < 1e-9);
        // IR window (−Y) pointing straight up: Y ≈ −1 g.
        let up = from_yaw_elevation_roll(0.0, std::f64::consts::FRAC_PI_2, 0.0);
        let f = specific_force_g(&Still(up), 0.0);
        assert!((f - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-9, "{f}");
        // Left side (+X) up: X ≈ +1 g.
        let left_up = DQuat::from_rotation_y(-std::f64::consts::FRAC_PI_2);
        let f = specific_force_g(&Still(left_up), 0.0);
        assert!((f - DVec3::X).length() < 1e-9, "{f}");
    }
}
