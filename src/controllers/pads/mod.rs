//! Game pads with a gyro — DualSense, DualShock 4, Switch Pro, Joy-Con — run like a Wii
//! Remote: a [`PadDecoder`] for their reports, a [`PadSession`] that runs the start
//! sequence and the fusion filter and speaks the Wii Remote session's events
//! ([`SessionEvent`](crate::controllers::session::SessionEvent)), and an [`EmulatedPad`]
//! that answers byte for byte like the hardware, driven by a motion script with each
//! device's rate, quantisation, noise and bias ([`PadSensorModel`]).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `emulator.rs` | [`EmulatedPad`]: a DualSense, DualShock 4, Switch Pro or Joy-Con that answers the host's start sequence and calibration reads and streams its reports from a motion script, byte for byte, with the device's rate, quantisation, noise and bias. |
//! | `session.rs` | [`PadSession`]: a pad's start sequence, then its reports through the decoder and the orientation filter, out as the Wii Remote session's events. |
//!
//! ```
//! use bevy_wii_deform::controllers::pads::{EmulatedPad, PadEmulatorConfig, PadSession};
//! use bevy_wii_deform::controllers::session::{SessionConfig, SessionEvent};
//! use bevy_wii_deform::controllers::{ControllerKind, Link};
//!
//! let pad = EmulatedPad::new(PadEmulatorConfig::new(ControllerKind::DualSense, Link::Bluetooth));
//! let mut session = PadSession::new(pad, ControllerKind::DualSense, Link::Bluetooth, SessionConfig::default());
//! let info = session.connect().unwrap();
//! assert!(info.factory_calibration);
//! for _ in 0..50 {
//!     session.poll(20).unwrap();
//! }
//! assert!(session.drain_events().any(|e| matches!(e, SessionEvent::Orientation(_))));
//! ```

mod emulator;
mod session;

pub use emulator::{EmulatedPad, PadEmulatorConfig, PadSensorModel};
pub use session::{PadInfo, PadSession};

use super::session::Buttons;
use super::sony::{self, SonyCalibration};
use super::switch::{self, SwitchCalibration};
use super::{ControllerKind, DecodeError, Link, PadButtons, PadReport};

/// A device's calibration, whichever family it belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PadCalibration {
    /// Sony pads.
    Sony(SonyCalibration),
    /// Switch controllers.
    Switch(SwitchCalibration),
}

/// Decodes one device's input reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadDecoder {
    kind: ControllerKind,
    link: Link,
    calibration: PadCalibration,
}

/// Why a decoder cannot be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PadKindError {
    /// The Wii Remote has its own session ([`crate::controllers::wiimote::Session`]).
    #[error("{0} reports are decoded by the Wii Remote session, not a pad decoder")]
    NotAPad(ControllerKind),
}

impl PadDecoder {
    /// A decoder with the datasheet's scales (no calibration report read).
    pub fn new(kind: ControllerKind, link: Link) -> Result<Self, PadKindError> {
        let calibration = if sony::is_sony(kind) {
            PadCalibration::Sony(SonyCalibration::nominal())
        } else if switch::is_switch(kind) {
            PadCalibration::Switch(SwitchCalibration::nominal())
        } else {
            return Err(PadKindError::NotAPad(kind));
        };
        Ok(Self {
            kind,
            link,
            calibration,
        })
    }

    /// Uses `calibration` (of the decoder's family; another family's is ignored).
    pub fn set_calibration(&mut self, calibration: PadCalibration) {
        if std::mem::discriminant(&calibration) == std::mem::discriminant(&self.calibration) {
            self.calibration = calibration;
        }
    }

    /// The calibration in use.
    pub fn calibration(&self) -> PadCalibration {
        self.calibration
    }

    /// The device.
    pub fn kind(&self) -> ControllerKind {
        self.kind
    }

    /// The link.
    pub fn link(&self) -> Link {
        self.link
    }

    /// Decodes one input report (report id first). A Bluetooth report whose CRC fails still
    /// decodes, with `crc_ok: Some(false)`; use [`PadReport::verified`] to refuse it.
    pub fn decode(&self, report: &[u8]) -> Result<PadReport, DecodeError> {
        match &self.calibration {
            PadCalibration::Sony(cal) => sony::decode(self.kind, self.link, report, cal),
            PadCalibration::Switch(cal) => switch::decode(self.kind, report, cal),
        }
    }
}

/// The roles as Wii Remote buttons, the vocabulary of the controls: clutch → B, grab → A,
/// recentre → Home, calibrate → 1, the d-pad → the d-pad, plus → +, minus → −.
pub fn roles_to_wii(b: &PadButtons) -> Buttons {
    let mut bits = 0;
    for (held, bit) in [
        (b.clutch, Buttons::B),
        (b.grab, Buttons::A),
        (b.recentre, Buttons::HOME),
        (b.calibrate, Buttons::ONE),
        (b.up, Buttons::UP),
        (b.down, Buttons::DOWN),
        (b.left, Buttons::LEFT),
        (b.right, Buttons::RIGHT),
        (b.plus, Buttons::PLUS),
        (b.minus, Buttons::MINUS),
    ] {
        if held {
            bits |= bit;
        }
    }
    Buttons(bits)
}

/// The inverse of [`roles_to_wii`] (for emulators driven with Wii buttons).
pub fn roles_from_wii(b: Buttons) -> PadButtons {
    PadButtons {
        clutch: b.pressed(Buttons::B),
        grab: b.pressed(Buttons::A),
        recentre: b.pressed(Buttons::HOME),
        calibrate: b.pressed(Buttons::ONE),
        up: b.pressed(Buttons::UP),
        down: b.pressed(Buttons::DOWN),
        left: b.pressed(Buttons::LEFT),
        right: b.pressed(Buttons::RIGHT),
        plus: b.pressed(Buttons::PLUS),
        minus: b.pressed(Buttons::MINUS),
        raw: b.0 as u32,
    }
}
