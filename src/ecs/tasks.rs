//! The background-solve pattern the deform and pose plugins share: at most one solve per
//! entity runs on Bevy's `AsyncComputeTaskPool`; a newer request supersedes it (the running
//! solve stops at its next iteration, after at least one, and the plugin starts the newest
//! when it lands), and the plugin polls it once a frame.

use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

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
    ///
    /// Solves call it between iterations, and it gives up the thread's core there for a
    /// moment: on kernels that preempt lazily (`PREEMPT_NONE` or `PREEMPT_LAZY`), a pool
    /// thread in a solve of several milliseconds otherwise keeps its core until the
    /// scheduler's next tick (4 ms at 250 Hz) while a thread of the frame, woken for that
    /// core, waits (`plugin_bench --collider` frames of 2–4 ms against 0.2 on 2 cores). With
    /// nothing else waiting, the yield returns at once.
    pub(crate) fn superseded(&self) -> bool {
        std::thread::yield_now();
        self.calls.set(self.calls.get() + 1);
        self.calls.get() > 1 && self.requested.load(Ordering::Relaxed) != self.generation
    }
}

/// One entity's background solve that takes the requests arriving while it runs itself: when a
/// solve lands, the task posts its output and, if a newer request waits, starts on it at once
/// (warm, on the same factorization) instead of ending and waiting for the next frame's poll
/// to start it. A drag whose solves take longer than a frame thus gets a new pose as soon as
/// the solver can make one; one whose solves are shorter gets one every frame.
///
/// The chain ends when a solve lands and no request waits, or when the task gives a request
/// back (it cannot take it, e.g. a new constraint set); the plugin then starts the next solve
/// itself.
pub(crate) struct ChainedTask<R, T> {
    task: Option<Task<()>>,
    shared: Arc<Mutex<Chain<R, T>>>,
    /// Requests so far: the running solve stops at its next iteration when this moves on.
    requested: Arc<AtomicU64>,
}

/// What the main thread and a [`ChainedTask`]'s task exchange.
struct Chain<R, T> {
    /// The newest request the task has not taken yet.
    next: Option<R>,
    /// Outputs posted since the last poll, oldest first.
    landed: Vec<T>,
    /// Whether the task still takes requests.
    open: bool,
}

impl<R, T> Default for ChainedTask<R, T> {
    fn default() -> Self {
        Self {
            task: None,
            shared: Arc::new(Mutex::new(Chain {
                next: None,
                landed: Vec::new(),
                open: false,
            })),
            requested: Arc::new(AtomicU64::new(0)),
        }
    }
}

/// What [`ChainedTask::poll`] collected.
pub(crate) struct Polled<R, T> {
    /// Outputs landed since the last poll, oldest first.
    pub(crate) landed: Vec<T>,
    /// The task has ended (the plugin may start the next solve).
    pub(crate) ended: bool,
    /// A request the ended task did not take.
    pub(crate) untaken: Option<R>,
}

/// Locks `mutex`, recovering the data when a panicking holder poisoned it (the exchange is
/// plain data, valid at every step).
fn lock<D>(mutex: &Mutex<D>) -> std::sync::MutexGuard<'_, D> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl<R: Send + 'static, T: Send + 'static> ChainedTask<R, T> {
    /// A newer request arrived: the running solve (if any) stops at its next iteration.
    pub(crate) fn supersede(&self) {
        self.requested.fetch_add(1, Ordering::Relaxed);
    }

    /// Whether a task is running (it may have ended since the last poll).
    pub(crate) fn is_running(&self) -> bool {
        self.task.is_some()
    }

    /// Whether outputs wait for the next poll.
    pub(crate) fn has_landed(&self) -> bool {
        !lock(&self.shared).landed.is_empty()
    }

    /// Hands `request` to the running task (replacing one it has not taken yet). Returns it
    /// when no task takes requests (none runs, or it has ended).
    pub(crate) fn offer(&self, request: R) -> Option<R> {
        let mut chain = lock(&self.shared);
        if self.task.is_none() || !chain.open {
            return Some(request);
        }
        chain.next = Some(request);
        None
    }

    /// Starts `step` in the background with its end of the exchange, and calls it again while
    /// it returns true (it took a follow-on request). Between steps the task yields to the
    /// pool, so chains of several entities take turns on its threads (one, on 2 cores).
    pub(crate) fn spawn(
        &mut self,
        mut step: impl FnMut(&mut ChainLink<R, T>) -> bool + Send + 'static,
    ) {
        {
            let mut chain = lock(&self.shared);
            chain.open = true;
            chain.next = None;
        }
        let mut link = ChainLink {
            shared: self.shared.clone(),
            cancellation: Cancellation {
                generation: self.requested.load(Ordering::Relaxed),
                requested: self.requested.clone(),
                calls: Cell::new(0),
            },
        };
        self.task = Some(AsyncComputeTaskPool::get().spawn(async move {
            while step(&mut link) {
                bevy::tasks::futures_lite::future::yield_now().await;
            }
        }));
    }

    /// The outputs landed since the last call and whether the task has ended (then its slot
    /// is free). `None` when there is nothing to report.
    pub(crate) fn poll(&mut self) -> Option<Polled<R, T>> {
        self.task.as_ref()?;
        let (landed, ended, untaken) = {
            let mut chain = lock(&self.shared);
            let ended = !chain.open;
            let untaken = if ended { chain.next.take() } else { None };
            (std::mem::take(&mut chain.landed), ended, untaken)
        };
        if ended {
            // The task only returns after closing the exchange: nothing is left to wait for.
            if let Some(task) = self.task.take() {
                task.detach();
            }
        } else if landed.is_empty() {
            // A task that panicked ends without closing the exchange.
            if self.task.as_ref().is_some_and(Task::is_finished) {
                self.task = None;
                lock(&self.shared).open = false;
                return Some(Polled {
                    landed,
                    ended: true,
                    untaken: lock(&self.shared).next.take(),
                });
            }
            return None;
        }
        Some(Polled {
            landed,
            ended,
            untaken,
        })
    }
}

/// A [`ChainedTask`]'s task's end of the exchange.
pub(crate) struct ChainLink<R, T> {
    shared: Arc<Mutex<Chain<R, T>>>,
    cancellation: Cancellation,
}

impl<R, T> ChainLink<R, T> {
    /// Asks whether a newer request superseded the current solve.
    pub(crate) fn cancellation(&self) -> &Cancellation {
        &self.cancellation
    }

    /// Posts a solve's output; returns the request waiting, if any (the task goes on with it,
    /// superseded only by requests after it), or ends the chain.
    pub(crate) fn land(&mut self, output: T) -> Option<R> {
        let mut chain = lock(&self.shared);
        chain.landed.push(output);
        let next = chain.next.take();
        if next.is_none() {
            chain.open = false;
        } else {
            self.cancellation.generation = self.cancellation.requested.load(Ordering::Relaxed);
            self.cancellation.calls.set(0);
        }
        next
    }

    /// Gives back a request the task cannot take, unless a newer one arrived meanwhile, and
    /// ends the chain.
    pub(crate) fn give_back(&mut self, request: R) {
        let mut chain = lock(&self.shared);
        if chain.next.is_none() {
            chain.next = Some(request);
        }
        chain.open = false;
    }
}
