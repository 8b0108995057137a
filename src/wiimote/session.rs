//! The connection state machine a real remote needs (`PROTOCOL.md` §6–§8, §11): identify,
//! status, accelerometer calibration, MotionPlus probe/activation/calibration, continuous
//! reporting, re-sending the mode after every status report, retries and timeouts, LEDs,
//! battery, rumble, MotionPlus loss and re-probe.
//!
//! A [`Session`] runs on one I/O thread and is driven with [`Session::connect`] then
//! [`Session::poll`] in a loop; events are drained with [`Session::drain_events`].

use std::collections::VecDeque;

use glam::{DQuat, DVec3};

use super::filter::{Calibration, FilterKind, ImuSample, OrientationFilter};
use super::ir::{IR_MODE_REGISTER, IrInitStep, IrMode, IrSensitivity, ir_init_sequence};
use super::protocol::{
    AccelCalibration, AddressSpace, Buttons, ExtensionData, ExtensionId, InputReport,
    MotionPlusCalibration, NunchukFrame, OutputReport, ReadReply, Status, classify_extension,
};
use super::transport::{Transport, TransportError};

/// Session settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionConfig {
    /// Player number 1..=4, shown on the LEDs.
    pub player: u8,
    /// Orientation filter.
    pub filter: FilterKind,
    /// Timeout per command, ms (1000).
    pub command_timeout_ms: u32,
    /// Retries per command (3).
    pub retries: u32,
    /// Minimum spacing between writes, ms (20).
    pub write_spacing_ms: u32,
    /// Wait after MotionPlus activation before verifying, ms (500).
    pub activation_wait_ms: u32,
    /// Battery status interval, ms (10 s).
    pub battery_interval_ms: u32,
    /// Re-probe interval for a missing external MotionPlus, ms (4 s).
    pub motion_plus_poll_ms: u32,
    /// MotionPlus frames missing for this long → re-activate, ms (500).
    pub motion_plus_timeout_ms: u32,
}

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            player: 1,
            filter: FilterKind::Fusion,
            command_timeout_ms: 1000,
            retries: 3,
            write_spacing_ms: 20,
            activation_wait_ms: 500,
            battery_interval_ms: 10_000,
            motion_plus_poll_ms: 4000,
            motion_plus_timeout_ms: 500,
        }
    }
}

/// Why a session failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SessionError {
    /// The transport failed (usually: the remote disconnected).
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// No answer within the timeout after all retries.
    #[error("no answer to {0} after retries")]
    Timeout(&'static str),
    /// The remote answered with an error code.
    #[error("the remote answered report 0x{report:02X} with error {code}")]
    Remote {
        /// Output report id.
        report: u8,
        /// Error code.
        code: u8,
    },
    /// The IR camera did not take its initialisation (the inner error says how).
    #[error("the IR camera did not answer: {0}")]
    Camera(Box<SessionError>),
    /// Not a Wii Remote (Balance Board, Pro Controller).
    #[error("unsupported device: {0}")]
    UnsupportedDevice(&'static str),
}

/// MotionPlus state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum MotionPlusState {
    /// None found (accelerometer-only tilt).
    #[default]
    Absent,
    /// Being activated.
    Activating,
    /// Delivering gyro frames.
    Active,
    /// Was active, stopped (unplugged or frames stopped); re-probing.
    Lost,
}

/// What is plugged into the extension (or pass-through) port.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum ExtensionState {
    /// Nothing.
    #[default]
    None,
    /// A Nunchuk.
    Nunchuk,
    /// Something else.
    Other,
}

/// Remote model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RemoteKind {
    /// RVL-CNT-01.
    Original,
    /// RVL-CNT-01-TR (MotionPlus inside).
    Plus,
}

/// What the handshake learned.
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteInfo {
    /// Model (from the MotionPlus ID byte; a Plus without it reads as Original).
    pub kind: RemoteKind,
    /// Accelerometer calibration in use.
    pub accel_calibration: AccelCalibration,
    /// Whether an EEPROM block had a valid checksum.
    pub accel_calibration_valid: bool,
    /// MotionPlus calibration, when a MotionPlus was found.
    pub motion_plus_calibration: Option<MotionPlusCalibration>,
    /// Whether its CRC matched (false → fallback constants).
    pub motion_plus_crc_ok: bool,
    /// MotionPlus state after the handshake.
    pub motion_plus: MotionPlusState,
    /// Battery byte.
    pub battery: u8,
}

/// One orientation estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientationSample {
    /// Host timestamp, µs.
    pub timestamp_us: u64,
    /// World←body orientation relative to the last recentre.
    pub orientation: DQuat,
    /// Bias-corrected body angular velocity, rad/s.
    pub angular_velocity: DVec3,
    /// Specific force, g.
    pub accel_g: DVec3,
    /// Fast-mode flags (x, y, z).
    pub gyro_fast: [bool; 3],
    /// Still right now.
    pub still: bool,
    /// Calibration state.
    pub calibration: Calibration,
}

/// Something that happened on the remote.
#[derive(Debug, Clone, PartialEq)]
pub enum SessionEvent {
    /// Buttons changed.
    Buttons {
        /// Held buttons.
        buttons: Buttons,
        /// Host time, µs.
        timestamp_us: u64,
    },
    /// Raw calibrated sensor sample (for filters run outside the session).
    Imu(ImuSample),
    /// Filtered orientation.
    Orientation(OrientationSample),
    /// Battery report.
    Battery {
        /// Level byte.
        level: u8,
        /// Nearly empty.
        low: bool,
    },
    /// MotionPlus state changed.
    MotionPlus(MotionPlusState),
    /// Extension changed.
    Extension(ExtensionState),
    /// Nunchuk input.
    Nunchuk(NunchukFrame),
}

const MAX_EVENTS: usize = 4096;

/// A connection to one remote over a [`Transport`].
pub struct Session<T: Transport> {
    transport: T,
    config: SessionConfig,
    filter: Box<dyn OrientationFilter>,
    rumble: bool,
    leds: u8,
    mode: u8,
    last_write_us: Option<u64>,
    acks: VecDeque<(u8, u8)>,
    replies: VecDeque<ReadReply>,
    status: Option<Status>,
    events: VecDeque<SessionEvent>,
    accel_cal: AccelCalibration,
    mp_cal: Option<MotionPlusCalibration>,
    mp_state: MotionPlusState,
    mp_mode: u8,
    kind: RemoteKind,
    discard_frames: u32,
    last_buttons: Buttons,
    last_sample_us: Option<u64>,
    last_gyro_us: Option<u64>,
    dt_avg: f64,
    last_mp_frame_us: u64,
    last_battery_us: u64,
    next_mp_probe_us: u64,
    extension: ExtensionState,
    connected: bool,
    malformed: u64,
}

impl<T: Transport> Session<T> {
    /// Wraps a transport.
    pub fn new(transport: T, config: SessionConfig) -> Self {
        Self {
            transport,
            filter: config.filter.build(),
            config,
            rumble: false,
            leds: 0,
            mode: 0x31,
            last_write_us: None,
            acks: VecDeque::new(),
            replies: VecDeque::new(),
            status: None,
            events: VecDeque::new(),
            accel_cal: AccelCalibration::default(),
            mp_cal: None,
            mp_state: MotionPlusState::Absent,
            mp_mode: 0x04,
            kind: RemoteKind::Original,
            discard_frames: 0,
            last_buttons: Buttons(0),
            last_sample_us: None,
            last_gyro_us: None,
            dt_avg: 0.01,
            last_mp_frame_us: 0,
            last_battery_us: 0,
            next_mp_probe_us: 0,
            extension: ExtensionState::None,
            connected: false,
            malformed: 0,
        }
    }

    /// The transport (e.g. to reach the emulator in tests).
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// Mutable transport.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// The current MotionPlus state.
    pub fn motion_plus_state(&self) -> MotionPlusState {
        self.mp_state
    }

    /// Number of malformed input reports seen (and ignored).
    pub fn malformed_reports(&self) -> u64 {
        self.malformed
    }

    /// The orientation filter.
    pub fn filter(&self) -> &dyn OrientationFilter {
        &*self.filter
    }

    /// Replaces the orientation filter.
    pub fn set_filter(&mut self, kind: FilterKind) {
        self.filter = kind.build();
        self.config.filter = kind;
    }

    /// Makes the current orientation the identity.
    pub fn recenter(&mut self) {
        self.filter.recenter();
    }

    /// Restarts gyro bias calibration.
    pub fn calibrate_now(&mut self) {
        self.filter.calibrate_now();
    }

    /// Takes the queued events.
    pub fn drain_events(&mut self) -> impl Iterator<Item = SessionEvent> + '_ {
        self.events.drain(..)
    }

    fn event(&mut self, e: SessionEvent) {
        if self.events.len() >= MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back(e);
    }

    fn now(&self) -> u64 {
        self.transport.now_us()
    }

    /// Sets the rumble motor (carried in every later report too).
    pub fn set_rumble(&mut self, on: bool) -> Result<(), SessionError> {
        self.rumble = on;
        self.write(OutputReport::Rumble { rumble: on })
    }

    /// Sets the player LEDs (bit 0 = LED1).
    pub fn set_leds(&mut self, leds: u8) -> Result<(), SessionError> {
        self.leds = leds & 0x0F;
        self.command(OutputReport::Leds {
            leds: self.leds,
            ack: true,
            rumble: self.rumble,
        })
    }

    /// Turns the IR camera on (`PROTOCOL.md` §17.2: pixel clock, logic, control, the two
    /// sensitivity blocks, the mode, control again) and reads the mode register back. A
    /// remote whose camera does not answer gives [`SessionError::Camera`]; the session keeps
    /// running (MotionPlus posing is unaffected), so a caller can carry on without a pointer.
    pub fn enable_ir(
        &mut self,
        mode: IrMode,
        sensitivity: IrSensitivity,
    ) -> Result<(), SessionError> {
        let camera = |e: SessionError| SessionError::Camera(Box::new(e));
        for step in ir_init_sequence(mode, sensitivity) {
            let report = match step {
                IrInitStep::Enable { report } => OutputReport::Flag {
                    id: report,
                    enable: true,
                    ack: true,
                    rumble: self.rumble,
                },
                IrInitStep::Write { address, bytes } => OutputReport::WriteMemory {
                    space: AddressSpace::Registers,
                    address,
                    data: bytes,
                    rumble: self.rumble,
                },
            };
            self.command(report).map_err(camera)?;
        }
        let read = self
            .read_memory(AddressSpace::Registers, IR_MODE_REGISTER, 1)
            .map_err(camera)?;
        if read.first() != Some(&mode.register_value()) {
            return Err(SessionError::Camera(Box::new(SessionError::Timeout(
                "the IR mode register to read back its mode",
            ))));
        }
        Ok(())
    }

    /// Writes one report, honouring the write spacing; never waits for an answer.
    fn write(&mut self, report: OutputReport) -> Result<(), SessionError> {
        if let Some(last) = self.last_write_us {
            let due = last + self.config.write_spacing_ms as u64 * 1000;
            while self.now() < due {
                let ms = ((due - self.now()) / 1000).max(1) as u32;
                self.pump(ms)?;
            }
        }
        let bytes = report.with_rumble(self.rumble).encode();
        self.transport.write(&bytes)?;
        self.last_write_us = Some(self.now());
        Ok(())
    }

    fn mode_report(&self) -> OutputReport {
        OutputReport::ReportMode {
            mode: self.mode,
            continuous: true,
            ack: true,
            rumble: self.rumble,
        }
    }

    /// Sends a report with the ack bit and waits for its 0x22; retries on timeout and on
    /// busy/unknown error codes.
    fn command(&mut self, report: OutputReport) -> Result<(), SessionError> {
        let id = report.encode()[0];
        let mut last_error = None;
        for _ in 0..=self.config.retries {
            self.acks.clear();
            self.write(report.clone())?;
            let deadline = self.now() + self.config.command_timeout_ms as u64 * 1000;
            loop {
                if let Some(pos) = self.acks.iter().position(|(r, _)| *r == id) {
                    let (_, code) = self.acks.remove(pos).expect("position is valid");
                    match code {
                        0 => return Ok(()),
                        6..=8 => return Err(SessionError::Remote { report: id, code }),
                        _ => {
                            last_error = Some(SessionError::Remote { report: id, code });
                            break;
                        }
                    }
                }
                let now = self.now();
                if now >= deadline {
                    break;
                }
                self.pump(((deadline - now) / 1000).clamp(1, 50) as u32)?;
            }
        }
        Err(last_error.unwrap_or(SessionError::Timeout("command")))
    }

    /// Reads `size` bytes of memory, collecting the 0x21 replies.
    fn read_memory(
        &mut self,
        space: AddressSpace,
        address: u32,
        size: u16,
    ) -> Result<Vec<u8>, SessionError> {
        for _ in 0..=self.config.retries {
            self.replies.clear();
            self.acks.clear();
            self.write(OutputReport::ReadMemory {
                space,
                address,
                size,
                rumble: self.rumble,
            })?;
            let deadline = self.now() + self.config.command_timeout_ms as u64 * 1000;
            let mut data = Vec::with_capacity(size as usize);
            let mut retry = false;
            while data.len() < size as usize {
                if let Some(r) = self.replies.pop_front() {
                    if r.error != 0 {
                        if matches!(r.error, 6..=8) {
                            return Err(SessionError::Remote {
                                report: 0x17,
                                code: r.error,
                            });
                        }
                        retry = true;
                        break;
                    }
                    data.extend_from_slice(&r.data);
                    continue;
                }
                if self.acks.iter().any(|(r, c)| *r == 0x17 && *c != 0) {
                    retry = true; // busy
                    break;
                }
                let now = self.now();
                if now >= deadline {
                    retry = true;
                    break;
                }
                self.pump(((deadline - now) / 1000).clamp(1, 50) as u32)?;
            }
            if !retry {
                data.truncate(size as usize);
                return Ok(data);
            }
            // Let a running read finish before asking again.
            let settle = self.now() + 100_000;
            while self.now() < settle {
                self.pump(20)?;
            }
        }
        Err(SessionError::Timeout("memory read"))
    }

    fn wait(&mut self, ms: u32) -> Result<(), SessionError> {
        let until = self.now() + ms as u64 * 1000;
        while self.now() < until {
            let left = ((until - self.now()) / 1000).clamp(1, 50) as u32;
            self.pump(left)?;
        }
        Ok(())
    }

    /// Runs the handshake (§6): LEDs, status, accelerometer calibration, MotionPlus probe and
    /// activation, continuous reporting. Errors leave the session disconnected.
    pub fn connect(&mut self) -> Result<RemoteInfo, SessionError> {
        self.connected = false;
        self.mp_state = MotionPlusState::Absent;
        self.mp_cal = None;
        self.leds = 1 << (self.config.player.clamp(1, 4) - 1);
        self.set_leds(self.leds)?;
        self.status = None;
        self.write(OutputReport::StatusRequest {
            rumble: self.rumble,
        })?;
        let deadline = self.now() + self.config.command_timeout_ms as u64 * 1000;
        while self.status.is_none() && self.now() < deadline {
            self.pump(20)?;
        }
        let status = self.status.ok_or(SessionError::Timeout("status"))?;
        let blocks = self.read_memory(AddressSpace::Eeprom, 0x16, 20)?;
        let (accel_cal, valid) = AccelCalibration::from_blocks(&blocks[..10], &blocks[10..20]);
        self.accel_cal = accel_cal;
        self.mode = 0x31;
        self.command(self.mode_report())?;
        let mut crc_ok = false;
        match self.probe_motion_plus() {
            Ok(ok) => crc_ok = ok,
            Err(e @ SessionError::UnsupportedDevice(_)) => return Err(e),
            Err(e @ SessionError::Transport(_)) => return Err(e),
            Err(_) => self.set_mp_state(MotionPlusState::Absent),
        }
        if self.mp_state != MotionPlusState::Active {
            self.probe_extension()?;
        }
        self.mode = 0x35;
        self.command(self.mode_report())?;
        self.connected = true;
        let now = self.now();
        self.last_battery_us = now;
        self.last_mp_frame_us = now;
        self.next_mp_probe_us = now + self.config.motion_plus_poll_ms as u64 * 1000;
        Ok(RemoteInfo {
            kind: self.kind,
            accel_calibration: accel_cal,
            accel_calibration_valid: valid,
            motion_plus_calibration: self.mp_cal,
            motion_plus_crc_ok: crc_ok,
            motion_plus: self.mp_state,
            battery: status.battery,
        })
    }

    fn set_mp_state(&mut self, s: MotionPlusState) {
        if self.mp_state != s {
            self.mp_state = s;
            self.event(SessionEvent::MotionPlus(s));
        }
    }

    fn read_id(&mut self, address: u32) -> Result<ExtensionId, SessionError> {
        let id = self.read_memory(AddressSpace::Registers, address, 6)?;
        Ok(ExtensionId::parse(&id))
    }

    fn probe_extension(&mut self) -> Result<(), SessionError> {
        let plugged = self.status.is_some_and(|s| s.extension_connected);
        if !plugged {
            self.set_extension(ExtensionState::None);
            return Ok(());
        }
        let _ = self.command(OutputReport::write_register(0xA400F0, 0x55, self.rumble));
        let _ = self.command(OutputReport::write_register(0xA400FB, 0x00, self.rumble));
        match self.read_id(0xA400FA) {
            Ok(ExtensionId::BalanceBoard) => Err(SessionError::UnsupportedDevice("Balance Board")),
            Ok(ExtensionId::ProController) => {
                Err(SessionError::UnsupportedDevice("Wii U Pro Controller"))
            }
            Ok(ExtensionId::Nunchuk) => {
                self.set_extension(ExtensionState::Nunchuk);
                Ok(())
            }
            Ok(_) => {
                self.set_extension(ExtensionState::Other);
                Ok(())
            }
            Err(SessionError::Transport(e)) => Err(e.into()),
            Err(_) => Ok(()),
        }
    }

    fn set_extension(&mut self, e: ExtensionState) {
        if self.extension != e {
            self.extension = e;
            self.event(SessionEvent::Extension(e));
        }
    }

    /// Finds, calibrates and activates a MotionPlus (§8). Returns whether its calibration
    /// CRC matched.
    fn probe_motion_plus(&mut self) -> Result<bool, SessionError> {
        let init = self.command(OutputReport::write_register(0xA600F0, 0x55, self.rumble));
        let inactive = match init {
            Ok(()) => matches!(
                self.read_id(0xA600FA),
                Ok(ExtensionId::MotionPlus { active: false, .. })
            ),
            Err(SessionError::Remote { code: 7, .. }) => false,
            Err(e) => return Err(e),
        };
        let id_first_byte_plus = |s: &mut Self, addr: u32| -> Result<bool, SessionError> {
            let id = s.read_memory(AddressSpace::Registers, addr, 6)?;
            Ok(id.first() == Some(&0x01))
        };
        if !inactive {
            // Absent or already active.
            return match self.read_id(0xA400FA) {
                Ok(ExtensionId::MotionPlus { active: true, mode }) => {
                    if id_first_byte_plus(self, 0xA400FA)? {
                        self.kind = RemoteKind::Plus;
                    }
                    self.mp_mode = mode;
                    let ok = self.read_mp_calibration(0xA40020)?;
                    self.discard_frames = 2;
                    self.set_mp_state(MotionPlusState::Active);
                    Ok(ok)
                }
                Ok(ExtensionId::BalanceBoard) => {
                    Err(SessionError::UnsupportedDevice("Balance Board"))
                }
                Ok(ExtensionId::ProController) => {
                    Err(SessionError::UnsupportedDevice("Wii U Pro Controller"))
                }
                _ => {
                    self.set_mp_state(MotionPlusState::Absent);
                    Ok(false)
                }
            };
        }
        if id_first_byte_plus(self, 0xA600FA)? {
            self.kind = RemoteKind::Plus;
        }
        // Pass-through: a Nunchuk behind the MotionPlus selects mode 0x05.
        self.mp_mode = 0x04;
        if self.status.is_some_and(|s| s.extension_connected) {
            self.probe_extension()?;
            if self.extension == ExtensionState::Nunchuk {
                self.mp_mode = 0x05;
            }
        }
        let crc_ok = self.read_mp_calibration(0xA60020)?;
        self.set_mp_state(MotionPlusState::Activating);
        for attempt in 0..3 {
            if attempt > 0 {
                self.wait(1000)?;
            }
            if self
                .command(OutputReport::write_register(
                    0xA600FE,
                    self.mp_mode,
                    self.rumble,
                ))
                .is_err()
            {
                continue;
            }
            self.wait(self.config.activation_wait_ms)?;
            self.command(self.mode_report())?;
            if let Ok(ExtensionId::MotionPlus { active: true, .. }) = self.read_id(0xA400FA) {
                self.discard_frames = 2;
                self.last_mp_frame_us = self.now();
                self.set_mp_state(MotionPlusState::Active);
                return Ok(crc_ok);
            }
        }
        self.set_mp_state(MotionPlusState::Lost);
        Err(SessionError::Timeout("MotionPlus activation"))
    }

    fn read_mp_calibration(&mut self, address: u32) -> Result<bool, SessionError> {
        for _ in 0..2 {
            let bytes = self.read_memory(AddressSpace::Registers, address, 32)?;
            if let Ok((cal, true)) = MotionPlusCalibration::parse(&bytes) {
                self.mp_cal = Some(cal);
                return Ok(true);
            }
        }
        self.mp_cal = Some(MotionPlusCalibration::fallback());
        Ok(false)
    }

    /// Reads and handles at most one report (waiting up to `timeout_ms`), then runs the
    /// periodic duties: battery status every 10 s, MotionPlus watchdog and re-probe.
    pub fn poll(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        self.pump(timeout_ms)?;
        if !self.connected {
            return Ok(());
        }
        let now = self.now();
        if now.saturating_sub(self.last_battery_us) >= self.config.battery_interval_ms as u64 * 1000
        {
            self.last_battery_us = now;
            self.write(OutputReport::StatusRequest {
                rumble: self.rumble,
            })?;
        }
        let watchdog = self.config.motion_plus_timeout_ms as u64 * 1000;
        let needs_probe = match self.mp_state {
            MotionPlusState::Active => now.saturating_sub(self.last_mp_frame_us) > watchdog,
            MotionPlusState::Lost | MotionPlusState::Absent => {
                self.kind == RemoteKind::Original && now >= self.next_mp_probe_us
            }
            MotionPlusState::Activating => false,
        };
        if needs_probe {
            if self.mp_state == MotionPlusState::Active {
                self.set_mp_state(MotionPlusState::Lost);
            }
            self.next_mp_probe_us = now + self.config.motion_plus_poll_ms as u64 * 1000;
            match self.probe_motion_plus() {
                Ok(_) => {}
                Err(e @ SessionError::Transport(_)) => return Err(e),
                Err(_) => {}
            }
            self.mode = 0x35;
            self.command(self.mode_report())?;
        }
        Ok(())
    }

    /// Reads one report and dispatches it.
    fn pump(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        let mut buf = [0u8; 32];
        let n = self.transport.read_timeout(&mut buf, timeout_ms)?;
        if n == 0 {
            return Ok(());
        }
        let report = match InputReport::decode(&buf[..n]) {
            Ok(r) => r,
            Err(_) => {
                self.malformed += 1;
                return Ok(());
            }
        };
        let now = self.now();
        match report {
            InputReport::Status(s) => {
                let previous = self.status.replace(s);
                self.event(SessionEvent::Battery {
                    level: s.battery,
                    low: s.battery_low,
                });
                self.buttons(s.buttons, now);
                if previous.is_some_and(|p| p.extension_connected && !s.extension_connected)
                    && self.mp_state == MotionPlusState::Active
                {
                    // Unplugged MotionPlus (or pass-through change): re-probe soon.
                    self.set_mp_state(MotionPlusState::Lost);
                    self.next_mp_probe_us = now;
                }
                // After any status report the remote stops data reports: re-send the mode.
                let r = self.mode_report();
                self.write(r)?;
            }
            InputReport::Ack { report, error, .. } => {
                if self.acks.len() > 32 {
                    self.acks.pop_front();
                }
                self.acks.push_back((report, error));
            }
            InputReport::ReadReply(r) => {
                self.buttons(r.buttons, now);
                self.replies.push_back(r);
            }
            InputReport::Data {
                buttons,
                accel,
                extension,
                ..
            } => {
                self.buttons(buttons, now);
                self.data(now, accel.map(|a| self.accel_cal.to_g(a)), extension);
            }
        }
        Ok(())
    }

    fn buttons(&mut self, b: Buttons, now: u64) {
        if b != self.last_buttons {
            self.last_buttons = b;
            self.event(SessionEvent::Buttons {
                buttons: b,
                timestamp_us: now,
            });
        }
    }

    fn data(&mut self, now: u64, accel: Option<DVec3>, ext: Option<[u8; 6]>) {
        let mp_active = self.mp_state == MotionPlusState::Active;
        let mut gyro = None;
        let mut fast = [false; 3];
        if let Some(e) = ext {
            match classify_extension(&e, mp_active) {
                ExtensionData::MotionPlus(f) if mp_active => {
                    self.last_mp_frame_us = now;
                    if self.discard_frames > 0 {
                        self.discard_frames -= 1;
                    } else if let Some(cal) = &self.mp_cal {
                        gyro = Some(cal.rates_deg(&f));
                        fast = [!f.slow[2], !f.slow[1], !f.slow[0]];
                    }
                    let ext_state = if f.extension_connected {
                        if self.extension == ExtensionState::None {
                            ExtensionState::Nunchuk
                        } else {
                            self.extension
                        }
                    } else {
                        ExtensionState::None
                    };
                    self.set_extension(ext_state);
                }
                ExtensionData::Nunchuk(n) if self.extension == ExtensionState::Nunchuk => {
                    self.event(SessionEvent::Nunchuk(n));
                }
                _ => {}
            }
        }
        let Some(accel_g) = accel else { return };
        // dt from host timestamps: averaged against jitter, raw across drops, 0 after gaps.
        // With pass-through frames the gyro updates every other report: its dt spans both.
        let prev = if gyro.is_some() {
            self.last_gyro_us.or(self.last_sample_us)
        } else {
            self.last_sample_us
        };
        let dt = match prev {
            None => 0.0,
            Some(prev) => {
                let raw = now.saturating_sub(prev) as f64 * 1e-6;
                if raw > 0.1 {
                    0.0
                } else if (raw - self.dt_avg).abs() > 0.005 {
                    raw.clamp(0.002, 0.05)
                } else {
                    self.dt_avg += 0.05 * (raw - self.dt_avg);
                    self.dt_avg.clamp(0.002, 0.05)
                }
            }
        };
        self.last_sample_us = Some(now);
        if gyro.is_some() {
            self.last_gyro_us = Some(now);
        }
        let sample = ImuSample {
            timestamp_us: now,
            dt,
            gyro_dps: gyro,
            gyro_fast: fast,
            accel_g,
        };
        self.filter.update(&sample);
        self.event(SessionEvent::Imu(sample));
        let o = OrientationSample {
            timestamp_us: now,
            orientation: self.filter.orientation(),
            angular_velocity: self.filter.angular_velocity(),
            accel_g,
            gyro_fast: fast,
            still: self.filter.is_still(),
            calibration: self.filter.calibration(),
        };
        self.event(SessionEvent::Orientation(o));
    }
}
