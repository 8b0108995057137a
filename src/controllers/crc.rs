//! CRC-32 (IEEE 802.3, reflected polynomial `0xEDB88320`, initial value and final XOR
//! `0xFFFFFFFF`): the checksum of the Wii MotionPlus calibration block (`PROTOCOL.md` §8) and
//! of Sony pads' Bluetooth reports. The Sony variant
//! hashes a one-byte Bluetooth HID header first (the *seed*): `0xA1` for input reports,
//! `0xA2` for output reports, `0xA3` for feature reports (`docs/PROTOCOL-SONY.md` §4).

const TABLE: [u32; 256] = {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

/// A running CRC-32.
#[derive(Debug, Clone, Copy)]
pub struct Crc32(u32);

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// A fresh checksum.
    pub const fn new() -> Self {
        Self(0xFFFF_FFFF)
    }

    /// Feeds bytes.
    pub fn update(mut self, bytes: &[u8]) -> Self {
        for &b in bytes {
            self.0 = TABLE[((self.0 ^ b as u32) & 0xFF) as usize] ^ (self.0 >> 8);
        }
        self
    }

    /// The checksum of everything fed.
    pub const fn finish(self) -> u32 {
        self.0 ^ 0xFFFF_FFFF
    }
}

/// CRC-32 of `seed` followed by `bytes`.
pub fn crc32_seeded(seed: u8, bytes: &[u8]) -> u32 {
    Crc32::new().update(&[seed]).update(bytes).finish()
}

/// CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    Crc32::new().update(bytes).finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_of_the_standard() {
        // The catalogue's check value for CRC-32/ISO-HDLC.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(&[]), 0);
        assert_eq!(crc32_seeded(b'1', b"23456789"), 0xCBF4_3926);
    }
}
