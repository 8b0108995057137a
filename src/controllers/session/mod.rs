//! What every controller's session speaks, whatever the device: its settings
//! ([`SessionConfig`]), its failures ([`SessionError`]), and the events it emits
//! ([`SessionEvent`], [`OrientationSample`]) in one vocabulary of inputs ([`inputs`]: the
//! Wii Remote's buttons, the Nunchuk and the IR camera's dots, which pads map onto).
//!
//! | question | file |
//! |---|---|
//! | what a session is set up with, how it fails, what it emits | `mod.rs` |
//! | the buttons, Nunchuk frame and IR dots events carry | `inputs.rs` |

use glam::{DQuat, DVec3};

pub mod inputs;

pub use inputs::{Buttons, IrDot, IrDots, IrSensitivity, NunchukFrame};

use crate::controllers::fusion::{Calibration, FilterKind, ImuSample};
use crate::controllers::transport::TransportError;

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
