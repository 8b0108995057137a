//! [`EmulatorClock`]: pacing emulated remotes by the app's own (possibly manual) time.

use std::sync::{Arc, Condvar, Mutex};

/// A clock the app advances (e.g. from Bevy's virtual time) that paces emulated remotes: a
/// report is delivered once the clock has reached its time, so a test steps the remote
/// exactly like the rest of the app, with no wall-clock sleeps. Closing it releases every
/// waiting remote (from then on reports come at once); the manager closes its remotes'
/// clocks when it stops.
#[derive(Clone, Default)]
pub struct EmulatorClock(Arc<(Mutex<ClockState>, Condvar)>);

#[derive(Default)]
struct ClockState {
    now_us: u64,
    closed: bool,
}

impl EmulatorClock {
    /// A clock at 0.
    pub fn new() -> Self {
        Self::default()
    }

    fn state(&self) -> std::sync::MutexGuard<'_, ClockState> {
        self.0.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Microseconds since the clock started.
    pub fn now_us(&self) -> u64 {
        self.state().now_us
    }

    /// Moves the clock forward to `t_us` (never back) and wakes the remotes waiting for it.
    pub fn advance_to(&self, t_us: u64) {
        let mut state = self.state();
        if t_us > state.now_us {
            state.now_us = t_us;
            self.0.1.notify_all();
        }
    }

    /// Releases every waiting remote, for good.
    pub fn close(&self) {
        self.state().closed = true;
        self.0.1.notify_all();
    }

    /// Blocks until the clock reaches `t_us` or is closed.
    pub(crate) fn wait_until(&self, t_us: u64) {
        let mut state = self.state();
        while state.now_us < t_us && !state.closed {
            state = self.0.1.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }
}

impl std::fmt::Debug for EmulatorClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("EmulatorClock")
            .field(&self.now_us())
            .finish()
    }
}

impl PartialEq for EmulatorClock {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// How an emulator's own time meets the world's: by an [`EmulatorClock`] (from the moment the
/// emulator opened), by the wall clock (`realtime`), or not at all (as fast as it is read).
/// Shared by every emulator, Wii Remote or pad.
#[derive(Clone)]
pub(crate) struct Pacing {
    clock: Option<EmulatorClock>,
    origin_us: u64,
    realtime: bool,
    epoch: web_time::Instant,
}

impl Pacing {
    /// Pacing from now.
    pub(crate) fn new(clock: Option<EmulatorClock>, realtime: bool) -> Self {
        Self {
            origin_us: clock.as_ref().map_or(0, EmulatorClock::now_us),
            clock,
            realtime,
            epoch: web_time::Instant::now(),
        }
    }

    /// Blocks until the emulator's time `t_us` has come (at once when unpaced).
    pub(crate) fn wait_until(&self, t_us: u64) {
        if let Some(clock) = &self.clock {
            clock.wait_until(self.origin_us + t_us);
        } else if self.realtime {
            let target = std::time::Duration::from_micros(t_us);
            let now = self.epoch.elapsed();
            if target > now {
                std::thread::sleep(target - now);
            }
        }
    }

    /// The emulator's time the world has reached, µs (`None` when unpaced).
    pub(crate) fn now_us(&self) -> Option<u64> {
        match &self.clock {
            Some(clock) => Some(clock.now_us().saturating_sub(self.origin_us)),
            None if self.realtime => Some(self.epoch.elapsed().as_micros() as u64),
            None => None,
        }
    }
}
