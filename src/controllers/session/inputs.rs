//! The inputs every controller's events are written in: the Wii Remote's buttons (the
//! vocabulary of the controls; a pad's buttons are mapped onto them by role), a Nunchuk
//! frame, and the IR camera's dots and sensitivity. Their wire encodings live with the device
//! that speaks them (`wiimote::protocol`, `wiimote::ir`).

use glam::DVec2;

/// Core buttons (bit layout of `BB BB`, mask applied).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Buttons(pub u16);

impl Buttons {
    /// D-pad left.
    pub const LEFT: u16 = 0x0001;
    /// D-pad right.
    pub const RIGHT: u16 = 0x0002;
    /// D-pad down.
    pub const DOWN: u16 = 0x0004;
    /// D-pad up.
    pub const UP: u16 = 0x0008;
    /// Plus.
    pub const PLUS: u16 = 0x0010;
    /// Two.
    pub const TWO: u16 = 0x0100;
    /// One.
    pub const ONE: u16 = 0x0200;
    /// B (trigger).
    pub const B: u16 = 0x0400;
    /// A.
    pub const A: u16 = 0x0800;
    /// Minus.
    pub const MINUS: u16 = 0x1000;
    /// Home.
    pub const HOME: u16 = 0x8000;

    /// Decodes the two core-button bytes.
    pub fn from_bytes(b0: u8, b1: u8) -> Self {
        Self(((b0 & 0x1F) as u16) | (((b1 & 0x9F) as u16) << 8))
    }

    /// Encodes to the two core-button bytes (accelerometer low bits zero).
    pub fn to_bytes(self) -> [u8; 2] {
        [(self.0 & 0x1F) as u8, ((self.0 >> 8) & 0x9F) as u8]
    }

    /// True when `button` (one of the constants) is held.
    pub fn pressed(self, button: u16) -> bool {
        self.0 & button != 0
    }
}

/// A decoded pass-through Nunchuk frame (MotionPlus mode 0x05, E5 bit1 = 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NunchukFrame {
    /// Stick X (≈128 centre).
    pub stick_x: u8,
    /// Stick Y (≈128 centre).
    pub stick_y: u8,
    /// C button.
    pub c: bool,
    /// Z button.
    pub z: bool,
}

/// Camera sensitivity: the two register blocks. Levels 1–5 are the console's settings (level 3
/// is its default); `Max` the highest sensitivity documented by WiiBrew.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IrSensitivity {
    /// Wii level 1 (least sensitive).
    Level1,
    /// Wii level 2.
    Level2,
    /// Wii level 3, the console's default.
    #[default]
    Level3,
    /// Wii level 4.
    Level4,
    /// Wii level 5.
    Level5,
    /// The highest sensitivity (longer range, more stray light).
    Max,
}

/// One tracked IR blob.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IrDot {
    /// Image x, 0..1024 (see the module's conventions).
    pub x: u16,
    /// Image y, 0..768.
    pub y: u16,
    /// Blob size 0..15 (extended and full modes; `None` in basic mode).
    pub size: Option<u8>,
}

impl IrDot {
    /// The dot's position as floating-point pixels.
    pub fn position(&self) -> DVec2 {
        DVec2::new(self.x as f64, self.y as f64)
    }
}

/// Up to four dots, in the camera's slots (an empty slot is `None`).
pub type IrDots = [Option<IrDot>; 4];
