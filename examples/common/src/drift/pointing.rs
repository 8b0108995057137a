//! A session of pointing at the screen and turning away: the sensor bar is in view a given
//! share of the time, so the IR heading reference can be scored (`PROTOCOL.md` §14, §17.6).

use glam::{DQuat, DVec3};

use super::{START_STILL, smoothstep};
use bevy_wii_deform::controllers::motion::Motion;
use bevy_wii_deform::controllers::wiimote::Rng;
use bevy_wii_deform::controllers::wiimote::from_yaw_elevation_roll;

/// Length of one point-then-turn-away cycle, s.
const CYCLE: f64 = 40.0;
/// Time to turn to and from the screen, s.
const TURN: f64 = 1.5;
/// Elevation the player aims at while pointing, degrees (the upper half of the screen: the
/// bar above it stays inside the camera's ±11.5° vertical view).
const AIM_ELEVATION: f64 = 4.0;

/// Pointing at the screen (small hand wobble around an aim at its upper half, rolled up to
/// ±20°) for `share` of every 40-s cycle, then turning away (50–110° either way, tilted and
/// rolled, with 1–2 Hz wiggles) for the rest; 5 s still on the table at the start, aimed at
/// the screen. The remote stands at one spot of the room: the bar's direction from it is fixed.
#[derive(Debug, Clone)]
pub struct PointingScenario {
    duration: f64,
    share: f64,
    /// Per cycle: heading away (deg), elevation away (deg), roll away (deg), and per axis the
    /// (frequency Hz, amplitude deg, phase rad) of the wobble while pointing and of the
    /// wiggle while away.
    cycles: Vec<Cycle>,
}

#[derive(Debug, Clone)]
struct Cycle {
    away: [f64; 3],
    wobble: [(f64, f64, f64); 3],
    wiggle: [(f64, f64, f64); 3],
}

impl PointingScenario {
    /// A session of `duration_s` seconds with the bar aimed at for `share` (0.05–1) of each
    /// cycle, turns and wobbles drawn from `seed`.
    pub fn new(seed: u64, duration_s: f64, share: f64) -> Self {
        let duration = duration_s.max(START_STILL + 1.0);
        let mut rng = Rng::new(seed ^ 0x1B0A7);
        let count = ((duration - START_STILL) / CYCLE).ceil() as usize + 1;
        let cycles = (0..count)
            .map(|_| {
                let side = if rng.range(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 };
                Cycle {
                    away: [
                        side * rng.range(50.0, 110.0),
                        rng.range(-30.0, 30.0),
                        rng.range(-45.0, 45.0),
                    ],
                    wobble: [
                        (rng.range(0.2, 0.9), 5.0, rng.range(0.0, 6.3)),
                        (rng.range(0.2, 0.9), 2.0, rng.range(0.0, 6.3)),
                        (rng.range(0.1, 0.4), 20.0, rng.range(0.0, 6.3)),
                    ],
                    wiggle: [
                        (rng.range(1.0, 2.0), 10.0, rng.range(0.0, 6.3)),
                        (rng.range(1.0, 2.0), 8.0, rng.range(0.0, 6.3)),
                        (rng.range(0.5, 1.5), 15.0, rng.range(0.0, 6.3)),
                    ],
                }
            })
            .collect();
        Self {
            duration,
            share: share.clamp(0.05, 1.0),
            cycles,
        }
    }

    /// Total length in seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// (yaw, elevation, roll) in degrees.
    fn angles(&self, t: f64) -> [f64; 3] {
        if t < START_STILL {
            return [0.0, AIM_ELEVATION, 0.0];
        }
        let tc = t - START_STILL;
        let cycle = &self.cycles[((tc / CYCLE) as usize).min(self.cycles.len() - 1)];
        let tc = tc.rem_euclid(CYCLE);
        let wave = |(f, a, p): (f64, f64, f64), envelope: f64| {
            envelope * a * (std::f64::consts::TAU * f * tc + p).sin()
        };
        let pointing = self.share * CYCLE;
        // Turned away: 0 while pointing, easing to 1 over TURN after it and back before the
        // cycle ends.
        let away = if tc < pointing {
            0.0
        } else {
            smoothstep((tc - pointing) / TURN) * smoothstep((CYCLE - tc) / TURN)
        };
        // The wobble fades in and out with the pointing phase (continuous at its ends).
        let wobble_env = if tc < pointing {
            smoothstep(tc / 1.0) * smoothstep((pointing - tc) / 1.0)
        } else {
            0.0
        };
        std::array::from_fn(|axis| {
            let base = if axis == 1 { AIM_ELEVATION } else { 0.0 };
            base + away * cycle.away[axis]
                + wave(cycle.wobble[axis], wobble_env)
                + wave(cycle.wiggle[axis], away)
        })
    }
}

impl Motion for PointingScenario {
    fn orientation(&self, t: f64) -> DQuat {
        let [y, e, r] = self.angles(t);
        from_yaw_elevation_roll(y.to_radians(), e.to_radians(), r.to_radians())
    }
    fn position(&self, _t: f64) -> DVec3 {
        DVec3::ZERO
    }
}
