//! The Wii Remote plugin: its system sets, the emulator clocks, settings changes and the
//! systems that turn the device manager's events into components and messages.

use bevy::prelude::*;

use super::{
    ConnectionState, ControllerButtonChanged, ControllerCalibration, ControllerConnected,
    ControllerDisconnected, ControllerEmulators, ControllerFilter, ControllerLink,
    ControllerOrientationChanged, ControllerProblem, ControllerProblems, ControllerSettings,
    ControllerSource, MotionController, remote_to_bevy, remote_vec_to_bevy,
};
use crate::controllers::emulation::{EmulatorClock, EmulatorControls};
use crate::controllers::fusion::CalibrationPhase;
use crate::controllers::gyro_pointer::{GyroPointer, GyroPointerSettings};
use crate::controllers::manager::{
    ControllerManager, EmulatedController, ManagerConfig, ManagerEvent, RemoteCommand, RemoteSource,
};
use crate::controllers::pads::PadEmulatorConfig;
use crate::controllers::session::{Buttons, MotionPlusState, SessionConfig};
use crate::controllers::wiimote::ir::{IrSensitivity, PointerSetup};
use crate::controllers::wiimote::smoothing::{PointerSmoothing, SmoothedPointer};
use crate::controllers::wiimote::{EmulatedBar, EmulatorConfig};
use crate::controllers::{ControllerKind, Link};

/// MotionController systems, in `PreUpdate`.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MotionControllerSystems {
    /// Drain the device threads: update [`MotionController`] entities, write messages. Runs in
    /// `PreUpdate`, so `Update` systems see this frame's input.
    Receive,
    /// Map remote motion onto [`crate::ecs::MotionHandleControl`] handles (in `Update`,
    /// before [`crate::ecs::DeformSystems::Request`]).
    Control,
}
/// Adds motion-controller input — Wii Remotes and gyro pads. See [`MotionController`] and the
/// messages in this module.
#[derive(Debug, Clone)]
pub struct MotionControllerPlugin {
    /// Filter used by every session.
    pub filter: ControllerFilter,
    /// Hardware or emulator.
    pub source: ControllerSource,
    /// The IR pointer: with a sensor bar set-up the camera is started after each handshake
    /// (basic mode, streamed beside the MotionPlus) and [`MotionController::pointer`] says where the
    /// remote points on the screen. `None` (the default): the camera stays off.
    pub pointer: Option<PointerSetup>,
    /// Smoothing of [`MotionController::pointer`] (a One Euro filter: steady at rest, little lag in
    /// motion; `PROTOCOL.md` §17.5); `None` gives the camera's raw pointer.
    pub pointer_smoothing: Option<PointerSmoothing>,
    /// The gyro pointer of controllers without an IR camera (pads): [`MotionController::pointer`]
    /// moves as the controller turns (player-space gyro) and recentres on the recentre
    /// button. `None` (the default): no pointer for them.
    pub gyro_pointer: Option<GyroPointerSettings>,
}

impl Default for MotionControllerPlugin {
    fn default() -> Self {
        Self {
            filter: ControllerFilter::Fusion,
            pointer: None,
            pointer_smoothing: Some(PointerSmoothing::default()),
            gyro_pointer: None,
            source: if cfg!(feature = "hidapi") {
                ControllerSource::Hardware
            } else {
                ControllerSource::Emulator(vec![EmulatorConfig::default().into()])
            },
        }
    }
}

impl MotionControllerPlugin {
    /// One emulated Wii Remote Plus.
    pub fn emulated() -> Self {
        Self {
            source: ControllerSource::Emulator(vec![EmulatorConfig::default().into()]),
            ..Default::default()
        }
    }

    /// One emulated gyro pad of `kind` over Bluetooth (a DualSense, a Switch Pro…), driven
    /// like the emulated Wii Remote through [`ControllerEmulators`].
    pub fn emulated_pad(kind: ControllerKind) -> Self {
        Self {
            source: ControllerSource::Emulator(vec![
                PadEmulatorConfig::new(kind, Link::Bluetooth).into(),
            ]),
            ..Default::default()
        }
    }

    /// With the IR pointer in the room `setup` ([`Self::pointer`]); emulated remotes see that
    /// room's sensor bar from its standing point (unless their config places one already), so
    /// `MotionControllerPlugin::emulated().with_pointer(PointerSetup::default())` points with no
    /// hardware (aim it through [`ControllerEmulators`]).
    ///
    /// Pads get the gyro pointer ([`Self::gyro_pointer`], default settings unless set).
    pub fn with_pointer(mut self, setup: PointerSetup) -> Self {
        self.pointer = Some(setup);
        self.gyro_pointer
            .get_or_insert_with(GyroPointerSettings::default);
        if let ControllerSource::Emulator(configs) = &mut self.source {
            for config in configs {
                let EmulatedController::Wiimote(config) = config else {
                    continue;
                };
                config.sensor_bar.get_or_insert(EmulatedBar {
                    setup,
                    position: glam::DVec3::ZERO,
                    noise_px: 0.5,
                });
            }
        }
        self
    }
}
impl Plugin for MotionControllerPlugin {
    fn build(&self, app: &mut App) {
        let (source, emulators) = match &self.source {
            #[cfg(feature = "hidapi")]
            ControllerSource::Hardware => (RemoteSource::Hid, ControllerEmulators::default()),
            #[cfg(not(feature = "hidapi"))]
            ControllerSource::Hardware => {
                warn!("bevy_wii_deform built without the `hidapi` feature: using the emulator");
                let c = EmulatorControls::default();
                (
                    RemoteSource::Emulated(vec![(EmulatorConfig::default().into(), c.clone())]),
                    ControllerEmulators(vec![c]),
                )
            }
            ControllerSource::Emulator(configs) => {
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
                    ControllerEmulators(controls),
                )
            }
        };
        let manager = ControllerManager::start(ManagerConfig {
            source,
            session: SessionConfig {
                filter: self.filter.into(),
                ir_camera: self.pointer.map(|_| IrSensitivity::Level3),
                ..Default::default()
            },
            channel_capacity: 1024,
        });
        app.insert_resource(ControllerLink { manager })
            .insert_resource(emulators)
            .insert_resource(ControllerSettings {
                filter: self.filter,
                pointer: self.pointer,
                pointer_smoothing: self.pointer_smoothing,
                gyro_pointer: self.gyro_pointer,
            })
            .register_type::<MotionController>()
            .register_type::<ControllerSettings>()
            .add_message::<ControllerConnected>()
            .add_message::<ControllerDisconnected>()
            .add_message::<ControllerOrientationChanged>()
            .add_message::<ControllerButtonChanged>()
            .add_message::<ControllerProblem>()
            .init_resource::<ControllerProblems>()
            .add_systems(
                PreUpdate,
                (apply_settings, receive_wiimote_events)
                    .chain()
                    .in_set(MotionControllerSystems::Receive),
            );
        // Emulated remotes paced by a clock follow the app's (real) time: with
        // `TimeUpdateStrategy::ManualDuration` a test steps them frame by frame.
        let clocks: Vec<EmulatorClock> = match &self.source {
            ControllerSource::Emulator(configs) => {
                configs.iter().filter_map(|c| c.clock().cloned()).collect()
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
    settings: Res<ControllerSettings>,
    link: Res<ControllerLink>,
    mut applied: Local<Option<ControllerFilter>>,
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
struct ControllerWriters<'w> {
    connected: MessageWriter<'w, ControllerConnected>,
    disconnected: MessageWriter<'w, ControllerDisconnected>,
    orientation: MessageWriter<'w, ControllerOrientationChanged>,
    buttons_changed: MessageWriter<'w, ControllerButtonChanged>,
    problems: MessageWriter<'w, ControllerProblem>,
}

fn receive_wiimote_events(
    mut commands: Commands,
    link: Res<ControllerLink>,
    mut remotes: Query<(Entity, &mut MotionController)>,
    mut writers: ControllerWriters,
    mut open_problems: ResMut<ControllerProblems>,
    settings: Res<ControllerSettings>,
    mut pointers: Local<PointerStates>,
) {
    let PointerStates { smoothing, gyro } = &mut *pointers;
    let mut out = EventOutputs {
        writers: &mut writers,
        open_problems: &mut open_problems,
        settings: &settings,
        smoothing,
        gyro_pointers: gyro,
    };
    // Entities spawned this frame are not queryable yet: buffer their state locally.
    let mut spawned: Vec<(Entity, MotionController)> = Vec::new();
    while let Ok(event) = link.manager.events().try_recv() {
        if let ManagerEvent::Problem { problem, .. } = &event {
            warn!("Wii Remote: {problem}");
            if !out.open_problems.0.contains(problem) {
                out.open_problems.0.push(problem.clone());
            }
        }
        let Some(id) = remote_of(&event) else {
            if let ManagerEvent::Problem { problem, .. } = &event {
                out.writers.problems.write(ControllerProblem {
                    entity: None,
                    problem: problem.clone(),
                });
            }
            continue;
        };
        let known = remotes.iter().find(|(_, w)| w.id == id).map(|(e, _)| e);
        let entity =
            match known.or_else(|| spawned.iter().find(|(_, w)| w.id == id).map(|(e, _)| *e)) {
                Some(e) => e,
                None => {
                    let e = commands.spawn(Name::new(format!("Wii Remote {id}"))).id();
                    spawned.push((
                        e,
                        MotionController {
                            id,
                            connection: ConnectionState::Disconnected,
                            orientation: Quat::IDENTITY,
                            ..Default::default()
                        },
                    ));
                    e
                }
            };
        if let Some((_, w)) = spawned.iter_mut().find(|(e, _)| *e == entity) {
            apply_event(w, entity, &event, &mut out);
        } else if let Ok((_, mut w)) = remotes.get_mut(entity) {
            apply_event(&mut w, entity, &event, &mut out);
        }
    }
    for (e, w) in spawned {
        commands.entity(e).try_insert(w);
    }
}

/// Each controller's pointer state: the IR pointer's smoothing, the gyro pointer.
#[derive(Default)]
struct PointerStates {
    smoothing: Vec<(u32, SmoothedPointer)>,
    gyro: Vec<(u32, GyroPointer)>,
}

/// Where a remote's events go besides its component.
struct EventOutputs<'a, 'w> {
    writers: &'a mut ControllerWriters<'w>,
    open_problems: &'a mut ControllerProblems,
    settings: &'a ControllerSettings,
    smoothing: &'a mut Vec<(u32, SmoothedPointer)>,
    gyro_pointers: &'a mut Vec<(u32, GyroPointer)>,
}

/// The remote an event is about (`None`: a problem with no remote, e.g. no permission to list
/// devices).
fn remote_of(event: &ManagerEvent) -> Option<u32> {
    match event {
        ManagerEvent::Problem { id, .. } => *id,
        ManagerEvent::Connected { id, .. }
        | ManagerEvent::PadConnected { id, .. }
        | ManagerEvent::Disconnected { id, .. }
        | ManagerEvent::Buttons { id, .. }
        | ManagerEvent::Orientation { id, .. }
        | ManagerEvent::Battery { id, .. }
        | ManagerEvent::Extension { id, .. }
        | ManagerEvent::MotionPlus { id, .. }
        | ManagerEvent::Nunchuk { id, .. }
        | ManagerEvent::Ir { id, .. } => Some(*id),
    }
}

/// Applies one event to its remote's component and writes its messages.
fn apply_event(
    w: &mut MotionController,
    entity: Entity,
    event: &ManagerEvent,
    out: &mut EventOutputs,
) {
    let id = w.id;
    match event {
        ManagerEvent::Connected { info, .. } => {
            w.connection = ConnectionState::Connected;
            for p in w.problems.drain(..) {
                out.open_problems.0.retain(|q| *q != p);
            }
            w.kind = ControllerKind::WiiRemote;
            w.battery = info.battery;
            w.motion_plus = info.motion_plus == MotionPlusState::Active;
            out.writers
                .connected
                .write(ControllerConnected { entity, id });
        }
        ManagerEvent::PadConnected { info, .. } => {
            w.connection = ConnectionState::Connected;
            for p in w.problems.drain(..) {
                out.open_problems.0.retain(|q| *q != p);
            }
            w.kind = info.kind;
            // A gyro is built in: the "MotionPlus" flag means "has a gyro".
            w.motion_plus = true;
            out.writers
                .connected
                .write(ControllerConnected { entity, id });
        }
        ManagerEvent::Disconnected { .. } => {
            w.connection = ConnectionState::Disconnected;
            w.buttons = 0;
            w.angular_velocity = Vec3::ZERO;
            out.writers
                .disconnected
                .write(ControllerDisconnected { entity, id });
        }
        ManagerEvent::Buttons { buttons, .. } => {
            let old = w.buttons;
            w.buttons = buttons.0;
            // The recentre button puts a gyro pointer back at the centre.
            if buttons.0 & !old & Buttons::HOME != 0
                && let Some((_, p)) = out.gyro_pointers.iter_mut().find(|(i, _)| *i == id)
            {
                p.recentre();
            }
            out.writers.buttons_changed.write(ControllerButtonChanged {
                entity,
                buttons: buttons.0,
                pressed: buttons.0 & !old,
                released: old & !buttons.0,
            });
        }
        ManagerEvent::Orientation { sample, .. } => {
            if let Some(changed) = apply_orientation(w, entity, sample) {
                out.writers.orientation.write(changed);
                if let Some(settings) = out.settings.gyro_pointer
                    && !w.kind.has_ir_camera()
                {
                    let pointers = &mut *out.gyro_pointers;
                    let index = match pointers.iter().position(|(i, _)| *i == id) {
                        Some(index) => index,
                        None => {
                            pointers.push((id, GyroPointer::new(settings)));
                            pointers.len() - 1
                        }
                    };
                    let at = pointers[index].1.update(sample.orientation);
                    w.pointer = Some(at.as_vec2());
                }
            }
        }
        ManagerEvent::Battery { level, .. } => w.battery = *level,
        ManagerEvent::MotionPlus { state, .. } => w.motion_plus = *state == MotionPlusState::Active,
        ManagerEvent::Extension { .. } => {}
        ManagerEvent::Ir {
            dots,
            gravity,
            timestamp_us,
            ..
        } => {
            w.ir_dots = dots
                .iter()
                .flatten()
                .map(|d| d.position().as_vec2())
                .collect();
            let raw = out
                .settings
                .pointer
                .and_then(|setup| setup.pointed_at(dots, *gravity).ok())
                .filter(|p| p.is_finite());
            let smoothing = out.settings.pointer_smoothing;
            w.pointer = smooth_pointer(out.smoothing, smoothing, id, raw, *timestamp_us)
                .map(|p| p.as_vec2());
        }
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
            out.writers.problems.write(ControllerProblem {
                entity: Some(entity),
                problem: problem.clone(),
            });
        }
    }
}

/// Takes a new orientation sample (ignored unless finite) and says what changed.
fn apply_orientation(
    w: &mut MotionController,
    entity: Entity,
    sample: &crate::controllers::session::OrientationSample,
) -> Option<ControllerOrientationChanged> {
    let q = remote_to_bevy(sample.orientation);
    let av = remote_vec_to_bevy(sample.angular_velocity);
    if !(q.is_finite() && av.is_finite()) {
        return None;
    }
    w.orientation = q;
    w.angular_velocity = av;
    w.timestamp_us = sample.timestamp_us;
    w.heading_from_bar = sample.heading_from_bar;
    w.calibration = match sample.calibration.phase {
        CalibrationPhase::Collecting { progress } => {
            ControllerCalibration::Collecting(progress as f32)
        }
        CalibrationPhase::Calibrated => {
            ControllerCalibration::Calibrated(sample.calibration.confidence as f32)
        }
    };
    Some(ControllerOrientationChanged {
        entity,
        rotation: q,
        angular_velocity: av,
        timestamp_us: sample.timestamp_us,
    })
}

/// The remote `id`'s pointer through its One Euro filter (reset while the bar is out of view,
/// so the pointer reappears where it points rather than sliding there).
fn smooth_pointer(
    filters: &mut Vec<(u32, SmoothedPointer)>,
    settings: Option<PointerSmoothing>,
    id: u32,
    raw: Option<glam::DVec2>,
    timestamp_us: u64,
) -> Option<glam::DVec2> {
    let Some(settings) = settings else {
        return raw;
    };
    let index = match filters.iter().position(|(i, _)| *i == id) {
        Some(index) => index,
        None => {
            filters.push((id, SmoothedPointer::new(settings)));
            filters.len() - 1
        }
    };
    let filter = &mut filters[index].1;
    filter.settings = settings;
    match raw {
        Some(at) => Some(filter.update(at, timestamp_us as f64 * 1e-6)),
        None => {
            filter.reset();
            None
        }
    }
}
