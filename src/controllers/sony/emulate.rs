//! What an emulated Sony pad sends: its factory calibration report and its input reports,
//! byte for byte in the layouts [`super::decode`] reads.

use glam::DVec3;

use super::{
    BT_REPORT_LEN, CRC_SEED_FEATURE, CRC_SEED_INPUT, NOMINAL_ACCEL_COUNTS_PER_G,
    NOMINAL_GYRO_COUNTS_PER_DPS, USB_REPORT, USB_REPORT_LEN, calibration_report, is_dualsense,
    layout,
};
use crate::controllers::crc::crc32_seeded;
use crate::controllers::rng::Rng;
use crate::controllers::{ControllerKind, Link, PadButtons};

/// Body frame → the pad's native axes (the inverse of `super::to_body`).
pub(crate) fn to_native(v: DVec3) -> [f64; 3] {
    [-v.x, v.z, v.y]
}

/// One unit's true sensitivities, and the factory numbers that describe them.
#[derive(Debug, Clone)]
pub(crate) struct SonyUnit {
    /// True gyro counts per deg/s, native axes.
    pub(crate) gyro_counts_per_dps: [f64; 3],
    /// True accelerometer counts per g.
    pub(crate) accel_counts_per_g: [f64; 3],
    /// True accelerometer zero, counts.
    pub(crate) accel_zero: [f64; 3],
    gyro_bias_field: [i16; 3],
}

impl SonyUnit {
    /// Draws a unit whose scales differ from the datasheet's by up to `scale_error`.
    pub(crate) fn draw(rng: &mut Rng, scale_error: f64) -> Self {
        let mut around = |nominal: f64| nominal * (1.0 + rng.range(-scale_error, scale_error));
        let gyro_counts_per_dps = [0; 3].map(|_: i32| around(NOMINAL_GYRO_COUNTS_PER_DPS));
        let accel_counts_per_g = [0; 3].map(|_: i32| around(NOMINAL_ACCEL_COUNTS_PER_G));
        let accel_zero = [0; 3].map(|_: i32| rng.range(-60.0, 60.0).round());
        let gyro_bias_field = [0; 3].map(|_: i32| rng.range(-20.0, 20.0).round() as i16);
        Self {
            gyro_counts_per_dps,
            accel_counts_per_g,
            accel_zero,
            gyro_bias_field,
        }
    }

    /// The calibration feature report this unit answers with (CRC-32 over Bluetooth).
    pub(crate) fn calibration_report(&self, kind: ControllerKind, link: Link) -> Vec<u8> {
        let (id, len) = calibration_report(kind, link);
        let mut r = vec![0u8; len];
        r[0] = id;
        let mut put = |at: usize, v: f64| {
            let v = v.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16;
            r[at..at + 2].copy_from_slice(&v.to_le_bytes());
        };
        for a in 0..3 {
            put(1 + 2 * a, self.gyro_bias_field[a] as f64);
        }
        // The factory turns the pad at ±speed deg/s and stores what each axis read.
        let speed = 540.0;
        let plus =
            [0, 1, 2].map(|a| self.gyro_bias_field[a] as f64 + speed * self.gyro_counts_per_dps[a]);
        let minus =
            [0, 1, 2].map(|a| self.gyro_bias_field[a] as f64 - speed * self.gyro_counts_per_dps[a]);
        if !is_dualsense(kind) && link == Link::Usb {
            for a in 0..3 {
                put(7 + 2 * a, plus[a]);
                put(13 + 2 * a, minus[a]);
            }
        } else {
            for a in 0..3 {
                put(7 + 4 * a, plus[a]);
                put(9 + 4 * a, minus[a]);
            }
        }
        put(19, speed);
        put(21, speed);
        for a in 0..3 {
            put(23 + 4 * a, self.accel_zero[a] + self.accel_counts_per_g[a]);
            put(25 + 4 * a, self.accel_zero[a] - self.accel_counts_per_g[a]);
        }
        if link == Link::Bluetooth {
            let crc = crc32_seeded(CRC_SEED_FEATURE, &r[..len - 4]);
            r[len - 4..].copy_from_slice(&crc.to_le_bytes());
        }
        r
    }
}

/// The three button bytes for held roles (clutch → R2, grab → Cross, recentre → PS,
/// calibrate → Triangle, the d-pad as the hat, plus → Options, minus → Create).
pub(crate) fn button_bytes(b: &PadButtons) -> [u8; 3] {
    let hat = match (b.up, b.right, b.down, b.left) {
        (true, true, _, _) => 1,
        (_, true, true, _) => 3,
        (_, _, true, true) => 5,
        (true, _, _, true) => 7,
        (true, _, _, _) => 0,
        (_, true, _, _) => 2,
        (_, _, true, _) => 4,
        (_, _, _, true) => 6,
        _ => 8,
    };
    let mut out = [hat, 0, 0];
    if b.plus {
        out[1] |= 0x20;
    }
    if b.minus {
        out[1] |= 0x10;
    }
    if b.grab {
        out[0] |= 0x20;
    }
    if b.calibrate {
        out[0] |= 0x80;
    }
    if b.clutch {
        out[1] |= 0x08;
    }
    if b.recentre {
        out[2] |= 0x01;
    }
    out
}

/// One sensor reading in counts, with the pad's timestamp ticks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SonyRaw {
    pub(crate) gyro: [i16; 3],
    pub(crate) accel: [i16; 3],
    /// Sensor clock ticks (1/3 µs DualSense, 16/3 µs DualShock 4; wraps).
    pub(crate) ticks: u32,
}

/// Writes a full input report into `out` (cleared first).
pub(crate) fn encode_input(
    kind: ControllerKind,
    link: Link,
    seq: u8,
    raw: &SonyRaw,
    buttons: &PadButtons,
    battery_percent: u8,
    out: &mut Vec<u8>,
) {
    let (id, base, len) = layout(kind, link);
    out.clear();
    out.resize(len, 0);
    out[0] = id;
    if link == Link::Bluetooth {
        // DualSense: a sequence tag; DualShock 4: the polling-rate/HID-enable byte.
        out[1] = if is_dualsense(kind) { seq << 4 } else { 0xC0 };
    }
    let c = &mut out[base..];
    c[..4].copy_from_slice(&[0x80; 4]);
    let b = button_bytes(buttons);
    let level = (battery_percent / 10).min(10);
    let (buttons_at, gyro_at) = if is_dualsense(kind) {
        c[6] = seq;
        c[27..31].copy_from_slice(&raw.ticks.to_le_bytes());
        c[52] = level;
        (7, 15)
    } else {
        c[9..11].copy_from_slice(&(raw.ticks as u16).to_le_bytes());
        c[29] = level;
        (4, 12)
    };
    c[buttons_at..buttons_at + 3].copy_from_slice(&b);
    if !is_dualsense(kind) {
        // The DualShock 4's third button byte counts reports in its upper six bits.
        c[buttons_at + 2] |= seq << 2;
    }
    for i in 0..3 {
        c[gyro_at + 2 * i..gyro_at + 2 * i + 2].copy_from_slice(&raw.gyro[i].to_le_bytes());
        c[gyro_at + 6 + 2 * i..gyro_at + 8 + 2 * i].copy_from_slice(&raw.accel[i].to_le_bytes());
    }
    if link == Link::Bluetooth {
        let crc = crc32_seeded(CRC_SEED_INPUT, &out[..len - 4]);
        out[len - 4..].copy_from_slice(&crc.to_le_bytes());
    }
    debug_assert!(out.len() == BT_REPORT_LEN || out.len() == USB_REPORT_LEN);
}

/// The reduced Bluetooth report 0x01 a pad sends until its calibration is read: sticks and
/// buttons, no sensors.
pub(crate) fn encode_reduced(buttons: &PadButtons, out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&[USB_REPORT, 0x80, 0x80, 0x80, 0x80]);
    out.extend_from_slice(&button_bytes(buttons));
    out.extend_from_slice(&[0, 0]);
}
