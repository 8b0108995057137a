//! What the playground needs besides the game itself: its command line, a motion
//! controller as a pointer (`--pointer [emulated[=KIND]]`: a Wii Remote's IR camera or a
//! pad's gyro; point at a thing, hold A / Cross, move and turn the controller, release — the
//! library's `ControllerPointerPlugin`, with a ring drawn where it points),
//! and the unattended run (`--screenshot PATH --frames N`: a scripted grab bends the bar, frame
//! N is saved, the app exits).

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::controllers::ControllerKind;
use bevy_wii_deform::prelude::*;

use crate::screenshot::{ScreenshotPlugin, UnattendedFrame};
use crate::{Bar, Cactus, Floor, cli, remote_cursor};

const USAGE: &str = "\
usage: playground [--pointer [emulated[=KIND]]] [--wobble] [--screenshot PATH [--frames N]]

  --pointer [emulated]  a motion controller points: a Wii Remote with its IR camera, a pad
                        with its gyro (emulated: a scripted Wii Remote; emulated=KIND: a
                        scripted dualsense, ds4, switch-pro, joycon-l or joycon-r)
  --wobble              things wobble and spring back when let go (W switches it)
  --screenshot PATH     bend the bar by a scripted grab, save frame N to PATH, exit
  --frames N            the frame to save (default 60)
  --drag bar|cactus     with --screenshot: a scripted two-second drag of that thing, released
                        before the frame is saved (the log gives grab → first pose and solves/s)
  --light               render as the web build does: a 640×360 window, no multisampling, no
                        tone mapping, no shadows, an unlit floor (for software GL)";

/// The playground's command line.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--pointer [emulated[=KIND]]`: `Some(the emulated kind, if emulated)`.
    pointer: Option<Option<ControllerKind>>,
    /// `--wobble`: start with the objects elastic (`DeformDynamics`).
    wobble: bool,
    /// `--screenshot PATH`.
    screenshot: Option<String>,
    /// `--frames N`.
    frames: u32,
    /// `--drag bar|cactus`: a scripted 120-frame drag of the bar (`false`) or the cactus
    /// (`true`) instead of the short grab.
    drag: Option<bool>,
    /// `--light` (always on the web): the web build's lighter rendering.
    light: bool,
}

impl Options {
    /// Parses the process's arguments (exits on `--help` or a bad argument).
    pub fn parse() -> Self {
        let mut options = Options {
            frames: 60,
            ..default()
        };
        let mut parser = cli::Parser::from_env();
        while let Some(arg) = cli::next(&mut parser, USAGE) {
            match arg {
                cli::Arg::Long("pointer") => {
                    options.pointer = Some(cli::emulated_controller(&mut parser, None, USAGE))
                }
                cli::Arg::Long("screenshot") => {
                    options.screenshot = Some(cli::string(&mut parser, USAGE))
                }
                cli::Arg::Long("frames") => options.frames = cli::value(&mut parser, USAGE),
                cli::Arg::Long("wobble") => options.wobble = true,
                cli::Arg::Long("light") => options.light = true,
                cli::Arg::Long("drag") => {
                    options.drag = Some(match cli::string(&mut parser, USAGE).as_str() {
                        "bar" => false,
                        "cactus" => true,
                        other => cli::fail(format!("unknown thing to drag {other:?}"), USAGE),
                    })
                }
                other => cli::unexpected(other, USAGE),
            }
        }
        options.light |= cfg!(target_arch = "wasm32");
        options
    }
}

/// Bevy's default plugins, without asset `.meta` lookups (the web page serves none, and each
/// miss is a console error); with `--light` (the web) a smaller window.
pub fn default_plugins(options: &Options) -> impl PluginGroup {
    let window = if options.light {
        // A quarter of the desktop window's pixels: many browsers render WebGL in software
        // (headless Chromium: SwiftShader), where a frame's cost grows with its pixels.
        Window {
            resolution: bevy::window::WindowResolution::new(640, 360),
            ..default()
        }
    } else {
        Window::default()
    };
    DefaultPlugins
        .set(AssetPlugin {
            meta_check: bevy::asset::AssetMetaCheck::Never,
            ..default()
        })
        .set(WindowPlugin {
            primary_window: Some(window),
            ..default()
        })
}

/// On the web (software WebGL in many browsers' sandboxes, one thread): no multisampling, no
/// tone mapping pass, no shadow maps and an unlit floor, which cost most of a
/// software-rendered frame.
fn lighten_for_the_web(
    mut commands: Commands,
    cameras: Query<Entity, Added<Camera3d>>,
    mut lights: Query<&mut DirectionalLight, Added<DirectionalLight>>,
    floors: Query<&MeshMaterial3d<StandardMaterial>, Added<Floor>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    for floor in &floors {
        if let Some(mut material) = materials.get_mut(&floor.0) {
            material.unlit = true;
        }
    }
    for camera in &cameras {
        commands.entity(camera).insert((
            Msaa::Off,
            bevy::core_pipeline::tonemapping::Tonemapping::Linear,
        ));
    }
    for mut light in &mut lights {
        light.shadow_maps_enabled = false;
    }
}

/// The pointer and the unattended run, as the options ask.
pub struct HarnessPlugin(pub Options);

impl Plugin for HarnessPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(Wobble(self.0.wobble))
            .insert_resource(ScriptedDrag(self.0.drag))
            .add_systems(Update, (switch_wobble, make_things_wobble).chain())
            .add_systems(Last, report_grabs);
        if self.0.light {
            app.add_systems(PostUpdate, lighten_for_the_web);
        }
        if let Some(emulated) = self.0.pointer {
            // A motion controller as a second pointer: A grabs where it points.
            app.add_plugins((
                remote_cursor::pointing_remote(emulated),
                remote_cursor::RemoteCursorPlugin {
                    emulated: emulated.is_some(),
                },
            ));
        }
        if let Some(path) = self.0.screenshot.clone() {
            let frames = self.0.frames;
            app.add_plugins(ScreenshotPlugin { path, frames })
                .add_systems(Update, grab_the_bar);
        }
    }
}

/// Whether the objects wobble (`--wobble`, W).
#[derive(Resource)]
struct Wobble(bool);

/// W: wobbling on or off.
fn switch_wobble(keys: Option<Res<ButtonInput<KeyCode>>>, mut wobble: ResMut<Wobble>) {
    if keys.is_some_and(|k| k.just_pressed(KeyCode::KeyW)) {
        wobble.0 = !wobble.0;
    }
}

/// Gives every bendable thing inertia and an elastic release while wobbling is on: let go, it
/// rings back to its shape (`DeformDynamics`); off, a bend stays where it is let go.
fn make_things_wobble(
    mut commands: Commands,
    wobble: Res<Wobble>,
    things: Query<(Entity, Has<DeformDynamics>), With<Deformable>>,
) {
    for (thing, wobbling) in &things {
        match (wobble.0, wobbling) {
            (true, false) => {
                commands.entity(thing).insert(DeformDynamics {
                    elastic: true,
                    ..default()
                });
            }
            (false, true) => {
                commands.entity(thing).remove::<DeformDynamics>();
            }
            _ => {}
        }
    }
}

/// The scripted drag's length in frames (`--drag`); the short grab's is 10.
const LONG_DRAG: u32 = 120;

/// Grabs the bar's tip (or, with `--drag cactus`, the cactus's top) at a third of the run and
/// drags it: for ten frames, or with `--drag` for 120 frames and then lets go.
fn grab_the_bar(
    frame: Res<UnattendedFrame>,
    shot: Res<ScreenshotPlugin>,
    drag: Res<ScriptedDrag>,
    bar: Single<(Entity, &GlobalTransform), With<Bar>>,
    cactus: Query<(Entity, &GlobalTransform), With<Cactus>>,
    camera: Single<(Entity, &Camera, &GlobalTransform)>,
    mut out: GrabWriters,
) {
    let frame = frame.0;
    let start = shot.frames / 3;
    let (target, transform, tip) = match (drag.0, cactus.single()) {
        (Some(true), Ok((cactus, transform))) => (cactus, transform, Vec3::new(0.0, 1.0, 0.0)),
        _ => (bar.0, bar.1, Vec3::new(0.0, 1.2, 0.0)),
    };
    let (camera, cam, cam_transform) = *camera;
    let tip = transform.transform_point(tip);
    let pointer = PointerId::Mouse;
    let frames = if drag.0.is_some() { LONG_DRAG } else { 10 };
    if frame == start {
        out.start.write(GrabStart {
            pointer,
            entity: target,
            point: tip,
            camera,
        });
    }
    if frame > start
        && frame <= start + frames
        && let Ok(from) = cam.world_to_viewport(cam_transform, tip)
    {
        // A long drag sweeps back and forth, so the pose keeps changing.
        let sweep = if drag.0.is_some() {
            ((frame - start) as f32 * 0.1).sin() * 3.0
        } else {
            1.0
        };
        out.moves.write(GrabMove {
            pointer,
            from,
            to: from + Vec2::new(14.0, 6.0) * sweep,
            rotate: false,
        });
    }
    if drag.0.is_some() && frame == start + frames + 1 {
        out.ends.write(GrabEnd { pointer });
    }
}

/// The messages a scripted grab writes.
#[derive(bevy::ecs::system::SystemParam)]
struct GrabWriters<'w> {
    start: MessageWriter<'w, GrabStart>,
    moves: MessageWriter<'w, GrabMove>,
    ends: MessageWriter<'w, GrabEnd>,
}

/// `--drag`: which thing the unattended run drags for long (`Some(true)`: the cactus).
#[derive(Resource)]
struct ScriptedDrag(Option<bool>);

/// A grab's figures so far.
#[derive(Default)]
struct GrabFigures {
    entity: Option<Entity>,
    started: Option<bevy::platform::time::Instant>,
    posed: bool,
    solves: u32,
    solve_ms: Vec<f64>,
}

/// Logs how a grab went: from the press (`GrabStart`) to the grabbed mesh's first
/// `DeformSolved` ("grab to first pose"), and at the release how many solves landed per second
/// while it was held. The web test reads these lines from the browser's console.
fn report_grabs(
    mut starts: MessageReader<GrabStart>,
    mut ends: MessageReader<GrabEnd>,
    mut solved: MessageReader<DeformSolved>,
    mut grab: Local<GrabFigures>,
) {
    for start in starts.read() {
        *grab = GrabFigures {
            entity: Some(start.entity),
            started: Some(bevy::platform::time::Instant::now()),
            ..default()
        };
    }
    for s in solved.read() {
        if grab.entity != Some(s.entity) {
            continue;
        }
        grab.solves += 1;
        grab.solve_ms.push(s.solve_ms);
        if !grab.posed
            && let Some(at) = grab.started
        {
            grab.posed = true;
            info!(
                "grab to first pose: {:.1} ms",
                at.elapsed().as_secs_f64() * 1e3
            );
        }
    }
    if ends.read().count() > 0
        && let Some(at) = grab.started.take()
    {
        let held = at.elapsed().as_secs_f64();
        grab.solve_ms.sort_by(f64::total_cmp);
        let median = grab.solve_ms.get(grab.solve_ms.len() / 2).copied();
        info!(
            "grab released: {} solves in {held:.2} s, {:.1} solves/s, median solve {:.2} ms",
            grab.solves,
            grab.solves as f64 / held.max(1e-9),
            median.unwrap_or(f64::NAN)
        );
        *grab = GrabFigures::default();
    }
}
