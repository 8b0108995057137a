//! Sony pads: DualSense, DualSense Edge and DualShock 4, over USB and Bluetooth
//! (`docs/PROTOCOL-SONY.md`).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `emulate.rs` | What an emulated Sony pad sends: its factory calibration report and its input reports, byte for byte in the layouts [`super::decode`] reads. |
//! | `output.rs` | Sony output reports: rumble, the light bar and the player lights — what the session writes after the start sequence (the player's number and colour, as a Wii Remote lights its LEDs) and on a rumble command. |
//!
//! * **Start sequence.** Reading the calibration feature report is the whole handshake: over
//!   Bluetooth it is also what switches the pad from its reduced report 0x01 (buttons and
//!   sticks only) to the full report (0x31 DualSense, 0x11 DualShock 4).
//! * **Calibration.** [`SonyCalibration::parse`] reads feature report 0x05 (DualSense, and
//!   DualShock 4 over Bluetooth) or 0x02 (DualShock 4 over USB) as Linux's `hid-playstation`
//!   does; an axis whose numbers are out of range falls back to the datasheet scale.
//! * **Input.** [`decode`] turns a report into one [`MotionSample`] (the pad's own timestamp
//!   included), the buttons and the battery, checking the CRC-32 over Bluetooth.
//!
//! **Native axes** (the pad flat on a table, seen from the player): +x right, +y up out of
//! the face, +z toward the player; gyro x = pitch, y = yaw, z = roll, right-handed. Into the
//! crate's body frame ([`MotionSample`]): `(X, Y, Z) = (−x, z, y)`.

pub(crate) mod emulate;
mod output;

pub use output::{SonyOutput, output_report, parse_output, player_output};

use glam::DVec3;

use super::crc::crc32_seeded;
use super::motion::GRAVITY;
use super::report::{check_report, le_i16, le_u32};
use super::{Battery, ControllerKind, DecodeError, Link, MotionSample, PadButtons, PadReport};

/// CRC seed (the Bluetooth HID header) of input reports.
pub const CRC_SEED_INPUT: u8 = 0xA1;
/// CRC seed of output reports.
pub const CRC_SEED_OUTPUT: u8 = 0xA2;
/// CRC seed of feature reports.
pub const CRC_SEED_FEATURE: u8 = 0xA3;

/// DualSense full report over Bluetooth.
pub const DUALSENSE_BT_REPORT: u8 = 0x31;
/// DualShock 4 full report over Bluetooth.
pub const DS4_BT_REPORT: u8 = 0x11;
/// USB input report (both pads), and the reduced Bluetooth report.
pub const USB_REPORT: u8 = 0x01;
/// Length of a USB input report.
pub const USB_REPORT_LEN: usize = 64;
/// Length of a Bluetooth full report (CRC-32 in its last four bytes).
pub const BT_REPORT_LEN: usize = 78;

/// Datasheet gyro scale: ±2000 deg/s over 16 bits.
pub const NOMINAL_GYRO_COUNTS_PER_DPS: f64 = 32768.0 / 2000.0;
/// Datasheet accelerometer scale: ±4 g over 16 bits.
pub const NOMINAL_ACCEL_COUNTS_PER_G: f64 = 8192.0;
/// Sony sensor clock tick of the DualSense (its 32-bit timestamp counts 1/3 µs).
const DUALSENSE_TICK_S: f64 = 1.0 / 3.0e6;
/// The DualShock 4's 16-bit timestamp counts 16/3 µs.
const DS4_TICK_S: f64 = 16.0 / 3.0e6;

/// Whether `kind` is one of Sony's pads.
pub fn is_sony(kind: ControllerKind) -> bool {
    matches!(
        kind,
        ControllerKind::DualSense | ControllerKind::DualSenseEdge | ControllerKind::DualShock4
    )
}

fn is_dualsense(kind: ControllerKind) -> bool {
    matches!(
        kind,
        ControllerKind::DualSense | ControllerKind::DualSenseEdge
    )
}

/// Where a report's common block starts, and the full report's id, for a pad and link.
fn layout(kind: ControllerKind, link: Link) -> (u8, usize, usize) {
    match (is_dualsense(kind), link) {
        (true, Link::Usb) => (USB_REPORT, 1, USB_REPORT_LEN),
        (true, Link::Bluetooth) => (DUALSENSE_BT_REPORT, 2, BT_REPORT_LEN),
        (false, Link::Usb) => (USB_REPORT, 1, USB_REPORT_LEN),
        (false, Link::Bluetooth) => (DS4_BT_REPORT, 3, BT_REPORT_LEN),
    }
}

/// The calibration feature report's id and length for a pad and link.
pub fn calibration_report(kind: ControllerKind, link: Link) -> (u8, usize) {
    match (is_dualsense(kind), link) {
        (true, _) => (0x05, 41),
        (false, Link::Usb) => (0x02, 37),
        (false, Link::Bluetooth) => (0x05, 41),
    }
}

/// Native sensor axes → the crate's body frame.
#[inline]
fn to_body(v: [f64; 3]) -> DVec3 {
    DVec3::new(-v[0], v[2], v[1])
}

/// How raw counts become SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SonyCalibration {
    /// Deg/s per count, native axes (pitch, yaw, roll).
    pub gyro_dps_per_count: [f64; 3],
    /// Accelerometer zero, counts, native axes.
    pub accel_zero: [f64; 3],
    /// G per count, native axes.
    pub accel_g_per_count: [f64; 3],
    /// Axes (gyro x, y, z, then accel x, y, z) whose factory numbers were out of range and
    /// got the datasheet scale instead.
    pub fallback_axes: [bool; 6],
}

impl SonyCalibration {
    /// Datasheet scales, no offsets: what a pad whose calibration cannot be read gets.
    pub fn nominal() -> Self {
        Self {
            gyro_dps_per_count: [1.0 / NOMINAL_GYRO_COUNTS_PER_DPS; 3],
            accel_zero: [0.0; 3],
            accel_g_per_count: [1.0 / NOMINAL_ACCEL_COUNTS_PER_G; 3],
            fallback_axes: [false; 6],
        }
    }

    /// Whether every axis came from the pad's factory numbers.
    pub fn is_factory(&self) -> bool {
        !self.fallback_axes.iter().any(|&f| f)
    }

    /// Parses the calibration feature report (report id first; over Bluetooth its last four
    /// bytes are a CRC-32 seeded with `0xA3`).
    ///
    /// Gyro: `deg/s = raw · (speed₊ + speed₋) / (|plus − bias| + |minus − bias|)` per axis.
    /// The bias field is *not* subtracted from readings, as Linux does not since 6.2 (the
    /// fusion filters estimate the residual bias anyway). Accelerometer:
    /// `g = (raw − (plus + minus)/2) · 2 / (plus − minus)`. An axis whose scale is not within
    /// a factor of two of the datasheet's falls back to it ([`Self::fallback_axes`]).
    pub fn parse(kind: ControllerKind, link: Link, report: &[u8]) -> Result<Self, DecodeError> {
        let (id, len) = calibration_report(kind, link);
        check_report(report, id, len, kind)?;
        if link == Link::Bluetooth {
            let stored = le_u32(report, len - 4);
            if crc32_seeded(CRC_SEED_FEATURE, &report[..len - 4]) != stored {
                return Err(DecodeError::Crc);
            }
        }
        let r = |at: usize| le_i16(report, at) as f64;
        let bias = [r(1), r(3), r(5)];
        // DualShock 4 over USB lists the three "plus" values, then the three "minus" ones;
        // every other report pairs them per axis.
        let (plus, minus) = if !is_dualsense(kind) && link == Link::Usb {
            ([r(7), r(9), r(11)], [r(13), r(15), r(17)])
        } else {
            ([r(7), r(11), r(15)], [r(9), r(13), r(17)])
        };
        let speed_2x = r(19) + r(21);
        let mut cal = Self::nominal();
        for a in 0..3 {
            let denom = (plus[a] - bias[a]).abs() + (minus[a] - bias[a]).abs();
            let scale = speed_2x / denom;
            let nominal = 1.0 / NOMINAL_GYRO_COUNTS_PER_DPS;
            if denom > 0.0 && scale.is_finite() && scale > nominal * 0.5 && scale < nominal * 2.0 {
                cal.gyro_dps_per_count[a] = scale;
            } else {
                cal.fallback_axes[a] = true;
            }
            let acc_plus = r(23 + 4 * a);
            let acc_minus = r(25 + 4 * a);
            let range_2g = acc_plus - acc_minus;
            let g_per_count = 2.0 / range_2g;
            let nominal = 1.0 / NOMINAL_ACCEL_COUNTS_PER_G;
            if range_2g > 0.0 && g_per_count > nominal * 0.5 && g_per_count < nominal * 2.0 {
                cal.accel_g_per_count[a] = g_per_count;
                cal.accel_zero[a] = acc_plus - range_2g / 2.0;
            } else {
                cal.fallback_axes[3 + a] = true;
            }
        }
        Ok(cal)
    }
}

/// The roles of Sony's buttons ([`PadButtons`]): clutch R2 or R1, grab Cross, recentre the
/// PS button, calibrate Triangle, the d-pad (the hat), plus Options, minus Create/Share. `raw` holds the three button bytes (byte 0 in
/// the low bits: d-pad hat, Square, Cross, Circle, Triangle; byte 1: L1, R1, L2, R2,
/// Create/Share, Options, L3, R3; byte 2: PS, touchpad, and the DualSense's mute — the
/// DualShock 4 counts reports in that byte's upper six bits, which are masked off).
fn buttons(b: [u8; 3], third_mask: u8) -> PadButtons {
    let raw = b[0] as u32 | (b[1] as u32) << 8 | ((b[2] & third_mask) as u32) << 16;
    // The hat: 0 north, clockwise in eighths, 8 (or more) released.
    let hat = b[0] & 0x0F;
    let pressed = |dirs: [u8; 3]| dirs.contains(&hat);
    PadButtons {
        clutch: b[1] & 0x0A != 0,
        grab: b[0] & 0x20 != 0,
        recentre: b[2] & 0x01 != 0,
        calibrate: b[0] & 0x80 != 0,
        up: pressed([7, 0, 1]),
        right: pressed([1, 2, 3]),
        down: pressed([3, 4, 5]),
        left: pressed([5, 6, 7]),
        plus: b[1] & 0x20 != 0,
        minus: b[1] & 0x10 != 0,
        raw,
    }
}

/// Decodes an input report (report id first; over Bluetooth without the `0xA1` header byte,
/// which the CRC is nevertheless seeded with) with `cal`.
pub fn decode(
    kind: ControllerKind,
    link: Link,
    report: &[u8],
    cal: &SonyCalibration,
) -> Result<PadReport, DecodeError> {
    let Some(&id) = report.first() else {
        return Err(DecodeError::Empty);
    };
    let (full_id, base, len) = layout(kind, link);
    if id != full_id {
        if link == Link::Bluetooth && id == USB_REPORT {
            return Err(DecodeError::NoMotion { id });
        }
        return Err(DecodeError::UnknownReport { id, kind });
    }
    if report.len() < len {
        return Err(DecodeError::Short {
            id,
            len: report.len(),
            need: len,
        });
    }
    let crc_ok = match link {
        Link::Usb => None,
        Link::Bluetooth => {
            Some(crc32_seeded(CRC_SEED_INPUT, &report[..len - 4]) == le_u32(report, len - 4))
        }
    };
    let c = &report[base..];
    let (button_bytes, gyro_at, time_s, battery) = if is_dualsense(kind) {
        let status = c[52];
        let battery = Battery {
            percent: ((status & 0x0F) * 10).min(100),
            charging: status >> 4 == 0x1,
        };
        let time = le_u32(c, 27) as f64 * DUALSENSE_TICK_S;
        ([c[7], c[8], c[9]], 15, time, battery)
    } else {
        let status = c[29];
        let cable = status & 0x10 != 0;
        let battery = Battery {
            percent: ((status & 0x0F) * 10).min(100),
            charging: cable && status & 0x0F < 11,
        };
        let time = u16::from_le_bytes([c[9], c[10]]) as f64 * DS4_TICK_S;
        ([c[4], c[5], c[6]], 12, time, battery)
    };
    let third_mask = if is_dualsense(kind) { 0x07 } else { 0x03 };
    let mut out = PadReport::new(buttons(button_bytes, third_mask), Some(battery), crc_ok);
    let raw = |i: usize| le_i16(c, gyro_at + 2 * i) as f64;
    let deg = std::f64::consts::PI / 180.0;
    let gyro = [0, 1, 2].map(|a| raw(a) * cal.gyro_dps_per_count[a] * deg);
    let accel =
        [0, 1, 2].map(|a| (raw(3 + a) - cal.accel_zero[a]) * cal.accel_g_per_count[a] * GRAVITY);
    out.push(MotionSample {
        gyro_rps: to_body(gyro),
        accel_mps2: to_body(accel),
        device_time_s: Some(time_s),
    });
    Ok(out)
}
