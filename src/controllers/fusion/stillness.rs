//! [`StillnessBias`]: the gyro bias from still periods, gated so that a slow steady turn is
//! not taken for stillness.

use std::collections::VecDeque;

use glam::DVec3;

use super::{Calibration, CalibrationPhase, ImuSample};

/// Gyro bias from still periods, with a gate that tells a slow steady turn from stillness.
///
/// A window of gyro and accelerometer samples counts as still when every axis' spread is small,
/// the accelerometer reads about 1 g and no axis is in fast mode. Once a bias is known, a still
/// window whose mean rate differs from it by more than `bias_gate_dps` (plus
/// `bias_gate_growth` per second since the last update, since the bias drifts with
/// temperature) is a slow turn, not stillness — the case that fools plain rest detectors (VQF's
/// included: its rest test compares the gyro with its own low-pass, so a steady 2 deg/s turn
/// reads as rest and is learnt as bias).
#[derive(Debug, Clone)]
pub struct StillnessBias {
    /// Stillness window length, samples.
    pub window: usize,
    /// Max per-axis gyro spread in the window to count as still, deg/s.
    pub still_gyro_spread_dps: f64,
    /// Max per-axis accel spread in the window to count as still, g.
    pub still_accel_spread_g: f64,
    /// Gate on the window mean once calibrated, deg/s (see the type docs) …
    pub bias_gate_dps: f64,
    /// … widened by this much per second since the last bias update, deg/s².
    pub bias_gate_growth: f64,
    /// Bias tracking time constant while still, s.
    pub bias_time_constant_s: f64,
    /// Time still before the bias is updated, s.
    pub settle_s: f64,
    bias: DVec3,
    calibrated: bool,
    confidence: f64,
    still: bool,
    still_for: f64,
    gyro_hist: VecDeque<DVec3>,
    accel_hist: VecDeque<DVec3>,
    since_bias_update: f64,
}

impl Default for StillnessBias {
    fn default() -> Self {
        Self {
            window: 50,
            still_gyro_spread_dps: 1.5,
            still_accel_spread_g: 0.06,
            bias_gate_dps: 0.3,
            bias_gate_growth: 0.005,
            bias_time_constant_s: 2.0,
            settle_s: 0.5,
            bias: DVec3::ZERO,
            calibrated: false,
            confidence: 0.0,
            still: false,
            still_for: 0.0,
            gyro_hist: VecDeque::new(),
            accel_hist: VecDeque::new(),
            since_bias_update: 0.0,
        }
    }
}

fn spread(h: &VecDeque<DVec3>) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::MAX);
    let mut hi = DVec3::splat(f64::MIN);
    let mut sum = DVec3::ZERO;
    for v in h {
        lo = lo.min(*v);
        hi = hi.max(*v);
        sum += *v;
    }
    (hi - lo, sum / h.len().max(1) as f64)
}

impl StillnessBias {
    /// Feeds one gyro sample (deg/s, bias included) with its sample. Returns true when the
    /// bias estimate changed.
    pub fn update(&mut self, g: DVec3, s: &ImuSample) -> bool {
        self.gyro_hist.push_back(g);
        self.accel_hist.push_back(s.accel_g);
        while self.gyro_hist.len() > self.window {
            self.gyro_hist.pop_front();
            self.accel_hist.pop_front();
        }
        let full = self.gyro_hist.len() >= self.window;
        let (gs, gmean) = spread(&self.gyro_hist);
        let (as_, amean) = spread(&self.accel_hist);
        let quiet = full
            && gs.max_element() < self.still_gyro_spread_dps
            && as_.max_element() < self.still_accel_spread_g
            && (amean.length() - 1.0).abs() < 0.1
            && !s.gyro_fast.iter().any(|f| *f);
        self.since_bias_update += s.dt;
        let gate = self.bias_gate_dps + self.bias_gate_growth * self.since_bias_update;
        let gated = !self.calibrated || (gmean - self.bias).abs().max_element() < gate;
        self.still = quiet && gated;
        self.still_for = if self.still {
            self.still_for + s.dt
        } else {
            0.0
        };
        if self.still && self.still_for >= self.settle_s {
            self.since_bias_update = 0.0;
            if !self.calibrated {
                self.bias = gmean;
                self.calibrated = true;
                self.confidence = 0.5;
            } else {
                let a = 1.0 - (-s.dt / self.bias_time_constant_s).exp();
                self.bias += (gmean - self.bias) * a;
                self.confidence = (self.confidence + s.dt).min(1.0);
            }
            return true;
        }
        if !self.still {
            // Confidence decays slowly while moving (temperature drift, random walk).
            self.confidence = (self.confidence - s.dt / 300.0).max(0.0);
        }
        false
    }

    /// Current bias estimate, deg/s.
    pub fn bias_dps(&self) -> DVec3 {
        self.bias
    }

    /// Whether the last window was judged still.
    pub fn is_still(&self) -> bool {
        self.still
    }

    /// Seconds the remote has been still.
    pub fn still_for(&self) -> f64 {
        self.still_for
    }

    /// The calibration state.
    pub fn calibration(&self) -> Calibration {
        Calibration {
            phase: if self.calibrated {
                CalibrationPhase::Calibrated
            } else {
                CalibrationPhase::Collecting {
                    progress: (self.still_for / self.settle_s).min(1.0),
                }
            },
            confidence: self.confidence,
            bias_dps: self.bias,
        }
    }

    /// Forgets the bias: the next still period calibrates afresh.
    pub fn restart(&mut self) {
        self.calibrated = false;
        self.confidence = 0.0;
        self.still_for = 0.0;
    }
}
