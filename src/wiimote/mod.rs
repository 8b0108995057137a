//! The Wii Remote + MotionPlus device layer (no Bevy): protocol, transports (hidapi and a
//! byte-exact emulator), the connection state machine, orientation filters, the drift
//! benchmark and a multi-remote manager. Specification: `docs/PROTOCOL.md` in the repository.
//!
//! ```
//! use bevy_wii_deform::wiimote::*;
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
mod emulator;
mod filter;
pub mod ir;
mod manager;
mod motion;
pub mod protocol;
mod rng;
mod session;
pub mod smoothing;
mod transport;

pub use diagnosis::{LinuxDevices, OpenErrorKind, RemoteProblem};
pub use emulator::{
    EmulatedBar, EmulatedRemote, EmulatorClock, EmulatorConfig, EmulatorControls, SensorModel,
    Variant,
};
pub use filter::{
    BarHeading, Calibration, CalibrationPhase, FilterKind, FusionFilter, ImuSample,
    OrientationFilter, PaperFilter, RawIntegration, StillnessBias, VqfFilter, snap_tilt,
};
pub use manager::{
    ManagerConfig, ManagerEvent, RemoteCommand, RemoteId, RemoteSource, WiimoteManager,
};
pub use motion::{
    ConstantRate, DemoMotion, FnMotion, GRAVITY, Motion, Still, body_rate, from_yaw_elevation_roll,
    specific_force_g,
};
pub use rng::Rng;
pub use session::{
    ExtensionState, MotionPlusState, OrientationSample, RemoteInfo, RemoteKind, SampleClock,
    Session, SessionConfig, SessionError, SessionEvent,
};
#[cfg(feature = "hidapi")]
pub use transport::{DeviceInfo, HidTransport, discover};
pub use transport::{Transport, TransportError};
