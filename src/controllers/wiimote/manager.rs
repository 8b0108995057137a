//! Discovers remotes and runs one I/O thread per remote, delivering typed events over a
//! channel. Dropping the [`WiimoteManager`] stops and joins every thread.

use std::collections::HashMap;
#[cfg(feature = "hidapi")]
use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, TrySendError, bounded, unbounded};

use super::diagnosis::RemoteProblem;
use super::emulator::{EmulatedRemote, EmulatorConfig, EmulatorControls};
use super::protocol::{Buttons, NunchukFrame};
use super::session::{
    ExtensionState, MotionPlusState, OrientationSample, RemoteInfo, Session, SessionConfig,
    SessionError, SessionEvent,
};
use crate::controllers::fusion::FilterKind;
use crate::controllers::pads::{EmulatedPad, PadEmulatorConfig, PadInfo, PadSession};
use crate::controllers::transport::Transport;

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
        dots: super::ir::IrDots,
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
    pub fn clock(&self) -> Option<&super::EmulatorClock> {
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

type CommandMap = Arc<Mutex<HashMap<RemoteId, Sender<RemoteCommand>>>>;

/// Runs the remotes' I/O threads.
pub struct WiimoteManager {
    events: Receiver<ManagerEvent>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    commands: CommandMap,
    /// Pacing clocks of emulated remotes, closed on drop so no thread waits forever.
    clocks: Vec<super::EmulatorClock>,
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
                    scan_hid(tx, stop, cmds, session)
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

impl Drop for WiimoteManager {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.clocks.iter().for_each(super::EmulatorClock::close);
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

/// Runs one emulated Wii Remote (reporting an emulated open error once, if it has one).
fn run_emulated_remote(
    id: RemoteId,
    emu: EmulatorConfig,
    controls: EmulatorControls,
    session: SessionConfig,
    tx: Sender<ManagerEvent>,
    commands: Receiver<RemoteCommand>,
    stop: Arc<AtomicBool>,
) {
    let problem_tx = tx.clone();
    let mut reported = false;
    let open = move || {
        if let Some(kind) = &emu.open_error {
            if !reported {
                reported = true;
                let node = format!("emulator:{id}");
                let problem = RemoteProblem::from_open_error(&node, kind);
                send(
                    &problem_tx,
                    ManagerEvent::Problem {
                        id: Some(id),
                        problem,
                    },
                );
            }
            return None;
        }
        controls.connected().then(|| {
            EmulatedRemote::with_controls(
                EmulatorConfig {
                    realtime: true,
                    ..emu.clone()
                },
                controls.clone(),
            )
        })
    };
    run_remote(id, open, Session::new, session, tx, commands, stop, true);
}

/// What the manager's I/O loop needs of a session, Wii Remote or pad.
trait ControllerSession {
    /// Runs the handshake; the event announcing the controller.
    fn connect_event(&mut self, id: RemoteId) -> Result<ManagerEvent, SessionError>;
    /// Reads and processes what arrived within `timeout_ms`.
    fn poll(&mut self, timeout_ms: u32) -> Result<(), SessionError>;
    /// Takes the events produced so far.
    fn take_events(&mut self) -> Vec<SessionEvent>;
    /// Recentres.
    fn recenter(&mut self);
    /// Restarts bias calibration.
    fn calibrate_now(&mut self);
    /// Switches the filter.
    fn set_filter(&mut self, kind: FilterKind);
    /// Rumble on/off (pads: ignored).
    fn set_rumble(&mut self, on: bool) -> Result<(), SessionError>;
}

impl<T: Transport> ControllerSession for Session<T> {
    fn connect_event(&mut self, id: RemoteId) -> Result<ManagerEvent, SessionError> {
        self.connect()
            .map(|info| ManagerEvent::Connected { id, info })
    }
    fn poll(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        Session::poll(self, timeout_ms)
    }
    fn take_events(&mut self) -> Vec<SessionEvent> {
        self.drain_events().collect()
    }
    fn recenter(&mut self) {
        Session::recenter(self);
    }
    fn calibrate_now(&mut self) {
        Session::calibrate_now(self);
    }
    fn set_filter(&mut self, kind: FilterKind) {
        Session::set_filter(self, kind);
    }
    fn set_rumble(&mut self, on: bool) -> Result<(), SessionError> {
        Session::set_rumble(self, on)
    }
}

impl<T: Transport> ControllerSession for PadSession<T> {
    fn connect_event(&mut self, id: RemoteId) -> Result<ManagerEvent, SessionError> {
        self.connect()
            .map(|info| ManagerEvent::PadConnected { id, info })
    }
    fn poll(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        PadSession::poll(self, timeout_ms)
    }
    fn take_events(&mut self) -> Vec<SessionEvent> {
        self.drain_events().collect()
    }
    fn recenter(&mut self) {
        PadSession::recenter(self);
    }
    fn calibrate_now(&mut self) {
        PadSession::calibrate_now(self);
    }
    fn set_filter(&mut self, kind: FilterKind) {
        PadSession::set_filter(self, kind);
    }
    fn set_rumble(&mut self, on: bool) -> Result<(), SessionError> {
        PadSession::set_rumble(self, on)
    }
}

/// How a remote's I/O loop ended.
#[derive(Debug)]
enum RemoteExit {
    /// Stopped, or the source had no more transports.
    Stopped,
    /// The handshake failed (without reconnecting).
    // Read by the hidapi scanner's diagnosis only.
    ConnectFailed(#[cfg_attr(not(feature = "hidapi"), allow(dead_code))] SessionError),
    /// It was connected and went away (without reconnecting).
    Disconnected,
}

/// Connects, polls, reports; on disconnect waits and reconnects until `stop`.
#[allow(clippy::too_many_arguments)]
fn run_remote<T, S: ControllerSession>(
    id: RemoteId,
    mut open: impl FnMut() -> Option<T>,
    make: impl Fn(T, SessionConfig) -> S,
    config: SessionConfig,
    tx: Sender<ManagerEvent>,
    commands: Receiver<RemoteCommand>,
    stop: Arc<AtomicBool>,
    reconnect: bool,
) -> RemoteExit {
    let mut filter = config.filter;
    while !stop.load(Ordering::Relaxed) {
        let Some(transport) = open() else {
            if !reconnect {
                return RemoteExit::Stopped;
            }
            std::thread::sleep(Duration::from_millis(100));
            continue;
        };
        let mut session = make(
            transport,
            SessionConfig {
                filter,
                ..config.clone()
            },
        );
        match session.connect_event(id) {
            Ok(event) => send(&tx, event),
            Err(e) => {
                forward(id, &mut session, &tx);
                if let SessionError::UnsupportedDevice(what) = e {
                    let problem = RemoteProblem::Unsupported {
                        node: format!("remote {id}"),
                        what: what.to_string(),
                    };
                    send(
                        &tx,
                        ManagerEvent::Problem {
                            id: Some(id),
                            problem,
                        },
                    );
                    return RemoteExit::ConnectFailed(e);
                }
                if !reconnect {
                    send(
                        &tx,
                        ManagerEvent::Disconnected {
                            id,
                            reason: e.to_string(),
                        },
                    );
                    return RemoteExit::ConnectFailed(e);
                }
                std::thread::sleep(Duration::from_millis(500));
                continue;
            }
        }
        let reason = loop {
            if stop.load(Ordering::Relaxed) {
                return RemoteExit::Stopped;
            }
            let failed = apply_commands(&commands, &mut session, &mut filter);
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
            return RemoteExit::Disconnected;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    RemoteExit::Stopped
}

/// Applies the commands waiting for a connected remote (switching filters updates `filter`,
/// kept across reconnects); the first that fails ends the session, with its reason.
fn apply_commands(
    commands: &Receiver<RemoteCommand>,
    session: &mut impl ControllerSession,
    filter: &mut FilterKind,
) -> Option<String> {
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
                *filter = k;
                session.set_filter(k);
                Ok(())
            }
        };
        if let Err(e) = r {
            return Some(e.to_string());
        }
    }
    None
}

fn forward(id: RemoteId, session: &mut impl ControllerSession, tx: &Sender<ManagerEvent>) {
    for e in session.take_events() {
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
            SessionEvent::Ir {
                dots,
                gravity,
                timestamp_us,
            } => ManagerEvent::Ir {
                id,
                dots,
                gravity,
                timestamp_us,
            },
        };
        send(tx, m);
    }
}

/// Problems already reported, per device node (so a remote failing every scan is reported
/// once, and again only when what is wrong changes).
#[cfg(feature = "hidapi")]
type Reported = Arc<Mutex<HashMap<String, Vec<RemoteProblem>>>>;

#[cfg(feature = "hidapi")]
fn report_once(
    tx: &Sender<ManagerEvent>,
    reported: &Reported,
    key: &str,
    id: Option<RemoteId>,
    problems: Vec<RemoteProblem>,
) {
    let mut map = lock(reported);
    if problems.is_empty() || map.get(key) == Some(&problems) {
        return;
    }
    for problem in &problems {
        send(
            tx,
            ManagerEvent::Problem {
                id,
                problem: problem.clone(),
            },
        );
    }
    map.insert(key.to_string(), problems);
}

/// Opens and runs one listed controller (`pad`: a gyro pad of that kind and link; `None`: a
/// Wii Remote); a failed open or a handshake nobody answers is diagnosed (sysfs:
/// permissions, the kernel driver) and reported.
#[cfg(feature = "hidapi")]
#[allow(clippy::too_many_arguments)]
fn run_hid_remote(
    id: RemoteId,
    path: &str,
    pad: Option<(crate::controllers::ControllerKind, crate::controllers::Link)>,
    session: SessionConfig,
    tx: Sender<ManagerEvent>,
    commands: Receiver<RemoteCommand>,
    stop: Arc<AtomicBool>,
    reported: &Reported,
) {
    use super::diagnosis::LinuxDevices;
    use super::session::SessionError;
    use crate::controllers::transport::{HidTransport, TransportError};
    let node = std::path::Path::new(path);
    let transport = match HidTransport::open(path) {
        Ok(t) => t,
        Err(e) => {
            let mut problems = match &e {
                TransportError::Open { kind, .. } => {
                    LinuxDevices::system().diagnose(node, Some(kind))
                }
                _ => Vec::new(),
            };
            if problems.is_empty() {
                problems.push(RemoteProblem::OpenFailed {
                    node: path.to_string(),
                    message: e.to_string(),
                });
            }
            report_once(&tx, reported, path, Some(id), problems);
            return;
        }
    };
    // One open per discovery: a dead handle never recovers, the scanner finds the device
    // again when it comes back.
    let mut once = Some(transport);
    let exit = match pad {
        None => run_remote(
            id,
            || once.take(),
            Session::new,
            session,
            tx.clone(),
            commands,
            stop,
            false,
        ),
        Some((kind, link)) => run_remote(
            id,
            || once.take(),
            |t, c| PadSession::new(t, kind, link, c),
            session,
            tx.clone(),
            commands,
            stop,
            false,
        ),
    };
    match exit {
        RemoteExit::ConnectFailed(SessionError::Timeout(_) | SessionError::Transport(_)) => {
            let mut problems = LinuxDevices::system().diagnose(node, None);
            if !problems
                .iter()
                .any(|p| matches!(p, RemoteProblem::KernelDriverBound { .. }))
            {
                problems.push(RemoteProblem::NoAnswer {
                    node: path.to_string(),
                });
            }
            if pad.is_some() && super::diagnosis::steam_running(std::path::Path::new("/proc")) {
                problems.push(RemoteProblem::SteamRunning {
                    node: path.to_string(),
                });
            }
            report_once(&tx, reported, path, Some(id), problems);
        }
        RemoteExit::Disconnected => {
            // It worked: report again if it fails later.
            lock(reported).remove(path);
        }
        RemoteExit::ConnectFailed(_) | RemoteExit::Stopped => {}
    }
}

#[cfg(feature = "hidapi")]
fn scan_hid(
    tx: Sender<ManagerEvent>,
    stop: Arc<AtomicBool>,
    commands: CommandMap,
    config: SessionConfig,
) {
    use super::diagnosis::LinuxDevices;
    use crate::controllers::transport::{discover, discover_pads};
    let mut ids: HashMap<String, RemoteId> = HashMap::new();
    let busy: Arc<Mutex<HashSet<String>>> = Arc::default();
    let reported: Reported = Arc::default();
    let mut threads: Vec<JoinHandle<()>> = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let listed = discover().and_then(|remotes| {
            let mut all: Vec<(String, Option<_>)> =
                remotes.into_iter().map(|d| (d.path, None)).collect();
            all.extend(
                discover_pads()?
                    .into_iter()
                    .map(|p| (p.path, Some((p.kind, p.link)))),
            );
            Ok(all)
        });
        match listed {
            Ok(found) => {
                if found.is_empty() {
                    // Nothing listed: say why, if sysfs knows (e.g. nodes hidapi skipped).
                    let problems = LinuxDevices::system().diagnose_all();
                    report_once(&tx, &reported, "", None, problems);
                }
                for (path, pad) in found {
                    if lock(&busy).contains(&path) {
                        continue;
                    }
                    let next = ids.len() as RemoteId;
                    let id = *ids.entry(path.clone()).or_insert(next);
                    lock(&busy).insert(path.clone());
                    let (ctx, crx) = unbounded();
                    lock(&commands).insert(id, ctx);
                    let mut session = config.clone();
                    session.player = (id % 4) as u8 + 1;
                    let (tx, stop, busy, reported, path) = (
                        tx.clone(),
                        stop.clone(),
                        busy.clone(),
                        reported.clone(),
                        path,
                    );
                    threads.push(std::thread::spawn(move || {
                        run_hid_remote(id, &path, pad, session, tx, crx, stop, &reported);
                        lock(&busy).remove(&path);
                    }));
                }
            }
            Err(e) => {
                let problems = vec![RemoteProblem::HidApi {
                    message: e.to_string(),
                }];
                report_once(&tx, &reported, "", None, problems);
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
