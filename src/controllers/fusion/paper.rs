//! [`PaperFilter`]: exactly the paper's method (`PROTOCOL.md` §12.2).

use glam::{DQuat, DVec3};

use super::{
    Calibration, CalibrationPhase, ImuSample, OrientationFilter, RAD, integrate, snap_tilt,
};

/// The paper's filter (see module docs). Parameters follow `PROTOCOL.md` §12.2.
#[derive(Debug, Clone)]
pub struct PaperFilter {
    /// Samples averaged for the bias (300).
    pub bias_samples: u32,
    /// Dead zone per axis, deg/s (0.5).
    pub dead_zone_dps: f64,
    /// Stillness: `| |f| − 1 |` below this (0.05 g) …
    pub still_accel_g: f64,
    /// … and `|ω'|` below this (1 deg/s) …
    pub still_rate_dps: f64,
    /// … for at least this long (0.5 s).
    pub still_time_s: f64,
    q: DQuat,
    reference: DQuat,
    w: DVec3,
    sum: DVec3,
    n: u32,
    bias: Option<DVec3>,
    still_for: f64,
}

impl Default for PaperFilter {
    fn default() -> Self {
        Self {
            bias_samples: 300,
            dead_zone_dps: 0.5,
            still_accel_g: 0.05,
            still_rate_dps: 1.0,
            still_time_s: 0.5,
            q: DQuat::IDENTITY,
            reference: DQuat::IDENTITY,
            w: DVec3::ZERO,
            sum: DVec3::ZERO,
            n: 0,
            bias: None,
            still_for: 0.0,
        }
    }
}

impl OrientationFilter for PaperFilter {
    fn name(&self) -> &'static str {
        "paper"
    }
    fn update(&mut self, s: &ImuSample) {
        let Some(g) = s.gyro_dps else { return };
        let Some(bias) = self.bias else {
            // Bias batch: restart on motion or a fast-mode sample.
            let mean = if self.n > 0 {
                self.sum / self.n as f64
            } else {
                g
            };
            if s.gyro_fast.iter().any(|f| *f) || (g - mean).abs().max_element() > 3.0 {
                self.sum = DVec3::ZERO;
                self.n = 0;
                return;
            }
            self.sum += g;
            self.n += 1;
            if self.n >= self.bias_samples {
                self.bias = Some(self.sum / self.n as f64);
                self.q = snap_tilt(DQuat::IDENTITY, s.accel_g);
            }
            return;
        };
        let d = g - bias;
        let dz = |x: f64| if x.abs() < self.dead_zone_dps { 0.0 } else { x };
        let w = DVec3::new(dz(d.x), dz(d.y), dz(d.z));
        self.w = w * RAD;
        self.q = integrate(self.q, self.w, s.dt);
        let still = (s.accel_g.length() - 1.0).abs() < self.still_accel_g
            && w.length() < self.still_rate_dps;
        self.still_for = if still { self.still_for + s.dt } else { 0.0 };
        if self.still_for >= self.still_time_s {
            self.q = snap_tilt(self.q, s.accel_g);
        }
    }
    fn orientation(&self) -> DQuat {
        self.reference.inverse() * self.q
    }
    fn angular_velocity(&self) -> DVec3 {
        self.w
    }
    fn calibration(&self) -> Calibration {
        match self.bias {
            Some(b) => Calibration {
                phase: CalibrationPhase::Calibrated,
                confidence: 1.0,
                bias_dps: b,
            },
            None => Calibration {
                phase: CalibrationPhase::Collecting {
                    progress: self.n as f64 / self.bias_samples as f64,
                },
                confidence: 0.0,
                bias_dps: DVec3::ZERO,
            },
        }
    }
    fn is_still(&self) -> bool {
        self.still_for >= self.still_time_s
    }
    fn recenter(&mut self) {
        self.reference = self.q;
    }
    fn calibrate_now(&mut self) {
        self.bias = None;
        self.sum = DVec3::ZERO;
        self.n = 0;
    }
}
