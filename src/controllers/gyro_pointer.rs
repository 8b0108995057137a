//! A pointer from the gyro alone, for controllers without an IR camera: **player-space
//! gyro**, as games aim with pads — turning about the direction of gravity moves the pointer
//! sideways whatever the controller's roll, pitching about the controller's own left–right
//! axis moves it up and down. It starts (and recentres) at the screen's centre and stays on
//! the screen.

use glam::{DQuat, DVec2, DVec3};

/// How far the pointer moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroPointerSettings {
    /// Screen widths per degree turned (horizontally); vertically the same physical distance,
    /// `sensitivity × aspect` screen heights per degree. Default 1/40: a 40° turn sweeps the
    /// screen's width.
    pub sensitivity: f64,
    /// The screen's width / height (16/9 by default).
    pub aspect: f64,
}

impl Default for GyroPointerSettings {
    fn default() -> Self {
        Self {
            sensitivity: 1.0 / 40.0,
            aspect: 16.0 / 9.0,
        }
    }
}

/// The pointer's state: where it is and the orientation it last moved from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroPointer {
    /// Settings.
    pub settings: GyroPointerSettings,
    position: DVec2,
    last: Option<DQuat>,
}

impl GyroPointer {
    /// A pointer at the centre.
    pub fn new(settings: GyroPointerSettings) -> Self {
        Self {
            settings,
            position: DVec2::splat(0.5),
            last: None,
        }
    }

    /// Where it points: (0, 0) top left … (1, 1) bottom right.
    pub fn position(&self) -> DVec2 {
        self.position
    }

    /// Back to the centre (the next orientation is the new reference).
    pub fn recentre(&mut self) {
        self.position = DVec2::splat(0.5);
        self.last = None;
    }

    /// Moves by the turn from the last orientation to `orientation` (world←body, world Z up,
    /// the body frame of [`crate::controllers::MotionSample`]). A non-finite orientation is
    /// ignored.
    pub fn update(&mut self, orientation: DQuat) -> DVec2 {
        if !orientation.is_finite() {
            return self.position;
        }
        if let Some(last) = self.last {
            let step = (last.inverse() * orientation).normalize();
            let step = if step.w < 0.0 { -step } else { step };
            let turn = step.to_scaled_axis();
            // Yaw about gravity (seen in the body frame), positive turning left; pitch about
            // the body's X axis (its left), positive nose down.
            let up = orientation.inverse() * DVec3::Z;
            let yaw = turn.dot(up).to_degrees();
            let pitch = turn.x.to_degrees();
            let s = self.settings;
            let moved =
                self.position + DVec2::new(-yaw * s.sensitivity, pitch * s.sensitivity * s.aspect);
            if moved.is_finite() {
                self.position = moved.clamp(DVec2::ZERO, DVec2::ONE);
            }
        }
        self.last = Some(orientation);
        self.position
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turn_of_ten_degrees_moves_ten_times_the_sensitivity() {
        let settings = GyroPointerSettings {
            sensitivity: 0.02,
            aspect: 1.5,
        };
        let mut p = GyroPointer::new(settings);
        // Held level, then turned 10° left in 1° steps.
        for i in 0..=10 {
            p.update(DQuat::from_rotation_z((i as f64).to_radians()));
        }
        let moved = DVec2::splat(0.5) - p.position();
        assert!((moved.x - 0.2).abs() < 0.002, "{moved}");
        assert!(moved.y.abs() < 1e-9);
        // Nose 10° down (about the body's X): down the screen by 10 · 0.02 · 1.5.
        let mut p = GyroPointer::new(settings);
        for i in 0..=10 {
            p.update(DQuat::from_rotation_x((i as f64).to_radians()));
        }
        assert!(
            (p.position().y - 0.5 - 0.3).abs() < 0.003,
            "{}",
            p.position()
        );
        // Rolled 90° onto its side, a turn about gravity still moves it sideways.
        let rolled = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let mut p = GyroPointer::new(settings);
        for i in 0..=10 {
            p.update(DQuat::from_rotation_z((i as f64).to_radians()) * rolled);
        }
        assert!(
            (0.5 - p.position().x - 0.2).abs() < 0.002,
            "{}",
            p.position()
        );
        p.recentre();
        assert_eq!(p.position(), DVec2::splat(0.5));
    }
}
