//! Smoothing for the IR pointer: the camera reports whole pixels with a little noise, so a
//! pointer held still trembles by a pixel or two, while a pointer swept across the screen must
//! not trail behind. The One Euro filter (Casiez, Roussel and Vogel, "1€ Filter: A Simple
//! Speed-based Low-pass Filter for Noisy Input in Interactive Systems", CHI 2012) does both: a
//! first-order low-pass whose cut-off rises with the pointer's speed — strong smoothing at rest,
//! little lag in motion (`docs/PROTOCOL.md` §17.5).

use glam::DVec2;

/// The One Euro filter's settings, for positions in screen widths/heights (0..1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointerSmoothing {
    /// Cut-off at rest, Hz (1.5): lower smooths a still pointer more.
    pub min_cutoff_hz: f64,
    /// Cut-off added per unit of speed (screens per second), Hz (10): higher trails less in
    /// fast motion.
    pub beta: f64,
    /// Cut-off of the speed estimate, Hz (1).
    pub derivative_cutoff_hz: f64,
}

impl Default for PointerSmoothing {
    fn default() -> Self {
        Self {
            min_cutoff_hz: 1.5,
            beta: 10.0,
            derivative_cutoff_hz: 1.0,
        }
    }
}

/// Smoothing factor of a first-order low-pass with cut-off `cutoff_hz` over `dt` seconds.
fn alpha(cutoff_hz: f64, dt: f64) -> f64 {
    let tau = 1.0 / (std::f64::consts::TAU * cutoff_hz.max(1e-6));
    1.0 / (1.0 + tau / dt)
}

/// One pointer's One Euro filter state.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SmoothedPointer {
    /// The settings.
    pub settings: PointerSmoothing,
    /// Last output, its speed estimate, and the time it was given, s.
    state: Option<(DVec2, DVec2, f64)>,
}

impl SmoothedPointer {
    /// A filter with `settings`.
    pub fn new(settings: PointerSmoothing) -> Self {
        Self {
            settings,
            state: None,
        }
    }

    /// Filters a pointer position seen at `time_s` seconds; the first after a
    /// [`Self::reset`] (or a time that does not move forward by 0.2 s or less) passes through.
    /// Non-finite input is ignored: the last output is returned (or the input, with none).
    pub fn update(&mut self, at: DVec2, time_s: f64) -> DVec2 {
        if !at.is_finite() || !time_s.is_finite() {
            return self.state.map_or(at, |(p, ..)| p);
        }
        let Some((previous, speed, t)) = self.state else {
            self.state = Some((at, DVec2::ZERO, time_s));
            return at;
        };
        let dt = time_s - t;
        if !(dt > 0.0 && dt <= 0.2) {
            // Out of order or after a gap: start again from here.
            self.state = Some((at, DVec2::ZERO, time_s));
            return at;
        }
        let s = self.settings;
        let raw_speed = (at - previous) / dt;
        let speed = speed.lerp(raw_speed, alpha(s.derivative_cutoff_hz, dt));
        let cutoff = s.min_cutoff_hz + s.beta.max(0.0) * speed.length();
        let out = previous.lerp(at, alpha(cutoff, dt));
        self.state = Some((out, speed, time_s));
        out
    }

    /// Forgets the past (the bar left the view): the next position passes through.
    pub fn reset(&mut self) {
        self.state = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controllers::wiimote::Rng;

    /// Held still with ±1-pixel-like noise the pointer trembles at least 3× less; swept at half a
    /// screen per second it trails by under 30 ms.
    #[test]
    fn still_pointers_tremble_less_and_moving_ones_do_not_trail() {
        let mut rng = Rng::new(7);
        let mut f = SmoothedPointer::default();
        let sigma = 0.001;
        let (mut raw2, mut out2, mut n) = (0.0, 0.0, 0.0);
        for k in 0..1000 {
            let noise = DVec2::new(rng.normal(), rng.normal()) * sigma;
            let out = f.update(DVec2::splat(0.5) + noise, k as f64 * 0.01);
            if k > 100 {
                raw2 += noise.length_squared();
                out2 += (out - DVec2::splat(0.5)).length_squared();
                n += 1.0;
            }
        }
        let (raw, out) = ((raw2 / n).sqrt(), (out2 / n).sqrt());
        assert!(out < raw / 3.0, "still: {out} from {raw}");
        let mut f = SmoothedPointer::default();
        let speed = 0.5;
        let mut lag = 0.0;
        for k in 0..100 {
            let t = k as f64 * 0.01;
            let out = f.update(DVec2::new(0.2 + speed * t, 0.5), t);
            lag = (0.2 + speed * t - out.x) / speed;
        }
        assert!(lag > 0.0 && lag < 0.03, "trails by {lag} s");
        // A gap or a reset passes the next position through.
        f.reset();
        assert_eq!(f.update(DVec2::new(0.9, 0.1), 5.0), DVec2::new(0.9, 0.1));
        assert_eq!(f.update(DVec2::NAN, 5.01), DVec2::new(0.9, 0.1));
    }
}
