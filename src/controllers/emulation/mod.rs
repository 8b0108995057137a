//! Emulated controllers' shared parts: what a user or test does to a running emulated
//! controller from outside ([`EmulatorControls`]: buttons, Nunchuk, hot-plug, power, the
//! ground-truth motion) and pacing by the app's own, possibly manual, time
//! ([`EmulatorClock`]). Each device's byte-exact emulator lives with the device
//! (`wiimote::EmulatedRemote`, `pads::EmulatedPad`).
//!
//! | question | file |
//! |---|---|
//! | how a test presses buttons, unplugs or powers off an emulated controller | `controls.rs` |
//! | how emulated reports are paced by the app's time (or real time) | `clock.rs` |

mod clock;
mod controls;

pub use clock::EmulatorClock;
pub(crate) use clock::Pacing;
pub use controls::EmulatorControls;
