//! Sony output reports: rumble, the light bar and the player lights — what the session writes
//! after the start sequence (the player's number and colour, as a Wii Remote lights its LEDs)
//! and on a rumble command. Over Bluetooth they end with a CRC-32 seeded with `0xA2`
//! (`docs/PROTOCOL-SONY.md` §4, §8).

use super::{CRC_SEED_OUTPUT, is_dualsense};
use crate::controllers::crc::crc32_seeded;
use crate::controllers::report::{check_report, le_u32};
use crate::controllers::{ControllerKind, DecodeError, Link};

/// What an output report sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SonyOutput {
    /// Strong (left) motor, 0–255.
    pub strong_motor: u8,
    /// Weak (right) motor, 0–255.
    pub weak_motor: u8,
    /// Light bar colour.
    pub lightbar: [u8; 3],
    /// DualSense player lights (5 bits, centre = 0x04); ignored by the DualShock 4.
    pub player_lights: u8,
}

/// The player lights and light bar colour of player `player` (1–4; others as 4), as Sony's
/// consoles show them: one centre light for player 1, two for 2, three for 3, four for 4, and
/// blue, red, green, pink.
pub fn player_output(player: u8) -> SonyOutput {
    let (lights, colour) = match player {
        1 => (0b00100, [0, 0, 64]),
        2 => (0b01010, [64, 0, 0]),
        3 => (0b10101, [0, 64, 0]),
        _ => (0b11011, [32, 0, 32]),
    };
    SonyOutput {
        player_lights: lights,
        lightbar: colour,
        ..SonyOutput::default()
    }
}

/// DualSense: first output flags (compatible vibration), second flags (light bar and player
/// lights), and where the common block starts and the report's length per link.
const DS_FLAG0_VIBRATION: u8 = 0x01;
const DS_FLAG1_LIGHTBAR: u8 = 0x04;
const DS_FLAG1_PLAYER_LIGHTS: u8 = 0x10;
/// DualShock 4: motors and light bar valid.
const DS4_FLAG_MOTOR: u8 = 0x01;
const DS4_FLAG_LED: u8 = 0x02;

/// (report id, start of the common block, length) of the output report.
fn layout(kind: ControllerKind, link: Link) -> (u8, usize, usize) {
    match (is_dualsense(kind), link) {
        (true, Link::Usb) => (0x02, 1, 63),
        (true, Link::Bluetooth) => (0x31, 3, 78),
        (false, Link::Usb) => (0x05, 1, 32),
        (false, Link::Bluetooth) => (0x11, 3, 78),
    }
}

/// The output report setting `out` (`seq`: the Bluetooth sequence number, 0–15).
pub fn output_report(kind: ControllerKind, link: Link, seq: u8, out: &SonyOutput) -> Vec<u8> {
    let (id, base, len) = layout(kind, link);
    let mut r = vec![0u8; len];
    r[0] = id;
    if is_dualsense(kind) {
        if link == Link::Bluetooth {
            r[1] = (seq & 0x0F) << 4;
            r[2] = 0x10;
        }
        let c = &mut r[base..];
        c[0] = DS_FLAG0_VIBRATION;
        c[1] = DS_FLAG1_LIGHTBAR | DS_FLAG1_PLAYER_LIGHTS;
        c[2] = out.weak_motor;
        c[3] = out.strong_motor;
        c[43] = out.player_lights & 0x1F;
        c[44..47].copy_from_slice(&out.lightbar);
    } else {
        if link == Link::Bluetooth {
            // HID data with a CRC, 4 ms polling.
            r[1] = 0xC4;
        }
        let c = &mut r[base..];
        c[0] = DS4_FLAG_MOTOR | DS4_FLAG_LED;
        c[3] = out.weak_motor;
        c[4] = out.strong_motor;
        c[5..8].copy_from_slice(&out.lightbar);
    }
    if link == Link::Bluetooth {
        let crc = crc32_seeded(CRC_SEED_OUTPUT, &r[..len - 4]);
        r[len - 4..].copy_from_slice(&crc.to_le_bytes());
    }
    r
}

/// Reads an output report back (what a pad — the emulator — does with one): its settings, or
/// why it is refused (wrong id, short, wrong CRC: a real pad ignores such a report).
pub fn parse_output(
    kind: ControllerKind,
    link: Link,
    report: &[u8],
) -> Result<SonyOutput, DecodeError> {
    let (id, base, len) = layout(kind, link);
    check_report(report, id, len, kind)?;
    if link == Link::Bluetooth
        && crc32_seeded(CRC_SEED_OUTPUT, &report[..len - 4]) != le_u32(report, len - 4)
    {
        return Err(DecodeError::Crc);
    }
    let c = &report[base..];
    Ok(if is_dualsense(kind) {
        SonyOutput {
            weak_motor: c[2],
            strong_motor: c[3],
            player_lights: c[43],
            lightbar: [c[44], c[45], c[46]],
        }
    } else {
        SonyOutput {
            weak_motor: c[3],
            strong_motor: c[4],
            player_lights: 0,
            lightbar: [c[5], c[6], c[7]],
        }
    })
}
