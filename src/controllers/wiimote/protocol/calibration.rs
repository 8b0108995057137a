//! Calibration records: the accelerometer's zero and gravity points and the MotionPlus
//! gyroscope's scales, read from the remote's memory (`PROTOCOL.md` §7).

use super::*;

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
        crate::controllers::crc::Crc32::new()
            .update(&bytes[0..14])
            .update(&bytes[16..30])
            .finish()
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

pub(super) fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}
