//! Wii Remotes in the ECS: [`WiimotePlugin`] runs the device manager off the main thread and
//! mirrors every remote as an entity with a [`Wiimote`] component, plus messages. This file
//! holds the data types; `plugin.rs` the plugin, its system sets and systems.

mod plugin;

use bevy::prelude::*;

use crate::controllers::ControllerKind;
use crate::controllers::wiimote::ir::PointerSetup;
use crate::controllers::wiimote::smoothing::PointerSmoothing;
use crate::controllers::wiimote::{
    EmulatedController, EmulatorControls, FilterKind, RemoteCommand, RemoteId, RemoteProblem,
    WiimoteManager, protocol::Buttons,
};

pub use plugin::{WiimotePlugin, WiimoteSystems};

/// Orientation filter choice (mirrors [`FilterKind`] for reflection and UIs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum WiimoteFilter {
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

impl From<WiimoteFilter> for FilterKind {
    fn from(f: WiimoteFilter) -> Self {
        match f {
            WiimoteFilter::Raw => FilterKind::Raw,
            WiimoteFilter::Paper => FilterKind::Paper,
            WiimoteFilter::Fusion => FilterKind::Fusion,
            WiimoteFilter::Vqf => FilterKind::Vqf,
        }
    }
}

/// Where remotes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum WiimoteSource {
    /// Real remotes over hidapi.
    Hardware,
    /// Emulated controllers (tests, demos, users without hardware), one per config: Wii
    /// Remotes ([`EmulatorConfig`](crate::controllers::wiimote::emulator::EmulatorConfig)) or gyro pads
    /// ([`PadEmulatorConfig`](crate::controllers::pads::PadEmulatorConfig)), each `.into()`.
    Emulator(Vec<EmulatedController>),
}
/// Current Wiimote settings (mirrored from the plugin). Changing `filter` switches every
/// connected remote's filter.
#[derive(Resource, Debug, Clone, Reflect)]
#[reflect(Resource)]
pub struct WiimoteSettings {
    /// Orientation filter.
    pub filter: WiimoteFilter,
    /// The sensor bar and screen the IR pointer is computed for (see
    /// [`WiimotePlugin::pointer`]); `None`: no pointer.
    #[reflect(ignore)]
    pub pointer: Option<PointerSetup>,
    /// How the pointer is smoothed (see [`WiimotePlugin::pointer_smoothing`]).
    #[reflect(ignore)]
    pub pointer_smoothing: Option<PointerSmoothing>,
    /// The pads' gyro pointer (see [`WiimotePlugin::gyro_pointer`]).
    #[reflect(ignore)]
    pub gyro_pointer: Option<crate::controllers::gyro_pointer::GyroPointerSettings>,
}

/// The running device manager (dropping it stops and joins its threads).
#[derive(Resource)]
pub struct WiimoteLink {
    manager: WiimoteManager,
}

impl WiimoteLink {
    /// Sends a command to one remote.
    pub fn send(&self, id: RemoteId, command: RemoteCommand) -> bool {
        self.manager.send(id, command)
    }
}

/// Controls of the emulated remotes (press buttons, plug, power off), when the source is the
/// emulator; index = remote id.
#[derive(Resource, Clone, Default)]
pub struct WiimoteEmulators(pub Vec<EmulatorControls>);

/// Connection state of a remote entity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum ConnectionState {
    /// Handshake done, data flowing.
    #[default]
    Connected,
    /// Gone; the entity stays and reconnects in place.
    Disconnected,
    /// Listed by the OS but unusable: see [`Wiimote::problems`] for why and the fix.
    Unusable,
}

/// Calibration state mirrored for reflection/UIs.
#[derive(Debug, Clone, Copy, PartialEq, Default, Reflect)]
pub enum WiimoteCalibration {
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
pub struct Wiimote {
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
    pub calibration: WiimoteCalibration,
    /// MotionPlus active.
    pub motion_plus: bool,
    /// Connection state.
    pub connection: ConnectionState,
    /// Nunchuk stick, −1..1 (zero without a Nunchuk).
    pub stick: Vec2,
    /// Host timestamp of the last sample, µs.
    pub timestamp_us: u64,
    /// The IR camera's dots in view, pixels (1024 × 768, x right, y down), when the camera
    /// runs ([`WiimotePlugin::pointer`]).
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

impl Wiimote {
    /// Whether a button (a [`Buttons`] constant) is held.
    pub fn pressed(&self, button: u16) -> bool {
        Buttons(self.buttons).pressed(button)
    }
}

/// A remote connected (or reconnected).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct WiimoteConnected {
    /// Its entity.
    pub entity: Entity,
    /// Manager id.
    pub id: u32,
}

/// A remote disconnected (its entity stays, state Disconnected).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct WiimoteDisconnected {
    /// Its entity.
    pub entity: Entity,
    /// Manager id.
    pub id: u32,
}

/// A remote is listed but unusable, or no remote is usable: the reason, whose `Display` is
/// the fix to apply. Written once per distinct problem.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct WiimoteProblem {
    /// The remote's entity, when the problem is about one remote.
    pub entity: Option<Entity>,
    /// What is wrong and how to fix it.
    pub problem: RemoteProblem,
}

/// Every Wii Remote problem reported and not yet resolved by a connection (for UIs that
/// list them; per-remote problems are also on [`Wiimote::problems`]).
#[derive(Resource, Debug, Clone, Default)]
pub struct WiimoteProblems(pub Vec<RemoteProblem>);

/// A new orientation sample.
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub struct WiimoteOrientationChanged {
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
pub struct WiimoteButtonChanged {
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
