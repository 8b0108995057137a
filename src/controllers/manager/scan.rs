//! Real controllers over hidapi: scanned every 2 s, one I/O thread per listed device, and a
//! device that cannot be used diagnosed (sysfs) and reported once per distinct problem.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, unbounded};

use super::io_loop::{RemoteExit, run_remote};
use super::{CommandMap, ManagerEvent, RemoteCommand, RemoteId, lock, send};
use crate::controllers::diagnosis::RemoteProblem;
use crate::controllers::pads::PadSession;
use crate::controllers::session::SessionConfig;
use crate::controllers::wiimote::Session;

/// Problems already reported, per device node (so a remote failing every scan is reported
/// once, and again only when what is wrong changes).
type Reported = Arc<Mutex<HashMap<String, Vec<RemoteProblem>>>>;

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
    use crate::controllers::diagnosis::LinuxDevices;
    use crate::controllers::session::SessionError;
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
            if pad.is_some()
                && crate::controllers::diagnosis::steam_running(std::path::Path::new("/proc"))
            {
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

pub(super) fn scan_hid(
    tx: Sender<ManagerEvent>,
    stop: Arc<AtomicBool>,
    commands: CommandMap,
    config: SessionConfig,
) {
    use crate::controllers::diagnosis::LinuxDevices;
    use crate::controllers::transport::discover_pads;
    use crate::controllers::wiimote::discover;
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
