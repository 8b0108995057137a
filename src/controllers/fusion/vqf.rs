//! [`VqfFilter`]: VQF (Laidig & Seel, "VQF: Highly accurate IMU orientation estimation with bias
//! estimation and magnetic disturbance rejection", Information Fusion 2023) in its 6-axis mode,
//! behind the crate's [`OrientationFilter`] trait.
//!
//! The algorithm is the `vqf-rs` crate, a port of the authors' C++ implementation; this file only
//! adapts units and frames. `tests/wiimote_device.rs` checks the adapter against values computed
//! by the authors' own implementation (the `vqf` Python package) on a documented sequence.
//!
//! VQF filters the accelerometer in an almost-inertial frame (so the centripetal acceleration of
//! a swing averages out), corrects the inclination with a 3-s time constant, and estimates the
//! gyro bias both at rest and during motion (the horizontal bias components are observable
//! through the inclination correction). Heading has no reference in 6-axis mode: its error is
//! the integral of the remaining vertical bias error.

use glam::{DQuat, DVec3};
use vqf_rs::{Params, VQF};

use super::{Calibration, CalibrationPhase, ImuSample, OrientationFilter};

/// Radians per degree.
const DEG: f64 = std::f64::consts::PI / 180.0;

/// Standard gravity, m/s² (VQF takes the accelerometer in m/s²).
const STANDARD_GRAVITY: f64 = 9.80665;

/// `period` if it is a usable sampling period, else the Wii Remote's 10 ms.
fn valid_period(period: f64) -> f64 {
    if period.is_finite() && period > 0.0 {
        period
    } else {
        0.01
    }
}

/// VQF's 6-axis estimate as world←body (world Z up); identity if it is not a rotation.
fn vqf_orientation(vqf: &VQF) -> DQuat {
    let q = vqf.quat_6d();
    let q = DQuat::from_xyzw(q.1, q.2, q.3, q.0);
    let norm = q.length();
    if norm.is_finite() && norm > 1e-9 {
        q / norm
    } else {
        DQuat::IDENTITY
    }
}

/// VQF in 6-axis mode (gyro + accelerometer). See the module docs.
pub struct VqfFilter {
    vqf: VQF,
    sample_period_s: f64,
    reference: DQuat,
    w: DVec3,
    calibrated: bool,
}

impl std::fmt::Debug for VqfFilter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VqfFilter")
            .field("sample_period_s", &self.sample_period_s)
            .field("orientation", &self.orientation())
            .finish_non_exhaustive()
    }
}

impl Default for VqfFilter {
    /// The authors' default parameters at the Wii Remote's 100 Hz report rate.
    fn default() -> Self {
        Self::new(0.01, Params::default())
    }
}

impl VqfFilter {
    /// A filter for samples arriving every `sample_period_s` seconds (the accelerometer's
    /// low-pass coefficients are computed for this period; the gyro is integrated with each
    /// sample's own `dt`).
    pub fn new(sample_period_s: f64, params: Params) -> Self {
        let sample_period_s = valid_period(sample_period_s);
        Self {
            vqf: VQF::new(sample_period_s, None, None, Some(params)),
            sample_period_s,
            reference: DQuat::IDENTITY,
            w: DVec3::ZERO,
            calibrated: false,
        }
    }

    /// The unreferenced estimate (world←body, world Z up), before recentring.
    pub(super) fn absolute(&self) -> DQuat {
        vqf_orientation(&self.vqf)
    }

    /// Hands VQF a gyro bias estimate (deg/s) with its uncertainty (deg/s).
    pub(super) fn set_bias_dps(&mut self, bias_dps: DVec3, sigma_dps: f64) {
        self.vqf
            .set_bias_estimate((bias_dps * DEG).to_array(), Some(sigma_dps * DEG));
    }

    fn bias_rad(&self) -> (DVec3, f64) {
        let (b, sigma) = self.vqf.bias_estimate();
        (DVec3::from_array(b), sigma)
    }
}

impl OrientationFilter for VqfFilter {
    fn name(&self) -> &'static str {
        "vqf"
    }

    fn update(&mut self, s: &ImuSample) {
        let acc = s.accel_g * STANDARD_GRAVITY;
        if !acc.is_finite() {
            return;
        }
        if let Some(g) = s.gyro_dps
            && g.is_finite()
            && s.dt > 0.0
            && s.dt.is_finite()
        {
            let g = g * DEG;
            self.vqf.update_gyr_with_ts(g.to_array(), s.dt);
            self.w = g - self.bias_rad().0;
        }
        self.vqf.update_acc(acc.to_array());
        // Calibrated once the bias is known to within 0.2 deg/s (VQF starts at 0.5 deg/s).
        if self.bias_rad().1 < 0.2f64.to_radians() || self.vqf.rest_detected() {
            self.calibrated = true;
        }
    }

    fn orientation(&self) -> DQuat {
        (self.reference.inverse() * self.absolute()).normalize()
    }

    fn angular_velocity(&self) -> DVec3 {
        self.w
    }

    fn calibration(&self) -> Calibration {
        let (bias, sigma) = self.bias_rad();
        let initial = self.vqf.params().bias_sigma_init.to_radians();
        let confidence = (1.0 - sigma / initial.max(1e-12)).clamp(0.0, 1.0);
        Calibration {
            phase: if self.calibrated {
                CalibrationPhase::Calibrated
            } else {
                CalibrationPhase::Collecting {
                    progress: confidence,
                }
            },
            confidence,
            bias_dps: bias / DEG,
        }
    }

    fn is_still(&self) -> bool {
        self.vqf.rest_detected()
    }

    fn recenter(&mut self) {
        self.reference = self.absolute();
    }

    fn calibrate_now(&mut self) {
        let sigma = self.vqf.params().bias_sigma_init.to_radians();
        self.vqf.set_bias_estimate([0.0; 3], Some(sigma));
        self.calibrated = false;
    }
}
