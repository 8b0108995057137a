//! The Wii Remote + MotionPlus driver (no Bevy): protocol, transports (hidapi and a
//! byte-exact emulator), the connection state machine and the IR camera. The
//! multi-controller manager is `crate::controllers::manager`. The orientation filters it feeds live in
//! [`crate::controllers::fusion`] and are re-exported here. Specification: `docs/PROTOCOL.md` in the repository.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `discover.rs` | Finding Wii Remotes through hidapi: by Nintendo's vendor and product ids, and by the Bluetooth name for clones that report other ids. |
//! | `emulator/` | A software Wii Remote (original with external MotionPlus, or Remote Plus "-TR") that speaks the real byte protocol behind the [`Transport`] trait. |
//! | `ir.rs` | The Wii Remote's IR camera: its initialisation, the dot formats of its reports, a camera model that projects a sensor bar, and the pointer (dots → where the remote points on the screen, roll-compensated with the accelerometer). |
//! | `protocol/` | Typed encode/decode of Wii Remote HID reports (see `PROTOCOL.md` §2–§8). |
//! | `session/` | The connection state machine a real remote needs (`PROTOCOL.md` §6–§8, §11): identify, status, accelerometer calibration, MotionPlus probe/activation/calibration, continuous reporting, re-sending the mode after every status report, retries and timeouts, LEDs, battery, rumble, MotionPlus loss and re-probe. |
//! | `smoothing.rs` | Smoothing for the IR pointer: the camera reports whole pixels with a little noise, so a pointer held still trembles by a pixel or two, while a pointer swept across the screen must not trail behind. |
//!
//! ```
//! use bevy_wii_deform::controllers::wiimote::*;
//!
//! // An emulated Wii Remote Plus turning about its yaw axis at 30 deg/s.
//! let remote = EmulatedRemote::new(EmulatorConfig::default());
//! remote.controls().set_motion(std::sync::Arc::new(ConstantRate {
//!     start: glam::DQuat::IDENTITY,
//!     axis: glam::DVec3::Z,
//!     rate: 30f64.to_radians(),
//! }));
//! let mut session = Session::new(remote, SessionConfig::default());
//! let info = session.connect().unwrap();
//! assert_eq!(info.motion_plus, MotionPlusState::Active);
//! for _ in 0..100 {
//!     session.poll(20).unwrap();
//! }
//! assert!(session.drain_events().any(|e| matches!(e, SessionEvent::Orientation(_))));
//! ```

#[cfg(feature = "hidapi")]
mod discover;
pub(crate) mod emulator;
pub mod ir;
pub mod protocol;
mod session;
pub mod smoothing;

pub use super::emulation::{EmulatorClock, EmulatorControls};
pub use super::fusion::{
    BarHeading, Calibration, CalibrationPhase, FilterKind, FusionFilter, ImuSample,
    OrientationFilter, PaperFilter, RawIntegration, StillnessBias, VqfFilter, snap_tilt,
};
pub use super::motion::{
    ConstantRate, DemoMotion, FnMotion, GRAVITY, Motion, Still, body_rate, from_yaw_elevation_roll,
    specific_force_g,
};
pub use super::rng::Rng;
#[cfg(feature = "hidapi")]
pub use super::transport::HidTransport;
pub use super::transport::{Transport, TransportError};
#[cfg(feature = "hidapi")]
pub use discover::{DeviceInfo, discover};
pub use emulator::{EmulatedBar, EmulatedRemote, EmulatorConfig, SensorModel, Variant};
pub use session::{
    ExtensionState, MotionPlusState, OrientationSample, RemoteInfo, RemoteKind, SampleClock,
    Session, SessionConfig, SessionError, SessionEvent,
};
