//! Nintendo Switch controllers: Pro Controller and Joy-Con (L)/(R), over Bluetooth and (the
//! Pro Controller) USB (`docs/PROTOCOL-SWITCH.md`).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `emulate.rs` | What an emulated Switch controller sends: subcommand replies (SPI flash reads included), USB handshake replies, and full reports with three IMU samples. |
//!
//! * **Start sequence** ([`start_sequence`]): over USB the `0x80` handshake that makes the Pro
//!   Controller talk HID; then subcommands in output report 0x01 — input report mode 0x30
//!   (full, 60–67 Hz), IMU on, and two SPI flash reads for the factory and user IMU
//!   calibration. Every subcommand is answered by input report 0x21.
//! * **Calibration** ([`SwitchCalibration`]): from SPI flash 0x6020 (factory) or 0x8028
//!   (user, when 0x8026 holds the magic `B2 A1`), as dekuNukem's notes give the formulas; an
//!   axis out of range falls back to the datasheet.
//! * **Input** ([`decode`]): report 0x30 carries **three** IMU samples, 5 ms apart over
//!   Bluetooth, **oldest first** (dekuNukem: "1st sample 0 ms, 2nd 5 ms, 3rd 10 ms"; Linux's
//!   `hid-nintendo` stamps them in that order), no CRC, no sensor timestamp.
//!
//! **Native axes** (Pro Controller flat, seen from the player): +x away from the player, +y
//! left, +z up; gyro right-handed about them. Into the crate's body frame: `(X, Y, Z) =
//! (y, −x, z)`. The right Joy-Con's IMU sits turned half a turn about x, so for it
//! `(X, Y, Z) = (−y, −x, −z)`. A Joy-Con's frame is its frame in the grip — upright, held
//! like a Wii Remote, which is how a single Joy-Con points.

pub(crate) mod emulate;

use glam::DVec3;

use super::motion::GRAVITY;
use super::report::{check_report, le_i16};
use super::{Battery, ControllerKind, DecodeError, Link, MotionSample, PadButtons, PadReport};

/// Full input report (buttons, sticks, three IMU samples).
pub const FULL_REPORT: u8 = 0x30;
/// Subcommand reply.
pub const REPLY_REPORT: u8 = 0x21;
/// The simple HID report a controller sends before it is switched to 0x30.
pub const SIMPLE_REPORT: u8 = 0x3F;
/// USB command reply (Pro Controller over USB).
pub const USB_REPLY_REPORT: u8 = 0x81;
/// Output report carrying rumble and a subcommand.
pub const SUBCOMMAND_REPORT: u8 = 0x01;
/// Length of reports 0x30 and 0x21 that the decoder needs.
pub const FULL_REPORT_LEN: usize = 49;
/// Length of the subcommand output report.
pub const SUBCOMMAND_LEN: usize = 49;
/// Rumble bytes meaning "no rumble" (320 Hz / 160 Hz at amplitude 0).
pub const NEUTRAL_RUMBLE: [u8; 8] = [0x00, 0x01, 0x40, 0x40, 0x00, 0x01, 0x40, 0x40];

/// Subcommand: set input report mode (argument 0x30 = full).
pub const SUB_INPUT_MODE: u8 = 0x03;
/// Subcommand: read SPI flash (address u32 LE, length u8 ≤ 0x1D).
pub const SUB_SPI_READ: u8 = 0x10;
/// Subcommand: set the player LEDs.
pub const SUB_PLAYER_LIGHTS: u8 = 0x30;
/// Subcommand: IMU on (1) / off (0).
pub const SUB_IMU: u8 = 0x40;

/// SPI address of the factory IMU calibration (24 bytes).
pub const SPI_FACTORY_IMU: u32 = 0x6020;
/// SPI address of the user IMU calibration's magic (2 bytes `B2 A1`, then 24 bytes).
pub const SPI_USER_IMU: u32 = 0x8026;

/// Datasheet accelerometer: ±8 g, so 4 g is 16384 counts.
pub const NOMINAL_ACCEL_DIVISOR: f64 = 16384.0;
/// Datasheet gyro: 936 deg/s is 13371 counts (±2000 deg/s range).
pub const NOMINAL_GYRO_DIVISOR: f64 = 13371.0;

/// Whether `kind` is one of Nintendo's Switch controllers.
pub fn is_switch(kind: ControllerKind) -> bool {
    matches!(
        kind,
        ControllerKind::SwitchPro | ControllerKind::JoyConLeft | ControllerKind::JoyConRight
    )
}

#[inline]
fn to_body(kind: ControllerKind, v: [f64; 3]) -> DVec3 {
    if kind == ControllerKind::JoyConRight {
        DVec3::new(-v[1], -v[0], -v[2])
    } else {
        DVec3::new(v[1], -v[0], v[2])
    }
}

/// How raw counts become SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwitchCalibration {
    /// Accelerometer: `g = raw · 4 / divisor` per native axis.
    pub accel_divisor: [f64; 3],
    /// Gyro origin, counts per native axis.
    pub gyro_origin: [f64; 3],
    /// Gyro: `deg/s = (raw − origin) · 936 / divisor`.
    pub gyro_divisor: [f64; 3],
    /// Axes (accel x, y, z, then gyro x, y, z) that fell back to the datasheet.
    pub fallback_axes: [bool; 6],
    /// Where the numbers came from.
    pub source: CalibrationSource,
}

/// Which SPI block a [`SwitchCalibration`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CalibrationSource {
    /// Datasheet values (nothing read yet).
    Nominal,
    /// The factory block at 0x6020.
    Factory,
    /// The user block at 0x8028 (the user recalibrated in the console's settings).
    User,
}

impl SwitchCalibration {
    /// Datasheet values.
    pub fn nominal() -> Self {
        Self {
            accel_divisor: [NOMINAL_ACCEL_DIVISOR; 3],
            gyro_origin: [0.0; 3],
            gyro_divisor: [NOMINAL_GYRO_DIVISOR; 3],
            fallback_axes: [false; 6],
            source: CalibrationSource::Nominal,
        }
    }

    /// Parses a 24-byte IMU calibration block: accelerometer origin, accelerometer
    /// sensitivity, gyro origin, gyro sensitivity, three little-endian `i16` each.
    pub fn from_block(block: &[u8], source: CalibrationSource) -> Result<Self, DecodeError> {
        if block.len() < 24 {
            return Err(DecodeError::Short {
                id: REPLY_REPORT,
                len: block.len(),
                need: 24,
            });
        }
        let r = |i: usize| le_i16(block, 2 * i) as f64;
        let mut cal = Self::nominal();
        cal.source = source;
        let sane = |d: f64, nominal: f64| d.is_finite() && d > nominal * 0.5 && d < nominal * 2.0;
        for a in 0..3 {
            let accel = r(3 + a) - r(a);
            if sane(accel, NOMINAL_ACCEL_DIVISOR) {
                cal.accel_divisor[a] = accel;
            } else {
                cal.fallback_axes[a] = true;
            }
            let origin = r(6 + a);
            let gyro = r(9 + a) - origin;
            if sane(gyro, NOMINAL_GYRO_DIVISOR) && origin.abs() < 2000.0 {
                cal.gyro_origin[a] = origin;
                cal.gyro_divisor[a] = gyro;
            } else {
                cal.fallback_axes[3 + a] = true;
            }
        }
        Ok(cal)
    }
}

/// The roles of the Switch's buttons: clutch ZR/R (ZL/L), grab A/B, recentre Home/Capture,
/// calibrate X, the d-pad, plus +, minus −. A left Joy-Con held alone has its arrows as face
/// buttons: → grabs and ↑ calibrates (no d-pad). `raw` holds bytes 3–5 of the report (right,
/// shared, left) in its low 24 bits.
fn buttons(kind: ControllerKind, b: [u8; 3]) -> PadButtons {
    let [right, shared, left] = b;
    let arrows_are_faces = kind == ControllerKind::JoyConLeft;
    let dpad = |bit: u8| !arrows_are_faces && left & bit != 0;
    PadButtons {
        clutch: right & 0xC0 != 0 || left & 0xC0 != 0,
        grab: right & 0x0C != 0 || (arrows_are_faces && left & 0x04 != 0),
        recentre: shared & 0x30 != 0,
        calibrate: right & 0x02 != 0 || (arrows_are_faces && left & 0x02 != 0),
        up: dpad(0x02),
        down: dpad(0x01),
        right: dpad(0x04),
        left: dpad(0x08),
        plus: shared & 0x02 != 0,
        minus: shared & 0x01 != 0,
        raw: right as u32 | (shared as u32) << 8 | (left as u32) << 16,
    }
}

/// Battery from byte 2's high nibble (level 0–4 in bits 5–7, charging in bit 4).
fn battery(byte: u8) -> Battery {
    let nibble = byte >> 4;
    Battery {
        percent: ((nibble >> 1).min(4) * 25),
        charging: nibble & 1 != 0,
    }
}

/// Decodes a full report 0x30 (or a subcommand reply 0x21, which carries buttons but no
/// samples) with `cal`. The three samples come out oldest first; they carry no device time.
pub fn decode(
    kind: ControllerKind,
    report: &[u8],
    cal: &SwitchCalibration,
) -> Result<PadReport, DecodeError> {
    let Some(&id) = report.first() else {
        return Err(DecodeError::Empty);
    };
    match id {
        FULL_REPORT | REPLY_REPORT => {}
        SIMPLE_REPORT => return Err(DecodeError::NoMotion { id }),
        _ => return Err(DecodeError::UnknownReport { id, kind }),
    }
    let need = if id == FULL_REPORT {
        FULL_REPORT_LEN
    } else {
        15
    };
    if report.len() < need {
        return Err(DecodeError::Short {
            id,
            len: report.len(),
            need,
        });
    }
    let mut out = PadReport::new(
        buttons(kind, [report[3], report[4], report[5]]),
        Some(battery(report[2])),
        None,
    );
    if id == REPLY_REPORT {
        return Ok(out);
    }
    let imu = &report[13..49];
    if imu.iter().all(|&b| b == 0) {
        return Err(DecodeError::ImuOff);
    }
    let deg = std::f64::consts::PI / 180.0;
    for s in 0..3 {
        let at = 12 * s;
        let raw = |i: usize| le_i16(imu, at + 2 * i) as f64;
        let accel = [0, 1, 2].map(|a| raw(a) * 4.0 / cal.accel_divisor[a] * GRAVITY);
        let gyro = [0, 1, 2]
            .map(|a| (raw(3 + a) - cal.gyro_origin[a]) * 936.0 / cal.gyro_divisor[a] * deg);
        out.push(MotionSample {
            gyro_rps: to_body(kind, gyro),
            accel_mps2: to_body(kind, accel),
            device_time_s: None,
        });
    }
    Ok(out)
}

/// One step of the start sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartStep {
    /// USB command `0x80 <cmd>`, answered by `0x81 <cmd>`.
    Usb(u8),
    /// A subcommand with up to five argument bytes, answered by report 0x21.
    Subcommand {
        /// Subcommand id.
        id: u8,
        /// Argument bytes (`len` of them).
        args: [u8; 5],
        /// Argument count.
        len: u8,
    },
}

impl StartStep {
    const fn sub(id: u8, args: [u8; 5], len: u8) -> Self {
        StartStep::Subcommand { id, args, len }
    }
}

/// The start sequence for a link and player (1–4): over USB handshake (0x02), 3 Mbit (0x03),
/// handshake again, HID only without timeout (0x04); then full report mode, IMU on, the
/// player's light, and the two calibration reads.
pub fn start_sequence(link: Link, player: u8) -> Vec<StartStep> {
    let mut steps = Vec::new();
    if link == Link::Usb {
        steps.extend([0x02, 0x03, 0x02, 0x04].map(StartStep::Usb));
    }
    let spi = |addr: u32, len: u8| {
        let a = addr.to_le_bytes();
        StartStep::sub(SUB_SPI_READ, [a[0], a[1], a[2], a[3], len], 5)
    };
    steps.extend([
        StartStep::sub(SUB_INPUT_MODE, [FULL_REPORT, 0, 0, 0, 0], 1),
        StartStep::sub(SUB_IMU, [0x01, 0, 0, 0, 0], 1),
        StartStep::sub(
            SUB_PLAYER_LIGHTS,
            [1 << (player.clamp(1, 4) - 1), 0, 0, 0, 0],
            1,
        ),
        spi(SPI_FACTORY_IMU, 24),
        spi(SPI_USER_IMU, 26),
    ]);
    steps
}

/// Output report 0x01 for a subcommand: counter (0–15), neutral rumble, the id, arguments.
pub fn subcommand_report(counter: u8, id: u8, args: &[u8]) -> [u8; SUBCOMMAND_LEN] {
    let mut r = [0u8; SUBCOMMAND_LEN];
    r[0] = SUBCOMMAND_REPORT;
    r[1] = counter & 0x0F;
    r[2..10].copy_from_slice(&NEUTRAL_RUMBLE);
    r[10] = id;
    let n = args.len().min(SUBCOMMAND_LEN - 11);
    r[11..11 + n].copy_from_slice(&args[..n]);
    r
}

/// A subcommand reply (report 0x21).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SubcommandReply {
    /// The subcommand answered.
    pub id: u8,
    /// Whether it was acknowledged (bit 7 of byte 13).
    pub ack: bool,
    /// Reply data (after the id byte).
    pub data: Vec<u8>,
}

/// Parses report 0x21.
pub fn parse_reply(report: &[u8]) -> Result<SubcommandReply, DecodeError> {
    check_report(report, REPLY_REPORT, 15, ControllerKind::SwitchPro)?;
    Ok(SubcommandReply {
        id: report[14],
        ack: report[13] & 0x80 != 0,
        data: report[15..].to_vec(),
    })
}

/// The data of an SPI read reply: address (u32 LE), length, then the bytes.
pub fn spi_data(reply: &SubcommandReply, addr: u32) -> Result<&[u8], DecodeError> {
    let d = &reply.data;
    if d.len() < 5 {
        return Err(DecodeError::Short {
            id: REPLY_REPORT,
            len: d.len() + 15,
            need: 20,
        });
    }
    let got = u32::from_le_bytes([d[0], d[1], d[2], d[3]]);
    let len = d[4] as usize;
    if got != addr || d.len() < 5 + len {
        return Err(DecodeError::Short {
            id: REPLY_REPORT,
            len: d.len() + 15,
            need: 20 + len,
        });
    }
    Ok(&d[5..5 + len])
}
