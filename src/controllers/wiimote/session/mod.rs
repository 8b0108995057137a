//! The connection state machine a real remote needs (`PROTOCOL.md` §6–§8, §11): identify,
//! status, accelerometer calibration, MotionPlus probe/activation/calibration, continuous
//! reporting, re-sending the mode after every status report, retries and timeouts, LEDs,
//! battery, rumble, MotionPlus loss and re-probe.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `commands.rs` | Talking to the remote: writes with retries, acknowledged commands, memory reads, LEDs, rumble and the IR camera's initialisation (`PROTOCOL.md` §3–§4, §17). |
//! | `connect.rs` | Connecting: identify, status, accelerometer calibration, the extension and MotionPlus probes, activation and calibration (`PROTOCOL.md` §6–§8). |
//! | `sample_clock.rs` | When each report was sampled, recovered from when it arrived (`docs/PROTOCOL.md` §10). |
//! | `stream.rs` | Streaming: polling reports, status and extension changes, buttons, and the IMU samples fed to the orientation filter (`PROTOCOL.md` §5, §11). |
//!
//! A [`Session`] runs on one I/O thread and is driven with [`Session::connect`] then
//! [`Session::poll`] in a loop; events are drained with [`Session::drain_events`].

use std::collections::VecDeque;

use glam::DVec3;

mod commands;
mod connect;
mod sample_clock;
mod stream;

pub use sample_clock::SampleClock;

use super::ir::{
    IR_MODE_REGISTER, IrCamera, IrInitStep, IrMode, IrSensitivity, decode_basic, ir_init_sequence,
};
use super::protocol::{
    AccelCalibration, AddressSpace, Buttons, ExtensionData, ExtensionId, InputReport,
    MotionPlusCalibration, OutputReport, ReadReply, Status, classify_extension,
};
use crate::controllers::fusion::{FilterKind, OrientationFilter};
pub use crate::controllers::session::{
    ExtensionState, MotionPlusState, OrientationSample, SessionConfig, SessionError, SessionEvent,
};
use crate::controllers::transport::Transport;

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
    sample_clock: sample_clock::SampleClock,
    last_sample_s: Option<f64>,
    last_gyro_s: Option<f64>,
    last_mp_frame_us: u64,
    last_battery_us: u64,
    next_mp_probe_us: u64,
    extension: ExtensionState,
    connected: bool,
    malformed: u64,
    /// The IR camera's mode once [`Session::enable_ir`] ran.
    ir_mode: Option<IrMode>,
    /// The last accelerometer reading, g (body frame).
    last_accel: DVec3,
    /// What the camera saw in the report being handled (`Some(None)`: the camera runs and
    /// does not see the bar), handed to the filter after the report's sample.
    bar_sighting: Option<Option<DVec3>>,
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
            sample_clock: sample_clock::SampleClock::default(),
            last_sample_s: None,
            last_gyro_s: None,
            last_mp_frame_us: 0,
            last_battery_us: 0,
            next_mp_probe_us: 0,
            extension: ExtensionState::None,
            connected: false,
            malformed: 0,
            ir_mode: None,
            last_accel: DVec3::Z,
            bar_sighting: None,
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
}
