//! [`EmulatorControls`]: what a user or test does to a running emulated remote.

use glam::DQuat;

use crate::controllers::motion::{Motion, Still};
use crate::controllers::session::inputs::{Buttons, NunchukFrame};

use std::sync::{Arc, Mutex};

/// Things a user (or test) does to the remote from outside while it runs: buttons, hot-plug,
/// power. Shared between threads.
#[derive(Clone)]
pub struct EmulatorControls(Arc<Mutex<ControlState>>);

pub(crate) struct ControlState {
    pub(crate) buttons: Buttons,
    pub(crate) nunchuk: Option<NunchukFrame>,
    pub(crate) motion_plus_plugged: bool,
    pub(crate) connected: bool,
    pub(crate) motion: Arc<dyn Motion>,
    pub(crate) generation: u64,
}

impl Default for EmulatorControls {
    fn default() -> Self {
        Self(Arc::new(Mutex::new(ControlState {
            buttons: Buttons(0),
            nunchuk: None,
            motion_plus_plugged: true,
            connected: true,
            motion: Arc::new(Still(DQuat::IDENTITY)),
            generation: 0,
        })))
    }
}

impl EmulatorControls {
    /// Runs `f` on the shared state (locked).
    pub(crate) fn with<R>(&self, f: impl FnOnce(&mut ControlState) -> R) -> R {
        let mut g = self.0.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut g)
    }
    /// Sets the held buttons.
    pub fn set_buttons(&self, b: Buttons) {
        self.with(|s| s.buttons = b);
    }
    /// Current held buttons.
    pub fn buttons(&self) -> Buttons {
        self.with(|s| s.buttons)
    }
    /// Plugs (Some) or unplugs (None) a Nunchuk, with stick/buttons state.
    pub fn set_nunchuk(&self, n: Option<NunchukFrame>) {
        self.with(|s| s.nunchuk = n);
    }
    /// Plugs or unplugs the external MotionPlus (ignored by the -TR).
    pub fn set_motion_plus_plugged(&self, plugged: bool) {
        self.with(|s| s.motion_plus_plugged = plugged);
    }
    /// Powers the remote off (false) or on again (true). While off, I/O fails with
    /// [`TransportError::Disconnected`](crate::controllers::transport::TransportError::Disconnected); powering on starts a fresh connection.
    pub fn set_connected(&self, connected: bool) {
        self.with(|s| {
            if connected && !s.connected {
                s.generation += 1;
            }
            s.connected = connected;
        });
    }
    /// Whether the remote is powered and linked.
    pub fn connected(&self) -> bool {
        self.with(|s| s.connected)
    }
    /// Replaces the ground-truth motion (times continue on the emulator clock).
    pub fn set_motion(&self, m: Arc<dyn Motion>) {
        self.with(|s| s.motion = m);
    }
    /// The ground-truth motion.
    pub fn motion(&self) -> Arc<dyn Motion> {
        self.with(|s| s.motion.clone())
    }
}
