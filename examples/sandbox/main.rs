//! Sandbox: load a model, paint fixed/handle regions, pose with the mouse (arcball) or a Wii
//! Remote — and a challenge mode that replays the paper's user study as a game.
//!
//! ```text
//! cargo run --release --example sandbox [-- MODEL|PATH.obj|PATH.off|PATH.gltf|PATH.glb]
//!     [--task NAME] [--demo] [--emulate[=KIND]] [--pointer] [--bend] [--screenshot PATH --frames N]
//!     [--windowless]
//! ```
//! Mouse: right-drag orbits, wheel zooms, middle-drag pans. In *Paint* mode left-drag paints
//! with the brush; in *Pose* mode left-drag turns the handle with an arcball, Shift+left-drag
//! moves it in the view plane. MotionController: hold B and turn the remote (1:1), D-pad/+/− move,
//! Home recentres. A DualSense, DualShock 4 or Switch pad works the same way (R2 / ZR the
//! clutch, PS / Home recentres; `--emulate=dualsense` and the like emulate one). `--pointer`:
//! the remote's IR camera (a pad's gyro) points too (a ring where it points,
//! filled while the sensor bar holds its heading); in *Paint* mode hold A to paint where it
//! points. Ctrl+Z / Ctrl+Y undo and redo.
//!
//! The app is a set of plugins, one per job, talking through resources, messages and states:
//!
//! | module | plugin | job |
//! |---|---|---|
//! | `camera.rs` | [`StagePlugin`] | camera, light, orbit controls |
//! | `loading.rs` | [`LoadingPlugin`] | built-in models, OBJ/OFF, glTF scenes through Bevy's loader |
//! | `parts.rs` | [`parts::ModelPartsPlugin`] | a glTF of several materials drawn part by part |
//! | `selection.rs` | [`SelectionPlugin`] | painting regions; regions → `FixedRegion` + handle |
//! | `history.rs` | [`HistoryPlugin`] | undo/redo of paint strokes and pose drags |
//! | `posing.rs` | [`PosingPlugin`] | which control (mouse or remote) drives the handle |
//! | `challenge.rs` | [`ChallengePlugin`] | target clouds, timer, results table |
//! | `files.rs` | [`FilesPlugin`] | setup save/load (RON), posed-mesh export (GLB) |
//! | `ui.rs` | [`PanelPlugin`] | the egui panel: shows state, writes requests |
//! | `scripted.rs` | [`UnattendedPlugin`] | `--demo`, `--screenshot`, `--windowless` runs |
//!
//! Modes are Bevy [`States`]: [`EditMode`] (paint or pose), [`InputMethod`] (mouse or Wii
//! Remote) and `ChallengeState` (off, running, done).

#[cfg(test)]
use bevy_wii_deform_examples::broken_gltf;
mod camera;
mod challenge;
use bevy_wii_deform_examples::cli;
mod files;
#[cfg(test)]
use bevy_wii_deform_examples::headless_gltf;
mod history;
mod loading;
use bevy_wii_deform_examples::missing_textures;
use bevy_wii_deform_examples::models;
mod parts;
mod posing;
use bevy_wii_deform_examples::remote_cursor;
mod scripted;
mod selection;
mod tasks;
mod ui;
use bevy_wii_deform_examples::undo_keys;

use std::time::Duration;

use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::settings::WgpuSettings;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use bevy_egui::EguiPlugin;
use bevy_wii_deform::controllers::ControllerKind;
use bevy_wii_deform::deform::TriMesh;
use bevy_wii_deform::prelude::*;

use camera::StagePlugin;
use challenge::ChallengePlugin;
use files::FilesPlugin;
use history::HistoryPlugin;
use loading::{LoadModel, LoadingPlugin, StartTask};
use posing::PosingPlugin;
use scripted::{Unattended, UnattendedPlugin};
use selection::SelectionPlugin;
use ui::PanelPlugin;

/// Painting regions or posing the handle.
#[derive(States, Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
enum EditMode {
    /// Left-drag paints with the brush.
    #[default]
    Paint,
    /// Left-drag (or the remote) moves the handle.
    Pose,
}

/// What drives the handle in Pose mode.
#[derive(States, Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
enum InputMethod {
    /// The library's `MouseHandleControl` (arcball).
    #[default]
    Mouse,
    /// The library's `MotionHandleControl`: a Wii Remote or a gyro pad.
    Controller,
}

impl InputMethod {
    /// The name used in the results table for the mouse; a controller's row names its kind
    /// ([`ControllerKind::name`](bevy_wii_deform::controllers::ControllerKind::name)).
    fn name(self) -> &'static str {
        match self {
            InputMethod::Mouse => "mouse",
            InputMethod::Controller => "controller",
        }
    }
}

/// The model being edited: its rest mesh and the entities that show and pose it.
#[derive(Resource)]
struct Model {
    name: String,
    mesh: TriMesh,
    diagonal: f64,
    entity: Option<Entity>,
    handle: Option<Entity>,
}

impl Default for Model {
    fn default() -> Self {
        Self {
            name: String::new(),
            mesh: TriMesh::default(),
            diagonal: 1.0,
            entity: None,
            handle: None,
        }
    }
}

/// The one-line status shown at the top of the panel (and logged).
#[derive(Resource, Default)]
struct StatusLine(String);

impl StatusLine {
    /// Shows and logs a message.
    fn set(&mut self, message: impl Into<String>) {
        self.0 = message.into();
        info!("{}", self.0);
    }
}

/// The order of the sandbox's work in a frame, all before the deformation requests.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
enum SandboxSet {
    /// Finishing loads, file drops.
    Load,
    /// Camera, painting, history, scripted input.
    Edit,
    /// Painted regions pushed into `FixedRegion` and the handle.
    Regions,
}

/// Command-line options.
struct Args {
    model: String,
    task: Option<String>,
    demo: bool,
    /// `--emulate[=KIND]`: the emulated controller instead of real ones.
    emulate: Option<ControllerKind>,
    /// `--pointer`: the remote's IR camera points (a ring where it points); A paints.
    pointer: bool,
    windowless: bool,
    unattended: Unattended,
}

const USAGE: &str = "\
usage: sandbox [MODEL] [--task NAME] [--demo] [--emulate[=KIND]] [--pointer] [--bend]
               [--screenshot PATH [--frames N]] [--windowless [--check-not-blank]]

  MODEL              a built-in model (bar, cactus, mannequin: the default) or an OBJ, OFF,
                     glTF or GLB file
  --task NAME        start a challenge task (assets/tasks/NAME.ron)
  --demo             an emulated Wii Remote plays the mannequin_wave task
  --emulate[=KIND]   a built-in emulator instead of a real controller: wiimote (default),
                     dualsense, dualsense-edge, ds4, switch-pro, joycon-l, joycon-r
  --pointer          the remote's IR camera points; A paints
  --bend             fix the lowest quarter, turn and move the top fifth (unattended runs)
  --screenshot PATH  save frame N to PATH, exit
  --frames N         the frame to save (default 30)
  --windowless       render into an image, no window (with --screenshot)
  --check-not-blank  exit non-zero when the saved frame is blank";

impl Args {
    fn parse() -> Self {
        let mut args = Args {
            model: "mannequin".into(),
            task: None,
            demo: false,
            emulate: None,
            pointer: false,
            windowless: false,
            unattended: Unattended {
                frames: 30,
                ..default()
            },
        };
        let mut parser = cli::Parser::from_env();
        while let Some(arg) = cli::next(&mut parser, USAGE) {
            match arg {
                cli::Arg::Value(model) => args.model = cli::positional(model, USAGE),
                cli::Arg::Long("task") => args.task = Some(cli::string(&mut parser, USAGE)),
                cli::Arg::Long("demo") => args.demo = true,
                cli::Arg::Long("emulate") => {
                    args.emulate = cli::emulated_controller(
                        &mut parser,
                        Some(ControllerKind::WiiRemote),
                        USAGE,
                    )
                }
                cli::Arg::Long("pointer") => args.pointer = true,
                cli::Arg::Long("windowless") => args.windowless = true,
                cli::Arg::Long("bend") => args.unattended.bend = true,
                cli::Arg::Long("check-not-blank") => args.unattended.check_not_blank = true,
                cli::Arg::Long("screenshot") => {
                    args.unattended.screenshot = Some(cli::string(&mut parser, USAGE))
                }
                cli::Arg::Long("frames") => args.unattended.frames = cli::value(&mut parser, USAGE),
                other => cli::unexpected(other, USAGE),
            }
        }
        if args.demo && args.task.is_none() {
            args.task = Some("mannequin_wave".into());
        }
        if args.demo || args.windowless {
            args.emulate.get_or_insert(ControllerKind::WiiRemote);
        }
        args.unattended.demo = args.demo;
        args.unattended.windowless = args.windowless;
        args
    }
}

/// Bevy's default plugins: with a window, or rendering into an image (`--windowless`).
fn add_bevy(app: &mut App, windowless: bool) {
    let render = RenderPlugin {
        synchronous_pipeline_compilation: true,
        render_creation: WgpuSettings::default().into(),
        ..default()
    };
    // Models may be loaded from anywhere (dropped files, paths outside `assets/`).
    let assets = AssetPlugin {
        unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow,
        ..default()
    };
    if windowless {
        app.add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: None,
                    exit_condition: ExitCondition::DontExit,
                    ..default()
                })
                .set(render)
                .set(assets)
                .disable::<WinitPlugin>(),
        )
        .add_plugins(bevy::app::ScheduleRunnerPlugin::run_loop(
            Duration::from_millis(5),
        ));
    } else {
        app.add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        title: "bevy_wii_deform sandbox".into(),
                        resolution: (1280, 800).into(),
                        ..default()
                    }),
                    ..default()
                })
                .set(render)
                .set(assets),
        )
        .add_plugins((EguiPlugin::default(), PanelPlugin));
    }
}

fn main() -> AppExit {
    let args = Args::parse();
    let mut app = App::new();
    add_bevy(&mut app, args.windowless);
    let wiimote = if args.pointer {
        app.add_plugins(remote_cursor::RemoteCursorPlugin {
            emulated: args.emulate.is_some(),
        });
        remote_cursor::pointing_remote(args.emulate)
    } else {
        remote_cursor::controllers(args.emulate)
    };
    app.add_plugins((
        DeformPlugin::default(),
        wiimote,
        MotionControlPlugin,
        MouseControlPlugin,
        MeshPickingPlugin,
        missing_textures::MissingTexturesPlugin,
    ))
    .init_state::<EditMode>()
    .insert_state(if args.demo {
        InputMethod::Controller
    } else {
        InputMethod::Mouse
    })
    .init_resource::<Model>()
    .init_resource::<StatusLine>()
    .configure_sets(
        Update,
        (SandboxSet::Load, SandboxSet::Edit, SandboxSet::Regions)
            .chain()
            .before(DeformSystems::Request),
    )
    .add_plugins((
        StagePlugin { demo: args.demo },
        LoadingPlugin,
        parts::ModelPartsPlugin,
        SelectionPlugin,
        HistoryPlugin,
        PosingPlugin,
        ChallengePlugin,
        FilesPlugin,
        UnattendedPlugin(args.unattended),
    ));
    app.world_mut().write_message(LoadModel(args.model));
    if let Some(task) = args.task {
        app.world_mut().write_message(StartTask(task));
    }
    app.run()
}
