//! What an emulated Switch controller sends: subcommand replies (SPI flash reads included),
//! USB handshake replies, and full reports with three IMU samples.

use glam::DVec3;

use super::{
    FULL_REPORT, NOMINAL_ACCEL_DIVISOR, NOMINAL_GYRO_DIVISOR, REPLY_REPORT, SIMPLE_REPORT,
    SPI_FACTORY_IMU, USB_REPLY_REPORT,
};
use crate::controllers::rng::Rng;
use crate::controllers::{ControllerKind, PadButtons};

/// Body frame → native axes (the inverse of `super::to_body`).
pub(crate) fn to_native(kind: ControllerKind, v: DVec3) -> [f64; 3] {
    if kind == ControllerKind::JoyConRight {
        [-v.y, -v.x, -v.z]
    } else {
        [-v.y, v.x, v.z]
    }
}

/// One unit's true sensor constants and its SPI flash.
#[derive(Debug, Clone)]
pub(crate) struct SwitchUnit {
    /// True accelerometer counts per g.
    pub(crate) accel_counts_per_g: [f64; 3],
    /// True gyro zero, counts.
    pub(crate) gyro_origin: [f64; 3],
    /// True gyro counts per deg/s.
    pub(crate) gyro_counts_per_dps: [f64; 3],
    factory: [u8; 24],
}

impl SwitchUnit {
    /// Draws a unit whose scales differ from the datasheet's by up to `scale_error`.
    pub(crate) fn draw(rng: &mut Rng, scale_error: f64) -> Self {
        let mut around = |nominal: f64| nominal * (1.0 + rng.range(-scale_error, scale_error));
        let accel_divisor = [0; 3].map(|_: i32| around(NOMINAL_ACCEL_DIVISOR));
        let gyro_divisor = [0; 3].map(|_: i32| around(NOMINAL_GYRO_DIVISOR));
        let gyro_origin = [0; 3].map(|_: i32| rng.range(-40.0, 40.0).round());
        let accel_origin = [0; 3].map(|_: i32| rng.range(-300.0, 300.0).round());
        let mut factory = [0u8; 24];
        let mut put = |i: usize, v: f64| {
            let v = v.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16;
            factory[2 * i..2 * i + 2].copy_from_slice(&v.to_le_bytes());
        };
        for a in 0..3 {
            put(a, accel_origin[a]);
            put(3 + a, accel_origin[a] + accel_divisor[a].round());
            put(6 + a, gyro_origin[a]);
            put(9 + a, gyro_origin[a] + gyro_divisor[a].round());
        }
        Self {
            accel_counts_per_g: accel_divisor.map(|d| d.round() / 4.0),
            gyro_origin,
            gyro_counts_per_dps: gyro_divisor.map(|d| d.round() / 936.0),
            factory,
        }
    }

    /// `len` bytes of SPI flash at `addr` (0xFF where nothing is written, as erased flash).
    pub(crate) fn spi(&self, addr: u32, len: usize) -> Vec<u8> {
        (0..len as u32)
            .map(|i| {
                let a = addr + i;
                // Everything else erased, the user block included (no B2 A1 magic).
                if (SPI_FACTORY_IMU..SPI_FACTORY_IMU + 24).contains(&a) {
                    self.factory[(a - SPI_FACTORY_IMU) as usize]
                } else {
                    0xFF
                }
            })
            .collect()
    }
}

/// Bytes 3–5 (right, shared, left) for held roles: clutch → ZR, grab → A, recentre →
/// Home, calibrate → X, the d-pad, + and −; on a left Joy-Con ZL, →, Capture, ↑ (and no
/// d-pad); a right Joy-Con has none either.
pub(crate) fn button_bytes(kind: ControllerKind, b: &PadButtons) -> [u8; 3] {
    let mut out = [0u8; 3];
    out[1] |= if b.plus { 0x02 } else { 0 } | if b.minus { 0x01 } else { 0 };
    if kind == ControllerKind::SwitchPro {
        for (held, bit) in [
            (b.down, 0x01),
            (b.up, 0x02),
            (b.right, 0x04),
            (b.left, 0x08),
        ] {
            if held {
                out[2] |= bit;
            }
        }
    }
    if kind == ControllerKind::JoyConLeft {
        out[2] |= if b.clutch { 0x80 } else { 0 } | if b.grab { 0x04 } else { 0 };
        out[2] |= if b.calibrate { 0x02 } else { 0 };
        out[1] |= if b.recentre { 0x20 } else { 0 };
    } else {
        out[0] |= if b.clutch { 0x80 } else { 0 } | if b.grab { 0x08 } else { 0 };
        out[0] |= if b.calibrate { 0x02 } else { 0 };
        out[1] |= if b.recentre { 0x10 } else { 0 };
    }
    out
}

/// The first 13 bytes every input report shares.
fn header(
    id: u8,
    timer: u8,
    kind: ControllerKind,
    buttons: &PadButtons,
    battery_percent: u8,
    out: &mut Vec<u8>,
    len: usize,
) {
    out.clear();
    out.resize(len, 0);
    out[0] = id;
    out[1] = timer;
    let level = (battery_percent / 25).min(4);
    // Connection nibble: 0xE = Pro/grip powered by itself, on Bluetooth.
    out[2] = (level << 5) | 0x0E;
    out[3..6].copy_from_slice(&button_bytes(kind, buttons));
    // Sticks centred (12-bit 0x800 each), vibrator byte.
    out[6..9].copy_from_slice(&[0x00, 0x08, 0x80]);
    out[9..12].copy_from_slice(&[0x00, 0x08, 0x80]);
    out[12] = 0x09;
}

/// A full report 0x30 with three samples (accel x y z, gyro x y z counts each), oldest
/// first.
pub(crate) fn encode_full(
    kind: ControllerKind,
    timer: u8,
    samples: &[[i16; 6]; 3],
    buttons: &PadButtons,
    battery_percent: u8,
    out: &mut Vec<u8>,
) {
    header(FULL_REPORT, timer, kind, buttons, battery_percent, out, 49);
    for (s, sample) in samples.iter().enumerate() {
        for (i, v) in sample.iter().enumerate() {
            let at = 13 + 12 * s + 2 * i;
            out[at..at + 2].copy_from_slice(&v.to_le_bytes());
        }
    }
}

/// The simple HID report 0x3F a controller sends before its mode is set.
pub(crate) fn encode_simple(out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&[
        SIMPLE_REPORT,
        0,
        0,
        0x08,
        0x00,
        0x80,
        0x00,
        0x80,
        0x00,
        0x80,
        0x00,
        0x80,
    ]);
}

/// A subcommand reply 0x21 acknowledging `id` with `data`.
pub(crate) fn encode_reply(
    kind: ControllerKind,
    timer: u8,
    id: u8,
    data: &[u8],
    buttons: &PadButtons,
    out: &mut Vec<u8>,
) {
    header(
        REPLY_REPORT,
        timer,
        kind,
        buttons,
        100,
        out,
        49.max(15 + data.len()),
    );
    out[13] = if data.is_empty() { 0x80 } else { 0x90 };
    out[14] = id;
    out[15..15 + data.len()].copy_from_slice(data);
}

/// A USB command reply `0x81 <cmd>`.
pub(crate) fn encode_usb_reply(cmd: u8, out: &mut Vec<u8>) {
    out.clear();
    out.resize(64, 0);
    out[0] = USB_REPLY_REPORT;
    out[1] = cmd;
}
