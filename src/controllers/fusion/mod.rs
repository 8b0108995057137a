//! Orientation filters: gyro integration with drift control, one trait, three methods. What
//! each is and what limits it: `docs/design/filters.md`.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `heading.rs` | The sensor bar as a heading reference: a 6-axis filter knows its tilt from gravity but has nothing to hold its heading (rotation about the vertical), whose error grows with the remaining vertical gyro bias. |
//! | `ours.rs` | [`FusionFilter`]: ours — VQF's inclination filter and motion-time bias estimation with our stillness detector, and the sensor bar as a heading reference. |
//! | `paper.rs` | [`PaperFilter`]: exactly the paper's method (`PROTOCOL.md` §12.2). |
//! | `raw.rs` | [`RawIntegration`]: the calibrated rates integrated as they are (a reference only). |
//! | `stillness.rs` | [`StillnessBias`]: the gyro bias from still periods, gated so that a slow steady turn is not taken for stillness. |
//! | `vqf.rs` | [`VqfFilter`]: VQF (Laidig & Seel, "VQF: Highly accurate IMU orientation estimation with bias estimation and magnetic disturbance rejection", Information Fusion 2023) in its 6-axis mode, behind the crate's [`OrientationFilter`] trait. |
//!
//! * [`RawIntegration`] — integrates the calibrated rates, no bias removal (reference only).
//! * [`PaperFilter`] — exactly the paper's method (`PROTOCOL.md` §12.2): bias from the first
//!   300 samples at rest, a 0.5 deg/s dead zone, integration by local increments, and tilt
//!   snapped to the accelerometer's gravity when still (yaw kept).
//! * [`FusionFilter`] — ours: VQF's inclination filter and motion-time bias estimation, with
//!   our gated stillness detector ([`StillnessBias`]) in place of VQF's rest detection, no
//!   dead zone, and the sensor bar as a heading reference while the IR camera sees it
//!   ([`BarHeading`]).
//! * [`crate::controllers::wiimote::VqfFilter`] — VQF (Laidig & Seel 2023), 6-axis, the published state of
//!   the art.
//!
//! Orientation is world←body with world Z up and the body axes of §5.3.

mod heading;
mod ours;
mod paper;
mod raw;
mod stillness;
mod vqf;

use glam::{DQuat, DVec3};
pub use heading::BarHeading;
pub use ours::FusionFilter;
pub use paper::PaperFilter;
pub use raw::RawIntegration;
pub use stillness::StillnessBias;
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
    /// direction to the sensor bar's centre (`crate::controllers::wiimote::ir::IrCamera::bar_direction`),
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
    /// [`crate::controllers::wiimote::VqfFilter`].
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

    /// Builds the filter for samples arriving every `sample_period_s` seconds (the device's
    /// true period: VQF's and our filter's low-pass coefficients depend on it; the paper's
    /// method and raw integration do not).
    pub fn build_for_period(self, sample_period_s: f64) -> Box<dyn OrientationFilter> {
        match self {
            FilterKind::Fusion => Box::new(FusionFilter::new(sample_period_s)),
            FilterKind::Vqf => Box::new(VqfFilter::new(sample_period_s, vqf_rs::Params::default())),
            other => other.build(),
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

/// `q` turned by the body rate `w_rad` (rad/s) over `dt` seconds.
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
        let truth = crate::controllers::motion::from_yaw_elevation_roll(0.8, 0.4, -0.3);
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
