//! Input reports (remote → host): status, read replies, acknowledgements and data reports with
//! buttons, accelerometer and extension bytes (MotionPlus, Nunchuk), decoded by report ID
//! (`PROTOCOL.md` §5–§6).

use super::*;
pub use crate::controllers::session::inputs::NunchukFrame;

/// Status report body (0x20).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Status {
    /// Buttons.
    pub buttons: Buttons,
    /// Battery nearly empty flag.
    pub battery_low: bool,
    /// Something is plugged into the extension port (or the MotionPlus is active).
    pub extension_connected: bool,
    /// Speaker enabled.
    pub speaker: bool,
    /// IR camera enabled.
    pub ir: bool,
    /// LED bits (LED1 = bit 0).
    pub leds: u8,
    /// Battery level 0..=255 (≈ 0x60–0x70 when full).
    pub battery: u8,
}

/// Read reply body (0x21).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadReply {
    /// Buttons.
    pub buttons: Buttons,
    /// Error code (0 = success, 7 = no device, 8 = bad address...).
    pub error: u8,
    /// Low 16 bits of the address of the first byte.
    pub address: u16,
    /// Valid data bytes (1..=16).
    pub data: Vec<u8>,
}

/// Raw 10-bit accelerometer counts (Y and Z have their LSB forced to 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AccelRaw(pub [u16; 3]);

/// A decoded MotionPlus 6-byte frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MotionPlusFrame {
    /// 14-bit yaw rate (about body Z).
    pub yaw: u16,
    /// 14-bit roll rate (about body Y).
    pub roll: u16,
    /// 14-bit pitch rate (about body X).
    pub pitch: u16,
    /// Slow (low-range) flag per axis, yaw/roll/pitch.
    pub slow: [bool; 3],
    /// Something plugged into the pass-through port.
    pub extension_connected: bool,
}

/// Extension bytes of a data report, classified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExtensionData {
    /// A MotionPlus gyro frame.
    MotionPlus(MotionPlusFrame),
    /// A Nunchuk frame passed through the MotionPlus.
    Nunchuk(NunchukFrame),
    /// Frame flagged invalid (E5 bit 0) or no extension bytes in this report type.
    None,
}

impl MotionPlusFrame {
    /// Decodes the 6 MotionPlus bytes (E0..E5).
    pub fn decode(e: &[u8]) -> Result<Self, ProtocolError> {
        if e.len() < 6 {
            return Err(ProtocolError::Truncated {
                id: 0,
                needed: 6,
                got: e.len(),
            });
        }
        if e[5] & 0x01 != 0 || e[5] & 0x02 == 0 {
            return Err(ProtocolError::NotGyroFrame);
        }
        Ok(Self {
            yaw: e[0] as u16 | ((e[3] as u16 >> 2) << 8),
            roll: e[1] as u16 | ((e[4] as u16 >> 2) << 8),
            pitch: e[2] as u16 | ((e[5] as u16 >> 2) << 8),
            slow: [e[3] & 0x02 != 0, e[4] & 0x02 != 0, e[3] & 0x01 != 0],
            extension_connected: e[4] & 0x01 != 0,
        })
    }

    /// Encodes to 6 bytes (used by the emulator).
    pub fn encode(&self) -> [u8; 6] {
        let (y, r, p) = (self.yaw & 0x3FFF, self.roll & 0x3FFF, self.pitch & 0x3FFF);
        [
            y as u8,
            r as u8,
            p as u8,
            ((y >> 8) as u8) << 2 | (self.slow[0] as u8) << 1 | self.slow[2] as u8,
            ((r >> 8) as u8) << 2 | (self.slow[1] as u8) << 1 | self.extension_connected as u8,
            ((p >> 8) as u8) << 2 | 0x02,
        ]
    }
}

/// Encodes a Nunchuk frame as a pass-through frame (E5 bit1 = 0), accelerometer bytes left
/// neutral.
pub fn nunchuk_passthrough_bytes(frame: &NunchukFrame, extension_connected: bool) -> [u8; 6] {
    [
        frame.stick_x,
        frame.stick_y,
        0x80,
        0x80,
        0x80 | extension_connected as u8,
        ((!frame.c) as u8) << 3 | ((!frame.z) as u8) << 2,
    ]
}

/// Encodes a Nunchuk frame as a plain Nunchuk report (MotionPlus inactive), accelerometer
/// neutral.
pub fn nunchuk_direct_bytes(frame: &NunchukFrame) -> [u8; 6] {
    [
        frame.stick_x,
        frame.stick_y,
        0x80,
        0x80,
        0x80,
        ((!frame.c) as u8) << 1 | (!frame.z) as u8,
    ]
}

fn nunchuk_from_passthrough(e: &[u8]) -> NunchukFrame {
    NunchukFrame {
        stick_x: e[0],
        stick_y: e[1],
        c: e[5] & 0x08 == 0,
        z: e[5] & 0x04 == 0,
    }
}

/// A remote → host report.
#[derive(Debug, Clone, PartialEq)]
pub enum InputReport {
    /// 0x20.
    Status(Status),
    /// 0x21.
    ReadReply(ReadReply),
    /// 0x22: acknowledgement of output report `report` with error code `error`.
    Ack {
        /// Buttons.
        buttons: Buttons,
        /// Output report id acknowledged.
        report: u8,
        /// Error code.
        error: u8,
    },
    /// 0x30–0x3F data reports.
    Data {
        /// Report id.
        id: u8,
        /// Buttons (none in 0x3D).
        buttons: Buttons,
        /// Accelerometer counts, if the report carries them.
        accel: Option<AccelRaw>,
        /// First 6 extension bytes, if the report carries them (classify with
        /// [`classify_extension`], which needs to know whether a MotionPlus is active).
        extension: Option<[u8; 6]>,
        /// The IR camera's bytes, if the report carries them: 12 extended-mode bytes in 0x33,
        /// 10 basic-mode bytes in 0x36 and 0x37 (decode with [`crate::controllers::wiimote::ir`]).
        ir: Option<Vec<u8>>,
    },
}

impl InputReport {
    /// Decodes hidapi bytes by report id. Extra trailing bytes (padding) are ignored.
    pub fn decode(bytes: &[u8]) -> Result<Self, ProtocolError> {
        let (&id, p) = bytes.split_first().ok_or(ProtocolError::Empty)?;
        let payload_len = match id {
            0x20 => 6,
            0x21 => 21,
            0x22 => 4,
            0x30 => 2,
            0x31 => 5,
            0x32 => 10,
            0x33 => 17,
            0x34..=0x37 | 0x3D..=0x3F => 21,
            other => return Err(ProtocolError::UnknownReport(other)),
        };
        if p.len() < payload_len {
            return Err(ProtocolError::Truncated {
                id,
                needed: payload_len + 1,
                got: bytes.len(),
            });
        }
        let buttons = Buttons::from_bytes(p[0], p[1]);
        Ok(match id {
            0x20 => Self::Status(Status {
                buttons,
                battery_low: p[2] & 0x01 != 0,
                extension_connected: p[2] & 0x02 != 0,
                speaker: p[2] & 0x04 != 0,
                ir: p[2] & 0x08 != 0,
                leds: p[2] >> 4,
                battery: p[5],
            }),
            0x21 => {
                let size = (p[2] >> 4) as usize + 1;
                Self::ReadReply(ReadReply {
                    buttons,
                    error: p[2] & 0x0F,
                    address: u16::from_be_bytes([p[3], p[4]]),
                    data: p[5..5 + size].to_vec(),
                })
            }
            0x22 => Self::Ack {
                buttons,
                report: p[2],
                error: p[3],
            },
            _ => {
                let (buttons, accel, ext): (Buttons, Option<AccelRaw>, Option<&[u8]>) = match id {
                    0x30 => (buttons, None, None),
                    0x31 => (buttons, Some(decode_accel(p)), None),
                    0x32 => (buttons, None, Some(&p[2..10])),
                    0x33 => (buttons, Some(decode_accel(p)), None),
                    0x34 => (buttons, None, Some(&p[2..21])),
                    0x35 => (buttons, Some(decode_accel(p)), Some(&p[5..21])),
                    0x36 => (buttons, None, Some(&p[12..21])),
                    0x37 => (buttons, Some(decode_accel(p)), Some(&p[15..21])),
                    0x3D => (Buttons(0), None, Some(&p[0..21])),
                    _ => (buttons, None, None),
                };
                let extension = match ext {
                    Some(e) if e.len() >= 6 => Some([e[0], e[1], e[2], e[3], e[4], e[5]]),
                    _ => None,
                };
                let ir = match id {
                    0x33 => Some(p[5..17].to_vec()),
                    0x36 => Some(p[2..12].to_vec()),
                    0x37 => Some(p[5..15].to_vec()),
                    _ => None,
                };
                Self::Data {
                    id,
                    buttons,
                    accel,
                    extension,
                    ir,
                }
            }
        })
    }
}

pub(super) fn decode_accel(p: &[u8]) -> AccelRaw {
    let x = ((p[2] as u16) << 2) | ((p[0] as u16 >> 5) & 0b11);
    let y = ((p[3] as u16) << 2) | ((p[1] as u16 >> 4) & 0b10);
    let z = ((p[4] as u16) << 2) | ((p[1] as u16 >> 5) & 0b10);
    AccelRaw([x, y, z])
}

/// Encodes accelerometer counts into `BB BB AX AY AZ` (buttons given), for the emulator.
pub fn encode_buttons_accel(buttons: Buttons, accel: AccelRaw) -> [u8; 5] {
    let [b0, b1] = buttons.to_bytes();
    let [x, y, z] = accel.0;
    [
        b0 | (((x & 0b11) as u8) << 5),
        b1 | (((y & 0b10) as u8) << 4) | (((z & 0b10) as u8) << 5),
        (x >> 2) as u8,
        (y >> 2) as u8,
        (z >> 2) as u8,
    ]
}

/// Classifies 6 extension bytes. With an active MotionPlus, E5 bit1 tells gyro frames from
/// pass-through frames and E5 bit0 marks invalid frames; otherwise the bytes are a plain
/// (unencrypted) Nunchuk report.
pub fn classify_extension(e: &[u8; 6], motion_plus_active: bool) -> ExtensionData {
    if !motion_plus_active {
        return ExtensionData::Nunchuk(NunchukFrame {
            stick_x: e[0],
            stick_y: e[1],
            c: e[5] & 0x02 == 0,
            z: e[5] & 0x01 == 0,
        });
    }
    if e[5] & 0x01 != 0 {
        return ExtensionData::None;
    }
    match MotionPlusFrame::decode(e) {
        Ok(f) => ExtensionData::MotionPlus(f),
        Err(_) => ExtensionData::Nunchuk(nunchuk_from_passthrough(e)),
    }
}
