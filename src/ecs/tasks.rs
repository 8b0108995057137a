//! The background-solve pattern the deform and pose plugins share: at most one solve per
//! entity runs on Bevy's `AsyncComputeTaskPool`; a newer request supersedes it (the running
//! solve stops at its next iteration, after at least one, and the plugin starts the newest
//! when it lands), and the plugin polls it once a frame.

use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task};

/// One entity's background solve slot; the latest request wins.
pub(crate) struct LatestTask<T> {
    task: Option<Task<T>>,
    /// Requests so far: a running solve whose generation is older is superseded.
    requested: Arc<AtomicU64>,
}

impl<T> Default for LatestTask<T> {
    fn default() -> Self {
        Self {
            task: None,
            requested: Arc::new(AtomicU64::new(0)),
        }
    }
}

impl<T: Send + 'static> LatestTask<T> {
    /// A newer request arrived: the running solve (if any) stops at its next iteration.
    pub(crate) fn supersede(&self) {
        self.requested.fetch_add(1, Ordering::Relaxed);
    }

    /// Whether a solve is running.
    pub(crate) fn is_running(&self) -> bool {
        self.task.is_some()
    }

    /// Starts `job` in the background with its [`Cancellation`] (for the current request).
    pub(crate) fn spawn(&mut self, job: impl FnOnce(Cancellation) -> T + Send + 'static) {
        let cancellation = Cancellation {
            generation: self.requested.load(Ordering::Relaxed),
            requested: self.requested.clone(),
            calls: Cell::new(0),
        };
        self.task = Some(AsyncComputeTaskPool::get().spawn(async move { job(cancellation) }));
    }

    /// The finished solve's output, once (`None` while running or idle).
    pub(crate) fn poll(&mut self) -> Option<T> {
        poll_slot(&mut self.task)
    }
}

/// The output of the task in `slot` once it has finished, emptying the slot (`None` while it
/// runs or when there is none).
pub(crate) fn poll_slot<T>(slot: &mut Option<Task<T>>) -> Option<T> {
    let out = check_ready(slot.as_mut()?)?;
    *slot = None;
    Some(out)
}

/// Handed to a background solve: asks whether a newer request superseded it.
pub(crate) struct Cancellation {
    generation: u64,
    requested: Arc<AtomicU64>,
    calls: Cell<u32>,
}

impl Cancellation {
    /// True once a newer request arrived — never on the first call, so every solve lands at
    /// least one iteration (a stream of requests still moves the pose).
    pub(crate) fn superseded(&self) -> bool {
        self.calls.set(self.calls.get() + 1);
        self.calls.get() > 1 && self.requested.load(Ordering::Relaxed) != self.generation
    }
}
