//! Discovers remotes and runs one I/O thread per remote, delivering typed events over a
//! channel. Dropping the [`WiimoteManager`] stops and joins every thread.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, TrySendError, bounded, unbounded};

use super::emulator::{EmulatedRemote, EmulatorConfig, EmulatorControls};
use super::filter::FilterKind;
use super::protocol::{Buttons, NunchukFrame};
use super::session::{
    ExtensionState, MotionPlusState, OrientationSample, RemoteInfo, Session, SessionConfig,
    SessionEvent,
};
use super::transport::Transport;

/// Identifies one remote for the lifetime of a manager (stable across reconnects of the
/// same device path / emulator).
pub type RemoteId = u32;

/// What the manager reports.
#[derive(Debug, Clone, PartialEq)]
pub enum ManagerEvent {
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
    /// A problem that is not tied to a connected remote (e.g. permissions), with advice.
    Problem(String),
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

/// Where remotes come from.
#[derive(Clone)]
pub enum RemoteSource {
    /// Real remotes over hidapi (scanned every 2 s).
    #[cfg(feature = "hidapi")]
    Hid,
    /// One emulated remote per entry (real-time clock), each with its controls.
    Emulated(Vec<(EmulatorConfig, EmulatorControls)>),
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
                },
                EmulatorControls::default(),
            )]),
            session: SessionConfig::default(),
            channel_capacity: 1024,
        }
    }
}

type CommandMap = Arc<Mutex<HashMap<RemoteId, Sender<RemoteCommand>>>>;

/// Runs the remotes' I/O threads.
pub struct WiimoteManager {
    events: Receiver<ManagerEvent>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    commands: CommandMap,
}

impl std::fmt::Debug for WiimoteManager {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WiimoteManager")
            .field("threads", &self.threads.len())
            .finish_non_exhaustive()
    }
}

impl WiimoteManager {
    /// Starts the I/O threads.
    pub fn start(config: ManagerConfig) -> Self {
        let (tx, rx) = bounded(config.channel_capacity.max(16));
        let stop = Arc::new(AtomicBool::new(false));
        let commands: CommandMap = Arc::default();
        let mut threads = Vec::new();
        match config.source.clone() {
            RemoteSource::Emulated(list) => {
                for (i, (emu, controls)) in list.into_iter().enumerate() {
                    let id = i as RemoteId;
                    let mut session = config.session.clone();
                    session.player = (i % 4) as u8 + 1;
                    let (ctx, crx) = unbounded();
                    lock(&commands).insert(id, ctx);
                    let (tx, stop) = (tx.clone(), stop.clone());
                    threads.push(std::thread::spawn(move || {
                        let open = move || {
                            if controls.connected() {
                                Some(EmulatedRemote::with_controls(
                                    EmulatorConfig {
                                        realtime: true,
                                        ..emu.clone()
                                    },
                                    controls.clone(),
                                ))
                            } else {
                                None
                            }
                        };
                        run_remote(id, open, session, tx, crx, stop, true);
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
                    scan_hid(tx, stop, cmds, session)
                }));
            }
        }
        Self {
            events: rx,
            stop,
            threads,
            commands,
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

impl Drop for WiimoteManager {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
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

/// Connects, polls, reports; on disconnect waits and reconnects until `stop`.
fn run_remote<T: Transport, F: FnMut() -> Option<T>>(
    id: RemoteId,
    mut open: F,
    config: SessionConfig,
    tx: Sender<ManagerEvent>,
    commands: Receiver<RemoteCommand>,
    stop: Arc<AtomicBool>,
    reconnect: bool,
) {
    let mut filter = config.filter;
    while !stop.load(Ordering::Relaxed) {
        let Some(transport) = open() else {
            if !reconnect {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
            continue;
        };
        let mut session = Session::new(
            transport,
            SessionConfig {
                filter,
                ..config.clone()
            },
        );
        match session.connect() {
            Ok(info) => send(&tx, ManagerEvent::Connected { id, info }),
            Err(e) => {
                forward(id, &mut session, &tx);
                if matches!(e, super::session::SessionError::UnsupportedDevice(_)) {
                    send(&tx, ManagerEvent::Problem(format!("remote {id}: {e}")));
                    return;
                }
                if !reconnect {
                    send(
                        &tx,
                        ManagerEvent::Disconnected {
                            id,
                            reason: e.to_string(),
                        },
                    );
                    return;
                }
                std::thread::sleep(Duration::from_millis(500));
                continue;
            }
        }
        let reason = loop {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            let mut failed = None;
            while let Ok(c) = commands.try_recv() {
                let r = match c {
                    RemoteCommand::Rumble(on) => session.set_rumble(on),
                    RemoteCommand::Recenter => {
                        session.recenter();
                        Ok(())
                    }
                    RemoteCommand::CalibrateNow => {
                        session.calibrate_now();
                        Ok(())
                    }
                    RemoteCommand::SetFilter(k) => {
                        filter = k;
                        session.set_filter(k);
                        Ok(())
                    }
                };
                if let Err(e) = r {
                    failed = Some(e.to_string());
                    break;
                }
            }
            if let Some(reason) = failed {
                break reason;
            }
            if let Err(e) = session.poll(10) {
                break e.to_string();
            }
            forward(id, &mut session, &tx);
        };
        forward(id, &mut session, &tx);
        send(&tx, ManagerEvent::Disconnected { id, reason });
        if !reconnect {
            return;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

fn forward<T: Transport>(id: RemoteId, session: &mut Session<T>, tx: &Sender<ManagerEvent>) {
    for e in session.drain_events() {
        let m = match e {
            SessionEvent::Buttons {
                buttons,
                timestamp_us,
            } => ManagerEvent::Buttons {
                id,
                buttons,
                timestamp_us,
            },
            SessionEvent::Orientation(sample) => ManagerEvent::Orientation { id, sample },
            SessionEvent::Battery { level, low } => ManagerEvent::Battery { id, level, low },
            SessionEvent::Extension(state) => ManagerEvent::Extension { id, state },
            SessionEvent::MotionPlus(state) => ManagerEvent::MotionPlus { id, state },
            SessionEvent::Nunchuk(frame) => ManagerEvent::Nunchuk { id, frame },
            SessionEvent::Imu(_) => continue,
        };
        send(tx, m);
    }
}

#[cfg(feature = "hidapi")]
fn scan_hid(
    tx: Sender<ManagerEvent>,
    stop: Arc<AtomicBool>,
    commands: CommandMap,
    config: SessionConfig,
) {
    use super::transport::{HidTransport, diagnose_linux, discover};
    let mut ids: HashMap<String, RemoteId> = HashMap::new();
    let busy: Arc<Mutex<HashSet<String>>> = Arc::default();
    let mut threads: Vec<JoinHandle<()>> = Vec::new();
    let mut warned = false;
    while !stop.load(Ordering::Relaxed) {
        match discover() {
            Ok(found) => {
                if found.is_empty() && !warned {
                    for d in diagnose_linux() {
                        send(&tx, ManagerEvent::Problem(d.to_string()));
                        warned = true;
                    }
                }
                for dev in found {
                    if lock(&busy).contains(&dev.path) {
                        continue;
                    }
                    let next = ids.len() as RemoteId;
                    let id = *ids.entry(dev.path.clone()).or_insert(next);
                    lock(&busy).insert(dev.path.clone());
                    let (ctx, crx) = unbounded();
                    lock(&commands).insert(id, ctx);
                    let mut session = config.clone();
                    session.player = (id % 4) as u8 + 1;
                    let (tx, stop, busy, path) = (tx.clone(), stop.clone(), busy.clone(), dev.path);
                    threads.push(std::thread::spawn(move || {
                        let mut opened = false;
                        let p = path.clone();
                        // One open per discovery: a dead handle never recovers, the scanner
                        // finds the device again when it comes back.
                        let open = || {
                            if opened {
                                None
                            } else {
                                opened = true;
                                HidTransport::open(&p).ok()
                            }
                        };
                        run_remote(id, open, session, tx, crx, stop, false);
                        lock(&busy).remove(&path);
                    }));
                }
            }
            Err(e) => {
                if !warned {
                    send(&tx, ManagerEvent::Problem(format!("hidapi: {e}")));
                    warned = true;
                }
            }
        }
        for _ in 0..20 {
            if stop.load(Ordering::Relaxed) {
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    for t in threads {
        let _ = t.join();
    }
}
