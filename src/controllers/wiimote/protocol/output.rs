//! Output reports (host → remote): LEDs, report mode, status request, memory and register
//! writes and reads (`PROTOCOL.md` §3–§4).

use super::*;

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

pub(super) fn space_bits(space: AddressSpace) -> u8 {
    match space {
        AddressSpace::Eeprom => 0x00,
        AddressSpace::Registers => 0x04,
    }
}

pub(super) fn decode_space(f: u8) -> Result<AddressSpace, ProtocolError> {
    match (f >> 2) & 3 {
        0 => Ok(AddressSpace::Eeprom),
        1 | 2 => Ok(AddressSpace::Registers),
        _ => Err(ProtocolError::InvalidOutput("address space 11 (error 6)")),
    }
}
