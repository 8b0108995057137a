//! The drift benchmark's sessions on gyro pads: the same scripted motions through a pad's
//! emulator (its rate, quantisation, noise and bias) and the pad session.

use std::sync::Arc;

use super::{ContinuousScenario, DriftScenario, Recording, START_STILL, SessionSet};
use bevy_wii_deform::controllers::fusion::FilterKind;
use bevy_wii_deform::controllers::motion::Motion;
use bevy_wii_deform::controllers::pads::{EmulatedPad, PadEmulatorConfig, PadSession};
use bevy_wii_deform::controllers::transport::Transport;
use bevy_wii_deform::controllers::wiimote::{SessionConfig, SessionEvent};

/// Records one session of `set` on the pad `config` describes (its seed replaced by `seed`).
/// `None` for [`SessionSet::Pointing`]: pads have no IR camera.
pub fn record_pad(
    set: SessionSet,
    config: &PadEmulatorConfig,
    seed: u64,
    duration_s: f64,
) -> Option<Recording> {
    match set {
        SessionSet::Default | SessionSet::NoWarmUp => {
            let scenario = Arc::new(DriftScenario::new(seed, duration_s));
            let end = scenario.duration();
            let s = scenario.clone();
            let still = move |t: f64| s.is_still(t);
            Some(record(scenario, config, seed, end, still))
        }
        SessionSet::Continuous => {
            let scenario = Arc::new(ContinuousScenario::new(seed, duration_s));
            let end = scenario.duration();
            Some(record(scenario, config, seed, end, |t| t < START_STILL))
        }
        SessionSet::Pointing => None,
    }
}

fn record<M: Motion + 'static>(
    motion: Arc<M>,
    config: &PadEmulatorConfig,
    seed: u64,
    duration_s: f64,
    still: impl Fn(f64) -> bool,
) -> Recording {
    let pad = EmulatedPad::new(PadEmulatorConfig {
        seed,
        realtime: false,
        clock: None,
        ..config.clone()
    });
    pad.controls().set_motion(motion.clone());
    let session_config = SessionConfig {
        filter: FilterKind::Raw,
        ..SessionConfig::default()
    };
    let mut session = PadSession::new(pad, config.kind, config.link, session_config);
    let mut rec = Recording::default();
    if session.connect().is_err() {
        return rec;
    }
    let end_us = (duration_s * 1e6) as u64;
    while session.transport().now_us() < end_us {
        if session.poll(20).is_err() {
            break;
        }
        for e in session.drain_events() {
            if let SessionEvent::Imu(s) = e {
                let t = s.timestamp_us as f64 * 1e-6;
                rec.samples.push(s);
                rec.truth.push(motion.orientation(t));
                rec.times.push(t);
                rec.still.push(still(t));
                rec.bar.push(None);
                rec.pointer.push(None);
            }
        }
    }
    rec
}
