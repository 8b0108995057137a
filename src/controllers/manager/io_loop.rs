//! One controller's I/O loop, whatever its kind: connect, poll, forward its events, apply
//! commands, reconnect.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender};

use super::{ManagerEvent, RemoteCommand, RemoteId, send};
use crate::controllers::diagnosis::RemoteProblem;
use crate::controllers::emulation::EmulatorControls;
use crate::controllers::fusion::FilterKind;
use crate::controllers::pads::PadSession;
use crate::controllers::session::{SessionConfig, SessionError, SessionEvent};
use crate::controllers::transport::Transport;
use crate::controllers::wiimote::{EmulatedRemote, EmulatorConfig, Session};

/// Runs one emulated Wii Remote (reporting an emulated open error once, if it has one).
pub(super) fn run_emulated_remote(
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
pub(super) trait ControllerSession {
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
pub(super) enum RemoteExit {
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
pub(super) fn run_remote<T, S: ControllerSession>(
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
