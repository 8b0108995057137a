//! The Wii Remote + MotionPlus driver (no Bevy): protocol, transports (hidapi and a
//! byte-exact emulator), the connection state machine, the drift benchmark and the
//! multi-controller manager. The orientation filters it feeds live in
//! [`crate::controllers::fusion`] and are re-exported here. Specification: `docs/PROTOCOL.md` in the repository.
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

pub mod diagnosis;
pub mod drift;
pub(crate) mod emulator;
pub mod ir;
mod manager;
pub mod protocol;
mod session;
pub mod smoothing;

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
pub use super::transport::{DeviceInfo, HidTransport, discover};
pub use super::transport::{Transport, TransportError};
pub use diagnosis::{LinuxDevices, OpenErrorKind, RemoteProblem};
pub use emulator::{
    EmulatedBar, EmulatedRemote, EmulatorClock, EmulatorConfig, EmulatorControls, SensorModel,
    Variant,
};
pub use manager::{
    EmulatedController, ManagerConfig, ManagerEvent, RemoteCommand, RemoteId, RemoteSource,
    WiimoteManager,
};
pub use session::{
    ExtensionState, MotionPlusState, OrientationSample, RemoteInfo, RemoteKind, SampleClock,
    Session, SessionConfig, SessionError, SessionEvent,
};
