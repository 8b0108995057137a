//! Discovers remotes and runs one I/O thread per remote, delivering typed events over a
//! channel. Dropping the [`ControllerManager`] stops and joins every thread.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `io_loop.rs` | One controller's I/O loop, whatever its kind: connect, poll, forward its events, apply commands, reconnect. |
//! | `scan.rs` | Real controllers over hidapi: scanned every 2 s, one I/O thread per listed device, and a device that cannot be used diagnosed (sysfs) and reported once per distinct problem. |

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, TrySendError, bounded, unbounded};

use super::diagnosis::RemoteProblem;
use super::emulation::EmulatorControls;
use super::session::{
    Buttons, ExtensionState, MotionPlusState, NunchukFrame, OrientationSample, SessionConfig,
};
use super::wiimote::{EmulatorConfig, RemoteInfo};
use crate::controllers::fusion::FilterKind;
use crate::controllers::pads::{EmulatedPad, PadEmulatorConfig, PadInfo, PadSession};

/// Identifies one remote for the lifetime of a manager (stable across reconnects of the
/// same device path / emulator).
pub type RemoteId = u32;

/// What the manager reports.
#[derive(Debug, Clone, PartialEq)]
pub enum ManagerEvent {
    /// A gyro pad (DualSense, DualShock 4, Switch Pro, Joy-Con) finished its start sequence.
    PadConnected {
        /// Controller.
        id: RemoteId,
        /// What the start sequence learned (kind, link, calibration).
        info: PadInfo,
    },
    /// A remote finished its handshake.
    Connected {
        /// Remote.
        id: RemoteId,
        /// What the handshake learned.
        info: RemoteInfo,
    },
    /// A remote went away (it may come back with the same id).
    Disconnected {
        /// Remote.
        id: RemoteId,
        /// Why.
        reason: String,
    },
    /// Buttons changed.
    Buttons {
        /// Remote.
        id: RemoteId,
        /// Held buttons.
        buttons: Buttons,
        /// Host time, µs.
        timestamp_us: u64,
    },
    /// New orientation estimate.
    Orientation {
        /// Remote.
        id: RemoteId,
        /// Sample.
        sample: OrientationSample,
    },
    /// What the IR camera sees (when [`SessionConfig::ir_camera`] started it).
    Ir {
        /// Remote.
        id: RemoteId,
        /// The dot slots.
        dots: super::session::IrDots,
        /// The accelerometer's last reading (g, body frame).
        gravity: glam::DVec3,
        /// Host time, µs.
        timestamp_us: u64,
    },
    /// Battery report.
    Battery {
        /// Remote.
        id: RemoteId,
        /// Level byte.
        level: u8,
        /// Nearly empty.
        low: bool,
    },
    /// Extension change.
    Extension {
        /// Remote.
        id: RemoteId,
        /// New state.
        state: ExtensionState,
    },
    /// MotionPlus change.
    MotionPlus {
        /// Remote.
        id: RemoteId,
        /// New state.
        state: MotionPlusState,
    },
    /// Nunchuk input.
    Nunchuk {
        /// Remote.
        id: RemoteId,
        /// Frame.
        frame: NunchukFrame,
    },
    /// A remote is listed but unusable, or none is usable: a typed reason whose `Display`
    /// is the fix. Reported once per distinct problem until the remote connects.
    Problem {
        /// The remote, when the problem is about one the manager has an id for.
        id: Option<RemoteId>,
        /// What is wrong and how to fix it.
        problem: RemoteProblem,
    },
}

/// Commands to a remote's I/O thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RemoteCommand {
    /// Rumble on/off.
    Rumble(bool),
    /// Recentre the orientation.
    Recenter,
    /// Restart bias calibration.
    CalibrateNow,
    /// Switch orientation filter.
    SetFilter(FilterKind),
}

/// One emulated controller of any kind.
#[derive(Debug, Clone, PartialEq)]
pub enum EmulatedController {
    /// A Wii Remote.
    Wiimote(EmulatorConfig),
    /// A gyro pad.
    Pad(PadEmulatorConfig),
}

impl EmulatedController {
    /// The clock it is paced by, if any.
    pub fn clock(&self) -> Option<&super::emulation::EmulatorClock> {
        match self {
            EmulatedController::Wiimote(c) => c.clock.as_ref(),
            EmulatedController::Pad(c) => c.clock.as_ref(),
        }
    }
}

impl From<EmulatorConfig> for EmulatedController {
    fn from(c: EmulatorConfig) -> Self {
        EmulatedController::Wiimote(c)
    }
}

impl From<PadEmulatorConfig> for EmulatedController {
    fn from(c: PadEmulatorConfig) -> Self {
        EmulatedController::Pad(c)
    }
}

/// Where controllers come from.
#[derive(Clone)]
pub enum RemoteSource {
    /// Real controllers over hidapi — Wii Remotes and gyro pads — scanned every 2 s.
    #[cfg(feature = "hidapi")]
    Hid,
    /// One emulated controller per entry (real-time clock), each with its controls.
    Emulated(Vec<(EmulatedController, EmulatorControls)>),
}

/// Manager settings.
#[derive(Clone)]
pub struct ManagerConfig {
    /// Source of remotes.
    pub source: RemoteSource,
    /// Per-session settings (the player number is assigned per remote).
    pub session: SessionConfig,
    /// Event channel capacity; orientation samples are dropped (never blocking the I/O
    /// thread) when the consumer falls behind.
    pub channel_capacity: usize,
}

impl Default for ManagerConfig {
    fn default() -> Self {
        Self {
            #[cfg(feature = "hidapi")]
            source: RemoteSource::Hid,
            #[cfg(not(feature = "hidapi"))]
            source: RemoteSource::Emulated(vec![(
                EmulatorConfig {
                    realtime: true,
                    ..Default::default()
                }
                .into(),
                EmulatorControls::default(),
            )]),
            session: SessionConfig::default(),
            channel_capacity: 1024,
        }
    }
}

mod io_loop;
#[cfg(feature = "hidapi")]
mod scan;

use io_loop::{run_emulated_remote, run_remote};

type CommandMap = Arc<Mutex<HashMap<RemoteId, Sender<RemoteCommand>>>>;

/// Runs the remotes' I/O threads.
pub struct ControllerManager {
    events: Receiver<ManagerEvent>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    commands: CommandMap,
    /// Pacing clocks of emulated remotes, closed on drop so no thread waits forever.
    clocks: Vec<super::emulation::EmulatorClock>,
}

impl std::fmt::Debug for ControllerManager {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControllerManager")
            .field("threads", &self.threads.len())
            .finish_non_exhaustive()
    }
}

impl ControllerManager {
    /// Starts the I/O threads.
    pub fn start(config: ManagerConfig) -> Self {
        let (tx, rx) = bounded(config.channel_capacity.max(16));
        let stop = Arc::new(AtomicBool::new(false));
        let commands: CommandMap = Arc::default();
        let mut threads = Vec::new();
        let mut clocks = Vec::new();
        match config.source.clone() {
            RemoteSource::Emulated(list) => {
                clocks.extend(list.iter().filter_map(|(emu, _)| emu.clock().cloned()));
                for (i, (emu, controls)) in list.into_iter().enumerate() {
                    let id = i as RemoteId;
                    let mut session = config.session.clone();
                    session.player = (i % 4) as u8 + 1;
                    let (ctx, crx) = unbounded();
                    lock(&commands).insert(id, ctx);
                    let (tx, stop) = (tx.clone(), stop.clone());
                    threads.push(std::thread::spawn(move || match emu {
                        EmulatedController::Wiimote(emu) => {
                            run_emulated_remote(id, emu, controls, session, tx, crx, stop);
                        }
                        EmulatedController::Pad(pad) => {
                            let (kind, link) = (pad.kind, pad.link);
                            let open = || {
                                controls.connected().then(|| {
                                    EmulatedPad::with_controls(
                                        PadEmulatorConfig {
                                            realtime: true,
                                            ..pad.clone()
                                        },
                                        controls.clone(),
                                    )
                                })
                            };
                            let make = |t, c| PadSession::new(t, kind, link, c);
                            run_remote(id, open, make, session, tx, crx, stop, true);
                        }
                    }));
                }
            }
            #[cfg(feature = "hidapi")]
            RemoteSource::Hid => {
                let (tx, stop, cmds, session) = (
                    tx.clone(),
                    stop.clone(),
                    commands.clone(),
                    config.session.clone(),
                );
                threads.push(std::thread::spawn(move || {
                    scan::scan_hid(tx, stop, cmds, session)
                }));
            }
        }
        Self {
            events: rx,
            stop,
            threads,
            commands,
            clocks,
        }
    }

    /// The event receiver (drain it every frame).
    pub fn events(&self) -> &Receiver<ManagerEvent> {
        &self.events
    }

    /// Sends a command to a remote; false if it is unknown.
    pub fn send(&self, id: RemoteId, command: RemoteCommand) -> bool {
        lock(&self.commands)
            .get(&id)
            .is_some_and(|tx| tx.send(command).is_ok())
    }

    /// Sends a command to every remote.
    pub fn broadcast(&self, command: RemoteCommand) {
        for tx in lock(&self.commands).values() {
            let _ = tx.send(command);
        }
    }
}

impl Drop for ControllerManager {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.clocks
            .iter()
            .for_each(super::emulation::EmulatorClock::close);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn send(tx: &Sender<ManagerEvent>, e: ManagerEvent) {
    match tx.try_send(e) {
        Ok(()) | Err(TrySendError::Disconnected(_)) => {}
        Err(TrySendError::Full(e)) => {
            // Drop samples under back-pressure, but never state changes.
            if !matches!(e, ManagerEvent::Orientation { .. }) {
                let _ = tx.send_timeout(e, Duration::from_millis(50));
            }
        }
    }
}
