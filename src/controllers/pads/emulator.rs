//! [`EmulatedPad`]: a DualSense, DualShock 4, Switch Pro or Joy-Con that answers the host's
//! start sequence and calibration reads and streams its reports from a motion script, byte
//! for byte, with the device's rate, quantisation, noise and bias.

use std::collections::VecDeque;

use glam::DVec3;

use crate::controllers::emulation::{EmulatorClock, EmulatorControls, Pacing};
use crate::controllers::motion::{self, Motion};
use crate::controllers::rng::Rng;
use crate::controllers::sony::{self, emulate::SonyUnit};
use crate::controllers::switch::{self, emulate::SwitchUnit};
use crate::controllers::transport::{Transport, TransportError};
use crate::controllers::{ControllerKind, Link};

use super::roles_from_wii;

/// One device's sensor error model and report timing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadSensorModel {
    /// Time between input reports, s.
    pub report_interval_s: f64,
    /// Sensor samples per report (3 on the Switch, spread evenly over the interval).
    pub samples_per_report: usize,
    /// Gyro white noise per sample, deg/s (1σ).
    pub gyro_noise_dps: f64,
    /// Gyro bias at power-on, deg/s (1σ per axis).
    pub gyro_turn_on_bias_dps: f64,
    /// Gyro bias random walk, deg/s per √s.
    pub gyro_bias_walk_dps: f64,
    /// Accelerometer white noise per sample, g (1σ).
    pub accel_noise_g: f64,
    /// Largest scale error of a unit, relative (its factory calibration describes it).
    pub scale_error: f64,
    /// A faulty unit: this body axis (0 X, 1 Y, 2 Z) reads reversed. Tests use it to show an
    /// axis mix-up is caught.
    pub reversed_axis: Option<usize>,
}

impl PadSensorModel {
    /// The model of `kind` over `link`: Sony pads 250 reports/s; Switch controllers a full
    /// report every 15 ms over Bluetooth (8 ms over USB) with three samples each. Noise and
    /// bias from the parts' datasheets (BMI-class and LSM6DS3-class IMUs), see
    /// `docs/PROTOCOL-SONY.md` §6 and `docs/PROTOCOL-SWITCH.md` §6.
    pub fn for_device(kind: ControllerKind, link: Link) -> Self {
        match kind {
            ControllerKind::DualShock4 => Self {
                report_interval_s: 1.0 / 250.0,
                samples_per_report: 1,
                gyro_noise_dps: 0.12,
                gyro_turn_on_bias_dps: 0.8,
                gyro_bias_walk_dps: 0.004,
                accel_noise_g: 0.002,
                scale_error: 0.03,
                reversed_axis: None,
            },
            ControllerKind::SwitchPro
            | ControllerKind::JoyConLeft
            | ControllerKind::JoyConRight => Self {
                report_interval_s: if link == Link::Usb { 0.008 } else { 0.015 },
                samples_per_report: 3,
                gyro_noise_dps: 0.07,
                gyro_turn_on_bias_dps: 0.5,
                gyro_bias_walk_dps: 0.004,
                accel_noise_g: 0.001,
                scale_error: 0.03,
                reversed_axis: None,
            },
            // DualSense, DualSense Edge (and, unused, the Wii Remote).
            _ => Self {
                report_interval_s: 1.0 / 250.0,
                samples_per_report: 1,
                gyro_noise_dps: 0.08,
                gyro_turn_on_bias_dps: 0.5,
                gyro_bias_walk_dps: 0.004,
                accel_noise_g: 0.0018,
                scale_error: 0.03,
                reversed_axis: None,
            },
        }
    }

    /// Sensor samples per second.
    pub fn sample_rate_hz(&self) -> f64 {
        self.samples_per_report as f64 / self.report_interval_s
    }
}

/// What is emulated and how.
#[derive(Debug, Clone, PartialEq)]
pub struct PadEmulatorConfig {
    /// The device.
    pub kind: ControllerKind,
    /// Its link.
    pub link: Link,
    /// Seed of the unit's constants and noise.
    pub seed: u64,
    /// Sensor model ([`PadSensorModel::for_device`] by default).
    pub sensors: PadSensorModel,
    /// Deliver reports in real time (apps) rather than as fast as they are read (tests).
    pub realtime: bool,
    /// Deliver reports as this clock reaches them (takes precedence over `realtime`).
    pub clock: Option<EmulatorClock>,
    /// Battery charge, %.
    pub battery_percent: u8,
}

impl PadEmulatorConfig {
    /// `kind` over `link` with its default sensor model, seed 1, virtual time.
    pub fn new(kind: ControllerKind, link: Link) -> Self {
        Self {
            kind,
            link,
            seed: 1,
            sensors: PadSensorModel::for_device(kind, link),
            realtime: false,
            clock: None,
            battery_percent: 80,
        }
    }
}

enum Unit {
    Sony(SonyUnit),
    Switch(SwitchUnit),
}

/// An emulated pad, used as a [`Transport`].
pub struct EmulatedPad {
    config: PadEmulatorConfig,
    controls: EmulatorControls,
    unit: Unit,
    rng: Rng,
    bias_dps: DVec3,
    now_us: u64,
    next_report_us: u64,
    pacing: Pacing,
    full_mode: bool,
    imu_on: bool,
    queue: VecDeque<Vec<u8>>,
    seq: u8,
    output: Option<sony::SonyOutput>,
    refused_outputs: u32,
}

impl EmulatedPad {
    /// A pad with fresh controls (held still, face up).
    pub fn new(config: PadEmulatorConfig) -> Self {
        Self::with_controls(config, EmulatorControls::default())
    }

    /// A pad driven by `controls` (motion, buttons — Wii names for the roles: B clutch, A
    /// grab, Home recentre, 1 calibrate — and the connection).
    pub fn with_controls(config: PadEmulatorConfig, controls: EmulatorControls) -> Self {
        let mut rng = Rng::new(config.seed);
        let unit = if switch::is_switch(config.kind) {
            Unit::Switch(SwitchUnit::draw(&mut rng, config.sensors.scale_error))
        } else {
            Unit::Sony(SonyUnit::draw(&mut rng, config.sensors.scale_error))
        };
        let sigma = config.sensors.gyro_turn_on_bias_dps;
        let bias_dps = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
        // Sony pads stream at once over USB; over Bluetooth they stream the reduced report
        // until the calibration is read. Switch controllers wait for their mode.
        let full_mode = !switch::is_switch(config.kind) && config.link == Link::Usb;
        Self {
            controls,
            unit,
            rng,
            bias_dps,
            now_us: 0,
            next_report_us: (config.sensors.report_interval_s * 1e6) as u64,
            pacing: Pacing::new(config.clock.clone(), config.realtime),
            full_mode,
            imu_on: false,
            queue: VecDeque::new(),
            seq: 0,
            output: None,
            refused_outputs: 0,
            config,
        }
    }

    /// The controls (motion, buttons, connection).
    pub fn controls(&self) -> EmulatorControls {
        self.controls.clone()
    }

    /// The configuration.
    pub fn config(&self) -> &PadEmulatorConfig {
        &self.config
    }

    /// What the last output report a Sony pad took set (rumble, light bar, player lights).
    pub fn last_output(&self) -> Option<sony::SonyOutput> {
        self.output
    }

    /// Output reports a Sony pad refused (wrong id, short, or a Bluetooth CRC that does not
    /// match: a real pad ignores them).
    pub fn refused_outputs(&self) -> u32 {
        self.refused_outputs
    }

    /// The gyro bias the unit has right now (body frame, deg/s): ground truth for tests.
    pub fn true_bias_dps(&self) -> DVec3 {
        self.bias_dps
    }

    /// Body-frame rate (deg/s) and specific force (g) the sensors read at `t`, errors
    /// included.
    fn sense(&mut self, m: &dyn Motion, t: f64) -> (DVec3, DVec3) {
        let s = self.config.sensors;
        let noise = |rng: &mut Rng, sigma: f64| {
            DVec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma
        };
        let mut w = motion::body_rate(m, t) * (180.0 / std::f64::consts::PI) + self.bias_dps;
        w += noise(&mut self.rng, s.gyro_noise_dps);
        let mut f = motion::specific_force_g(m, t) + noise(&mut self.rng, s.accel_noise_g);
        if let Some(axis) = s.reversed_axis.filter(|&a| a < 3) {
            w[axis] = -w[axis];
            f[axis] = -f[axis];
        }
        (w, f)
    }

    fn report(&mut self, t_report: f64) {
        let s = self.config.sensors;
        let kind = self.config.kind;
        let link = self.config.link;
        let buttons = roles_from_wii(self.controls.buttons());
        let m = self.controls.motion();
        let walk = s.gyro_bias_walk_dps * s.report_interval_s.sqrt();
        self.bias_dps += DVec3::new(self.rng.normal(), self.rng.normal(), self.rng.normal()) * walk;
        self.seq = self.seq.wrapping_add(1);
        let count = |v: f64| v.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16;
        let mut out = Vec::with_capacity(80);
        match &self.unit {
            Unit::Sony(unit) => {
                if !self.full_mode {
                    sony::emulate::encode_reduced(&buttons, &mut out);
                } else {
                    let unit = unit.clone();
                    let (w, f) = self.sense(m.as_ref(), t_report);
                    let (w, f) = (sony::emulate::to_native(w), sony::emulate::to_native(f));
                    let ticks = if kind == ControllerKind::DualShock4 {
                        ((t_report * 3.0e6 / 16.0).round() as u64 & 0xFFFF) as u32
                    } else {
                        ((t_report * 3.0e6).round() as u64 & 0xFFFF_FFFF) as u32
                    };
                    let raw = sony::emulate::SonyRaw {
                        gyro: [0, 1, 2].map(|a| count(w[a] * unit.gyro_counts_per_dps[a])),
                        accel: [0, 1, 2]
                            .map(|a| count(f[a] * unit.accel_counts_per_g[a] + unit.accel_zero[a])),
                        ticks,
                    };
                    sony::emulate::encode_input(
                        kind,
                        link,
                        self.seq & 0x3F,
                        &raw,
                        &buttons,
                        self.config.battery_percent,
                        &mut out,
                    );
                }
            }
            Unit::Switch(unit) => {
                if !self.full_mode {
                    switch::emulate::encode_simple(&mut out);
                } else {
                    let unit = unit.clone();
                    let n = s.samples_per_report.max(1);
                    let step = s.report_interval_s / n as f64;
                    let mut samples = [[0i16; 6]; 3];
                    for (i, sample) in samples.iter_mut().enumerate() {
                        if !self.imu_on {
                            break;
                        }
                        // Oldest first: the last sample is the report's own instant.
                        let t = t_report - (2 - i) as f64 * step;
                        let (w, f) = self.sense(m.as_ref(), t);
                        let w = switch::emulate::to_native(kind, w);
                        let f = switch::emulate::to_native(kind, f);
                        for a in 0..3 {
                            sample[a] = count(f[a] * unit.accel_counts_per_g[a]);
                            sample[3 + a] =
                                count(w[a] * unit.gyro_counts_per_dps[a] + unit.gyro_origin[a]);
                        }
                    }
                    switch::emulate::encode_full(
                        kind,
                        self.seq,
                        &samples,
                        &buttons,
                        self.config.battery_percent,
                        &mut out,
                    );
                }
            }
        }
        self.queue.push_back(out);
    }

    fn answer_switch(&mut self, report: &[u8]) {
        let kind = self.config.kind;
        let Unit::Switch(unit) = &self.unit else {
            return;
        };
        let buttons = roles_from_wii(self.controls.buttons());
        let mut out = Vec::new();
        match report.first() {
            Some(0x80) if report.len() >= 2 && self.config.link == Link::Usb => {
                switch::emulate::encode_usb_reply(report[1], &mut out);
            }
            Some(&switch::SUBCOMMAND_REPORT) if report.len() >= 11 => {
                let id = report[10];
                let args = &report[11..];
                let mut data = Vec::new();
                match id {
                    switch::SUB_INPUT_MODE if args.first() == Some(&switch::FULL_REPORT) => {
                        self.full_mode = true;
                    }
                    switch::SUB_IMU => self.imu_on = args.first() == Some(&1),
                    switch::SUB_SPI_READ if args.len() >= 5 => {
                        let addr = u32::from_le_bytes([args[0], args[1], args[2], args[3]]);
                        let len = (args[4] as usize).min(0x1D);
                        data.extend_from_slice(&args[..4]);
                        data.push(len as u8);
                        data.extend(unit.spi(addr, len));
                    }
                    _ => {}
                }
                switch::emulate::encode_reply(kind, self.seq, id, &data, &buttons, &mut out);
            }
            _ => return,
        }
        self.queue.push_back(out);
    }
}

impl Transport for EmulatedPad {
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
        if !self.controls.connected() {
            return Err(TransportError::Disconnected);
        }
        if switch::is_switch(self.config.kind) {
            self.answer_switch(report);
        } else {
            match sony::parse_output(self.config.kind, self.config.link, report) {
                Ok(output) => self.output = Some(output),
                Err(_) => self.refused_outputs += 1,
            }
        }
        Ok(report.len())
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError> {
        if !self.controls.connected() {
            return Err(TransportError::Disconnected);
        }
        if self.queue.is_empty() {
            let deadline = self.now_us + timeout_ms as u64 * 1000;
            if self.next_report_us > deadline {
                self.pacing.wait_until(deadline);
                self.now_us = deadline;
                return Ok(0);
            }
            let t = self.next_report_us;
            self.pacing.wait_until(t);
            self.now_us = t;
            self.next_report_us += (self.config.sensors.report_interval_s * 1e6).round() as u64;
            self.report(t as f64 * 1e-6);
        }
        let Some(r) = self.queue.pop_front() else {
            return Ok(0);
        };
        let n = r.len().min(buf.len());
        buf[..n].copy_from_slice(&r[..n]);
        Ok(n)
    }

    fn now_us(&self) -> u64 {
        self.now_us
    }

    fn get_feature_report(&mut self, buf: &mut [u8]) -> Result<usize, TransportError> {
        if !self.controls.connected() {
            return Err(TransportError::Disconnected);
        }
        let Unit::Sony(unit) = &self.unit else {
            return Err(TransportError::Unsupported("feature reports"));
        };
        let (id, _) = sony::calibration_report(self.config.kind, self.config.link);
        if buf.first() != Some(&id) {
            return Err(TransportError::Io(format!(
                "feature report 0x{:02X} not emulated",
                buf.first().copied().unwrap_or(0)
            )));
        }
        let r = unit.calibration_report(self.config.kind, self.config.link);
        let n = r.len().min(buf.len());
        buf[..n].copy_from_slice(&r[..n]);
        self.full_mode = true;
        Ok(n)
    }
}
