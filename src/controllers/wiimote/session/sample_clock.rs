//! When each report was sampled, recovered from when it arrived (`docs/PROTOCOL.md` §10).
//!
//! The remote samples on a fixed tick (~100 Hz) but the host sees its reports through a
//! Bluetooth stack that delays them by a varying amount and sometimes hands over two or three
//! at once. Integrating the gyro over the raw *arrival* spacing with a floor on short spacings
//! (the spec's clamp to [2 ms, 50 ms]) turns every such burst into rotation that never
//! happened: two reports handed over together integrate 2 ms too much, so with bursts of two
//! a turn reads 10 % long. [`SampleClock`] instead keeps a clock that advances by one learned
//! period per report and never runs ahead of an arrival: jitter costs nothing, a burst's
//! reports share the ticks they were sampled on, and a report that comes half a period or more
//! after the clock's next tick means ticks without a report (lost, or the remote paused its
//! reports for a memory read) — the clock catches up by whole periods at once.

use std::collections::VecDeque;

/// A gap longer than this is a dropout: the clock restarts, no time is integrated across it.
const DROPOUT_S: f64 = 0.1;
/// Shortest and longest period the clock accepts (the spec's [2 ms, 50 ms]).
const PERIOD_RANGE_S: (f64, f64) = (0.002, 0.05);
/// Arrival spacings over which the period is measured.
const PERIOD_WINDOW: usize = 64;

/// A report clock recovered from arrival times. See the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleClock {
    /// The report period, s (starts at 10 ms, learned from the arrivals).
    period_s: f64,
    /// Estimated sample time of the last report, s (host clock).
    last_sample_s: Option<f64>,
    /// Arrival time of the last report, s.
    last_arrival_s: f64,
    /// Recent arrival spacings within half a period of the period (not bursts, not gaps), s.
    spacings: VecDeque<f64>,
}

impl Default for SampleClock {
    fn default() -> Self {
        Self {
            period_s: 0.01,
            last_sample_s: None,
            last_arrival_s: 0.0,
            spacings: VecDeque::with_capacity(PERIOD_WINDOW),
        }
    }
}

impl SampleClock {
    /// The learned report period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Takes a report that arrived at `arrival_us` (host clock) and gives its estimated sample
    /// time in seconds, or `None` for the first report and the first after a dropout (nothing
    /// to integrate from).
    pub fn sample_time(&mut self, arrival_us: u64) -> Option<f64> {
        let arrival = arrival_us as f64 * 1e-6;
        let previous = self.last_sample_s;
        let spacing = arrival - self.last_arrival_s;
        self.last_arrival_s = arrival;
        let Some(previous) = previous.filter(|_| (0.0..=DROPOUT_S).contains(&spacing)) else {
            self.last_sample_s = Some(arrival);
            return None;
        };
        self.measure_period(spacing);
        let period = self.period_s;
        // One period on, never after the report arrived; half a period or more behind the
        // arrival: ticks went by without a report.
        let next = previous + period;
        let late = arrival - next;
        let sample = if late >= 0.5 * period {
            (next + (late / period).round() * period).min(arrival)
        } else {
            next.min(arrival)
        };
        self.last_sample_s = Some(sample);
        Some(sample)
    }

    /// The period: the mean of the recent spacings that look like one tick (within half a
    /// period of it), so that bursts, pauses and jitter do not move it.
    fn measure_period(&mut self, spacing: f64) {
        if (spacing - self.period_s).abs() >= 0.5 * self.period_s {
            return;
        }
        if self.spacings.len() == PERIOD_WINDOW {
            self.spacings.pop_front();
        }
        self.spacings.push_back(spacing);
        let mean = self.spacings.iter().sum::<f64>() / self.spacings.len() as f64;
        if mean.is_finite() {
            self.period_s = mean.clamp(PERIOD_RANGE_S.0, PERIOD_RANGE_S.1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds arrival times (ms) and gives the spans between consecutive sample times (ms).
    fn spans(arrivals_ms: &[f64]) -> Vec<f64> {
        let mut clock = SampleClock::default();
        let mut last = None;
        let mut out = Vec::new();
        for &a in arrivals_ms {
            let t = clock.sample_time((a * 1000.0) as u64);
            if let (Some(t), Some(l)) = (t, last) {
                out.push((t - l) * 1e3);
            }
            last = t.or(last);
        }
        out
    }

    #[test]
    fn bursts_and_jitter_integrate_the_elapsed_ticks() {
        // Pairs handed over at once, and 3 ms of jitter on every third report.
        let mut arrivals = Vec::new();
        for k in 0..200 {
            let t = 10.0 * k as f64;
            let delivered = if k % 2 == 1 { t + 10.0 } else { t };
            arrivals.push(delivered + if k % 3 == 0 { 3.0 } else { 0.0 });
        }
        arrivals.sort_by(f64::total_cmp);
        let s = spans(&arrivals);
        let total: f64 = s.iter().sum();
        // The arrival spacing alternates 0–20 ms; integrated with the spec's 2-ms floor it
        // would be 10 % long. The clock's spans sum to the elapsed ticks within one jitter.
        assert!((total - 10.0 * s.len() as f64).abs() < 3.5, "{total}");
        // No rotation invented: a burst's reports share their two ticks (20 ms, then 0).
        assert!(s.iter().all(|d| (-1e-9..=23.0).contains(d)), "{s:?}");
    }

    #[test]
    fn a_lost_report_is_made_up_at_once() {
        // Ticks of 10 ms, the 50th report lost.
        let arrivals: Vec<f64> = (0..120)
            .filter(|&k| k != 50)
            .map(|k| 10.0 * k as f64 + 2.0)
            .collect();
        let s = spans(&arrivals);
        let total: f64 = s.iter().sum();
        // From the second report (tick 1) to the last (tick 119): 117 spans covering 118
        // ticks, the lost one counted once, not dropped.
        assert_eq!(s.len(), 117);
        assert!((total - 1180.0).abs() < 0.5, "{total} {s:?}");
        // Made up in the lost report's own span, none cut short.
        assert!((s[48] - 20.0).abs() < 1e-9, "{s:?}");
        assert!(s.iter().all(|d| *d > 9.5), "{s:?}");
    }

    #[test]
    fn a_gap_restarts_the_clock() {
        let mut clock = SampleClock::default();
        assert_eq!(clock.sample_time(0), None);
        assert!(clock.sample_time(10_000).is_some());
        assert_eq!(clock.sample_time(400_000), None);
        let t = clock.sample_time(410_000).unwrap();
        assert!((t - 0.41).abs() < 1e-9);
    }

    #[test]
    fn the_period_is_learned() {
        // A 95-Hz remote (10.53 ms).
        let period = 1000.0 / 95.0;
        let arrivals: Vec<f64> = (0..400).map(|k| period * k as f64).collect();
        let s = spans(&arrivals);
        let last = &s[300..];
        let mean = last.iter().sum::<f64>() / last.len() as f64;
        assert!((mean - period).abs() < 0.02, "{mean}");
    }
}
