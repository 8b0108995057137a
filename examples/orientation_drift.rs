//! Drift benchmark (PROTOCOL.md §14): seeded 10-minute synthetic sessions through the
//! emulator and the session code, scored for every filter against the ground truth.
//!
//! ```text
//! cargo run --release --example orientation_drift -- --json [--seeds 5] [--seconds 600]
//! ```
//! The last stdout line is one JSON object keyed by filter name (`raw`, `paper`, `ours`).

use bevy_wii_deform::wiimote::{FilterKind, drift};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str, default: f64| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let seeds = value("--seeds", 5.0) as u64;
    let seconds = value("--seconds", 600.0);
    let json = args.iter().any(|a| a == "--json");
    let mut scores: Vec<Vec<drift::FilterScore>> = vec![Vec::new(); FilterKind::ALL.len()];
    let mut floor = 0.0;
    for seed in 1..=seeds {
        let rec = drift::record_session(seed, seconds);
        eprintln!(
            "seed {seed}: {} samples, {:.0} s",
            rec.samples.len(),
            rec.times.last().copied().unwrap_or(0.0)
        );
        floor += drift::accelerometer_tilt_floor(&rec) / seeds as f64;
        for (k, kind) in FilterKind::ALL.iter().enumerate() {
            scores[k].push(drift::score(*kind, &rec));
        }
    }
    eprintln!("accelerometer-only tilt error while still (the floor for tilt): {floor:.3}° RMS");
    println!(
        "{:<6} {:>10} {:>12} {:>12} {:>12} {:>12} {:>8}",
        "filter", "tilt RMS°", "tilt still°", "yaw °/min", "attitude°", "rel2s p95°", "µs/smp"
    );
    let mut parts = Vec::new();
    for (k, kind) in FilterKind::ALL.iter().enumerate() {
        let m = drift::mean(&scores[k]);
        println!(
            "{:<6} {:>10.3} {:>12.3} {:>12.3} {:>12.3} {:>12.3} {:>8.3}",
            kind.name(),
            m.tilt_rms_deg,
            m.tilt_max_still_deg,
            m.yaw_drift_deg_per_min,
            m.attitude_rms_deg,
            m.relative_rotation_p95_deg,
            m.us_per_sample
        );
        parts.push(format!("\"{}\": {}", kind.name(), m.to_json()));
    }
    if json {
        println!("{{{}}}", parts.join(", "));
    }
}
