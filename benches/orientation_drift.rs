//! Drift benchmark (PROTOCOL.md §14): seeded 10-minute synthetic sessions through the
//! emulator and the session code, scored for every filter against the ground truth, on every
//! session set (`default`, `no_warm_up`, `continuous`, `pointing`; see `bevy_wii_deform_examples::drift`).
//!
//! ```text
//! cargo run --release --example orientation_drift -- --json [--device wiimote|dualsense|ds4|switch-pro|joycon] [--seeds 5] [--first-seed 1] [--seconds 600] [--set NAME] [--ideal LIST] [--in-view 0.5]
//! ```
//! `--device` runs the sessions through that controller's emulator and session instead of
//! the Wii Remote's (its rate, quantisation, noise and bias; `PadSensorModel`). Pads have no
//! IR camera (no `pointing` set) and no warm-up drift in their model (no `no_warm_up` set);
//! every filter that depends on the sample period (ours, VQF) is built for the device's
//! true period, VQF with its published default parameters (both in the JSON:
//! `"device"`, `"rate_hz"`, `"vqf_settings"`).
//! The `pointing` set aims at a screen with a sensor bar `--in-view` of the time (default
//! 0.5) with the IR camera on; it adds `ours_ir` (our filter fed with the bar's sightings: the
//! heading reference of `PROTOCOL.md` §17.6) and `in_view_share` (the share of samples in which
//! the camera saw the bar) and `pointer_rms_percent_of_width` (the pointer's RMS error while
//! the bar is in view, per cent of the screen's width).
//! `--ideal` removes sensor errors from the emulated unit, to find which one limits a filter:
//! a comma-separated list of `accel` (misalignment and scale), `gyro_scale` (calibration-block
//! scale error), `gyro_misalignment`, `bias_walk`, `warm_up`, `gyro_noise` (σ 0.01 deg/s).
//! The last stdout line is one JSON object: the default set's scores keyed by filter name
//! (`raw`, `paper`, `ours`, `vqf`), and under `sets` every set's scores by filter plus the
//! accelerometer-only tilt floor, and `ideal` (the `--ideal` list, empty for the real sensor
//! model). Metrics include BROAD-style `heading_rmse_deg` and
//! `inclination_rmse_deg`.

use bevy_wii_deform_examples::cli;

use bevy_wii_deform::controllers::pads::{PadEmulatorConfig, PadSensorModel};
use bevy_wii_deform::controllers::wiimote::{FilterKind, SensorModel};
use bevy_wii_deform::controllers::{ControllerKind, Link};
use bevy_wii_deform_examples::drift::{self, SessionSet};

/// `model` with the errors named in `list` (see the module docs) removed.
fn idealised(mut model: SensorModel, list: &str) -> Result<SensorModel, String> {
    for name in list.split(',').filter(|n| !n.is_empty()) {
        match name {
            "accel" => {
                model.accel_misalignment = 0.0;
                model.accel_scale_error = 0.0;
            }
            "gyro_scale" => model.gyro_block_scale_error = 0.0,
            "gyro_misalignment" => model.gyro_misalignment = 0.0,
            "bias_walk" => model.gyro_bias_walk = 0.0,
            "warm_up" => model.gyro_temperature_drift_dps = 0.0,
            "gyro_noise" => model.gyro_noise_dps = 0.01,
            other => return Err(format!("unknown sensor error {other}")),
        }
    }
    Ok(model)
}

/// Mean scores of every filter on one set, and the accelerometer's own tilt error.
struct SetReport {
    set: SessionSet,
    scores: Vec<drift::FilterScore>,
    floor: f64,
    /// `ours` fed with the bar's sightings, and the share of samples that saw it (the
    /// `pointing` set only).
    with_bar: Option<(drift::FilterScore, f64, f64)>,
}

/// What one set is run with.
struct RunSettings<'a> {
    /// A pad's emulator (its kind, link and sensor model); `None`: the Wii Remote's.
    pad: Option<PadEmulatorConfig>,
    ideal: &'a str,
    seeds: std::ops::RangeInclusive<u64>,
    seconds: f64,
    in_view: f64,
}

fn run_set(set: SessionSet, run: &RunSettings) -> SetReport {
    let RunSettings {
        ref pad,
        ideal,
        ref seeds,
        seconds,
        in_view,
    } = *run;
    let period = pad
        .as_ref()
        .map_or(0.01, |p| 1.0 / p.sensors.sample_rate_hz());
    let sensor = match idealised(set.sensor(), ideal) {
        Ok(sensor) => sensor,
        Err(e) => {
            eprintln!(
                "{e}: accel, gyro_scale, gyro_misalignment, bias_walk, warm_up or gyro_noise"
            );
            std::process::exit(2);
        }
    };
    let mut per_filter: Vec<Vec<drift::FilterScore>> = vec![Vec::new(); FilterKind::ALL.len()];
    let mut floors = Vec::new();
    let (mut with_bar, mut shares, mut pointer) = (Vec::new(), Vec::new(), Vec::new());
    for seed in seeds.clone() {
        let rec = match pad {
            Some(pad) => drift::record_pad(set, pad, seed, seconds).unwrap_or_default(),
            None if set == SessionSet::Pointing => {
                drift::record_pointing(sensor.clone(), seed, seconds, in_view)
            }
            None => set.record_with_sensor(sensor.clone(), seed, seconds),
        };
        eprintln!(
            "{} seed {seed}: {} samples, {:.0} s",
            set.name(),
            rec.samples.len(),
            rec.times.last().copied().unwrap_or(0.0)
        );
        floors.push(drift::accelerometer_tilt_floor(&rec));
        for (k, kind) in FilterKind::ALL.iter().enumerate() {
            per_filter[k].push(drift::score_at_period(*kind, &rec, period));
        }
        if set == SessionSet::Pointing {
            with_bar.push(drift::score_with_bar(FilterKind::Fusion, &rec));
            shares.push(rec.in_view_share());
            pointer.extend(rec.pointer_rms_error());
        }
    }
    SetReport {
        set,
        scores: per_filter.iter().map(|s| drift::mean(s)).collect(),
        floor: floors.iter().sum::<f64>() / floors.len().max(1) as f64,
        with_bar: (!with_bar.is_empty()).then(|| {
            (
                drift::mean(&with_bar),
                shares.iter().sum::<f64>() / shares.len() as f64,
                pointer.iter().sum::<f64>() / pointer.len().max(1) as f64,
            )
        }),
    }
}

fn print_table(report: &SetReport) {
    println!(
        "\n{} (accelerometer-only tilt error while still: {:.3}° RMS)",
        report.set.name(),
        report.floor
    );
    println!(
        "{:<7} {:>9} {:>11} {:>10} {:>10} {:>11} {:>9} {:>9} {:>7}",
        "filter",
        "tilt RMS°",
        "tilt still°",
        "yaw °/min",
        "attitude°",
        "rel2s p95°",
        "heading°",
        "inclin.°",
        "µs/smp"
    );
    let with_bar = report.with_bar.iter().map(|(m, ..)| ("ours_ir", m));
    for (name, m) in FilterKind::ALL
        .iter()
        .map(|k| k.name())
        .zip(&report.scores)
        .chain(with_bar)
    {
        println!(
            "{:<7} {:>9.3} {:>11.3} {:>10.3} {:>10.3} {:>11.3} {:>9.3} {:>9.3} {:>7.3}",
            name,
            m.tilt_rms_deg,
            m.tilt_max_still_deg,
            m.yaw_drift_deg_per_min,
            m.attitude_rms_deg,
            m.relative_rotation_p95_deg,
            m.heading_rmse_deg,
            m.inclination_rmse_deg,
            m.us_per_sample
        );
    }
    if let Some((_, share, pointer)) = report.with_bar {
        println!(
            "bar in view {:.1} % of the samples; pointer error {:.3} % of the screen width (RMS)",
            share * 100.0,
            pointer * 100.0
        );
    }
}

fn filters_json(report: &SetReport) -> String {
    let mut fields: Vec<String> = FilterKind::ALL
        .iter()
        .zip(&report.scores)
        .map(|(kind, m)| format!("\"{}\": {}", kind.name(), m.to_json()))
        .collect();
    if let Some((m, share, pointer)) = &report.with_bar {
        fields.push(format!("\"ours_ir\": {}", m.to_json()));
        fields.push(format!("\"in_view_share\": {share:.4}"));
        fields.push(format!(
            "\"pointer_rms_percent_of_width\": {:.4}",
            pointer * 100.0
        ));
    }
    fields.join(", ")
}

const USAGE: &str = "\
usage: orientation_drift [--device KIND] [--seeds N] [--first-seed N] [--seconds S] [--set NAME]
                         [--ideal WHAT] [--in-view SHARE] [--json]

  --device KIND    wiimote (default), dualsense, ds4, switch-pro, joycon (= joycon-r),
                   joycon-l, joycon-r, dualsense-edge
  --seeds N        sessions per set (default 5)
  --first-seed N   the first seed (default 1)
  --seconds S      session length (default 600)
  --set NAME       default, no_warm_up, continuous or pointing (default: all)
  --ideal WHAT     sensor errors to remove (an ablation)
  --in-view SHARE  share of the pointing session with the sensor bar in view
  --json           print the JSON line";

fn main() {
    let (mut seeds, mut first, mut seconds) = (5.0f64, 1.0f64, 600.0);
    let (mut json, mut ideal, mut in_view, mut set) = (
        false,
        String::new(),
        drift::DEFAULT_IN_VIEW_SHARE,
        None::<String>,
    );
    let mut device = ControllerKind::WiiRemote;
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("seeds") => seeds = cli::value(&mut parser, USAGE),
            cli::Arg::Long("first-seed") => first = cli::value(&mut parser, USAGE),
            cli::Arg::Long("seconds") => seconds = cli::value(&mut parser, USAGE),
            cli::Arg::Long("json") => json = true,
            cli::Arg::Long("ideal") => ideal = cli::string(&mut parser, USAGE),
            cli::Arg::Long("in-view") => in_view = cli::value(&mut parser, USAGE),
            cli::Arg::Long("set") => set = Some(cli::string(&mut parser, USAGE)),
            cli::Arg::Long("device") => {
                let name = cli::string(&mut parser, USAGE);
                device = ControllerKind::from_name(&name)
                    .unwrap_or_else(|| cli::fail(format!("unknown device {name:?}"), USAGE));
            }
            other => cli::unexpected(other, USAGE),
        }
    }
    let seeds = seeds.max(1.0) as u64;
    let first = first.max(0.0) as u64;
    let ideal = ideal.as_str();
    let pad = (device != ControllerKind::WiiRemote).then(|| {
        // Sony pads over USB, Switch controllers over Bluetooth: how each is most often held.
        let link = if matches!(
            device,
            ControllerKind::SwitchPro | ControllerKind::JoyConLeft | ControllerKind::JoyConRight
        ) {
            Link::Bluetooth
        } else {
            Link::Usb
        };
        PadEmulatorConfig {
            sensors: PadSensorModel::for_device(device, link),
            ..PadEmulatorConfig::new(device, link)
        }
    });
    if pad.is_some() && !ideal.is_empty() {
        cli::fail("--ideal removes the Wii Remote's sensor errors only", USAGE);
    }
    let sets: Vec<SessionSet> = match set.as_deref() {
        Some(name) => match SessionSet::from_name(name) {
            Some(set) => vec![set],
            None => {
                eprintln!("unknown set {name}: default, no_warm_up, continuous or pointing");
                std::process::exit(2);
            }
        },
        None if pad.is_some() => vec![SessionSet::Default, SessionSet::Continuous],
        None => SessionSet::ALL.to_vec(),
    };
    if pad.is_some() && sets.contains(&SessionSet::Pointing) {
        cli::fail("the pointing set needs an IR camera (a Wii Remote)", USAGE);
    }
    let rate_hz = pad.as_ref().map_or(100.0, |p| p.sensors.sample_rate_hz());
    let run = RunSettings {
        pad,
        ideal,
        seeds: first..=first + seeds - 1,
        seconds,
        in_view,
    };
    let reports: Vec<SetReport> = sets.iter().map(|set| run_set(*set, &run)).collect();
    for r in &reports {
        print_table(r);
    }
    if json {
        let head = reports
            .iter()
            .find(|r| r.set == SessionSet::Default)
            .unwrap_or(&reports[0]);
        let sets = reports
            .iter()
            .map(|r| {
                format!(
                    "\"{}\": {{{}, \"accelerometer_floor_deg\": {:.4}}}",
                    r.set.name(),
                    filters_json(r),
                    r.floor
                )
            })
            .collect::<Vec<_>>()
            .join(", ");
        // Which sensor errors were removed (`--ideal`), so an ablation is never read as a
        // default-set figure.
        println!(
            "{{{}, \"sets\": {{{sets}}}, \"ideal\": {:?}, \"device\": \"{}\", \"rate_hz\": {rate_hz:.3}, \
             \"vqf_settings\": {{\"sample_period_s\": {:.6}, \"params\": \"vqf-rs defaults (Laidig & Seel 2023)\"}}}}",
            filters_json(head),
            ideal,
            device.name(),
            1.0 / rate_hz
        );
    }
}
