//! Decodes motion-controller input reports: hex on stdin, one report per line (report id
//! first; over Bluetooth *without* the `0xA1` transaction byte, which Sony's CRC-32 is
//! nevertheless seeded with), one JSON object per line on stdout, then a summary.
//!
//! ```text
//! cargo run --release --example motion_decode -- --device dualsense|ds4|switch-pro|joycon|joycon-l|joycon-r [--bluetooth] < reports.hex
//! ```
//! Each line gives `{"accel_mps2": [x, y, z], "gyro_rps": [x, y, z], "timestamp_s": …,
//! "crc_ok": …, "buttons": {…}}` in the crate's body frame (`MotionSample`), with the
//! datasheet's scales (no calibration report is read); a report with several samples (the
//! Switch's three) gives `"samples": [{"accel_mps2", "gyro_rps"}, …]` oldest first instead of
//! the two arrays. A report that does not decode gives `{"error": "…"}`. The last line is
//! `{"summary": {…}}`. It exits 0 once its input is read, whatever the reports held; 2 for
//! bad arguments.

use bevy_wii_deform_examples::cli;

use std::io::BufRead;

use bevy_wii_deform::controllers::pads::PadDecoder;
use bevy_wii_deform::controllers::{ControllerKind, Link, MotionSample, PadReport};
use serde_json::{Value, json};

const USAGE: &str = "\
usage: motion_decode --device KIND [--bluetooth] < REPORTS

  --device KIND  dualsense, dualsense-edge, ds4, switch-pro, joycon (= joycon-r), joycon-l,
                 joycon-r
  --bluetooth    the reports came over Bluetooth (Sony: full reports with a CRC-32)

  stdin: one input report per line, in hex (spaces allowed), report id first";

fn vector(v: glam::DVec3) -> Value {
    json!([v.x, v.y, v.z])
}

fn sample_json(s: &MotionSample) -> Value {
    json!({"accel_mps2": vector(s.accel_mps2), "gyro_rps": vector(s.gyro_rps)})
}

fn report_json(r: &PadReport) -> Value {
    let b = r.buttons;
    let mut out = serde_json::Map::new();
    match r.samples() {
        [one] => {
            out.insert("accel_mps2".into(), vector(one.accel_mps2));
            out.insert("gyro_rps".into(), vector(one.gyro_rps));
        }
        many => {
            out.insert("samples".into(), many.iter().map(sample_json).collect());
        }
    }
    let time = r.samples().first().and_then(|s| s.device_time_s);
    out.insert("timestamp_s".into(), json!(time));
    out.insert("crc_ok".into(), json!(r.crc_ok));
    out.insert(
        "buttons".into(),
        json!({"clutch": b.clutch, "grab": b.grab, "recentre": b.recentre,
               "calibrate": b.calibrate, "raw": b.raw}),
    );
    Value::Object(out)
}

fn parse_hex(line: &str) -> Result<Vec<u8>, String> {
    let digits: String = line.chars().filter(|c| !c.is_whitespace()).collect();
    if !digits.len().is_multiple_of(2) {
        return Err(format!("odd number of hex digits ({})", digits.len()));
    }
    (0..digits.len())
        .step_by(2)
        .map(|i| {
            u8::from_str_radix(&digits[i..i + 2], 16)
                .map_err(|_| format!("not hex: {:?}", &digits[i..i + 2]))
        })
        .collect()
}

fn main() {
    let (mut device, mut link) = (None, Link::Usb);
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("device") => {
                let name = cli::string(&mut parser, USAGE);
                device = Some(
                    ControllerKind::from_name(&name)
                        .filter(|k| *k != ControllerKind::WiiRemote)
                        .unwrap_or_else(|| cli::fail(format!("unknown device {name:?}"), USAGE)),
                );
            }
            cli::Arg::Long("bluetooth") => link = Link::Bluetooth,
            other => cli::unexpected(other, USAGE),
        }
    }
    let Some(device) = device else {
        cli::fail("--device is required", USAGE);
    };
    let decoder = PadDecoder::new(device, link).unwrap_or_else(|e| cli::fail(e, USAGE));
    let (mut lines, mut decoded, mut errors, mut samples, mut crc_failures) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let stdin = std::io::stdin();
    for line in stdin.lock().lines() {
        let Ok(line) = line else { break };
        lines += 1;
        let result =
            parse_hex(&line).and_then(|bytes| decoder.decode(&bytes).map_err(|e| e.to_string()));
        match result {
            Ok(report) => {
                decoded += 1;
                samples += report.samples().len() as u64;
                if report.crc_ok == Some(false) {
                    crc_failures += 1;
                }
                println!("{}", report_json(&report));
            }
            Err(e) => {
                errors += 1;
                println!("{}", json!({"error": e}));
            }
        }
    }
    println!(
        "{}",
        json!({"summary": {"device": device.name(), "link": link.name(), "lines": lines,
                           "decoded": decoded, "errors": errors, "samples": samples,
                           "crc_failures": crc_failures}})
    );
}
