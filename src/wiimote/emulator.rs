//! A software Wii Remote (original with external MotionPlus, or Remote Plus "-TR") that speaks
//! the real byte protocol behind the [`Transport`] trait. Sensors are synthesised from a
//! ground-truth [`Motion`] with the error model of `PROTOCOL.md` §13.3, on a deterministic
//! virtual clock, in real time (demos), or paced by an [`EmulatorClock`] the app advances
//! (tests that step time by hand).

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use glam::{DMat3, DQuat, DVec3};

use super::motion::{self, Motion, Still};
use super::protocol::{
    AccelCalibration, AccelRaw, AddressSpace, Buttons, GyroRange, MotionPlusCalibration,
    MotionPlusFrame, NunchukFrame, OutputReport, encode_buttons_accel,
};
use super::rng::Rng;
use super::transport::{Transport, TransportError};

/// Which remote is emulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// RVL-CNT-01 (PID 0x0306), optionally with an external MotionPlus dongle.
    Original {
        /// A MotionPlus is plugged in at power-on.
        motion_plus: bool,
    },
    /// RVL-CNT-01-TR (PID 0x0330) with built-in MotionPlus.
    Plus,
    /// A Balance Board (same PID as the original; must be rejected by the session).
    BalanceBoard,
}

/// Sensor error model (defaults from `PROTOCOL.md` §13.3).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorModel {
    /// Gyro white noise σ per sample at 100 Hz, deg/s.
    pub gyro_noise_dps: f64,
    /// Turn-on bias σ, deg/s.
    pub gyro_turn_on_bias_dps: f64,
    /// Bias random walk, deg/s/√s.
    pub gyro_bias_walk: f64,
    /// Temperature drift reached after 10 minutes (deg/s, random sign per axis).
    pub gyro_temperature_drift_dps: f64,
    /// Cross-axis sensitivity, uniform in ± this (off-diagonal terms).
    pub gyro_misalignment: f64,
    /// Calibration-block scale error (uniform ±).
    pub gyro_block_scale_error: f64,
    /// Calibration-block zero error σ in 16-bit counts.
    pub gyro_block_zero_error: f64,
    /// Slow-mode sensitivities in 14-bit counts per deg/s (yaw, roll, pitch); `None` = draw.
    pub gyro_slow_counts_per_dps: Option<[f64; 3]>,
    /// Mirrored gyro polarity (with a matching calibration block).
    pub reversed: bool,
    /// Accelerometer noise σ, g.
    pub accel_noise_g: f64,
    /// Accelerometer cross-axis sensitivity, uniform in ± this (off-diagonal terms).
    pub accel_misalignment: f64,
    /// Accelerometer scale error, uniform in ± this (diagonal terms).
    pub accel_scale_error: f64,
}

impl Default for SensorModel {
    fn default() -> Self {
        Self {
            gyro_noise_dps: 0.15,
            gyro_turn_on_bias_dps: 0.5,
            gyro_bias_walk: 0.01,
            gyro_temperature_drift_dps: 1.0,
            gyro_misalignment: 0.01,
            gyro_block_scale_error: 0.02,
            gyro_block_zero_error: 40.0,
            gyro_slow_counts_per_dps: Some([15.64, 20.03, 14.33]),
            reversed: false,
            accel_noise_g: 0.0033,
            accel_misalignment: 0.02,
            accel_scale_error: 0.02,
        }
    }
}

impl SensorModel {
    /// A perfect sensor (no noise, bias, misalignment or calibration error).
    pub fn ideal() -> Self {
        Self {
            gyro_noise_dps: 0.0,
            gyro_turn_on_bias_dps: 0.0,
            gyro_bias_walk: 0.0,
            gyro_temperature_drift_dps: 0.0,
            gyro_misalignment: 0.0,
            gyro_block_scale_error: 0.0,
            gyro_block_zero_error: 0.0,
            accel_noise_g: 0.0,
            accel_misalignment: 0.0,
            accel_scale_error: 0.0,
            ..Self::default()
        }
    }
}

/// A clock the app advances (e.g. from Bevy's virtual time) that paces emulated remotes: a
/// report is delivered once the clock has reached its time, so a test steps the remote
/// exactly like the rest of the app, with no wall-clock sleeps. Closing it releases every
/// waiting remote (from then on reports come at once); the manager closes its remotes'
/// clocks when it stops.
#[derive(Clone, Default)]
pub struct EmulatorClock(Arc<(Mutex<ClockState>, Condvar)>);

#[derive(Default)]
struct ClockState {
    now_us: u64,
    closed: bool,
}

impl EmulatorClock {
    /// A clock at 0.
    pub fn new() -> Self {
        Self::default()
    }

    fn state(&self) -> std::sync::MutexGuard<'_, ClockState> {
        self.0.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Microseconds since the clock started.
    pub fn now_us(&self) -> u64 {
        self.state().now_us
    }

    /// Moves the clock forward to `t_us` (never back) and wakes the remotes waiting for it.
    pub fn advance_to(&self, t_us: u64) {
        let mut state = self.state();
        if t_us > state.now_us {
            state.now_us = t_us;
            self.0.1.notify_all();
        }
    }

    /// Releases every waiting remote, for good.
    pub fn close(&self) {
        self.state().closed = true;
        self.0.1.notify_all();
    }

    /// Blocks until the clock reaches `t_us` or is closed.
    fn wait_until(&self, t_us: u64) {
        let mut state = self.state();
        while state.now_us < t_us && !state.closed {
            state = self.0.1.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }
}

impl std::fmt::Debug for EmulatorClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("EmulatorClock")
            .field(&self.now_us())
            .finish()
    }
}

impl PartialEq for EmulatorClock {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Emulator configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorConfig {
    /// Which remote.
    pub variant: Variant,
    /// Seed: same seed → byte-identical stream.
    pub seed: u64,
    /// Data report rate (100 Hz on PCs, 200 Hz in sniff mode).
    pub report_rate_hz: f64,
    /// Delivery jitter, ± microseconds (uniform).
    pub jitter_us: u32,
    /// Probability of dropping a data report.
    pub drop_probability: f64,
    /// Deliver `k` reports at once every `k` ticks (Bluetooth burst), if set.
    pub burst: Option<u32>,
    /// MotionPlus activation/deactivation time, ms.
    pub activation_ms: u32,
    /// Send no status reports on MotionPlus activation (Dolphin PR #8626 case).
    pub drop_activation_status: bool,
    /// Garbage MotionPlus frames after activation.
    pub garbage_frames_after_activation: u32,
    /// The first N activations silently fail.
    pub activation_fails_n_times: u32,
    /// Pad input reports to 22 bytes like Windows.
    pub windows_padding: bool,
    /// Ack every output report, even without the ack bit.
    pub always_ack: bool,
    /// -TR quirk: extra unsolicited `22 .. RR 02` acks.
    pub error2_acks: bool,
    /// Deliver reports in real time (sleep until due) instead of instantly.
    pub realtime: bool,
    /// Deliver reports as this clock reaches them (takes precedence over `realtime`); the
    /// emulator's time starts at the clock's time when the remote is opened.
    pub clock: Option<EmulatorClock>,
    /// Battery level byte.
    pub battery: u8,
    /// Sensor error model.
    pub sensors: SensorModel,
    /// Emulates a remote the OS lists but refuses to open (the manager reports this as a
    /// [`crate::wiimote::RemoteProblem`] and retries); `None` opens normally.
    pub open_error: Option<crate::wiimote::OpenErrorKind>,
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            variant: Variant::Plus,
            seed: 1,
            report_rate_hz: 100.0,
            jitter_us: 2000,
            drop_probability: 0.0,
            burst: None,
            activation_ms: 50,
            drop_activation_status: false,
            garbage_frames_after_activation: 2,
            activation_fails_n_times: 0,
            windows_padding: false,
            always_ack: false,
            error2_acks: false,
            realtime: false,
            clock: None,
            battery: 0x68,
            sensors: SensorModel::default(),
            open_error: None,
        }
    }
}

/// Things a user (or test) does to the remote from outside while it runs: buttons, hot-plug,
/// power. Shared between threads.
#[derive(Clone)]
pub struct EmulatorControls(Arc<Mutex<ControlState>>);

struct ControlState {
    buttons: Buttons,
    nunchuk: Option<NunchukFrame>,
    motion_plus_plugged: bool,
    connected: bool,
    motion: Arc<dyn Motion>,
    generation: u64,
}

impl Default for EmulatorControls {
    fn default() -> Self {
        Self(Arc::new(Mutex::new(ControlState {
            buttons: Buttons(0),
            nunchuk: None,
            motion_plus_plugged: true,
            connected: true,
            motion: Arc::new(Still(DQuat::IDENTITY)),
            generation: 0,
        })))
    }
}

impl EmulatorControls {
    fn with<R>(&self, f: impl FnOnce(&mut ControlState) -> R) -> R {
        let mut g = self.0.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut g)
    }
    /// Sets the held buttons.
    pub fn set_buttons(&self, b: Buttons) {
        self.with(|s| s.buttons = b);
    }
    /// Current held buttons.
    pub fn buttons(&self) -> Buttons {
        self.with(|s| s.buttons)
    }
    /// Plugs (Some) or unplugs (None) a Nunchuk, with stick/buttons state.
    pub fn set_nunchuk(&self, n: Option<NunchukFrame>) {
        self.with(|s| s.nunchuk = n);
    }
    /// Plugs or unplugs the external MotionPlus (ignored by the -TR).
    pub fn set_motion_plus_plugged(&self, plugged: bool) {
        self.with(|s| s.motion_plus_plugged = plugged);
    }
    /// Powers the remote off (false) or on again (true). While off, I/O fails with
    /// [`TransportError::Disconnected`]; powering on starts a fresh connection.
    pub fn set_connected(&self, connected: bool) {
        self.with(|s| {
            if connected && !s.connected {
                s.generation += 1;
            }
            s.connected = connected;
        });
    }
    /// Whether the remote is powered and linked.
    pub fn connected(&self) -> bool {
        self.with(|s| s.connected)
    }
    /// Replaces the ground-truth motion (times continue on the emulator clock).
    pub fn set_motion(&self, m: Arc<dyn Motion>) {
        self.with(|s| s.motion = m);
    }
    /// The ground-truth motion.
    pub fn motion(&self) -> Arc<dyn Motion> {
        self.with(|s| s.motion.clone())
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum MpPhase {
    Absent,
    Inactive,
    Activating { until_us: u64, mode: u8, fail: bool },
    Active { mode: u8 },
    Deactivating { until_us: u64 },
}

/// Per-unit sensor constants drawn from the seed.
#[derive(Debug, Clone)]
struct Unit {
    gyro_rest: [f64; 3],
    gyro_k_slow: [f64; 3],
    gyro_k_fast: [f64; 3],
    gyro_bias: [f64; 3],
    gyro_temp: [f64; 3],
    gyro_mis: DMat3,
    accel_cal: AccelCalibration,
    accel_true_zero: [f64; 3],
    accel_true_span: [f64; 3],
    accel_mis: DMat3,
    mp_cal: MotionPlusCalibration,
}

impl Unit {
    fn draw(rng: &mut Rng, s: &SensorModel) -> Self {
        let k_slow = s.gyro_slow_counts_per_dps.unwrap_or_else(|| {
            [
                rng.range(14.2, 20.1),
                rng.range(14.2, 20.1),
                rng.range(14.2, 20.1),
            ]
        });
        let pol = if s.reversed { -1.0 } else { 1.0 };
        let gyro_k_slow = k_slow.map(|k| k * pol);
        let mut gyro_k_fast = [0.0; 3];
        for a in 0..3 {
            gyro_k_fast[a] = gyro_k_slow[a] / rng.range(3.6, 4.4);
        }
        let gyro_rest = [0; 3].map(|_: i32| rng.range(7100.0, 8100.0));
        let gyro_bias = [0; 3].map(|_: i32| rng.normal() * s.gyro_turn_on_bias_dps);
        let gyro_temp = [0; 3].map(|_: i32| {
            s.gyro_temperature_drift_dps
                * if rng.uniform() < 0.5 { -1.0 } else { 1.0 }
                * rng.range(0.3, 1.0)
        });
        let mis = |rng: &mut Rng, cross: f64, scale: f64| {
            let mut m = DMat3::IDENTITY;
            for c in 0..3 {
                for r in 0..3 {
                    let e = if r == c { scale } else { cross };
                    let v = m.col(c)[r] + rng.range(-e, e);
                    m.col_mut(c)[r] = v;
                }
            }
            m
        };
        // Gyro scale errors live in the calibration block; only cross-axis terms here.
        let gyro_mis = mis(rng, s.gyro_misalignment, 0.0);
        let accel_true_zero = [0; 3].map(|_: i32| 512.0 + rng.normal() * 6.0);
        let accel_true_span = [0; 3].map(|_: i32| rng.range(100.0, 111.0));
        let accel_cal = AccelCalibration {
            zero: std::array::from_fn(|a| {
                (accel_true_zero[a] + rng.range(-1.0, 1.0)).round() as u16
            }),
            one_g: std::array::from_fn(|a| {
                (accel_true_zero[a] + accel_true_span[a] + rng.range(-1.0, 1.0)).round() as u16
            }),
        };
        let accel_mis = mis(rng, s.accel_misalignment, s.accel_scale_error);
        // Calibration block: scale − zero = 4·k·degrees·sign (sign yaw −1, roll +1, pitch −1).
        let sign = [-1.0, 1.0, -1.0];
        let range = |k: [f64; 3], degrees: u16, uid: u8, rng: &mut Rng| {
            let mut zero = [0u16; 3];
            let mut scale = [0u16; 3];
            for a in 0..3 {
                let z = 4.0 * gyro_rest[a] + rng.normal() * s.gyro_block_zero_error;
                let err = 1.0 + rng.range(-s.gyro_block_scale_error, s.gyro_block_scale_error);
                let sc = z + 4.0 * k[a] * err * degrees as f64 * sign[a];
                zero[a] = z.round().clamp(0.0, 65535.0) as u16;
                scale[a] = sc.round().clamp(0.0, 65535.0) as u16;
            }
            GyroRange {
                zero,
                scale,
                degrees,
                uid,
            }
        };
        let fast = range(gyro_k_fast, 1200, 0x4F, rng);
        let slow = range(gyro_k_slow, 270, 0xE5, rng);
        Self {
            gyro_rest,
            gyro_k_slow,
            gyro_k_fast,
            gyro_bias,
            gyro_temp,
            gyro_mis,
            accel_cal,
            accel_true_zero,
            accel_true_span,
            accel_mis,
            mp_cal: MotionPlusCalibration { fast, slow },
        }
    }
}

const EEPROM_SIZE: usize = 0x1700;

struct PendingRead {
    chunks: VecDeque<Vec<u8>>,
}

/// The emulated remote. Implements [`Transport`]; give it to a session like a hidapi device.
pub struct EmulatedRemote {
    config: EmulatorConfig,
    controls: EmulatorControls,
    generation: u64,
    rng: Rng,
    unit: Unit,
    epoch: Instant,
    /// The pacing clock's time when this remote was opened.
    clock_origin: u64,
    now_us: u64,
    next_tick_us: u64,
    tick: u64,
    queue: VecDeque<(u64, Vec<u8>)>,
    eeprom: Vec<u8>,
    rumble: bool,
    leds: u8,
    mode: u8,
    continuous: bool,
    reporting_enabled: bool,
    mp: MpPhase,
    mp_last_mode: u8,
    mp_regs: [u8; 256],
    ext_initialized: bool,
    ext_line: bool,
    garbage_left: u32,
    activations_failed: u32,
    frame_counter: u64,
    read: Option<PendingRead>,
    gyro_slow: [bool; 3],
    bias_walk: [f64; 3],
    last_sensor_t: f64,
    was_mp_plugged: bool,
    was_nunchuk: bool,
    delivered: VecDeque<(u64, u64)>,
}

impl EmulatedRemote {
    /// Creates a powered-on remote with its own controls.
    pub fn new(config: EmulatorConfig) -> Self {
        Self::with_controls(config, EmulatorControls::default())
    }

    /// Creates a remote driven by shared `controls` (several transports opened over time —
    /// reconnects — share one set of controls).
    pub fn with_controls(config: EmulatorConfig, controls: EmulatorControls) -> Self {
        let mut rng = Rng::new(config.seed);
        let unit = Unit::draw(&mut rng, &config.sensors);
        let mut eeprom = vec![0u8; EEPROM_SIZE];
        let block = unit.accel_cal.encode();
        eeprom[0x16..0x20].copy_from_slice(&block);
        eeprom[0x20..0x2A].copy_from_slice(&block);
        let ir = [
            0x5A, 0x00, 0x82, 0x8E, 0x5E, 0x00, 0x00, 0x7A, 0x20, 0xB4, 0x00,
        ];
        eeprom[0..11].copy_from_slice(&ir);
        eeprom[0x0B..0x16].copy_from_slice(&ir);
        let generation = controls.with(|s| s.generation);
        let mut this = Self {
            controls,
            generation,
            rng,
            unit,
            epoch: Instant::now(),
            clock_origin: config.clock.as_ref().map_or(0, EmulatorClock::now_us),
            now_us: 0,
            next_tick_us: 0,
            tick: 0,
            queue: VecDeque::new(),
            eeprom,
            rumble: false,
            leds: 0,
            mode: 0x30,
            continuous: false,
            reporting_enabled: true,
            mp: MpPhase::Absent,
            mp_last_mode: 0,
            mp_regs: [0; 256],
            ext_initialized: false,
            ext_line: false,
            garbage_left: 0,
            activations_failed: 0,
            frame_counter: 0,
            read: None,
            gyro_slow: [true; 3],
            bias_walk: [0.0; 3],
            last_sensor_t: 0.0,
            was_mp_plugged: false,
            was_nunchuk: false,
            delivered: VecDeque::new(),
            config,
        };
        this.power_on();
        this
    }

    fn power_on(&mut self) {
        self.mode = 0x30;
        self.continuous = false;
        self.reporting_enabled = true;
        self.leds = 0;
        self.rumble = false;
        self.read = None;
        self.queue.clear();
        self.ext_initialized = false;
        let mp_plugged = self.has_mp_hardware();
        self.mp = if mp_plugged {
            MpPhase::Inactive
        } else {
            MpPhase::Absent
        };
        self.mp_last_mode = 0;
        self.was_mp_plugged = mp_plugged;
        self.was_nunchuk = self.controls.with(|s| s.nunchuk.is_some());
        self.ext_line = self.compute_ext_line();
        self.next_tick_us = self.now_us + self.period_us();
    }

    fn has_mp_hardware(&self) -> bool {
        match self.config.variant {
            Variant::Plus => true,
            Variant::Original { motion_plus } => {
                motion_plus && self.controls.with(|s| s.motion_plus_plugged)
            }
            Variant::BalanceBoard => false,
        }
    }

    /// The shared controls.
    pub fn controls(&self) -> &EmulatorControls {
        &self.controls
    }

    /// The MotionPlus calibration block this unit reports.
    pub fn motion_plus_calibration(&self) -> MotionPlusCalibration {
        self.unit.mp_cal
    }

    /// The accelerometer calibration stored in EEPROM.
    pub fn accel_calibration(&self) -> AccelCalibration {
        self.unit.accel_cal
    }

    /// True orientation at the current virtual time.
    pub fn true_orientation(&self) -> DQuat {
        self.controls
            .motion()
            .orientation(self.now_us as f64 * 1e-6)
    }

    /// True gyro bias (deg/s, x = pitch, y = roll, z = yaw) at the current time.
    pub fn true_gyro_bias(&self) -> DVec3 {
        let t = self.now_us as f64 * 1e-6;
        let b = self.bias_dps(t);
        DVec3::new(b[2], b[1], b[0])
    }

    /// Whether the MotionPlus is active (for tests).
    pub fn motion_plus_active(&self) -> bool {
        matches!(self.mp, MpPhase::Active { .. })
    }

    /// Sensor sampling time (µs) of the data report delivered at `delivery_us`, for the most
    /// recent 256 data reports. Lets benchmarks compare estimates with the truth at the
    /// instant the sensors were sampled, not when the report arrived.
    pub fn sample_time_of(&self, delivery_us: u64) -> Option<u64> {
        self.delivered
            .iter()
            .rev()
            .find(|(d, _)| *d == delivery_us)
            .map(|(_, s)| *s)
    }

    /// Current LED bits.
    pub fn leds(&self) -> u8 {
        self.leds
    }

    /// Current rumble state.
    pub fn rumble(&self) -> bool {
        self.rumble
    }

    /// Current data reporting mode and whether reporting is enabled.
    pub fn reporting(&self) -> (u8, bool, bool) {
        (self.mode, self.continuous, self.reporting_enabled)
    }

    fn period_us(&self) -> u64 {
        (1e6 / self.config.report_rate_hz.max(1.0)) as u64
    }

    fn compute_ext_line(&self) -> bool {
        let nunchuk = self.controls.with(|s| s.nunchuk.is_some());
        match self.mp {
            MpPhase::Active { .. } => true,
            MpPhase::Activating { .. } | MpPhase::Deactivating { .. } => false,
            _ => nunchuk || self.config.variant == Variant::BalanceBoard,
        }
    }

    fn buttons(&self) -> Buttons {
        self.controls.buttons()
    }

    fn push(&mut self, at_us: u64, mut report: Vec<u8>) {
        if self.config.windows_padding && report.len() < 22 {
            report.resize(22, 0);
        }
        self.queue.push_back((at_us, report));
    }

    fn status_report(&self) -> Vec<u8> {
        let b = self.buttons().to_bytes();
        let lf = (self.ext_line as u8) << 1 | (self.leds << 4) | (self.config.battery < 0x20) as u8;
        vec![0x20, b[0], b[1], lf, 0, 0, self.config.battery]
    }

    fn ack(&mut self, report: u8, error: u8) {
        let b = self.buttons().to_bytes();
        let at = self.now_us + 1000;
        self.push(at, vec![0x22, b[0], b[1], report, error]);
    }

    fn update_ext_line(&mut self, send_status: bool) {
        let line = self.compute_ext_line();
        if line != self.ext_line {
            self.ext_line = line;
            if send_status {
                let at = self.now_us + 500;
                let r = self.status_report();
                self.push(at, r);
                self.reporting_enabled = false;
            }
        }
    }

    /// Advances state machines (activation timers, hot-plug) to `now_us`.
    fn advance_state(&mut self) {
        let gen_now = self.controls.with(|s| s.generation);
        if gen_now != self.generation {
            self.generation = gen_now;
            self.power_on();
        }
        // Hot-plug of the external MotionPlus and Nunchuk.
        let mp_plugged = self.has_mp_hardware();
        if mp_plugged != self.was_mp_plugged {
            self.was_mp_plugged = mp_plugged;
            if !mp_plugged {
                self.mp = MpPhase::Absent;
                self.update_ext_line(true);
            } else {
                self.mp = MpPhase::Inactive; // no status report: poll to find it
            }
        }
        let nunchuk = self.controls.with(|s| s.nunchuk.is_some());
        if nunchuk != self.was_nunchuk {
            self.was_nunchuk = nunchuk;
            if !nunchuk {
                self.ext_initialized = false;
            }
            // While the MotionPlus is active, pass-through hot-plug shows only in E4 bit0.
            if !matches!(self.mp, MpPhase::Active { .. }) {
                self.update_ext_line(true);
            }
        }
        match self.mp {
            MpPhase::Activating {
                until_us,
                mode,
                fail,
            } if self.now_us >= until_us => {
                if fail {
                    self.mp = MpPhase::Inactive;
                } else {
                    self.mp = MpPhase::Active { mode };
                    self.mp_last_mode = mode;
                    self.garbage_left = self.config.garbage_frames_after_activation;
                }
                let quiet = self.config.drop_activation_status;
                self.update_ext_line(!quiet);
            }
            MpPhase::Deactivating { until_us } if self.now_us >= until_us => {
                self.mp = MpPhase::Inactive;
                self.ext_initialized = false;
                self.update_ext_line(true);
            }
            _ => {}
        }
    }

    fn mp_id(&self, active: bool) -> [u8; 6] {
        let first = if self.config.variant == Variant::Plus {
            0x01
        } else {
            0x00
        };
        match self.mp {
            MpPhase::Active { mode } if active => [first, 0, 0xA4, 0x20, mode, 0x05],
            _ => [first, 0, 0xA6, 0x20, self.mp_last_mode, 0x05],
        }
    }

    /// Register read: Ok(bytes) or Err(error code).
    fn read_registers(&mut self, slave: u8, offset: u8, size: usize) -> Result<Vec<u8>, u8> {
        let slave = slave & 0xFE;
        let mut regs = [0u8; 256];
        match slave {
            0xA0 => return Err(8),
            0xA6 => {
                if self.mp != MpPhase::Inactive {
                    return Err(7);
                }
                regs = self.mp_regs;
                regs[0x20..0x40].copy_from_slice(&self.unit.mp_cal.encode());
                regs[0xFA..].copy_from_slice(&self.mp_id(false));
            }
            0xA4 => match self.mp {
                MpPhase::Active { .. } => {
                    regs = self.mp_regs;
                    regs[0x20..0x40].copy_from_slice(&self.unit.mp_cal.encode());
                    regs[0xFA..].copy_from_slice(&self.mp_id(true));
                }
                MpPhase::Activating { .. } | MpPhase::Deactivating { .. } => return Err(7),
                _ => {
                    if self.config.variant == Variant::BalanceBoard {
                        regs[0xFA..].copy_from_slice(&[0, 0, 0xA4, 0x20, 0x04, 0x02]);
                    } else if self.controls.with(|s| s.nunchuk.is_some()) {
                        if self.ext_initialized {
                            regs[0xFA..].copy_from_slice(&[0, 0, 0xA4, 0x20, 0, 0]);
                        } else {
                            regs[0xFA..].copy_from_slice(&[0xFF; 6]);
                        }
                    } else {
                        return Err(7);
                    }
                }
            },
            0xB0 | 0xA2 => {}
            _ => return Err(7),
        }
        let start = offset as usize;
        if start + size > 256 {
            return Err(8);
        }
        Ok(regs[start..start + size].to_vec())
    }

    fn write_registers(&mut self, slave: u8, offset: u8, data: &[u8]) -> u8 {
        let slave = slave & 0xFE;
        let v = data.first().copied().unwrap_or(0);
        match slave {
            0xA0 => 8,
            0xA6 => {
                if self.mp != MpPhase::Inactive {
                    return 7;
                }
                if offset == 0xFE && data.len() == 1 && matches!(v, 0x04 | 0x05 | 0x07) {
                    let fail = self.activations_failed < self.config.activation_fails_n_times;
                    if fail {
                        self.activations_failed += 1;
                    }
                    self.mp = MpPhase::Activating {
                        until_us: self.now_us + self.config.activation_ms as u64 * 1000,
                        mode: v,
                        fail,
                    };
                    let quiet = self.config.drop_activation_status;
                    self.update_ext_line(!quiet);
                } else {
                    for (i, b) in data.iter().enumerate() {
                        if let Some(r) = self.mp_regs.get_mut(offset as usize + i) {
                            *r = *b;
                        }
                    }
                }
                0
            }
            0xA4 => match self.mp {
                MpPhase::Active { .. } => {
                    if (offset == 0xF0 && v == 0x55)
                        || (offset == 0xFE && !matches!(v, 0x04 | 0x05 | 0x07))
                    {
                        self.mp = MpPhase::Deactivating {
                            until_us: self.now_us + self.config.activation_ms as u64 * 1000,
                        };
                        self.update_ext_line(true);
                    } else if offset == 0xFE {
                        self.mp = MpPhase::Active { mode: v };
                        self.mp_last_mode = v;
                    }
                    0
                }
                MpPhase::Activating { .. } | MpPhase::Deactivating { .. } => 7,
                _ => {
                    let present = self.controls.with(|s| s.nunchuk.is_some())
                        || self.config.variant == Variant::BalanceBoard;
                    if !present {
                        return 7;
                    }
                    if offset == 0xF0 && v == 0x55 {
                        self.ext_initialized = true;
                    }
                    0
                }
            },
            0xB0 | 0xA2 => 0,
            _ => 7,
        }
    }

    fn handle_output(&mut self, report: &[u8]) {
        if let Some(&f) = report.get(1)
            && report[0] != 0x18
        {
            self.rumble = f & 1 != 0;
        }
        let decoded = OutputReport::decode(report);
        let id = report.first().copied().unwrap_or(0);
        if self.config.error2_acks && id != 0x10 && self.rng.uniform() < 0.2 {
            self.ack(id, 2);
        }
        let (ack_requested, error) = match decoded {
            Err(_) => {
                if id == 0x16 || id == 0x17 {
                    self.ack(id, 6);
                }
                return;
            }
            Ok(OutputReport::Rumble { .. }) => return,
            Ok(OutputReport::Leds { leds, ack, .. }) => {
                self.leds = leds;
                (ack, 0)
            }
            Ok(OutputReport::ReportMode {
                mode,
                continuous,
                ack,
                ..
            }) => {
                if !matches!(mode, 0x30..=0x3F) {
                    return; // invalid mode: whole report ignored
                }
                self.mode = mode;
                self.continuous = continuous;
                self.reporting_enabled = true;
                (ack, 0)
            }
            Ok(OutputReport::Flag { ack, .. }) => (ack, 0),
            Ok(OutputReport::StatusRequest { .. }) => {
                let at = self.now_us + 1000;
                let r = self.status_report();
                self.push(at, r);
                self.reporting_enabled = false;
                return;
            }
            Ok(OutputReport::WriteMemory {
                space,
                address,
                data,
                ..
            }) => {
                if data.is_empty() || data.len() > 16 {
                    return; // silently ignored, no ack
                }
                let error = match space {
                    AddressSpace::Eeprom => {
                        let a = address as usize;
                        if a + data.len() > EEPROM_SIZE {
                            8
                        } else {
                            self.eeprom[a..a + data.len()].copy_from_slice(&data);
                            0
                        }
                    }
                    AddressSpace::Registers => {
                        self.write_registers((address >> 16) as u8, address as u8, &data)
                    }
                };
                self.ack(0x16, error);
                return;
            }
            Ok(OutputReport::ReadMemory {
                space,
                address,
                size,
                ..
            }) => {
                if size == 0 {
                    return;
                }
                if self.read.is_some() {
                    self.ack(0x17, 4);
                    return;
                }
                let size = size as usize;
                let result = match space {
                    AddressSpace::Eeprom => {
                        let a = address as usize;
                        if a + size > EEPROM_SIZE {
                            Err(8)
                        } else {
                            Ok(self.eeprom[a..a + size].to_vec())
                        }
                    }
                    AddressSpace::Registers => {
                        self.read_registers((address >> 16) as u8, address as u8, size)
                    }
                };
                let b = self.buttons().to_bytes();
                let lo = address as u16;
                let mut chunks = VecDeque::new();
                match result {
                    Err(code) => {
                        let mut r = vec![0x21, b[0], b[1], 0xF0 | code];
                        r.extend_from_slice(&lo.to_be_bytes());
                        r.resize(22, 0);
                        chunks.push_back(r);
                    }
                    Ok(data) => {
                        for (i, c) in data.chunks(16).enumerate() {
                            let mut r = vec![0x21, b[0], b[1], ((c.len() as u8 - 1) << 4)];
                            r.extend_from_slice(&(lo.wrapping_add(16 * i as u16)).to_be_bytes());
                            r.extend_from_slice(c);
                            r.resize(22, 0);
                            chunks.push_back(r);
                        }
                    }
                }
                self.read = Some(PendingRead { chunks });
                return;
            }
            Ok(OutputReport::SpeakerData) => return,
        };
        if ack_requested || self.config.always_ack {
            self.ack(id, error);
        }
    }

    fn bias_dps(&self, t: f64) -> [f64; 3] {
        let ramp = (t / 600.0).min(1.0);
        std::array::from_fn(|a| {
            self.unit.gyro_bias[a] + self.bias_walk[a] + self.unit.gyro_temp[a] * ramp
        })
    }

    fn gyro_frame(&mut self, t: f64, motion: &dyn Motion, ext_connected: bool) -> MotionPlusFrame {
        let s = &self.config.sensors;
        let dt = (t - self.last_sensor_t).max(0.0);
        self.last_sensor_t = t;
        for b in &mut self.bias_walk {
            *b += self.rng.normal() * s.gyro_bias_walk * dt.sqrt();
        }
        let w =
            self.unit.gyro_mis * (motion::body_rate(motion, t) * (180.0 / std::f64::consts::PI));
        let bias = self.bias_dps(t);
        // Frame axis order: yaw (z), roll (y), pitch (x).
        let rates = [w.z, w.y, w.x];
        let noise_scale = (self.config.report_rate_hz / 100.0).sqrt();
        let mut raw = [0u16; 3];
        for a in 0..3 {
            let rate = rates[a] + bias[a] + self.rng.normal() * s.gyro_noise_dps * noise_scale;
            let slow_limit = 8191.0 / self.unit.gyro_k_slow[a].abs();
            let threshold = slow_limit.min(440.0);
            if self.gyro_slow[a] && rate.abs() > threshold {
                self.gyro_slow[a] = false;
            } else if !self.gyro_slow[a] && rate.abs() < threshold * 0.9 {
                self.gyro_slow[a] = true;
            }
            let k = if self.gyro_slow[a] {
                self.unit.gyro_k_slow[a]
            } else {
                self.unit.gyro_k_fast[a]
            };
            let counts = (self.unit.gyro_rest[a] + k * rate).round();
            raw[a] = counts.clamp(0.0, 16383.0) as u16;
        }
        MotionPlusFrame {
            yaw: raw[0],
            roll: raw[1],
            pitch: raw[2],
            slow: self.gyro_slow,
            extension_connected: ext_connected,
        }
    }

    fn accel(&mut self, t: f64, motion: &dyn Motion) -> AccelRaw {
        let s = &self.config.sensors;
        let f = self.unit.accel_mis * motion::specific_force_g(motion, t);
        let mut raw = [0u16; 3];
        for a in 0..3 {
            let g = (f[a] + self.rng.normal() * s.accel_noise_g).clamp(-3.6, 3.6);
            let counts = (self.unit.accel_true_zero[a] + self.unit.accel_true_span[a] * g).round();
            let mut c = counts.clamp(0.0, 1023.0) as u16;
            if a > 0 {
                c &= !1;
            }
            raw[a] = c;
        }
        AccelRaw(raw)
    }

    fn data_report(&mut self, sample_t: f64) -> Vec<u8> {
        let motion = self.controls.motion();
        let buttons = self.buttons();
        let accel = self.accel(sample_t, &*motion);
        let nunchuk = self.controls.with(|s| s.nunchuk);
        let ext: [u8; 6] = match self.mp {
            MpPhase::Active { mode } => {
                self.frame_counter += 1;
                let passthrough =
                    mode != 0x04 && nunchuk.is_some() && self.frame_counter.is_multiple_of(2);
                let gyro = self.gyro_frame(sample_t, &*motion, nunchuk.is_some());
                if self.garbage_left > 0 {
                    self.garbage_left -= 1;
                    let mut g = [0u8; 6];
                    for b in &mut g {
                        *b = self.rng.next_u64() as u8;
                    }
                    g[5] = (g[5] | 0x02) & !0x01;
                    g
                } else if passthrough {
                    nunchuk
                        .map(|n| n.encode_passthrough(true))
                        .unwrap_or([0; 6])
                } else {
                    gyro.encode()
                }
            }
            _ => match nunchuk {
                Some(n) if self.ext_initialized => n.encode_direct(),
                _ => [0xFF; 6],
            },
        };
        let ba = encode_buttons_accel(buttons, accel);
        let bb = buttons.to_bytes();
        let mut r = vec![self.mode];
        match self.mode {
            0x30 => r.extend_from_slice(&bb),
            0x31 => r.extend_from_slice(&ba),
            0x32 => {
                r.extend_from_slice(&bb);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 2]);
            }
            0x33 => {
                r.extend_from_slice(&ba);
                r.extend_from_slice(&[0xFF; 12]);
            }
            0x34 => {
                r.extend_from_slice(&bb);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 13]);
            }
            0x35 => {
                r.extend_from_slice(&ba);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 10]);
            }
            0x36 => {
                r.extend_from_slice(&bb);
                r.extend_from_slice(&[0xFF; 10]);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 3]);
            }
            0x37 => {
                r.extend_from_slice(&ba);
                r.extend_from_slice(&[0xFF; 10]);
                r.extend_from_slice(&ext);
            }
            _ => {
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 15]);
            }
        }
        r
    }

    /// Runs one report slot at `self.next_tick_us`.
    fn run_tick(&mut self) {
        let nominal = self.next_tick_us;
        self.tick += 1;
        self.next_tick_us = nominal + self.period_us();
        let jitter = if self.config.jitter_us > 0 {
            self.rng.range(0.0, self.config.jitter_us as f64 * 2.0) as u64
        } else {
            0
        };
        let deliver = match self.config.burst {
            Some(k) if k > 1 => {
                let k = k as u64;
                nominal + (k - 1 - (self.tick - 1) % k) * self.period_us() + jitter
            }
            _ => nominal + jitter,
        };
        if let Some(read) = &mut self.read {
            if let Some(chunk) = read.chunks.pop_front() {
                self.push(nominal + 500, chunk);
            }
            if self.read.as_ref().is_some_and(|r| r.chunks.is_empty()) {
                self.read = None;
            }
            return;
        }
        if !self.reporting_enabled || self.mode == 0x30 && !self.continuous {
            return;
        }
        let sample_t = nominal as f64 * 1e-6;
        let report = self.data_report(sample_t);
        if self.config.drop_probability > 0.0 && self.rng.uniform() < self.config.drop_probability {
            return;
        }
        if self.delivered.len() >= 256 {
            self.delivered.pop_front();
        }
        self.delivered.push_back((deliver, nominal));
        self.push(deliver, report);
    }

    fn wait_until(&self, t_us: u64) {
        if let Some(clock) = &self.config.clock {
            clock.wait_until(self.clock_origin + t_us);
        } else if self.config.realtime {
            let target = std::time::Duration::from_micros(t_us);
            let now = self.epoch.elapsed();
            if target > now {
                std::thread::sleep(target - now);
            }
        }
    }
}

impl Transport for EmulatedRemote {
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
        if !self.controls.connected() {
            return Err(TransportError::Disconnected);
        }
        if let Some(clock) = &self.config.clock {
            let now = clock.now_us().saturating_sub(self.clock_origin);
            self.now_us = self.now_us.max(now);
        } else if self.config.realtime {
            self.now_us = self.now_us.max(self.epoch.elapsed().as_micros() as u64);
        }
        self.advance_state();
        self.handle_output(report);
        Ok(report.len())
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError> {
        let deadline = self.now_us + timeout_ms as u64 * 1000;
        loop {
            if !self.controls.connected() {
                return Err(TransportError::Disconnected);
            }
            self.advance_state();
            // Earliest queued report, next report slot, next state timer.
            let earliest = self
                .queue
                .iter()
                .enumerate()
                .min_by_key(|(_, (t, _))| *t)
                .map(|(i, (t, _))| (i, *t));
            let mut next = self.next_tick_us;
            if let MpPhase::Activating { until_us, .. } | MpPhase::Deactivating { until_us } =
                self.mp
            {
                next = next.min(until_us);
            }
            if let Some((_, t)) = earliest {
                next = next.min(t);
            }
            if next > deadline {
                self.wait_until(deadline);
                self.now_us = self.now_us.max(deadline);
                return Ok(0);
            }
            self.wait_until(next);
            self.now_us = self.now_us.max(next);
            match earliest {
                Some((i, t)) if t <= next => {
                    let (_, r) = self.queue.remove(i).expect("index from iter");
                    let n = r.len().min(buf.len());
                    buf[..n].copy_from_slice(&r[..n]);
                    return Ok(n);
                }
                _ => {}
            }
            if next == self.next_tick_us {
                self.run_tick();
            }
        }
    }

    fn now_us(&self) -> u64 {
        self.now_us
    }
}
