//! A decoded input report, whatever the device, and why a report did not decode.

use super::{ControllerKind, MotionSample, PadButtons};

/// How a controller is connected: the report layouts differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Link {
    /// A cable.
    #[default]
    Usb,
    /// Bluetooth (Sony reports then carry a CRC-32).
    Bluetooth,
}

impl Link {
    /// `usb` or `bluetooth`.
    pub fn name(self) -> &'static str {
        match self {
            Link::Usb => "usb",
            Link::Bluetooth => "bluetooth",
        }
    }
}

/// Battery state as the report gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Battery {
    /// Charge, 0–100 % (in the device's steps: 10 % on Sony pads, 25 % on Nintendo's).
    pub percent: u8,
    /// On a charger or cable.
    pub charging: bool,
}

/// Most sensor samples one report carries (the Switch sends three).
pub const MAX_SAMPLES: usize = 3;

/// One decoded input report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadReport {
    samples: [MotionSample; MAX_SAMPLES],
    count: u8,
    /// Buttons held.
    pub buttons: PadButtons,
    /// Battery, when the report has it.
    pub battery: Option<Battery>,
    /// Whether the report's CRC-32 matched; `None` when the transport has no CRC (USB, and
    /// every Nintendo report). A decoder fills the report even when it is `Some(false)`;
    /// [`PadReport::verified`] turns that into an error.
    pub crc_ok: Option<bool>,
}

impl PadReport {
    /// A report with no samples yet.
    pub(crate) fn new(buttons: PadButtons, battery: Option<Battery>, crc_ok: Option<bool>) -> Self {
        let zero = MotionSample {
            gyro_rps: glam::DVec3::ZERO,
            accel_mps2: glam::DVec3::ZERO,
            device_time_s: None,
        };
        Self {
            samples: [zero; MAX_SAMPLES],
            count: 0,
            buttons,
            battery,
            crc_ok,
        }
    }

    /// Appends a sample (ignored beyond [`MAX_SAMPLES`]).
    pub(crate) fn push(&mut self, s: MotionSample) {
        if (self.count as usize) < MAX_SAMPLES {
            self.samples[self.count as usize] = s;
            self.count += 1;
        }
    }

    /// The sensor samples, oldest first.
    pub fn samples(&self) -> &[MotionSample] {
        &self.samples[..self.count as usize]
    }

    /// The report, or [`DecodeError::Crc`] when its CRC did not match.
    pub fn verified(self) -> Result<Self, DecodeError> {
        match self.crc_ok {
            Some(false) => Err(DecodeError::Crc),
            _ => Ok(self),
        }
    }
}

/// Why a report did not decode. The session counts these and goes on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Zero bytes.
    #[error("empty report")]
    Empty,
    /// A report id this device does not send with motion data.
    #[error("report 0x{id:02X} is not an input report a {kind} sends")]
    UnknownReport {
        /// The id.
        id: u8,
        /// The device it was decoded as.
        kind: ControllerKind,
    },
    /// Shorter than its layout.
    #[error("report 0x{id:02X} has {len} bytes, its layout needs {need}")]
    Short {
        /// The id.
        id: u8,
        /// Bytes received.
        len: usize,
        /// Bytes the layout needs.
        need: usize,
    },
    /// The CRC-32 does not match the bytes (a corrupted Bluetooth report).
    #[error("CRC-32 mismatch")]
    Crc,
    /// A known report without sensor data: the pad has not been switched to its full report
    /// yet (Sony's reduced Bluetooth report 0x01, the Switch's simple report 0x3F).
    #[error(
        "report 0x{id:02X} carries no motion data: the start sequence has not switched the pad to its full report"
    )]
    NoMotion {
        /// The id.
        id: u8,
    },
    /// A Switch full report whose IMU is still off (all-zero samples before subcommand
    /// 0x40 enables it).
    #[error("the IMU is off (no sample in the report)")]
    ImuOff,
}

/// The checks a fixed layout starts with: some bytes, the expected report id, enough of them.
pub(crate) fn check_report(
    report: &[u8],
    id: u8,
    need: usize,
    kind: ControllerKind,
) -> Result<(), DecodeError> {
    let Some(&first) = report.first() else {
        return Err(DecodeError::Empty);
    };
    if first != id {
        return Err(DecodeError::UnknownReport { id: first, kind });
    }
    if report.len() < need {
        return Err(DecodeError::Short {
            id,
            len: report.len(),
            need,
        });
    }
    Ok(())
}

/// Little-endian `i16` at `at`.
#[inline]
pub(crate) fn le_i16(b: &[u8], at: usize) -> i16 {
    i16::from_le_bytes([b[at], b[at + 1]])
}

/// Little-endian `u32` at `at`.
#[inline]
pub(crate) fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}
