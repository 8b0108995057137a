//! Typed encode/decode of Wii Remote HID reports (see `PROTOCOL.md` §2–§8).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `calibration.rs` | Calibration records: the accelerometer's zero and gravity points and the MotionPlus gyroscope's scales, read from the remote's memory (`PROTOCOL.md` §7). |
//! | `extension.rs` | Extension identification (`PROTOCOL.md` §8). |
//! | `input.rs` | Input reports (remote → host): status, read replies, acknowledgements and data reports with buttons, accelerometer and extension bytes (MotionPlus, Nunchuk), decoded by report ID (`PROTOCOL.md` §5–§6). |
//! | `output.rs` | Output reports (host → remote): LEDs, report mode, status request, memory and register writes and reads (`PROTOCOL.md` §3–§4). |
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

pub use crate::controllers::session::inputs::Buttons;

mod calibration;
mod extension;
mod input;
mod output;

pub use calibration::*;
pub use extension::*;
pub use input::*;
pub use output::*;

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
}
