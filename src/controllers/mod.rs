//! Motion controllers (no Bevy): **devices → sensor samples → fusion → orientation**.
//!
//! Three tiers, each importing only the tiers above it in this list:
//!
//! 1. **Shared by every controller** (imports no device): what a report is ([`report`],
//!    [`crc`]), what a sample is ([`MotionSample`], [`ControllerKind`]), how a body moves
//!    ([`motion`]), the orientation filters ([`fusion`]), pointing with a gyro
//!    ([`gyro_pointer`]), the I/O ([`transport`]), why Linux will not open a device
//!    ([`diagnosis`]), what a session is set up with and emits ([`session`]), and the
//!    emulators' controls and clock ([`emulation`]).
//! 2. **Devices** — one folder per family, its protocol decoded byte by byte, its start
//!    sequence, factory calibration and a byte-exact emulator: [`wiimote`] (Wii Remote +
//!    MotionPlus and its IR camera, the device the paper used), [`sony`] (DualSense, DualSense
//!    Edge, DualShock 4), [`switch`] (Switch Pro Controller, Joy-Con L/R). Device folders never
//!    import each other. [`pads`] is the one session for the gyro pads of both pad families
//!    (it imports `sony` and `switch`, never `wiimote`).
//! 3. **The manager** ([`manager`]): discovers controllers of every kind and runs one I/O
//!    thread per controller; it is what the ECS layer (`crate::ecs`) talks to.
//!
//! | question | file |
//! |---|---|
//! | how a DualSense's gyro becomes a rotation | `sony/mod.rs` (report → [`MotionSample`]), `pads/session.rs` (start sequence, filter), `fusion/` (the filter) |
//! | which filter turns samples into an orientation | `fusion/mod.rs` |
//! | what the Wii Remote's bytes mean | `wiimote/protocol/`, `wiimote/ir.rs` (`docs/PROTOCOL.md`) |
//! | how a Wii Remote is connected and kept going | `wiimote/session/` |
//! | how a Switch controller is started and calibrated | `switch/mod.rs` (`docs/PROTOCOL-SWITCH.md`) |
//! | what a session is set up with, what it emits, the buttons | `session/` |
//! | how tests emulate a controller and step its time | `wiimote/emulator/`, `pads/emulator.rs`, `emulation/` |
//! | how controllers are found, opened and run on threads | `manager/` |
//! | why a controller cannot be opened on Linux | `diagnosis.rs` (`docs/wiimote-linux.md`) |
//! | the hidapi side | `transport.rs` |
//! | a sample's body frame, a controller's kind, a report's link | `sample.rs`, `report.rs` |
//! | the emulators' reproducible noise | `rng.rs` |

pub mod crc;
pub mod diagnosis;
pub mod emulation;
pub mod fusion;
pub mod gyro_pointer;
pub mod manager;
pub mod motion;
pub mod pads;
mod report;
mod rng;
mod sample;
pub mod session;
pub mod sony;
pub mod switch;
pub mod transport;
pub mod wiimote;

pub use report::{Battery, DecodeError, Link, MAX_SAMPLES, PadReport};
pub use sample::{ControllerKind, MotionSample, PadButtons};
#[cfg(feature = "hidapi")]
pub use transport::{PadDeviceInfo, discover_pads};
