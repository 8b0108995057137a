//! `WiimotePlugin`: runs the device manager off the main thread and mirrors every remote as
//! an entity with a [`Wiimote`] component, plus messages.

use bevy::prelude::*;

use crate::wiimote::{
    CalibrationPhase, EmulatorClock, EmulatorConfig, EmulatorControls, FilterKind, ManagerConfig,
    ManagerEvent, MotionPlusState, RemoteCommand, RemoteId, RemoteProblem, RemoteSource,
    SessionConfig, WiimoteManager, protocol::Buttons,
};

/// Wiimote systems, in `PreUpdate`.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WiimoteSystems {
    /// Drain the device threads: update [`Wiimote`] entities, write messages. Runs in
    /// `PreUpdate`, so `Update` systems see this frame's input.
    Receive,
    /// Map remote motion onto [`crate::ecs::WiimoteHandleControl`] handles (in `Update`,
    /// before [`crate::ecs::DeformSystems::Request`]).
    Control,
}

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
    /// Emulated remotes (tests, demos, users without hardware), one per config.
    Emulator(Vec<EmulatorConfig>),
}

/// Adds Wii Remote input. See [`Wiimote`] and the messages in this module.
#[derive(Debug, Clone)]
pub struct WiimotePlugin {
    /// Filter used by every session.
    pub filter: WiimoteFilter,
    /// Hardware or emulator.
    pub source: WiimoteSource,
}

impl Default for WiimotePlugin {
    fn default() -> Self {
        Self {
            filter: WiimoteFilter::Fusion,
            source: if cfg!(feature = "hidapi") {
                WiimoteSource::Hardware
            } else {
                WiimoteSource::Emulator(vec![EmulatorConfig::default()])
            },
        }
    }
}

impl WiimotePlugin {
    /// One emulated Wii Remote Plus.
    pub fn emulated() -> Self {
        Self {
            source: WiimoteSource::Emulator(vec![EmulatorConfig::default()]),
            ..Default::default()
        }
    }
}

/// Current Wiimote settings (mirrored from the plugin). Changing `filter` switches every
/// connected remote's filter.
#[derive(Resource, Debug, Clone, Reflect)]
#[reflect(Resource)]
pub struct WiimoteSettings {
    /// Orientation filter.
    pub filter: WiimoteFilter,
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

/// One Wii Remote, on its own entity.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
pub struct Wiimote {
    /// Manager id (stable across reconnects).
    pub id: u32,
    /// Orientation in Bevy's frame (Y up, the remote pointing along −Z at identity),
    /// relative to the last recentre.
    pub orientation: Quat,
    /// Angular velocity in Bevy's frame, rad/s.
    pub angular_velocity: Vec3,
    /// Held buttons (bits of [`Buttons`]).
    pub buttons: u16,
    /// Battery level byte (~0x60–0x70 when full).
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

impl Plugin for WiimotePlugin {
    fn build(&self, app: &mut App) {
        let (source, emulators) = match &self.source {
            #[cfg(feature = "hidapi")]
            WiimoteSource::Hardware => (RemoteSource::Hid, WiimoteEmulators::default()),
            #[cfg(not(feature = "hidapi"))]
            WiimoteSource::Hardware => {
                warn!("bevy_wii_deform built without the `hidapi` feature: using the emulator");
                let c = EmulatorControls::default();
                (
                    RemoteSource::Emulated(vec![(EmulatorConfig::default(), c.clone())]),
                    WiimoteEmulators(vec![c]),
                )
            }
            WiimoteSource::Emulator(configs) => {
                let controls: Vec<EmulatorControls> = configs
                    .iter()
                    .map(|_| EmulatorControls::default())
                    .collect();
                (
                    RemoteSource::Emulated(
                        configs
                            .iter()
                            .cloned()
                            .zip(controls.iter().cloned())
                            .collect(),
                    ),
                    WiimoteEmulators(controls),
                )
            }
        };
        let manager = WiimoteManager::start(ManagerConfig {
            source,
            session: SessionConfig {
                filter: self.filter.into(),
                ..Default::default()
            },
            channel_capacity: 1024,
        });
        app.insert_resource(WiimoteLink { manager })
            .insert_resource(emulators)
            .insert_resource(WiimoteSettings {
                filter: self.filter,
            })
            .register_type::<Wiimote>()
            .register_type::<WiimoteSettings>()
            .add_message::<WiimoteConnected>()
            .add_message::<WiimoteDisconnected>()
            .add_message::<WiimoteOrientationChanged>()
            .add_message::<WiimoteButtonChanged>()
            .add_message::<WiimoteProblem>()
            .init_resource::<WiimoteProblems>()
            .add_systems(
                PreUpdate,
                (apply_settings, receive_wiimote_events)
                    .chain()
                    .in_set(WiimoteSystems::Receive),
            );
        // Emulated remotes paced by a clock follow the app's (real) time: with
        // `TimeUpdateStrategy::ManualDuration` a test steps them frame by frame.
        let clocks: Vec<EmulatorClock> = match &self.source {
            WiimoteSource::Emulator(configs) => {
                configs.iter().filter_map(|c| c.clock.clone()).collect()
            }
            _ => Vec::new(),
        };
        if !clocks.is_empty() {
            app.insert_resource(EmulatorClocks(clocks)).add_systems(
                First,
                advance_emulator_clocks.after(bevy::time::TimeSystems),
            );
        }
    }
}

/// The pacing clocks of the plugin's emulated remotes.
#[derive(Resource)]
struct EmulatorClocks(Vec<EmulatorClock>);

fn advance_emulator_clocks(clocks: Res<EmulatorClocks>, time: Res<Time<Real>>) {
    let now = time.elapsed().as_micros() as u64;
    for clock in &clocks.0 {
        clock.advance_to(now);
    }
}

fn apply_settings(
    settings: Res<WiimoteSettings>,
    link: Res<WiimoteLink>,
    mut applied: Local<Option<WiimoteFilter>>,
) {
    // Only a real change switches filters (a new filter starts uncalibrated).
    let current = *applied.get_or_insert(settings.filter);
    if settings.filter != current {
        *applied = Some(settings.filter);
        link.manager
            .broadcast(RemoteCommand::SetFilter(settings.filter.into()));
    }
}

/// The messages [`receive_wiimote_events`] writes.
#[derive(bevy::ecs::system::SystemParam)]
struct WiimoteWriters<'w> {
    connected: MessageWriter<'w, WiimoteConnected>,
    disconnected: MessageWriter<'w, WiimoteDisconnected>,
    orientation: MessageWriter<'w, WiimoteOrientationChanged>,
    buttons_changed: MessageWriter<'w, WiimoteButtonChanged>,
    problems: MessageWriter<'w, WiimoteProblem>,
}

fn receive_wiimote_events(
    mut commands: Commands,
    link: Res<WiimoteLink>,
    mut remotes: Query<(Entity, &mut Wiimote)>,
    mut writers: WiimoteWriters,
    mut open_problems: ResMut<WiimoteProblems>,
) {
    let WiimoteWriters {
        connected,
        disconnected,
        orientation,
        buttons_changed,
        problems,
    } = &mut writers;
    let find = |id: u32, remotes: &mut Query<(Entity, &mut Wiimote)>| -> Option<Entity> {
        remotes.iter().find(|(_, w)| w.id == id).map(|(e, _)| e)
    };
    // Entities spawned this frame are not queryable yet: buffer their state locally.
    let mut spawned: Vec<(Entity, Wiimote)> = Vec::new();
    while let Ok(event) = link.manager.events().try_recv() {
        if let ManagerEvent::Problem { problem, .. } = &event {
            warn!("Wii Remote: {problem}");
            if !open_problems.0.contains(problem) {
                open_problems.0.push(problem.clone());
            }
        }
        let id = match &event {
            ManagerEvent::Problem { id: None, problem } => {
                problems.write(WiimoteProblem {
                    entity: None,
                    problem: problem.clone(),
                });
                continue;
            }
            ManagerEvent::Problem { id: Some(id), .. }
            | ManagerEvent::Connected { id, .. }
            | ManagerEvent::Disconnected { id, .. }
            | ManagerEvent::Buttons { id, .. }
            | ManagerEvent::Orientation { id, .. }
            | ManagerEvent::Battery { id, .. }
            | ManagerEvent::Extension { id, .. }
            | ManagerEvent::MotionPlus { id, .. }
            | ManagerEvent::Nunchuk { id, .. } => *id,
        };
        let entity = match find(id, &mut remotes)
            .or_else(|| spawned.iter().find(|(_, w)| w.id == id).map(|(e, _)| *e))
        {
            Some(e) => e,
            None => {
                let e = commands.spawn(Name::new(format!("Wii Remote {id}"))).id();
                spawned.push((
                    e,
                    Wiimote {
                        id,
                        connection: ConnectionState::Disconnected,
                        orientation: Quat::IDENTITY,
                        ..Default::default()
                    },
                ));
                e
            }
        };
        let mut apply = |w: &mut Wiimote| match &event {
            ManagerEvent::Connected { info, .. } => {
                w.connection = ConnectionState::Connected;
                for p in w.problems.drain(..) {
                    open_problems.0.retain(|q| *q != p);
                }
                w.battery = info.battery;
                w.motion_plus = info.motion_plus == MotionPlusState::Active;
                connected.write(WiimoteConnected { entity, id });
            }
            ManagerEvent::Disconnected { .. } => {
                w.connection = ConnectionState::Disconnected;
                w.buttons = 0;
                w.angular_velocity = Vec3::ZERO;
                disconnected.write(WiimoteDisconnected { entity, id });
            }
            ManagerEvent::Buttons { buttons, .. } => {
                let old = w.buttons;
                w.buttons = buttons.0;
                buttons_changed.write(WiimoteButtonChanged {
                    entity,
                    buttons: buttons.0,
                    pressed: buttons.0 & !old,
                    released: old & !buttons.0,
                });
            }
            ManagerEvent::Orientation { sample, .. } => {
                let q = remote_to_bevy(sample.orientation);
                let av = remote_vec_to_bevy(sample.angular_velocity);
                if q.is_finite() && av.is_finite() {
                    w.orientation = q;
                    w.angular_velocity = av;
                    w.timestamp_us = sample.timestamp_us;
                    w.calibration = match sample.calibration.phase {
                        CalibrationPhase::Collecting { progress } => {
                            WiimoteCalibration::Collecting(progress as f32)
                        }
                        CalibrationPhase::Calibrated => {
                            WiimoteCalibration::Calibrated(sample.calibration.confidence as f32)
                        }
                    };
                    orientation.write(WiimoteOrientationChanged {
                        entity,
                        rotation: q,
                        angular_velocity: av,
                        timestamp_us: sample.timestamp_us,
                    });
                }
            }
            ManagerEvent::Battery { level, .. } => w.battery = *level,
            ManagerEvent::MotionPlus { state, .. } => {
                w.motion_plus = *state == MotionPlusState::Active
            }
            ManagerEvent::Extension { .. } => {}
            ManagerEvent::Nunchuk { frame, .. } => {
                let axis = |v: u8| ((v as f32 - 128.0) / 100.0).clamp(-1.0, 1.0);
                w.stick = Vec2::new(axis(frame.stick_x), axis(frame.stick_y));
            }
            ManagerEvent::Problem { problem, .. } => {
                if w.connection != ConnectionState::Connected {
                    w.connection = ConnectionState::Unusable;
                }
                if !w.problems.contains(problem) {
                    w.problems.push(problem.clone());
                }
                problems.write(WiimoteProblem {
                    entity: Some(entity),
                    problem: problem.clone(),
                });
            }
        };
        if let Some((_, w)) = spawned.iter_mut().find(|(e, _)| *e == entity) {
            apply(w);
        } else if let Ok((_, mut w)) = remotes.get_mut(entity) {
            apply(&mut w);
        }
    }
    for (e, w) in spawned {
        commands.entity(e).insert(w);
    }
}
