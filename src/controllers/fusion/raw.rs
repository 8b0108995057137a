//! [`RawIntegration`]: the calibrated rates integrated as they are (a reference only).

use glam::{DQuat, DVec3};

use super::{Calibration, CalibrationPhase, ImuSample, OrientationFilter, RAD, integrate};

/// Integrates the calibrated rates without removing bias.
#[derive(Debug, Clone, Default)]
pub struct RawIntegration {
    q: DQuat,
    reference: DQuat,
    w: DVec3,
}

impl OrientationFilter for RawIntegration {
    fn name(&self) -> &'static str {
        "raw"
    }
    fn update(&mut self, s: &ImuSample) {
        if let Some(g) = s.gyro_dps {
            self.w = g * RAD;
            self.q = integrate(self.q, self.w, s.dt);
        }
    }
    fn orientation(&self) -> DQuat {
        self.reference.inverse() * self.q
    }
    fn angular_velocity(&self) -> DVec3 {
        self.w
    }
    fn calibration(&self) -> Calibration {
        Calibration {
            phase: CalibrationPhase::Calibrated,
            confidence: 0.0,
            bias_dps: DVec3::ZERO,
        }
    }
    fn is_still(&self) -> bool {
        false
    }
    fn recenter(&mut self) {
        self.reference = self.q;
    }
    fn calibrate_now(&mut self) {}
}
