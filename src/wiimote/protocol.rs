//! Typed encode/decode of Wii Remote HID reports (see `PROTOCOL.md` §2–§8).
//!
//! Bytes are as `hidapi` sees them: report ID first. Input reports are parsed by ID, never by
//! length (Windows pads every report to 22 bytes); any short or unknown input is a typed
//! [`ProtocolError`], never a panic.

use glam::DVec3;

/// Nintendo's USB/Bluetooth vendor id.
pub const VENDOR_ID: u16 = 0x057E;
/// Product id of the original Wii Remote (and of some Remote Plus units).
pub const PRODUCT_ID_ORIGINAL: u16 = 0x0306;
/// Product id of the Wii Remote Plus (-TR).
pub const PRODUCT_ID_PLUS: u16 = 0x0330;
/// Bluetooth name of the original remote.
pub const NAME_ORIGINAL: &str = "Nintendo RVL-CNT-01";
/// Bluetooth name of the Remote Plus.
pub const NAME_PLUS: &str = "Nintendo RVL-CNT-01-TR";

/// Decoding failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProtocolError {
    /// The buffer is empty.
    #[error("empty report")]
    Empty,
    /// The report is shorter than its ID requires.
    #[error("report 0x{id:02X} needs {needed} bytes, got {got}")]
    Truncated {
        /// Report id.
        id: u8,
        /// Bytes required including the id.
        needed: usize,
        /// Bytes present.
        got: usize,
    },
    /// Unknown or unsupported report id.
    #[error("unknown report id 0x{0:02X}")]
    UnknownReport(u8),
    /// An output report has an invalid field.
    #[error("invalid output report: {0}")]
    InvalidOutput(&'static str),
    /// A MotionPlus frame is flagged invalid (hot-plug) or not a gyro frame.
    #[error("not a valid MotionPlus gyro frame")]
    NotGyroFrame,
}

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

/// Address space of a memory access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AddressSpace {
    /// The remote's EEPROM (24-bit offset).
    Eeprom,
    /// Control registers on the I2C bus (slave byte in the address).
    Registers,
}

/// A host → remote report. `rumble` is carried in every report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OutputReport {
    /// 0x10: rumble only.
    Rumble {
        /// Motor state.
        rumble: bool,
    },
    /// 0x11: player LEDs (bits 0..3 = LED1..LED4).
    Leds {
        /// LED bit mask.
        leds: u8,
        /// Ask for a 0x22 ack.
        ack: bool,
        /// Motor state.
        rumble: bool,
    },
    /// 0x12: data reporting mode.
    ReportMode {
        /// Input report id 0x30–0x3F.
        mode: u8,
        /// Send continuously (~100 Hz) rather than on change.
        continuous: bool,
        /// Ask for a 0x22 ack.
        ack: bool,
        /// Motor state.
        rumble: bool,
    },
    /// 0x13/0x14/0x19/0x1A: IR / speaker enable flags (unused by us, decoded for the emulator).
    Flag {
        /// Report id.
        id: u8,
        /// Enable bit.
        enable: bool,
        /// Ask for a 0x22 ack.
        ack: bool,
        /// Motor state.
        rumble: bool,
    },
    /// 0x15: status request.
    StatusRequest {
        /// Motor state.
        rumble: bool,
    },
    /// 0x16: write up to 16 bytes.
    WriteMemory {
        /// Address space.
        space: AddressSpace,
        /// 24-bit address (`0xA400F0` style for registers).
        address: u32,
        /// 1..=16 bytes (other lengths are encoded but ignored by a real remote).
        data: Vec<u8>,
        /// Motor state.
        rumble: bool,
    },
    /// 0x17: read `size` bytes.
    ReadMemory {
        /// Address space.
        space: AddressSpace,
        /// 24-bit address.
        address: u32,
        /// Number of bytes.
        size: u16,
        /// Motor state.
        rumble: bool,
    },
    /// 0x18: speaker data (decoded for completeness; never sent).
    SpeakerData,
}

impl OutputReport {
    /// Encodes to hidapi bytes (report id first).
    pub fn encode(&self) -> Vec<u8> {
        let r = |rumble: bool| rumble as u8;
        match self {
            Self::Rumble { rumble } => vec![0x10, r(*rumble)],
            Self::Leds { leds, ack, rumble } => {
                vec![
                    0x11,
                    ((leds & 0x0F) << 4) | ((*ack as u8) << 1) | r(*rumble),
                ]
            }
            Self::ReportMode {
                mode,
                continuous,
                ack,
                rumble,
            } => vec![
                0x12,
                ((*continuous as u8) << 2) | ((*ack as u8) << 1) | r(*rumble),
                *mode,
            ],
            Self::Flag {
                id,
                enable,
                ack,
                rumble,
            } => vec![
                *id,
                ((*enable as u8) << 2) | ((*ack as u8) << 1) | r(*rumble),
            ],
            Self::StatusRequest { rumble } => vec![0x15, r(*rumble)],
            Self::WriteMemory {
                space,
                address,
                data,
                rumble,
            } => {
                let mut out = vec![0u8; 22];
                out[0] = 0x16;
                out[1] = space_bits(*space) | r(*rumble);
                out[2..5].copy_from_slice(&address.to_be_bytes()[1..]);
                out[5] = data.len() as u8;
                let n = data.len().min(16);
                out[6..6 + n].copy_from_slice(&data[..n]);
                out
            }
            Self::ReadMemory {
                space,
                address,
                size,
                rumble,
            } => {
                let mut out = vec![0x17, space_bits(*space) | r(*rumble)];
                out.extend_from_slice(&address.to_be_bytes()[1..]);
                out.extend_from_slice(&size.to_be_bytes());
                out
            }
            Self::SpeakerData => vec![0x18; 22],
        }
    }

    /// Decodes host bytes (used by the emulator). Reports with an invalid mode or address
    /// space decode successfully where the remote would answer with an error code.
    pub fn decode(bytes: &[u8]) -> Result<Self, ProtocolError> {
        let (&id, rest) = bytes.split_first().ok_or(ProtocolError::Empty)?;
        let need = |n: usize| {
            if bytes.len() < n {
                Err(ProtocolError::Truncated {
                    id,
                    needed: n,
                    got: bytes.len(),
                })
            } else {
                Ok(())
            }
        };
        need(2)?;
        let f = rest[0];
        let rumble = f & 1 != 0;
        let ack = f & 2 != 0;
        Ok(match id {
            0x10 => Self::Rumble { rumble },
            0x11 => Self::Leds {
                leds: f >> 4,
                ack,
                rumble,
            },
            0x12 => {
                need(3)?;
                Self::ReportMode {
                    mode: rest[1],
                    continuous: f & 4 != 0,
                    ack,
                    rumble,
                }
            }
            0x13 | 0x14 | 0x19 | 0x1A => Self::Flag {
                id,
                enable: f & 4 != 0,
                ack,
                rumble,
            },
            0x15 => Self::StatusRequest { rumble },
            0x16 => {
                need(7)?;
                let address = u32::from_be_bytes([0, rest[1], rest[2], rest[3]]);
                let n = rest[4] as usize;
                // An invalid length (0 or > 16) is kept as such so the remote can ignore it.
                let data = if (1..=16).contains(&n) {
                    rest[5..(5 + n).min(rest.len())].to_vec()
                } else {
                    vec![0; n]
                };
                Self::WriteMemory {
                    space: decode_space(f)?,
                    address,
                    data,
                    rumble,
                }
            }
            0x17 => {
                need(7)?;
                Self::ReadMemory {
                    space: decode_space(f)?,
                    address: u32::from_be_bytes([0, rest[1], rest[2], rest[3]]),
                    size: u16::from_be_bytes([rest[4], rest[5]]),
                    rumble,
                }
            }
            0x18 => Self::SpeakerData,
            other => return Err(ProtocolError::UnknownReport(other)),
        })
    }

    /// The same report carrying `rumble` (the motor bit rides in every output report).
    pub fn with_rumble(mut self, on: bool) -> Self {
        match &mut self {
            Self::Rumble { rumble }
            | Self::Leds { rumble, .. }
            | Self::ReportMode { rumble, .. }
            | Self::Flag { rumble, .. }
            | Self::StatusRequest { rumble }
            | Self::WriteMemory { rumble, .. }
            | Self::ReadMemory { rumble, .. } => *rumble = on,
            Self::SpeakerData => {}
        }
        self
    }

    /// A one-byte register write at `address` (24-bit `0xA400F0` notation).
    pub fn write_register(address: u32, value: u8, rumble: bool) -> Self {
        Self::WriteMemory {
            space: AddressSpace::Registers,
            address,
            data: vec![value],
            rumble,
        }
    }

    /// A register read.
    pub fn read_register(address: u32, size: u16, rumble: bool) -> Self {
        Self::ReadMemory {
            space: AddressSpace::Registers,
            address,
            size,
            rumble,
        }
    }
}

fn space_bits(space: AddressSpace) -> u8 {
    match space {
        AddressSpace::Eeprom => 0x00,
        AddressSpace::Registers => 0x04,
    }
}

fn decode_space(f: u8) -> Result<AddressSpace, ProtocolError> {
    match (f >> 2) & 3 {
        0 => Ok(AddressSpace::Eeprom),
        1 | 2 => Ok(AddressSpace::Registers),
        _ => Err(ProtocolError::InvalidOutput("address space 11 (error 6)")),
    }
}

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

impl NunchukFrame {
    /// Encodes as a pass-through frame (E5 bit1 = 0), accelerometer bytes left neutral.
    pub fn encode_passthrough(&self, extension_connected: bool) -> [u8; 6] {
        [
            self.stick_x,
            self.stick_y,
            0x80,
            0x80,
            0x80 | extension_connected as u8,
            ((!self.c) as u8) << 3 | ((!self.z) as u8) << 2,
        ]
    }

    /// Encodes as a plain Nunchuk report (MotionPlus inactive), accelerometer neutral.
    pub fn encode_direct(&self) -> [u8; 6] {
        [
            self.stick_x,
            self.stick_y,
            0x80,
            0x80,
            0x80,
            ((!self.c) as u8) << 1 | (!self.z) as u8,
        ]
    }

    fn decode_passthrough(e: &[u8]) -> Self {
        Self {
            stick_x: e[0],
            stick_y: e[1],
            c: e[5] & 0x08 == 0,
            z: e[5] & 0x04 == 0,
        }
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
                Self::Data {
                    id,
                    buttons,
                    accel,
                    extension,
                }
            }
        })
    }
}

fn decode_accel(p: &[u8]) -> AccelRaw {
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
        Err(_) => ExtensionData::Nunchuk(NunchukFrame::decode_passthrough(e)),
    }
}

/// Accelerometer calibration from EEPROM (0x16 or 0x20, 10 bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelCalibration {
    /// Zero-g counts per axis.
    pub zero: [u16; 3],
    /// +1 g counts per axis.
    pub one_g: [u16; 3],
}

impl Default for AccelCalibration {
    fn default() -> Self {
        Self {
            zero: [512; 3],
            one_g: [616; 3],
        }
    }
}

impl AccelCalibration {
    /// Parses a 10-byte block; `None` when the checksum does not match.
    pub fn parse(block: &[u8]) -> Option<Self> {
        if block.len() < 10 || Self::checksum(&block[..9]) != block[9] {
            return None;
        }
        let unpack = |hi: &[u8], lo: u8| {
            [
                ((hi[0] as u16) << 2) | ((lo >> 4) & 3) as u16,
                ((hi[1] as u16) << 2) | ((lo >> 2) & 3) as u16,
                ((hi[2] as u16) << 2) | (lo & 3) as u16,
            ]
        };
        let cal = Self {
            zero: unpack(&block[0..3], block[3]),
            one_g: unpack(&block[4..7], block[7]),
        };
        (0..3).all(|i| cal.one_g[i] != cal.zero[i]).then_some(cal)
    }

    /// Picks the first valid of two blocks, else the defaults (zero 512, +1 g 616).
    pub fn from_blocks(primary: &[u8], backup: &[u8]) -> (Self, bool) {
        match Self::parse(primary).or_else(|| Self::parse(backup)) {
            Some(c) => (c, true),
            None => (Self::default(), false),
        }
    }

    /// `(0x55 + Σ bytes) mod 256`.
    pub fn checksum(bytes: &[u8]) -> u8 {
        bytes.iter().fold(0x55u8, |a, b| a.wrapping_add(*b))
    }

    /// Encodes a 10-byte block with checksum (byte 8 = 0x40).
    pub fn encode(&self) -> [u8; 10] {
        let mut b = [0u8; 10];
        let pack_lo =
            |v: [u16; 3]| (((v[0] & 3) as u8) << 4) | (((v[1] & 3) as u8) << 2) | (v[2] & 3) as u8;
        for i in 0..3 {
            b[i] = (self.zero[i] >> 2) as u8;
            b[4 + i] = (self.one_g[i] >> 2) as u8;
        }
        b[3] = pack_lo(self.zero);
        b[7] = pack_lo(self.one_g);
        b[8] = 0x40;
        b[9] = Self::checksum(&b[..9]);
        b
    }

    /// Converts counts to acceleration in g (body frame of §5.3).
    pub fn to_g(&self, raw: AccelRaw) -> DVec3 {
        DVec3::from_array(std::array::from_fn(|i| {
            (raw.0[i] as f64 - self.zero[i] as f64) / (self.one_g[i] as f64 - self.zero[i] as f64)
        }))
    }
}

/// One of the two (fast/slow) halves of the MotionPlus calibration block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroRange {
    /// 16-bit zero per axis (yaw, roll, pitch).
    pub zero: [u16; 3],
    /// 16-bit reading at `degrees` deg/s per axis.
    pub scale: [u16; 3],
    /// Reference rate in deg/s (byte × 6).
    pub degrees: u16,
    /// Unit id byte.
    pub uid: u8,
}

/// The 32-byte MotionPlus calibration block with its CRC-32.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionPlusCalibration {
    /// High-range ("fast") constants.
    pub fast: GyroRange,
    /// Low-range ("slow") constants.
    pub slow: GyroRange,
}

/// Output sign per axis (pitch, roll, yaw → x, y, z) that turns calibrated values into
/// right-hand-rule rates about the §5.3 axes.
const AXIS_SIGN: [f64; 3] = [-1.0, 1.0, -1.0];

impl MotionPlusCalibration {
    /// Parses 32 bytes. Returns the block and whether its CRC-32 matched.
    pub fn parse(bytes: &[u8]) -> Result<(Self, bool), ProtocolError> {
        if bytes.len() < 32 {
            return Err(ProtocolError::Truncated {
                id: 0,
                needed: 32,
                got: bytes.len(),
            });
        }
        let range = |b: &[u8]| GyroRange {
            zero: [be16(b, 0), be16(b, 2), be16(b, 4)],
            scale: [be16(b, 6), be16(b, 8), be16(b, 10)],
            degrees: b[12] as u16 * 6,
            uid: b[13],
        };
        let stored = ((be16(bytes, 0x0E) as u32) << 16) | be16(bytes, 0x1E) as u32;
        Ok((
            Self {
                fast: range(&bytes[0..16]),
                slow: range(&bytes[16..32]),
            },
            stored == Self::crc(bytes),
        ))
    }

    /// CRC-32 (IEEE) over bytes 0x00..0x0D and 0x10..0x1D.
    pub fn crc(bytes: &[u8]) -> u32 {
        let mut c = Crc32::new();
        c.update(&bytes[0..14]);
        c.update(&bytes[16..30]);
        c.finish()
    }

    /// Encodes with a valid CRC.
    pub fn encode(&self) -> [u8; 32] {
        let mut b = [0u8; 32];
        for (off, r) in [(0usize, &self.fast), (16, &self.slow)] {
            for i in 0..3 {
                b[off + 2 * i..off + 2 * i + 2].copy_from_slice(&r.zero[i].to_be_bytes());
                b[off + 6 + 2 * i..off + 8 + 2 * i].copy_from_slice(&r.scale[i].to_be_bytes());
            }
            b[off + 12] = (r.degrees / 6) as u8;
            b[off + 13] = r.uid;
        }
        let crc = Self::crc(&b);
        b[0x0E..0x10].copy_from_slice(&((crc >> 16) as u16).to_be_bytes());
        b[0x1E..0x20].copy_from_slice(&(crc as u16).to_be_bytes());
        b
    }

    /// Dolphin's emulated constants (fallback when the CRC fails twice): 16.12 / 3.63 counts
    /// per deg/s around 8192.
    pub fn fallback() -> Self {
        let range = |counts_per_dps: f64, degrees: u16| {
            let zero = 8192u16 * 4;
            let delta = (counts_per_dps * degrees as f64 * 4.0) as i32;
            GyroRange {
                zero: [zero; 3],
                // scale − zero = 4·k·degrees·sign (sign per yaw, roll, pitch).
                scale: [
                    (zero as i32 - delta) as u16,
                    (zero as i32 + delta).min(65535) as u16,
                    (zero as i32 - delta) as u16,
                ],
                degrees,
                uid: 0,
            }
        };
        Self {
            fast: range(3.63, 1200),
            slow: range(16.12, 270),
        }
    }

    /// Converts a frame to body angular velocity in deg/s (x = pitch, y = roll, z = yaw,
    /// right-hand rule about the §5.3 axes). Uses the block for scale and sign only; the
    /// caller removes the run-time bias.
    #[allow(clippy::needless_range_loop)] // three axes, indexed in parallel arrays
    pub fn rates_deg(&self, f: &MotionPlusFrame) -> DVec3 {
        // Frame order yaw, roll, pitch → output x = pitch, y = roll, z = yaw.
        let raw = [f.yaw, f.roll, f.pitch];
        let mut out = [0.0f64; 3];
        for a in 0..3 {
            let r = if f.slow[a] { &self.slow } else { &self.fast };
            let den = r.scale[a] as f64 - r.zero[a] as f64;
            let norm = if den == 0.0 {
                0.0
            } else {
                (raw[a] as f64 * 4.0 - r.zero[a] as f64) / den
            };
            let axis = 2 - a; // yaw→z(2), roll→y(1), pitch→x(0)
            out[axis] = norm * r.degrees as f64 * AXIS_SIGN[axis];
        }
        DVec3::from_array(out)
    }
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

/// Bitwise IEEE CRC-32 (zlib polynomial), enough for 28-byte blocks.
#[derive(Debug, Clone, Copy)]
pub struct Crc32(u32);

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// Starts a CRC.
    pub fn new() -> Self {
        Self(0xFFFF_FFFF)
    }
    /// Feeds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u32;
            for _ in 0..8 {
                let mask = (self.0 & 1).wrapping_neg();
                self.0 = (self.0 >> 1) ^ (0xEDB8_8320 & mask);
            }
        }
    }
    /// The final value.
    pub fn finish(self) -> u32 {
        !self.0
    }
}

/// Extension identifier (6 bytes at 0xA400FA).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExtensionId {
    /// Nunchuk.
    Nunchuk,
    /// Classic Controller (or Pro).
    Classic,
    /// Balance Board (not a Wii Remote: rejected).
    BalanceBoard,
    /// Wii U Pro Controller (rejected).
    ProController,
    /// A MotionPlus; `active` when read at 0xA4, `mode` = pass-through mode byte.
    MotionPlus {
        /// Read at 0xA4 (active) rather than 0xA6.
        active: bool,
        /// Mode byte (0x04/0x05/0x07, or last mode / 0 when inactive).
        mode: u8,
    },
    /// Nothing / not initialised.
    None,
    /// Unknown bytes.
    Unknown([u8; 6]),
}

impl ExtensionId {
    /// Classifies the 6 ID bytes.
    pub fn parse(b: &[u8]) -> Self {
        if b.len() < 6 {
            return Self::None;
        }
        let id: [u8; 6] = [b[0], b[1], b[2], b[3], b[4], b[5]];
        if id == [0xFF; 6] {
            return Self::None;
        }
        if id[5] == 0x05 && id[3] == 0x20 && (id[2] == 0xA4 || id[2] == 0xA6) {
            return Self::MotionPlus {
                active: id[2] == 0xA4,
                mode: id[4],
            };
        }
        match id[2..] {
            [0xA4, 0x20, 0x00, 0x00] => Self::Nunchuk,
            [0xA4, 0x20, 0x01, 0x01] => Self::Classic,
            [0xA4, 0x20, 0x04, 0x02] => Self::BalanceBoard,
            [0xA4, 0x20, 0x01, 0x20] => Self::ProController,
            _ => Self::Unknown(id),
        }
    }
}

/// Parses space-separated hex (`"11 12"`), for fixtures and tools.
pub fn parse_hex(s: &str) -> Option<Vec<u8>> {
    s.split_whitespace()
        .map(|t| u8::from_str_radix(t, 16).ok())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_examples_match_spec() {
        let leds = OutputReport::Leds {
            leds: 1,
            ack: true,
            rumble: false,
        };
        assert_eq!(leds.encode(), vec![0x11, 0x12]);
        let mode = OutputReport::ReportMode {
            mode: 0x35,
            continuous: true,
            ack: true,
            rumble: false,
        };
        assert_eq!(mode.encode(), vec![0x12, 0x06, 0x35]);
        let read = OutputReport::ReadMemory {
            space: AddressSpace::Eeprom,
            address: 0x16,
            size: 10,
            rumble: false,
        };
        assert_eq!(read.encode(), vec![0x17, 0, 0, 0, 0x16, 0, 0x0A]);
        let w = OutputReport::write_register(0xA400F0, 0x55, false).encode();
        assert_eq!(&w[..7], &[0x16, 0x04, 0xA4, 0x00, 0xF0, 0x01, 0x55]);
        assert_eq!(w.len(), 22);
        for r in [leds, mode, read] {
            assert_eq!(OutputReport::decode(&r.encode()).unwrap(), r);
        }
        // Rumble is carried.
        assert_eq!(
            OutputReport::StatusRequest { rumble: true }.encode(),
            vec![0x15, 0x01]
        );
    }

    #[test]
    fn accel_worked_example() {
        let r = InputReport::decode(&[0x31, 0x20, 0x20, 0x80, 0x7F, 0x9A]).unwrap();
        let InputReport::Data { accel, .. } = r else {
            panic!("not data")
        };
        assert_eq!(accel.unwrap().0, [513, 510, 616]);
        let enc = encode_buttons_accel(Buttons(0), AccelRaw([513, 510, 616]));
        assert_eq!(enc, [0x20, 0x20, 0x80, 0x7F, 0x9A]);
    }

    #[test]
    fn motionplus_worked_example() {
        let f = MotionPlusFrame {
            yaw: 8000,
            roll: 8192,
            pitch: 7500,
            slow: [true; 3],
            extension_connected: false,
        };
        assert_eq!(f.encode(), [0x40, 0x00, 0x4C, 0x7F, 0x82, 0x76]);
        assert_eq!(MotionPlusFrame::decode(&f.encode()).unwrap(), f);
    }

    #[test]
    fn short_and_unknown_reports_are_errors() {
        assert_eq!(InputReport::decode(&[]), Err(ProtocolError::Empty));
        assert!(matches!(
            InputReport::decode(&[0x35, 0, 0]),
            Err(ProtocolError::Truncated { id: 0x35, .. })
        ));
        assert_eq!(
            InputReport::decode(&[0x99, 0]),
            Err(ProtocolError::UnknownReport(0x99))
        );
        assert!(OutputReport::decode(&[0x12, 0x06]).is_err());
    }

    #[test]
    fn accel_calibration_roundtrip() {
        let c = AccelCalibration {
            zero: [509, 512, 508],
            one_g: [611, 612, 614],
        };
        assert_eq!(AccelCalibration::parse(&c.encode()), Some(c));
        let mut bad = c.encode();
        bad[9] ^= 1;
        assert_eq!(AccelCalibration::parse(&bad), None);
        assert_eq!(AccelCalibration::from_blocks(&bad, &c.encode()), (c, true));
        assert!(!AccelCalibration::from_blocks(&bad, &bad).1);
    }

    #[test]
    fn extension_ids() {
        assert_eq!(
            ExtensionId::parse(&[0, 0, 0xA6, 0x20, 0x05, 0x05]),
            ExtensionId::MotionPlus {
                active: false,
                mode: 5
            }
        );
        assert_eq!(
            ExtensionId::parse(&[0, 0, 0xA4, 0x20, 0, 0]),
            ExtensionId::Nunchuk
        );
        assert_eq!(
            ExtensionId::parse(&[0, 0, 0xA4, 0x20, 4, 2]),
            ExtensionId::BalanceBoard
        );
        assert_eq!(ExtensionId::parse(&[0xFF; 6]), ExtensionId::None);
    }

    #[test]
    fn crc32_of_known_string() {
        let mut c = Crc32::new();
        c.update(b"123456789");
        assert_eq!(c.finish(), 0xCBF4_3926);
    }
}
