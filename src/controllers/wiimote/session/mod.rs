//! The connection state machine a real remote needs (`PROTOCOL.md` §6–§8, §11): identify,
//! status, accelerometer calibration, MotionPlus probe/activation/calibration, continuous
//! reporting, re-sending the mode after every status report, retries and timeouts, LEDs,
//! battery, rumble, MotionPlus loss and re-probe.
//!
//! A [`Session`] runs on one I/O thread and is driven with [`Session::connect`] then
//! [`Session::poll`] in a loop; events are drained with [`Session::drain_events`].

use std::collections::VecDeque;

use glam::{DQuat, DVec3};

mod commands;
mod connect;
mod sample_clock;
mod stream;

pub use sample_clock::SampleClock;

use super::ir::{
    IR_MODE_REGISTER, IrCamera, IrDots, IrInitStep, IrMode, IrSensitivity, decode_basic,
    ir_init_sequence,
};
use super::protocol::{
    AccelCalibration, AddressSpace, Buttons, ExtensionData, ExtensionId, InputReport,
    MotionPlusCalibration, NunchukFrame, OutputReport, ReadReply, Status, classify_extension,
};
use crate::controllers::fusion::{Calibration, FilterKind, ImuSample, OrientationFilter};
use crate::controllers::transport::{Transport, TransportError};

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
    /// Start the IR camera in basic mode at this sensitivity after the handshake (`None`: the
    /// camera stays off). A camera that does not answer leaves it off; the MotionPlus goes on.
    pub ir_camera: Option<IrSensitivity>,
    /// With the camera on, the orientation filter takes its heading from the sensor bar while
    /// it is in view (`PROTOCOL.md` §17.6; `true`).
    pub ir_heading: bool,
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
            ir_camera: None,
            ir_heading: true,
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
    /// The heading is held by the sensor bar right now (IR camera on, bar in view, a filter
    /// with a heading reference: `PROTOCOL.md` §17.6).
    pub heading_from_bar: bool,
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
    /// What the IR camera sees (basic mode, streamed in report 0x37 beside the MotionPlus):
    /// up to four dots, 1024 × 768 pixels.
    Ir {
        /// The dot slots.
        dots: IrDots,
        /// The accelerometer's last reading (g, body frame): the roll the pointer undoes.
        gravity: DVec3,
        /// Host time, µs.
        timestamp_us: u64,
    },
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
