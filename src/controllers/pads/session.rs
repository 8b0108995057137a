//! [`PadSession`]: a pad's start sequence, then its reports through the decoder and the
//! orientation filter, out as the Wii Remote session's events.

use std::collections::VecDeque;

use crate::controllers::fusion::{FilterKind, OrientationFilter};
use crate::controllers::session::{OrientationSample, SessionConfig, SessionError, SessionEvent};
use crate::controllers::sony::{self, SonyCalibration};
use crate::controllers::switch::{self, CalibrationSource, StartStep, SwitchCalibration};
use crate::controllers::transport::{Transport, TransportError};
use crate::controllers::{ControllerKind, DecodeError, Link, PadButtons, PadReport};

use super::{PadCalibration, PadDecoder, PadSensorModel, roles_to_wii};

/// What the start sequence learned.
#[derive(Debug, Clone, PartialEq)]
pub struct PadInfo {
    /// The device.
    pub kind: ControllerKind,
    /// Its link.
    pub link: Link,
    /// The calibration in use.
    pub calibration: PadCalibration,
    /// Whether it is the unit's own (factory or user) calibration on every axis, not the
    /// datasheet's.
    pub factory_calibration: bool,
}

/// Gaps longer than this are dropouts: the next sample is not integrated across them.
const MAX_GAP_S: f64 = 0.1;
const MAX_EVENTS: usize = 4096;

/// A connection to one pad over a [`Transport`].
pub struct PadSession<T: Transport> {
    transport: T,
    decoder: PadDecoder,
    config: SessionConfig,
    filter: Box<dyn OrientationFilter>,
    events: VecDeque<SessionEvent>,
    buf: Vec<u8>,
    buttons: PadButtons,
    battery: Option<u8>,
    last_device_time: Option<f64>,
    last_report_us: Option<u64>,
    last_sample_us: Option<u64>,
    report_interval_s: f64,
    sample_period_s: f64,
    counter: u8,
    lights: sony::SonyOutput,
    output_seq: u8,
    malformed: u64,
    last_error: Option<DecodeError>,
}

impl<T: Transport> PadSession<T> {
    /// A session (not connected yet). `kind` must be a pad (not a Wii Remote); a Wii Remote
    /// gets a decoder of Sony's layout and every report fails to decode.
    pub fn new(transport: T, kind: ControllerKind, link: Link, config: SessionConfig) -> Self {
        let sample_period_s = 1.0 / PadSensorModel::for_device(kind, link).sample_rate_hz();
        let decoder = PadDecoder::new(kind, link)
            .or_else(|_| PadDecoder::new(ControllerKind::DualSense, link))
            .expect("the DualSense is a pad");
        let report_interval_s = if switch::is_switch(kind) {
            if link == Link::Usb { 0.008 } else { 0.015 }
        } else {
            0.004
        };
        Self {
            transport,
            decoder,
            filter: config.filter.build_for_period(sample_period_s),
            sample_period_s,
            config,
            events: VecDeque::new(),
            buf: vec![0u8; 512],
            buttons: PadButtons::default(),
            battery: None,
            last_device_time: None,
            last_report_us: None,
            last_sample_us: None,
            report_interval_s,
            counter: 0,
            lights: sony::SonyOutput::default(),
            output_seq: 0,
            malformed: 0,
            last_error: None,
        }
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The decoder (with the calibration in use).
    pub fn decoder(&self) -> &PadDecoder {
        &self.decoder
    }

    /// Reports that did not decode (wrong CRC, short, unknown id…) since the start.
    pub fn malformed_reports(&self) -> u64 {
        self.malformed
    }

    /// Why the last malformed report did not decode.
    pub fn last_decode_error(&self) -> Option<&DecodeError> {
        self.last_error.as_ref()
    }

    /// The orientation filter.
    pub fn filter(&self) -> &dyn OrientationFilter {
        self.filter.as_ref()
    }

    /// Replaces the orientation filter.
    pub fn set_filter(&mut self, kind: FilterKind) {
        self.filter = kind.build_for_period(self.sample_period_s);
        self.config.filter = kind;
    }

    /// Rumble on or off (Sony pads: both motors at three quarters; Switch controllers: not
    /// driven, their rumble encoding is not implemented).
    pub fn set_rumble(&mut self, on: bool) -> Result<(), SessionError> {
        if !sony::is_sony(self.decoder.kind()) {
            return Ok(());
        }
        let level = if on { 192 } else { 0 };
        self.lights.strong_motor = level;
        self.lights.weak_motor = level;
        self.write_sony_output()
    }

    fn write_sony_output(&mut self) -> Result<(), SessionError> {
        self.output_seq = (self.output_seq + 1) & 0x0F;
        let report = sony::output_report(
            self.decoder.kind(),
            self.decoder.link(),
            self.output_seq,
            &self.lights,
        );
        self.transport.write(&report)?;
        Ok(())
    }

    /// Makes the current orientation the identity.
    pub fn recenter(&mut self) {
        self.filter.recenter();
    }

    /// Restarts the gyro bias estimate.
    pub fn calibrate_now(&mut self) {
        self.filter.calibrate_now();
    }

    /// Takes the events produced so far.
    pub fn drain_events(&mut self) -> impl Iterator<Item = SessionEvent> + '_ {
        self.events.drain(..)
    }

    fn push(&mut self, e: SessionEvent) {
        if self.events.len() >= MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back(e);
    }

    /// Runs the start sequence: Sony pads read their calibration feature report (which is
    /// what switches them to full reports over Bluetooth); Switch controllers get the USB
    /// handshake, full report mode, the IMU and two SPI calibration reads. A calibration
    /// that cannot be read leaves the datasheet's; a step that is never answered is a
    /// [`SessionError::Timeout`].
    pub fn connect(&mut self) -> Result<PadInfo, SessionError> {
        let kind = self.decoder.kind();
        let link = self.decoder.link();
        let calibration = if sony::is_sony(kind) {
            PadCalibration::Sony(self.read_sony_calibration()?)
        } else {
            PadCalibration::Switch(self.run_switch_start()?)
        };
        self.decoder.set_calibration(calibration);
        // The player's number and colour (a Wii Remote lights its LEDs the same way).
        if sony::is_sony(kind) {
            self.lights = sony::player_output(self.config.player);
            self.write_sony_output()?;
        }
        let factory_calibration = match calibration {
            PadCalibration::Sony(c) => c.is_factory(),
            PadCalibration::Switch(c) => {
                c.source != CalibrationSource::Nominal && !c.fallback_axes.iter().any(|&f| f)
            }
        };
        Ok(PadInfo {
            kind,
            link,
            calibration,
            factory_calibration,
        })
    }

    fn read_sony_calibration(&mut self) -> Result<SonyCalibration, SessionError> {
        let kind = self.decoder.kind();
        let link = self.decoder.link();
        let (id, len) = sony::calibration_report(kind, link);
        for _ in 0..=self.config.retries {
            let mut buf = vec![0u8; len.max(64)];
            buf[0] = id;
            match self.transport.get_feature_report(&mut buf) {
                Ok(n) => {
                    if let Ok(cal) = SonyCalibration::parse(kind, link, &buf[..n.min(buf.len())]) {
                        return Ok(cal);
                    }
                }
                Err(TransportError::Disconnected) => {
                    return Err(SessionError::Transport(TransportError::Disconnected));
                }
                Err(_) => {}
            }
        }
        Ok(SonyCalibration::nominal())
    }

    fn run_switch_start(&mut self) -> Result<SwitchCalibration, SessionError> {
        let link = self.decoder.link();
        let mut factory = None;
        let mut user = None;
        for step in switch::start_sequence(link, self.config.player) {
            match step {
                StartStep::Usb(cmd) => {
                    self.exchange(&[0x80, cmd], |r| {
                        (r.first() == Some(&switch::USB_REPLY_REPORT) && r.get(1) == Some(&cmd))
                            .then_some(())
                    })
                    .map_err(|_| SessionError::Timeout("the Switch USB handshake"))?;
                }
                StartStep::Subcommand { id, args, len } => {
                    self.counter = (self.counter + 1) & 0x0F;
                    let out = switch::subcommand_report(self.counter, id, &args[..len as usize]);
                    let reply = self.exchange(&out, |r| {
                        switch::parse_reply(r).ok().filter(|reply| reply.id == id)
                    });
                    let is_spi = id == switch::SUB_SPI_READ;
                    let reply = match reply {
                        Ok(reply) => reply,
                        // A calibration that cannot be read leaves the datasheet's.
                        Err(_) if is_spi => continue,
                        Err(e) => return Err(e),
                    };
                    if is_spi {
                        let addr = u32::from_le_bytes([args[0], args[1], args[2], args[3]]);
                        let Ok(data) = switch::spi_data(&reply, addr) else {
                            continue;
                        };
                        if addr == switch::SPI_FACTORY_IMU {
                            factory =
                                SwitchCalibration::from_block(data, CalibrationSource::Factory)
                                    .ok();
                        } else if addr == switch::SPI_USER_IMU && data.starts_with(&[0xB2, 0xA1]) {
                            user =
                                SwitchCalibration::from_block(&data[2..], CalibrationSource::User)
                                    .ok();
                        }
                    }
                }
            }
        }
        Ok(user.or(factory).unwrap_or_else(SwitchCalibration::nominal))
    }

    /// Writes `out` and reads until `matches` accepts a report, retrying the write; never
    /// longer than the configured timeout per try.
    fn exchange<R>(
        &mut self,
        out: &[u8],
        matches: impl Fn(&[u8]) -> Option<R>,
    ) -> Result<R, SessionError> {
        for _ in 0..=self.config.retries {
            self.transport.write(out)?;
            let start = self.transport.now_us();
            let budget = self.config.command_timeout_ms as u64 * 1000;
            // At most one read per report slot: a pad streaming other reports cannot keep
            // this loop going forever.
            for _ in 0..512 {
                let elapsed = self.transport.now_us().saturating_sub(start);
                if elapsed >= budget {
                    break;
                }
                let left = ((budget - elapsed) / 1000).max(1) as u32;
                let n = self.transport.read_timeout(&mut self.buf, left)?;
                if n == 0 {
                    continue;
                }
                if let Some(r) = matches(&self.buf[..n]) {
                    return Ok(r);
                }
            }
        }
        Err(SessionError::Timeout("a Switch subcommand"))
    }

    /// Reads one report (waiting at most `timeout_ms`), decodes it and feeds its samples to
    /// the filter. A report that does not decode is counted
    /// ([`Self::malformed_reports`]) and skipped; only the transport failing is an error.
    pub fn poll(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        let n = self.transport.read_timeout(&mut self.buf, timeout_ms)?;
        if n == 0 {
            return Ok(());
        }
        let now_us = self.transport.now_us();
        match self
            .decoder
            .decode(&self.buf[..n])
            .and_then(PadReport::verified)
        {
            Ok(report) => self.take(report, now_us),
            // A subcommand reply or a simple report between full reports is not malformed.
            Err(DecodeError::NoMotion { .. }) | Err(DecodeError::ImuOff) => {}
            Err(e) => {
                self.malformed += 1;
                self.last_error = Some(e);
            }
        }
        Ok(())
    }

    fn take(&mut self, report: PadReport, now_us: u64) {
        if report.buttons != self.buttons {
            self.buttons = report.buttons;
            self.push(SessionEvent::Buttons {
                buttons: roles_to_wii(&report.buttons),
                timestamp_us: now_us,
            });
        }
        if let Some(b) = report.battery
            && self.battery != Some(b.percent)
        {
            self.battery = Some(b.percent);
            self.push(SessionEvent::Battery {
                level: (b.percent as u16 * 2).min(200) as u8,
                low: b.percent <= 10 && !b.charging,
            });
        }
        let samples = report.samples();
        if samples.is_empty() {
            return;
        }
        // Report spacing: the device's clock where it has one, else the host's, smoothed.
        if let Some(last) = self.last_report_us {
            let gap = now_us.saturating_sub(last) as f64 * 1e-6;
            if gap > 0.0 && gap < MAX_GAP_S {
                self.report_interval_s += 0.05 * (gap - self.report_interval_s);
            }
        }
        let gap_from_last_report = self
            .last_report_us
            .map(|l| now_us.saturating_sub(l) as f64 * 1e-6);
        self.last_report_us = Some(now_us);
        let step = self.report_interval_s / samples.len() as f64;
        let n = samples.len();
        for (i, s) in samples.iter().enumerate() {
            if !s.is_finite() {
                self.malformed += 1;
                continue;
            }
            let dt = match (s.device_time_s, self.last_device_time) {
                (Some(t), Some(last)) => {
                    let period = device_clock_period(self.decoder.kind());
                    (t - last).rem_euclid(period)
                }
                _ if i > 0 => step,
                _ => gap_from_last_report.map_or(0.0, |g| g - (n - 1) as f64 * step),
            };
            self.last_device_time = s.device_time_s;
            let dt = if dt > 0.0 && dt < MAX_GAP_S { dt } else { 0.0 };
            // The newest sample is the report's instant; older ones step back from it.
            let t_us = now_us.saturating_sub(((n - 1 - i) as f64 * step * 1e6) as u64);
            let t_us = self.last_sample_us.map_or(t_us, |l| t_us.max(l));
            self.last_sample_us = Some(t_us);
            let imu = s.to_imu(t_us, dt);
            self.filter.update(&imu);
            self.push(SessionEvent::Imu(imu));
            let sample = OrientationSample {
                timestamp_us: t_us,
                orientation: self.filter.orientation(),
                angular_velocity: self.filter.angular_velocity(),
                accel_g: imu.accel_g,
                gyro_fast: [false; 3],
                still: self.filter.is_still(),
                calibration: self.filter.calibration(),
                heading_from_bar: false,
            };
            self.push(SessionEvent::Orientation(sample));
        }
    }
}

/// How long the device's sample clock counts before it wraps, s (a huge value where the
/// device has none).
fn device_clock_period(kind: ControllerKind) -> f64 {
    match kind {
        ControllerKind::DualShock4 => 65536.0 * 16.0 / 3.0e6,
        ControllerKind::DualSense | ControllerKind::DualSenseEdge => 4_294_967_296.0 / 3.0e6,
        _ => f64::MAX,
    }
}
