//! The drift benchmark of `PROTOCOL.md` §14: a scripted 10-minute session (still, wiggles,
//! slow yaw, fast swings, held tilted poses) through the emulator and the session code, scored
//! against the ground truth for every filter.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `pads.rs` | The drift benchmark's sessions on gyro pads: the same scripted motions through a pad's emulator (its rate, quantisation, noise and bias) and the pad session. |
//! | `pointing.rs` | A session of pointing at the screen and turning away: the sensor bar is in view a given share of the time, so the IR heading reference can be scored (`PROTOCOL.md` §14, §17.6). |
//!
//! Four [`SessionSet`]s: the default sessions; the same without the gyro's warm-up drift (the
//! conditions the paper's filter was designed for); continuous motion with no still period
//! longer than 1 s after the first 5 s on the table (the hard case for stillness-gated bias
//! estimation); and pointing at a screen with a sensor bar part of the time
//! ([`PointingScenario`], the IR camera on: [`score_with_bar`] scores a filter fed with the
//! bar's sightings, `ours_ir` in the benchmark).

use web_time::Instant;

use glam::{DQuat, DVec2, DVec3};

use bevy_wii_deform::controllers::fusion::{FilterKind, ImuSample, OrientationFilter};
use bevy_wii_deform::controllers::motion::{Motion, from_yaw_elevation_roll};
use bevy_wii_deform::controllers::session::{SessionConfig, SessionEvent};
use bevy_wii_deform::controllers::transport::Transport;
use bevy_wii_deform::controllers::wiimote::Rng;
use bevy_wii_deform::controllers::wiimote::Session;
use bevy_wii_deform::controllers::wiimote::ir::{IrCamera, IrSensitivity, PointerSetup};
use bevy_wii_deform::controllers::wiimote::{
    EmulatedBar, EmulatedRemote, EmulatorConfig, SensorModel, Variant,
};

mod pads;
mod pointing;
pub use pads::record_pad;
pub use pointing::PointingScenario;

/// The share of each cycle the [`SessionSet::Pointing`] sessions aim at the screen (0.5).
pub const DEFAULT_IN_VIEW_SHARE: f64 = 0.5;

const START_STILL: f64 = 5.0;
const WIGGLE: f64 = 60.0;
const SLOW: f64 = 20.0;
const SWING: f64 = 10.0;
const HOLD: f64 = 5.0;
const CYCLE: f64 = WIGGLE + SLOW + SWING + HOLD;
const END_STILL: f64 = 60.0;
const SWING_AMPLITUDE: f64 = 100.0; // degrees
const SWING_PEAK_RATE: f64 = 800.0; // deg/s
const ARM: f64 = 0.15; // m: ~3 g centripetal at 800 deg/s

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// The §14 scripted motion.
#[derive(Debug, Clone)]
pub struct DriftScenario {
    cycles: u32,
    wiggles: Vec<[(f64, f64, f64); 6]>,
}

impl DriftScenario {
    /// A scenario of about `duration_s` seconds (whole cycles), wiggle frequencies from `seed`.
    pub fn new(seed: u64, duration_s: f64) -> Self {
        let cycles = (((duration_s - START_STILL - END_STILL) / CYCLE)
            .round()
            .max(1.0)) as u32;
        let mut rng = Rng::new(seed ^ 0xD21F7);
        let wiggles = (0..cycles)
            .map(|_| {
                std::array::from_fn(|k| {
                    let slow = k % 2 == 0;
                    let f = if slow {
                        rng.range(0.2, 0.6)
                    } else {
                        rng.range(0.8, 2.0)
                    };
                    let amp = if slow {
                        28.0
                    } else {
                        (45.0 / (std::f64::consts::TAU * f)).min(10.0)
                    };
                    (f, amp, rng.range(0.0, std::f64::consts::TAU))
                })
            })
            .collect();
        Self { cycles, wiggles }
    }

    /// Total length in seconds.
    pub fn duration(&self) -> f64 {
        START_STILL + self.cycles as f64 * CYCLE + END_STILL
    }

    /// Whether the scripted remote holds still at `t` (scored as still).
    pub fn is_still(&self, t: f64) -> bool {
        let moving = self
            .orientation(t + 0.3)
            .angle_between(self.orientation(t - 0.3))
            > 1e-9
            || self.angles(t).3 != 0.0;
        !moving
    }

    /// (yaw, elevation, roll in degrees, swing angle in degrees).
    fn angles(&self, t: f64) -> (f64, f64, f64, f64) {
        if t < START_STILL {
            return (0.0, 0.0, 0.0, 0.0);
        }
        let k = ((t - START_STILL) / CYCLE).floor();
        let mut yaw = 0.0;
        // Slow turns alternate direction: +40°, −40°, …
        for c in 0..(k as u32).min(self.cycles) {
            yaw += if c % 2 == 0 { 40.0 } else { -40.0 };
        }
        if k as u32 >= self.cycles {
            // Final still phase: return smoothly from the last held pose, then hold.
            let tc = t - START_STILL - self.cycles as f64 * CYCLE;
            let back = 1.0 - smoothstep(tc / 2.0);
            return (yaw, 30.0 * back, 45.0 * back, 0.0);
        }
        let c = k as usize;
        let tc = t - START_STILL - k * CYCLE;
        let dir = if c.is_multiple_of(2) { 1.0 } else { -1.0 };
        if tc < WIGGLE {
            // Return from the previous held pose during the first 2 s, wiggles enveloped.
            let back = if c > 0 {
                1.0 - smoothstep(tc / 2.0)
            } else {
                0.0
            };
            let env = smoothstep(tc / 3.0) * smoothstep((WIGGLE - tc) / 3.0);
            let w = &self.wiggles[c];
            let s = |i: usize| {
                let (f1, a1, p1) = w[2 * i];
                let (f2, a2, p2) = w[2 * i + 1];
                env * (a1 * (std::f64::consts::TAU * f1 * tc + p1).sin()
                    + a2 * (std::f64::consts::TAU * f2 * tc + p2).sin())
            };
            (yaw + s(0), 30.0 * back + s(1), 45.0 * back + s(2), 0.0)
        } else if tc < WIGGLE + SLOW {
            (yaw + dir * 2.0 * (tc - WIGGLE), 0.0, 0.0, 0.0)
        } else if tc < WIGGLE + SLOW + SWING {
            let ts = tc - WIGGLE - SLOW;
            let period = SWING_AMPLITUDE * std::f64::consts::PI / SWING_PEAK_RATE;
            let mut swing = 0.0;
            for start in [2.0, 6.0] {
                let tau = ts - start;
                if (0.0..period).contains(&tau) {
                    swing = SWING_AMPLITUDE
                        * 0.5
                        * (1.0 - (std::f64::consts::TAU * tau / period).cos());
                }
            }
            (yaw + dir * 40.0, 0.0, 0.0, swing)
        } else {
            let th = smoothstep((tc - WIGGLE - SLOW - SWING) / 1.0);
            (yaw + dir * 40.0, 30.0 * th, 45.0 * th, 0.0)
        }
    }
}

impl Motion for DriftScenario {
    fn orientation(&self, t: f64) -> DQuat {
        let (y, e, r, s) = self.angles(t);
        from_yaw_elevation_roll(y.to_radians(), e.to_radians(), r.to_radians())
            * DQuat::from_rotation_x(-s.to_radians())
    }
    fn position(&self, t: f64) -> DVec3 {
        let (y, e, r, s) = self.angles(t);
        if s == 0.0 {
            return DVec3::ZERO;
        }
        let base = from_yaw_elevation_roll(y.to_radians(), e.to_radians(), r.to_radians());
        // The remote swings on an arm pivoting behind it (toward the player, +Y).
        base * (DQuat::from_rotation_x(-s.to_radians()) * DVec3::new(0.0, -ARM, 0.0)
            + DVec3::new(0.0, ARM, 0.0))
    }
}

/// Continuous hand motion: after the first 5 s on the table, every axis moves all the time
/// (three incommensurate sinusoids each, one of them a slow 0.03–0.08 Hz "aiming" drift), so no
/// still period lasts longer than the instants where all rates cross zero together.
#[derive(Debug, Clone)]
pub struct ContinuousScenario {
    duration: f64,
    /// Per axis (yaw, elevation, roll): (frequency Hz, amplitude deg, phase rad) × 3.
    waves: [[(f64, f64, f64); 3]; 3],
}

impl ContinuousScenario {
    /// A scenario of `duration_s` seconds with frequencies and phases drawn from `seed`.
    pub fn new(seed: u64, duration_s: f64) -> Self {
        let mut rng = Rng::new(seed ^ 0xC0471);
        let waves = std::array::from_fn(|axis| {
            let scale = if axis == 0 { 1.5 } else { 1.0 };
            [
                (rng.range(0.03, 0.08), 25.0 * scale, rng.range(0.0, 6.3)),
                (rng.range(0.2, 0.5), 12.0 * scale, rng.range(0.0, 6.3)),
                (rng.range(0.9, 1.6), 4.0, rng.range(0.0, 6.3)),
            ]
        });
        Self {
            duration: duration_s.max(START_STILL + 1.0),
            waves,
        }
    }

    /// Total length in seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    fn angles(&self, t: f64) -> [f64; 3] {
        if t < START_STILL {
            return [0.0; 3];
        }
        let tc = t - START_STILL;
        // Ease in over 2 s; the waves start at their value at tc = 0 subtracted, so the pose is
        // continuous at the end of the still start.
        let env = smoothstep(tc / 2.0);
        std::array::from_fn(|axis| {
            self.waves[axis]
                .iter()
                .map(|(f, a, p)| {
                    let w = std::f64::consts::TAU * f;
                    a * ((w * tc + p).sin() - p.sin())
                })
                .sum::<f64>()
                * env
        })
    }
}

impl Motion for ContinuousScenario {
    fn orientation(&self, t: f64) -> DQuat {
        let [y, e, r] = self.angles(t);
        from_yaw_elevation_roll(y.to_radians(), e.to_radians(), r.to_radians())
    }
    fn position(&self, _t: f64) -> DVec3 {
        DVec3::ZERO
    }
}

/// A family of benchmark sessions (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SessionSet {
    /// The §14 scenario with the default sensor model (gyro warm-up drift included).
    Default,
    /// The §14 scenario without the gyro's temperature (warm-up) drift.
    NoWarmUp,
    /// [`ContinuousScenario`] with the default sensor model.
    Continuous,
    /// [`PointingScenario`] (the bar aimed at [`DEFAULT_IN_VIEW_SHARE`] of the time) with the
    /// default sensor model and the IR camera on: 2 m from a 42-inch screen, 0.5 px of noise.
    Pointing,
}

impl SessionSet {
    /// Every set, in report order.
    pub const ALL: [SessionSet; 4] = [
        SessionSet::Default,
        SessionSet::NoWarmUp,
        SessionSet::Continuous,
        SessionSet::Pointing,
    ];

    /// The name used in reports (`default`, `no_warm_up`, `continuous`, `pointing`).
    pub fn name(self) -> &'static str {
        match self {
            SessionSet::Default => "default",
            SessionSet::NoWarmUp => "no_warm_up",
            SessionSet::Continuous => "continuous",
            SessionSet::Pointing => "pointing",
        }
    }

    /// Parses [`SessionSet::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The emulated sensor of this set.
    pub fn sensor(self) -> SensorModel {
        match self {
            SessionSet::NoWarmUp => SensorModel {
                gyro_temperature_drift_dps: 0.0,
                ..SensorModel::default()
            },
            SessionSet::Default | SessionSet::Continuous | SessionSet::Pointing => {
                SensorModel::default()
            }
        }
    }

    /// Records one session of this set.
    pub fn record(self, seed: u64, duration_s: f64) -> Recording {
        self.record_with_sensor(self.sensor(), seed, duration_s)
    }

    /// Records one session of this set's motion with another sensor model (for ablations: which
    /// sensor error limits a filter).
    pub fn record_with_sensor(self, sensor: SensorModel, seed: u64, duration_s: f64) -> Recording {
        match self {
            SessionSet::Default | SessionSet::NoWarmUp => {
                let scenario = std::sync::Arc::new(DriftScenario::new(seed, duration_s));
                let still = {
                    let s = scenario.clone();
                    move |t: f64| s.is_still(t)
                };
                let end = scenario.duration();
                record_motion(scenario, sensor, seed, end, still)
            }
            SessionSet::Continuous => {
                let scenario = std::sync::Arc::new(ContinuousScenario::new(seed, duration_s));
                let end = scenario.duration();
                record_motion(scenario, sensor, seed, end, |t| t < START_STILL)
            }
            SessionSet::Pointing => {
                record_pointing(sensor, seed, duration_s, DEFAULT_IN_VIEW_SHARE)
            }
        }
    }
}

/// Records a [`PointingScenario`] session aiming at the screen `share` of the time (the IR
/// camera on, the bar 2 m away, 0.5 px of pixel noise): [`Recording::bar`] holds what the
/// camera saw with each sample.
pub fn record_pointing(sensor: SensorModel, seed: u64, duration_s: f64, share: f64) -> Recording {
    let scenario = std::sync::Arc::new(PointingScenario::new(seed, duration_s, share));
    let end = scenario.duration();
    let bar = EmulatedBar {
        setup: PointerSetup::default(),
        position: DVec3::ZERO,
        noise_px: 0.5,
    };
    record_with_bar(scenario, sensor, seed, end, Some(bar), |t| t < START_STILL)
}

/// Scores of one filter on one or more sessions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FilterScore {
    /// RMS angle between true and estimated gravity in the body frame, degrees.
    pub tilt_rms_deg: f64,
    /// Max tilt error during the held still poses, degrees.
    pub tilt_max_still_deg: f64,
    /// Least-squares slope of the heading error, degrees per minute (absolute).
    pub yaw_drift_deg_per_min: f64,
    /// RMS geodesic attitude error, degrees.
    pub attitude_rms_deg: f64,
    /// 95th percentile of the error of 2-second relative rotations, degrees.
    pub relative_rotation_p95_deg: f64,
    /// BROAD-style heading error: RMS over the session of the rotation about the world's
    /// vertical in the error quaternion `q_est · q_true⁻¹` (swing–twist split), degrees. Every
    /// filter starts with the true heading, so no offset is removed.
    pub heading_rmse_deg: f64,
    /// BROAD-style inclination error: RMS of the remaining (horizontal-axis) rotation of the
    /// same error quaternion, degrees.
    pub inclination_rmse_deg: f64,
    /// Filter update cost, µs per sample.
    pub us_per_sample: f64,
}

impl FilterScore {
    /// The scores as a JSON object (keeps serde out of the library's dependencies).
    pub fn to_json(&self) -> String {
        format!(
            "{{\"tilt_rms_deg\": {:.4}, \"tilt_max_still_deg\": {:.4}, \"yaw_drift_deg_per_min\": {:.4}, \"attitude_rms_deg\": {:.4}, \"relative_rotation_p95_deg\": {:.4}, \"heading_rmse_deg\": {:.4}, \"inclination_rmse_deg\": {:.4}, \"us_per_sample\": {:.4}}}",
            self.tilt_rms_deg,
            self.tilt_max_still_deg,
            self.yaw_drift_deg_per_min,
            self.attitude_rms_deg,
            self.relative_rotation_p95_deg,
            self.heading_rmse_deg,
            self.inclination_rmse_deg,
            self.us_per_sample
        )
    }
}

/// A recorded session: calibrated samples with the truth at their sampling instants.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// Samples as the session produced them.
    pub samples: Vec<ImuSample>,
    /// True orientation at each sample's sensor time.
    pub truth: Vec<DQuat>,
    /// Sensor time of each sample, s.
    pub times: Vec<f64>,
    /// Whether the scenario holds still at that time (for the still-tilt metric).
    pub still: Vec<bool>,
    /// What the IR camera saw with each sample: the body-frame direction to the sensor bar's
    /// centre, `None` when it was not in view (or the camera was off).
    pub bar: Vec<Option<DVec3>>,
    /// Where the pointer said the remote pointed with each sample (normalised screen
    /// coordinates, [`PointerSetup::pointed_at`]), `None` without the bar.
    pub pointer: Vec<Option<DVec2>>,
    /// The room the camera saw (`None`: no bar).
    pub setup: Option<PointerSetup>,
}

impl Recording {
    /// The share of samples with the bar in view.
    pub fn in_view_share(&self) -> f64 {
        let seen = self.bar.iter().filter(|b| b.is_some()).count();
        seen as f64 / self.bar.len().max(1) as f64
    }

    /// RMS distance between where the pointer said the remote pointed and where it truly
    /// pointed (the true pointing ray of a remote at the standing point, met with the screen
    /// plane), over the samples with a pointer, as a share of the screen's width; `None`
    /// without any.
    pub fn pointer_rms_error(&self) -> Option<f64> {
        let setup = self.setup?;
        let (mut sum, mut n) = (0.0, 0usize);
        for (pointer, truth) in self.pointer.iter().zip(&self.truth) {
            let Some(at) = pointer else { continue };
            let ray = *truth * DVec3::NEG_Y;
            if ray.y >= -1e-9 {
                continue;
            }
            let hit = ray * (-setup.distance / ray.y);
            let error = DVec2::new(
                (at.x - (0.5 - hit.x / setup.screen_width)) * setup.screen_width,
                (at.y - (0.5 - hit.z / setup.screen_height)) * setup.screen_height,
            );
            sum += error.length_squared();
            n += 1;
        }
        (n > 0).then(|| (sum / n as f64).sqrt() / setup.screen_width)
    }
}

/// Runs the default §14 scenario through the emulator (Remote Plus, default sensor model, seed)
/// and the session, and records what a filter would see ([`SessionSet::Default`]).
pub fn record_session(seed: u64, duration_s: f64) -> Recording {
    SessionSet::Default.record(seed, duration_s)
}

/// Runs `motion` for `duration_s` seconds through the emulator (Remote Plus, `sensor`, `seed`)
/// and the session code; `still(t)` marks the instants scored as held still.
pub fn record_motion<M: Motion + 'static>(
    motion: std::sync::Arc<M>,
    sensor: SensorModel,
    seed: u64,
    duration_s: f64,
    still: impl Fn(f64) -> bool,
) -> Recording {
    record_with_bar(motion, sensor, seed, duration_s, None, still)
}

/// As [`record_motion`], with a sensor bar in the room (`Some`: the IR camera on).
pub fn record_with_bar<M: Motion + 'static>(
    motion: std::sync::Arc<M>,
    sensor: SensorModel,
    seed: u64,
    duration_s: f64,
    bar: Option<EmulatedBar>,
    still: impl Fn(f64) -> bool,
) -> Recording {
    let emu = EmulatedRemote::new(EmulatorConfig {
        variant: Variant::Plus,
        seed,
        sensors: sensor,
        sensor_bar: bar,
        ..Default::default()
    });
    emu.controls().set_motion(motion.clone());
    let config = SessionConfig {
        ir_camera: bar.map(|_| IrSensitivity::default()),
        ..SessionConfig::default()
    };
    let mut session = Session::new(emu, config);
    let mut rec = Recording {
        setup: bar.map(|b| b.setup),
        ..Recording::default()
    };
    if session.connect().is_err() {
        return rec;
    }
    let camera = IrCamera::default();
    let mut pointed = None;
    let end_us = (duration_s * 1e6) as u64;
    // The camera's dots arrive in the same report as the sample, just before it.
    let mut seen = None;
    while session.transport().now_us() < end_us {
        if session.poll(20).is_err() {
            break;
        }
        let events: Vec<SessionEvent> = session.drain_events().collect();
        for e in events {
            match e {
                SessionEvent::Ir { dots, gravity, .. } => {
                    seen = camera.bar_direction(&dots).ok();
                    pointed = rec
                        .setup
                        .and_then(|setup| setup.pointed_at(&dots, gravity).ok());
                }
                SessionEvent::Imu(s) => {
                    let t_us = session
                        .transport()
                        .sample_time_of(s.timestamp_us)
                        .unwrap_or(s.timestamp_us);
                    let t = t_us as f64 * 1e-6;
                    rec.samples.push(s);
                    rec.truth.push(motion.orientation(t));
                    rec.times.push(t);
                    rec.still.push(still(t));
                    rec.bar.push(seen.take());
                    rec.pointer.push(pointed.take());
                }
                _ => {}
            }
        }
    }
    rec
}

/// Splits a world-frame error rotation into (heading, inclination) angles in degrees: the
/// twist about world Z and the angle of the remaining swing about a horizontal axis.
pub fn heading_inclination_deg(error: DQuat) -> (f64, f64) {
    let q = if error.w < 0.0 { -error } else { error };
    let heading = wrap((2.0 * q.z.atan2(q.w)).to_degrees());
    let inclination = (2.0 * (q.w * q.w + q.z * q.z).sqrt().min(1.0).acos()).to_degrees();
    (heading, inclination)
}

fn heading(q: DQuat) -> f64 {
    let p = q * DVec3::NEG_Y;
    p.x.atan2(-p.y).to_degrees()
}

fn wrap(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

fn percentile(mut v: Vec<f64>, p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// Scores one filter on a recording (metrics from t ≥ 5 s, after the start-up still phase),
/// the camera's sightings not given to it (a 6-axis run).
pub fn score(kind: FilterKind, rec: &Recording) -> FilterScore {
    score_filter(&mut *kind.build(), rec)
}

/// As [`score`], the filter built for samples every `sample_period_s` seconds
/// ([`FilterKind::build_for_period`]): the device's true period.
pub fn score_at_period(kind: FilterKind, rec: &Recording, sample_period_s: f64) -> FilterScore {
    score_filter(&mut *kind.build_for_period(sample_period_s), rec)
}

/// As [`score`], with the camera's sightings of the bar ([`Recording::bar`]) handed to the
/// filter after each sample ([`OrientationFilter::observe_bar`]).
pub fn score_with_bar(kind: FilterKind, rec: &Recording) -> FilterScore {
    let mut filter = kind.build();
    let estimates = estimate(&mut *filter, rec, true);
    score_estimates(rec, &estimates.0, estimates.1)
}

/// Scores a filter instance (e.g. with tuned parameters) on a recording, from its current
/// state, without the camera's sightings.
pub fn score_filter(f: &mut dyn OrientationFilter, rec: &Recording) -> FilterScore {
    let (est, us) = estimate(f, rec, false);
    score_estimates(rec, &est, us)
}

/// Runs a filter over a recording: its estimate at each sample, and µs per sample.
pub fn estimate(
    f: &mut dyn OrientationFilter,
    rec: &Recording,
    with_bar: bool,
) -> (Vec<DQuat>, f64) {
    let mut est = Vec::with_capacity(rec.samples.len());
    let t0 = Instant::now();
    for (i, s) in rec.samples.iter().enumerate() {
        f.update(s);
        if with_bar {
            f.observe_bar(rec.bar.get(i).copied().flatten());
        }
        est.push(f.orientation());
    }
    let us = t0.elapsed().as_secs_f64() * 1e6 / rec.samples.len().max(1) as f64;
    (est, us)
}

#[allow(clippy::needless_range_loop)] // parallel per-sample arrays
/// Scores per-sample estimates against a recording's truth.
fn score_estimates(rec: &Recording, est: &[DQuat], us: f64) -> FilterScore {
    let first = rec
        .times
        .iter()
        .position(|t| *t >= START_STILL)
        .unwrap_or(0);
    let (mut tilt2, mut att2, mut n) = (0.0f64, 0.0f64, 0.0f64);
    let (mut heading2, mut inclination2) = (0.0f64, 0.0f64);
    let mut tilt_still: f64 = 0.0;
    let (mut sx, mut sy, mut sxx, mut sxy) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut yaw_err_unwrapped = 0.0;
    let mut last_err: Option<f64> = None;
    for i in first..rec.samples.len() {
        let (qt, qe) = (rec.truth[i], est[i]);
        let tilt = (qt.inverse() * DVec3::Z)
            .angle_between(qe.inverse() * DVec3::Z)
            .to_degrees();
        let att = qt.angle_between(qe).to_degrees();
        tilt2 += tilt * tilt;
        att2 += att * att;
        let (h, inc) = heading_inclination_deg(qe * qt.inverse());
        heading2 += h * h;
        inclination2 += inc * inc;
        n += 1.0;
        if rec.still[i] {
            tilt_still = tilt_still.max(tilt);
        }
        // Heading error (unwrapped), only where the heading is well defined.
        let pt = qt * DVec3::NEG_Y;
        if pt.z.abs() < 0.9 {
            let e = wrap(heading(qe) - heading(qt));
            yaw_err_unwrapped = match last_err {
                Some(prev) => yaw_err_unwrapped + wrap(e - prev),
                None => e,
            };
            last_err = Some(e);
            let x = rec.times[i] / 60.0;
            sx += x;
            sy += yaw_err_unwrapped;
            sxx += x * x;
            sxy += x * yaw_err_unwrapped;
        }
    }
    let m = n.max(1.0);
    let slope = (m * sxy - sx * sy) / (m * sxx - sx * sx).max(1e-12);
    // 2-second relative rotations every 0.5 s.
    let mut rel = Vec::new();
    let mut i = first;
    while i < rec.samples.len() {
        let target = rec.times[i] + 2.0;
        if let Some(j) = rec.times[i..]
            .iter()
            .position(|t| *t >= target)
            .map(|k| k + i)
        {
            let dt = rec.truth[i].inverse() * rec.truth[j];
            let de = est[i].inverse() * est[j];
            rel.push(dt.angle_between(de).to_degrees());
        } else {
            break;
        }
        let next = rec.times[i] + 0.5;
        i = rec.times[i..]
            .iter()
            .position(|t| *t >= next)
            .map(|k| k + i)
            .unwrap_or(rec.samples.len());
    }
    FilterScore {
        tilt_rms_deg: (tilt2 / m).sqrt(),
        tilt_max_still_deg: tilt_still,
        yaw_drift_deg_per_min: slope.abs(),
        attitude_rms_deg: (att2 / m).sqrt(),
        relative_rotation_p95_deg: percentile(rel, 0.95),
        heading_rmse_deg: (heading2 / m).sqrt(),
        inclination_rmse_deg: (inclination2 / m).sqrt(),
        us_per_sample: us,
    }
}

/// Mean of scores over several sessions.
pub fn mean(scores: &[FilterScore]) -> FilterScore {
    let n = scores.len().max(1) as f64;
    let mut m = FilterScore::default();
    for s in scores {
        m.tilt_rms_deg += s.tilt_rms_deg / n;
        m.tilt_max_still_deg += s.tilt_max_still_deg / n;
        m.yaw_drift_deg_per_min += s.yaw_drift_deg_per_min / n;
        m.attitude_rms_deg += s.attitude_rms_deg / n;
        m.relative_rotation_p95_deg += s.relative_rotation_p95_deg / n;
        m.heading_rmse_deg += s.heading_rmse_deg / n;
        m.inclination_rmse_deg += s.inclination_rmse_deg / n;
        m.us_per_sample += s.us_per_sample / n;
    }
    m
}

/// The tilt error of the accelerometer alone during still samples (RMS, degrees): the floor
/// any gravity-referenced filter converges to (cross-axis and calibration errors of the
/// emulated sensor).
pub fn accelerometer_tilt_floor(rec: &Recording) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0.0f64);
    for ((s, q), still) in rec.samples.iter().zip(&rec.truth).zip(&rec.still) {
        if *still {
            let e = s.accel_g.angle_between(q.inverse() * DVec3::Z).to_degrees();
            sum += e * e;
            n += 1.0;
        }
    }
    if n > 0.0 { (sum / n).sqrt() } else { 0.0 }
}
