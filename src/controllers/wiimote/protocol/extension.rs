//! Extension identification (`PROTOCOL.md` §8).

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
