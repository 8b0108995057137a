//! Wii Remotes in the ECS: [`MotionControllerPlugin`] runs the device manager off the main thread and
//! mirrors every remote as an entity with a [`MotionController`] component, plus messages. This file
//! holds the data types; `plugin.rs` the plugin, its system sets and systems.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin.rs` | The Wii Remote plugin: its system sets, the emulator clocks, settings changes and the systems that turn the device manager's events into components and messages. |

mod plugin;

use bevy::prelude::*;

use crate::controllers::ControllerKind;
use crate::controllers::diagnosis::RemoteProblem;
use crate::controllers::emulation::EmulatorControls;
use crate::controllers::fusion::FilterKind;
use crate::controllers::manager::{ControllerManager, EmulatedController, RemoteCommand, RemoteId};
use crate::controllers::session::Buttons;
use crate::controllers::wiimote::ir::PointerSetup;
use crate::controllers::wiimote::smoothing::PointerSmoothing;

pub use plugin::{MotionControllerPlugin, MotionControllerSystems};

/// Orientation filter choice (mirrors [`FilterKind`] for reflection and UIs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum ControllerFilter {
    /// Raw integration.
    Raw,
    /// The paper's method.
    Paper,
    /// Ours (default).
    #[default]
    Fusion,
    /// VQF (Laidig & Seel 2023).
    Vqf,
}

impl From<ControllerFilter> for FilterKind {
    fn from(f: ControllerFilter) -> Self {
        match f {
            ControllerFilter::Raw => FilterKind::Raw,
            ControllerFilter::Paper => FilterKind::Paper,
            ControllerFilter::Fusion => FilterKind::Fusion,
            ControllerFilter::Vqf => FilterKind::Vqf,
        }
    }
}

/// Where remotes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ControllerSource {
    /// Real remotes over hidapi.
    Hardware,
    /// Emulated controllers (tests, demos, users without hardware), one per config: Wii
    /// Remotes ([`EmulatorConfig`](crate::controllers::wiimote::emulator::EmulatorConfig)) or gyro pads
    /// ([`PadEmulatorConfig`](crate::controllers::pads::PadEmulatorConfig)), each `.into()`.
    Emulator(Vec<EmulatedController>),
}
/// Current MotionController settings (mirrored from the plugin). Changing `filter` switches every
/// connected remote's filter.
#[derive(Resource, Debug, Clone, Reflect)]
#[reflect(Resource)]
pub struct ControllerSettings {
    /// Orientation filter.
    pub filter: ControllerFilter,
    /// The sensor bar and screen the IR pointer is computed for (see
    /// [`MotionControllerPlugin::pointer`]); `None`: no pointer.
    #[reflect(ignore)]
    pub pointer: Option<PointerSetup>,
    /// How the pointer is smoothed (see [`MotionControllerPlugin::pointer_smoothing`]).
    #[reflect(ignore)]
    pub pointer_smoothing: Option<PointerSmoothing>,
    /// The pads' gyro pointer (see [`MotionControllerPlugin::gyro_pointer`]).
    #[reflect(ignore)]
    pub gyro_pointer: Option<crate::controllers::gyro_pointer::GyroPointerSettings>,
}

/// The running device manager (dropping it stops and joins its threads).
#[derive(Resource)]
pub struct ControllerLink {
    manager: ControllerManager,
}

impl ControllerLink {
    /// Sends a command to one remote.
    pub fn send(&self, id: RemoteId, command: RemoteCommand) -> bool {
        self.manager.send(id, command)
    }
}

/// Controls of the emulated remotes (press buttons, plug, power off), when the source is the
/// emulator; index = remote id.
#[derive(Resource, Clone, Default)]
pub struct ControllerEmulators(pub Vec<EmulatorControls>);

/// Connection state of a remote entity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum ConnectionState {
    /// Handshake done, data flowing.
    #[default]
    Connected,
    /// Gone; the entity stays and reconnects in place.
    Disconnected,
    /// Listed by the OS but unusable: see [`MotionController::problems`] for why and the fix.
    Unusable,
}

/// Calibration state mirrored for reflection/UIs.
#[derive(Debug, Clone, Copy, PartialEq, Default, Reflect)]
pub enum ControllerCalibration {
    /// Collecting still samples (0..1).
    Collecting(f32),
    /// Bias estimated; confidence 0..1.
    Calibrated(f32),
    /// No gyro data yet.
    #[default]
    Unknown,
}

/// One motion controller on its own entity — a Wii Remote or a gyro pad (DualSense,
/// DualShock 4, Switch Pro, Joy-Con); the name is the crate's first device's.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
pub struct MotionController {
    /// Manager id (stable across reconnects).
    pub id: u32,
    /// What it is.
    #[reflect(ignore)]
    pub kind: ControllerKind,
    /// Orientation in Bevy's frame (Y up, the remote pointing along −Z at identity),
    /// relative to the last recentre.
    pub orientation: Quat,
    /// Angular velocity in Bevy's frame, rad/s.
    pub angular_velocity: Vec3,
    /// Held buttons (bits of [`Buttons`]).
    pub buttons: u16,
    /// Battery level byte: a Wii Remote's own (0xC8 = full); a pad's charge as the same
    /// scale, percent × 2.
    pub battery: u8,
    /// Gyro calibration.
    pub calibration: ControllerCalibration,
    /// MotionPlus active.
    pub motion_plus: bool,
    /// Connection state.
    pub connection: ConnectionState,
    /// Nunchuk stick, −1..1 (zero without a Nunchuk).
    pub stick: Vec2,
    /// Host timestamp of the last sample, µs.
    pub timestamp_us: u64,
    /// The IR camera's dots in view, pixels (1024 × 768, x right, y down), when the camera
    /// runs ([`MotionControllerPlugin::pointer`]).
    pub ir_dots: Vec<Vec2>,
    /// Where the remote points on the screen, (0, 0) top left … (1, 1) bottom right
    /// (roll-compensated, `PROTOCOL.md` §17.5); `None` while the bar is out of view or the
    /// camera is off.
    pub pointer: Option<Vec2>,
    /// The heading is held by the sensor bar right now (the camera sees it, `PROTOCOL.md`
    /// §17.6); otherwise it is the 6-axis filter's, drifting slowly.
    pub heading_from_bar: bool,
    /// Why the remote is unusable (permissions, the kernel driver, …), each with its fix in
    /// `Display`; cleared when it connects.
    #[reflect(ignore)]
    pub problems: Vec<RemoteProblem>,
}

impl MotionController {
    /// Whether a button (a [`Buttons`] constant) is held.
    pub fn pressed(&self, button: u16) -> bool {
        Buttons(self.buttons).pressed(button)
    }
}

/// A remote connected (or reconnected).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct ControllerConnected {
    /// Its entity.
    pub entity: Entity,
    /// Manager id.
    pub id: u32,
}

/// A remote disconnected (its entity stays, state Disconnected).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct ControllerDisconnected {
    /// Its entity.
    pub entity: Entity,
    /// Manager id.
    pub id: u32,
}

/// A remote is listed but unusable, or no remote is usable: the reason, whose `Display` is
/// the fix to apply. Written once per distinct problem.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct ControllerProblem {
    /// The remote's entity, when the problem is about one remote.
    pub entity: Option<Entity>,
    /// What is wrong and how to fix it.
    pub problem: RemoteProblem,
}

/// Every Wii Remote problem reported and not yet resolved by a connection (for UIs that
/// list them; per-remote problems are also on [`MotionController::problems`]).
#[derive(Resource, Debug, Clone, Default)]
pub struct ControllerProblems(pub Vec<RemoteProblem>);

/// A new orientation sample.
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub struct ControllerOrientationChanged {
    /// The remote's entity.
    pub entity: Entity,
    /// Orientation in Bevy's frame.
    pub rotation: Quat,
    /// Angular velocity in Bevy's frame, rad/s.
    pub angular_velocity: Vec3,
    /// Host timestamp, µs.
    pub timestamp_us: u64,
}

/// Buttons changed.
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub struct ControllerButtonChanged {
    /// The remote's entity.
    pub entity: Entity,
    /// Held now.
    pub buttons: u16,
    /// Newly pressed.
    pub pressed: u16,
    /// Newly released.
    pub released: u16,
}

/// Maps the remote's frame (X left, Y back, Z top; world Z up) to Bevy's (Y up, −Z forward):
/// X → −X, Y → +Z, Z → +Y. A proper rotation, so `q_bevy = C q C⁻¹`.
pub fn remote_to_bevy(q: glam::DQuat) -> Quat {
    let q = q.as_quat();
    // C as a quaternion: rotation taking (X,Y,Z) to (−X, Z, Y).
    let c = Quat::from_mat3(&Mat3::from_cols(Vec3::NEG_X, Vec3::Z, Vec3::Y));
    (c * q * c.inverse()).normalize()
}

/// Maps a vector from the remote's frame to Bevy's.
pub fn remote_vec_to_bevy(v: glam::DVec3) -> Vec3 {
    Vec3::new(-v.x as f32, v.z as f32, v.y as f32)
}
