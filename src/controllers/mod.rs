//! Motion controllers (no Bevy): **devices → sensor samples → fusion → orientation**.
//!
//! * **Devices** — one driver per controller family, each with its protocol decoded byte by
//!   byte, the start sequence it needs, its factory calibration and an emulator that answers
//!   exactly like the hardware: [`wiimote`] (Wii Remote + MotionPlus, with the IR camera),
//!   [`sony`] (DualSense, DualSense Edge, DualShock 4) and [`switch`] (Switch Pro Controller,
//!   Joy-Con L/R). Specifications: `docs/PROTOCOL.md` (Wii Remote), `docs/PROTOCOL-SONY.md`,
//!   `docs/PROTOCOL-SWITCH.md`.
//! * **Sensor samples** — every driver turns its reports into [`MotionSample`]s: calibrated
//!   SI units (rad/s, m/s²) in one body frame shared by all devices ([`MotionSample`] says
//!   which), with the device's own timestamp where it has one.
//! * **Fusion** — [`fusion`]: the orientation filters (ours, VQF, the paper's), fed the same
//!   way whatever the device.
//! * **Orientation** — [`pads::PadSession`] and the Wii Remote's
//!   [`wiimote::Session`] run the filters and emit [`wiimote::OrientationSample`]s; the
//!   [`wiimote::WiimoteManager`] runs one I/O thread per controller of any kind and is what the
//!   ECS layer (`crate::ecs`) talks to.

pub mod crc;
pub mod fusion;
pub mod gyro_pointer;
pub mod motion;
pub mod pads;
mod report;
mod rng;
mod sample;
pub mod sony;
pub mod switch;
pub mod transport;
pub mod wiimote;

pub use report::{Battery, DecodeError, Link, MAX_SAMPLES, PadReport};
pub use sample::{ControllerKind, MotionSample, PadButtons};
#[cfg(feature = "hidapi")]
pub use transport::{PadDeviceInfo, discover_pads};
