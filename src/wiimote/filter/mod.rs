//! Orientation filters: gyro integration with drift control, one trait, three methods. What
//! each is and what limits it: `docs/design/filters.md`.
//!
//! * [`RawIntegration`] — integrates the calibrated rates, no bias removal (reference only).
//! * [`PaperFilter`] — exactly the paper's method (`PROTOCOL.md` §12.2): bias from the first
//!   300 samples at rest, a 0.5 deg/s dead zone, integration by local increments, and tilt
//!   snapped to the accelerometer's gravity when still (yaw kept).
//! * [`FusionFilter`] — ours: VQF's inclination filter and motion-time bias estimation, with
//!   our gated stillness detector ([`StillnessBias`]) in place of VQF's rest detection, no
//!   dead zone, and the sensor bar as a heading reference while the IR camera sees it
//!   ([`BarHeading`]).
//! * [`crate::wiimote::VqfFilter`] — VQF (Laidig & Seel 2023), 6-axis, the published state of
//!   the art.
//!
//! Orientation is world←body with world Z up and the body axes of §5.3.

use std::collections::VecDeque;

mod heading;
mod vqf;

use glam::{DQuat, DVec3};
pub use heading::BarHeading;
pub use vqf::VqfFilter;

/// Radians per degree.
const RAD: f64 = std::f64::consts::PI / 180.0;

/// One sensor sample handed to a filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Host timestamp, µs.
    pub timestamp_us: u64,
    /// Time since the previous sample, s (0 after a dropout: do not integrate).
    pub dt: f64,
    /// Calibrated body rates in deg/s (x pitch, y roll, z yaw), bias *not* removed; `None`
    /// for reports without a MotionPlus frame.
    pub gyro_dps: Option<DVec3>,
    /// Fast (high-range) flag per axis x, y, z.
    pub gyro_fast: [bool; 3],
    /// Specific force in g (body frame).
    pub accel_g: DVec3,
}

/// Where bias calibration stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CalibrationPhase {
    /// Collecting samples at rest; `progress` in 0..1.
    Collecting {
        /// Fraction done.
        progress: f64,
    },
    /// A bias estimate is in use.
    Calibrated,
}

/// Calibration state, visible to users.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Phase.
    pub phase: CalibrationPhase,
    /// 0..1: how much the current bias estimate is trusted.
    pub confidence: f64,
    /// Current gyro bias estimate, deg/s.
    pub bias_dps: DVec3,
}

/// An orientation estimator fed with [`ImuSample`]s.
pub trait OrientationFilter: Send {
    /// Short name (`raw`, `paper`, `ours`).
    fn name(&self) -> &'static str;
    /// Consumes one sample.
    fn update(&mut self, sample: &ImuSample);
    /// Estimated orientation (world←body), relative to the last recentre.
    fn orientation(&self) -> DQuat;
    /// Bias-corrected body angular velocity, rad/s.
    fn angular_velocity(&self) -> DVec3;
    /// Bias calibration state.
    fn calibration(&self) -> Calibration;
    /// Whether the remote is currently judged still.
    fn is_still(&self) -> bool;
    /// Makes the current orientation the identity.
    fn recenter(&mut self);
    /// Restarts bias calibration (hold the remote still afterwards).
    fn calibrate_now(&mut self);
    /// What the IR camera saw with the sample just given to [`Self::update`]: the body-frame
    /// direction to the sensor bar's centre (`crate::wiimote::ir::IrCamera::bar_direction`),
    /// `None` when the bar is not in view. Filters with a heading reference ([`FusionFilter`])
    /// correct their heading from it; the others ignore it.
    fn observe_bar(&mut self, _bar: Option<DVec3>) {}
    /// Whether the heading is currently held by the sensor bar (see [`Self::observe_bar`]).
    fn heading_from_bar(&self) -> bool {
        false
    }
}

/// Filter choice, for settings and UIs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum FilterKind {
    /// [`RawIntegration`].
    Raw,
    /// [`PaperFilter`].
    Paper,
    /// [`FusionFilter`] (default).
    #[default]
    Fusion,
    /// [`crate::wiimote::VqfFilter`].
    Vqf,
}

impl FilterKind {
    /// Builds the filter with default parameters.
    pub fn build(self) -> Box<dyn OrientationFilter> {
        match self {
            FilterKind::Raw => Box::new(RawIntegration::default()),
            FilterKind::Paper => Box::new(PaperFilter::default()),
            FilterKind::Fusion => Box::new(FusionFilter::default()),
            FilterKind::Vqf => Box::new(VqfFilter::default()),
        }
    }

    /// All filters, in report order.
    pub const ALL: [FilterKind; 4] = [
        FilterKind::Raw,
        FilterKind::Paper,
        FilterKind::Fusion,
        FilterKind::Vqf,
    ];

    /// The name the filter reports.
    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Raw => "raw",
            FilterKind::Paper => "paper",
            FilterKind::Fusion => "ours",
            FilterKind::Vqf => "vqf",
        }
    }
}

fn integrate(q: DQuat, w_rad: DVec3, dt: f64) -> DQuat {
    (q * DQuat::from_scaled_axis(w_rad * dt)).normalize()
}

/// Tilt (elevation + roll) from measured gravity, heading kept from `q`. Returns `q`
/// unchanged where the heading is undefined (pointing straight up/down) or `f` is zero.
pub fn snap_tilt(q: DQuat, f: DVec3) -> DQuat {
    let Some(g) = f.try_normalize() else {
        return q;
    };
    // Orientation model R = Rz(ψ)·Rx(a)·Ry(b): body "up" is (−cos a sin b, sin a, cos a cos b).
    let a = g.y.clamp(-1.0, 1.0).asin(); // = −elevation of the pointing axis −Y
    let b = (-g.x).atan2(g.z); // roll about the pointing axis
    let p = q * DVec3::NEG_Y;
    let horizontal = (p.x * p.x + p.y * p.y).sqrt();
    if horizontal < 1e-6 {
        return q;
    }
    let psi = p.x.atan2(-p.y);
    DQuat::from_rotation_z(psi) * DQuat::from_rotation_x(a) * DQuat::from_rotation_y(b)
}

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

/// Ours: VQF's inclination filter and motion-time bias estimation (through the `vqf-rs` port),
/// with its rest detection replaced by [`StillnessBias`], which does not learn slow steady turns
/// as bias.
///
/// Each sample: our stillness detector updates the bias from still windows and hands it to VQF
/// with uncertainty `still_bias_sigma_dps`; VQF integrates the gyro minus that bias, low-passes
/// the accelerometer in an almost-inertial frame (so the centripetal acceleration of a swing
/// averages out), corrects the inclination with time constant `tau_acc_s`, and keeps refining
/// the horizontal bias components while the remote moves (they are observable through the
/// inclination correction). The yaw bias is observable only through still periods and through
/// how the remote's attitude mixes axes, as in every 6-axis filter.
///
/// The two parameters were chosen on the drift benchmark's seeds 1–3 (all three session sets)
/// and checked on held-out seeds; VQF's published defaults are 3 s and (at rest) 0.03 deg/s.
/// A looser bias uncertainty lets VQF's motion-time estimation keep correcting the bias
/// between still periods; a shorter inclination time constant follows gravity more closely
/// after the gyro's scale error has tilted the estimate during a fast swing.
///
/// With the IR camera on, [`OrientationFilter::observe_bar`] feeds a [`BarHeading`]: while the
/// bar is in view the heading is held to it; out of view the filter is the 6-axis one above,
/// continuing from the last corrected heading.
pub struct FusionFilter {
    vqf: VqfFilter,
    stillness: StillnessBias,
    heading: BarHeading,
    /// The corrected estimate at the last recentre.
    reference: DQuat,
    /// `dt` of the last sample, s.
    last_dt: f64,
    /// Bias uncertainty handed to VQF after a still update, deg/s (0.3).
    pub still_bias_sigma_dps: f64,
}

impl std::fmt::Debug for FusionFilter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FusionFilter")
            .field("stillness", &self.stillness)
            .field("orientation", &self.orientation())
            .finish_non_exhaustive()
    }
}

impl Default for FusionFilter {
    fn default() -> Self {
        Self::new(0.01)
    }
}

impl FusionFilter {
    /// A filter for samples arriving every `sample_period_s` seconds (the accelerometer
    /// low-pass is designed for this period; the gyro uses each sample's own `dt`).
    pub fn new(sample_period_s: f64) -> Self {
        Self::with_tau_acc(sample_period_s, 1.0)
    }

    /// As [`Self::new`] with the inclination correction's time constant `tau_acc_s` (1 s by
    /// default).
    pub fn with_tau_acc(sample_period_s: f64, tau_acc_s: f64) -> Self {
        let params = vqf_rs::Params {
            tau_acc: tau_acc_s,
            rest_bias_est_enabled: false,
            mag_dist_rejection_enabled: false,
            ..Default::default()
        };
        Self {
            vqf: VqfFilter::new(sample_period_s, params),
            stillness: StillnessBias::default(),
            heading: BarHeading::default(),
            reference: DQuat::IDENTITY,
            last_dt: 0.0,
            still_bias_sigma_dps: 0.3,
        }
    }

    /// The sensor-bar heading reference (its settings, whether it holds the heading now).
    pub fn bar_heading(&self) -> &BarHeading {
        &self.heading
    }

    /// The sensor-bar heading reference, to change its settings or make it forget the bar.
    pub fn bar_heading_mut(&mut self) -> &mut BarHeading {
        &mut self.heading
    }

    /// The corrected estimate before recentring (world←body).
    fn absolute(&self) -> DQuat {
        self.heading.apply(self.vqf.absolute())
    }

    /// The stillness and bias detector.
    pub fn stillness(&self) -> &StillnessBias {
        &self.stillness
    }
}

impl OrientationFilter for FusionFilter {
    fn name(&self) -> &'static str {
        "ours"
    }
    fn update(&mut self, s: &ImuSample) {
        // Our stillness detector sets the bias before VQF integrates the sample.
        if let Some(g) = s.gyro_dps.filter(|g| g.is_finite())
            && s.dt > 0.0
            && s.dt.is_finite()
            && s.accel_g.is_finite()
            && self.stillness.update(g, s)
        {
            self.vqf
                .set_bias_dps(self.stillness.bias_dps(), self.still_bias_sigma_dps);
        }
        self.vqf.update(s);
        self.last_dt = s.dt;
    }
    fn orientation(&self) -> DQuat {
        (self.reference.inverse() * self.absolute()).normalize()
    }
    fn angular_velocity(&self) -> DVec3 {
        self.vqf.angular_velocity()
    }
    fn calibration(&self) -> Calibration {
        Calibration {
            bias_dps: self.vqf.calibration().bias_dps,
            ..self.stillness.calibration()
        }
    }
    fn is_still(&self) -> bool {
        self.stillness.is_still()
    }
    fn recenter(&mut self) {
        self.reference = self.absolute();
    }
    fn calibrate_now(&mut self) {
        self.stillness.restart();
    }
    fn observe_bar(&mut self, bar: Option<DVec3>) {
        self.heading.observe(self.vqf.absolute(), bar, self.last_dt);
    }
    fn heading_from_bar(&self) -> bool {
        self.heading.in_view()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: u64, gyro: DVec3, accel: DVec3) -> ImuSample {
        ImuSample {
            timestamp_us: t,
            dt: 0.01,
            gyro_dps: Some(gyro),
            gyro_fast: [false; 3],
            accel_g: accel,
        }
    }

    #[test]
    fn snap_tilt_matches_gravity_and_keeps_heading() {
        let truth = crate::wiimote::motion::from_yaw_elevation_roll(0.8, 0.4, -0.3);
        let f = truth.inverse() * DVec3::Z;
        let wrong = DQuat::from_rotation_z(0.8) * DQuat::from_rotation_x(-0.2);
        let q = snap_tilt(wrong, f);
        assert!(q.angle_between(truth) < 1e-9, "{}", q.angle_between(truth));
    }

    #[test]
    fn paper_dead_zone_swallows_slow_motion_ours_does_not() {
        let bias = DVec3::new(0.3, -0.2, 0.4);
        let mut paper = PaperFilter::default();
        let mut ours = FusionFilter::default();
        let mut t = 0;
        for _ in 0..400 {
            t += 10_000;
            let s = sample(t, bias, DVec3::Z);
            paper.update(&s);
            ours.update(&s);
        }
        assert_eq!(paper.calibration().phase, CalibrationPhase::Calibrated);
        assert_eq!(ours.calibration().phase, CalibrationPhase::Calibrated);
        // 0.4 deg/s yaw for 20 s = 8°.
        for _ in 0..2000 {
            t += 10_000;
            let s = sample(t, bias + DVec3::new(0.0, 0.0, 0.4), DVec3::Z);
            paper.update(&s);
            ours.update(&s);
        }
        let yaw = |q: DQuat| q.to_euler(glam::EulerRot::ZXY).0.to_degrees();
        assert!(
            yaw(paper.orientation()).abs() < 0.5,
            "paper {}",
            yaw(paper.orientation())
        );
        assert!(
            (yaw(ours.orientation()) - 8.0).abs() < 1.0,
            "ours {}",
            yaw(ours.orientation())
        );
    }

    #[test]
    fn recenter_makes_identity() {
        for kind in FilterKind::ALL {
            let mut f = kind.build();
            for k in 0..400 {
                f.update(&sample(k * 10_000, DVec3::new(0.0, 0.0, 20.0), DVec3::Z));
            }
            f.recenter();
            assert!(
                f.orientation().angle_between(DQuat::IDENTITY) < 1e-9,
                "{}",
                f.name()
            );
        }
    }

    #[test]
    fn paper_bias_batch_restarts_on_motion() {
        let mut p = PaperFilter::default();
        for k in 0..299 {
            p.update(&sample(k, DVec3::ZERO, DVec3::Z));
        }
        p.update(&sample(300, DVec3::new(10.0, 0.0, 0.0), DVec3::Z));
        assert!(matches!(
            p.calibration().phase,
            CalibrationPhase::Collecting { .. }
        ));
    }
}
