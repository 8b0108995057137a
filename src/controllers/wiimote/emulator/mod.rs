//! A software Wii Remote (original with external MotionPlus, or Remote Plus "-TR") that speaks
//! the real byte protocol behind the [`Transport`] trait. Sensors are synthesised from a
//! ground-truth [`Motion`] with the error model of `PROTOCOL.md` §13.3, on a deterministic
//! virtual clock, in real time (demos), or paced by an [`EmulatorClock`] the app advances
//! (tests that step time by hand).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `config.rs` | What is emulated: the remote's variant, its sensor error model and the emulator's settings. |
//! | `reports.rs` | How the emulated remote answers the host: output reports, register reads and writes, the MotionPlus activation sequence, status reports and acknowledgements (`PROTOCOL.md`). |
//! | `sensors.rs` | The emulated sensors: per-unit constants drawn from the seed and the gyro, accelerometer and data reports synthesised from the ground-truth motion with the error model of `PROTOCOL.md` §13.3. |
//!
//! Where things are: `mod.rs` — the remote, its timeline and the [`Transport`] side;
//! `config.rs` — variant, sensor error model, settings; `sensors.rs` — per-unit constants and
//! the synthesised gyro/accelerometer data reports; `reports.rs` — answering output reports,
//! registers and the MotionPlus activation. Buttons, hot-plug and power from outside
//! ([`EmulatorControls`]) and pacing by the app's time ([`EmulatorClock`]) are shared with
//! the pads' emulators: `crate::controllers::emulation`.
//!
//! [`Motion`]: crate::controllers::motion::Motion
//! [`EmulatorClock`]: crate::controllers::emulation::EmulatorClock

use std::collections::VecDeque;

use glam::{DQuat, DVec3};

use super::protocol::{AccelCalibration, Buttons, MotionPlusCalibration};
use crate::controllers::emulation::{EmulatorControls, Pacing};
use crate::controllers::rng::Rng;
use crate::controllers::transport::{Transport, TransportError};
use reports::{EEPROM_SIZE, MpPhase, PendingRead};
use sensors::Unit;

mod config;
mod reports;
mod sensors;

pub use config::{EmulatedBar, EmulatorConfig, SensorModel, Variant};

/// The emulated remote. Implements [`Transport`]; give it to a session like a hidapi device.
pub struct EmulatedRemote {
    config: EmulatorConfig,
    controls: EmulatorControls,
    generation: u64,
    rng: Rng,
    unit: Unit,
    /// How its time meets the world's.
    pacing: Pacing,
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
    /// The IR camera's registers (0xB0xxxx), as the host wrote them.
    camera_regs: [u8; 256],
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
            pacing: Pacing::new(config.clock.clone(), config.realtime),
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
            camera_regs: [0; 256],
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

    fn buttons(&self) -> Buttons {
        self.controls.buttons()
    }

    fn push(&mut self, at_us: u64, mut report: Vec<u8>) {
        if self.config.windows_padding && report.len() < 22 {
            report.resize(22, 0);
        }
        self.queue.push_back((at_us, report));
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
        self.pacing.wait_until(t_us);
    }
}

impl Transport for EmulatedRemote {
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
        if !self.controls.connected() {
            return Err(TransportError::Disconnected);
        }
        if let Some(now) = self.pacing.now_us() {
            self.now_us = self.now_us.max(now);
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
