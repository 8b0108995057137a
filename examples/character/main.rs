//! Pose a rigged glTF character with the mouse: the Fox (or any rigged glTF given by path),
//! loaded through Bevy's glTF loader and made poseable with one component.
//!
//! ```text
//! cargo run --release --example character [-- PATH.glb] [--screenshot PATH --frames N]
//! ```
//! * **Left-drag on the character**: grabs the vertices around the point under the cursor
//!   (on the *posed* mesh: picking ray-casts the CPU-skinned positions) and drags them in the
//!   view plane; the skeleton follows, As-Rigid-As-Possible. Release: the pose stays.
//! * **T**: the tail on spring bones or not (on at start: it swings as the Fox is dragged).
//! * **F**: pin / unpin the feet (the joints nearest the ground; pinned at start).
//! * **S** / **L**: save the pose (RON + a one-keyframe glTF clip) to `poses/` / load the RON.
//! * **R**: back to the pose the character was loaded in.
//! * **Timeline** (bottom panel): scrub, play/loop, set/delete/move keys (step, linear or
//!   cubic), import one of the model's own clips, export the clip to `poses/clip.glb`.
//! * **Body** (right panel): joint limits from the humanoid preset, mirrored edits (an
//!   effector on one side drives its mirror image) and feet planted by position effectors
//!   (ankles free) instead of pinned. **Right-click** on the character plants the joint nearest
//!   the click (a position effector; right-click again to lift it); **Alt + right-click**
//!   anywhere makes the head look there (again by the point to let go).
//! * **Poses** (right panel): the pose library in `poses/library/`: apply, apply mirrored,
//!   blend two, save the current pose by name. **Ctrl+Z / Ctrl+Y**: undo / redo.
//! * **`--author-demo OUT.glb`**: poses the character by three scripted grabs, keys them at
//!   0, 0.5 and 1 s, exports the clip, plays it back through Bevy's glTF loader and prints
//!   the playback error as JSON (see [`authoring`]).
//! * **`--pointer [emulated[=KIND]]`**: a motion controller points — a Wii Remote with its IR
//!   camera, a DualSense, DualShock 4 or Switch pad with its gyro (a ring where it points):
//!   hold A (Cross) on the character to grab there, point elsewhere to drag, turn the
//!   controller to turn the grab 1:1, add the clutch (B, R2, ZR) to turn without moving.
//! * **`--clip PATH [--animation NAME] [--map FILE]`**: a clip made for another skeleton (a
//!   BVH, or another glTF character's animation) retargeted onto the character with its feet
//!   kept planted (the library's `RetargetPlugin`) and played by its `AnimationPlayer`; a
//!   ring round each foot shows the source's contacts and a cross under each sole on the
//!   ground the character's own, **K** bakes it again with contacts off
//!   (or on) to compare. The panel's "Clip from a file" section does the same for a file
//!   named there.
//! * **`--remote [emulated[=KIND]]`**: a motion controller drives a handle on the head: hold
//!   the clutch and turn it to turn the head 1:1, D-pad to move it (`emulated=dualsense` and
//!   the like for the built-in emulators).
//!
//! The app is plugins, one per job: [`scene::ScenePlugin`] (camera, light, the
//! character), [`grab::CharacterGrabPlugin`], [`files::PoseFilesPlugin`],
//! [`timeline::TimelinePlugin`], [`history::UndoPlugin`], [`ui::UiPlugin`] (the panels) and
//! [`hud::HudPlugin`]; [`unattended::UnattendedPlugin`] scripts a grab for screenshots and
//! [`authoring::AuthorDemoPlugin`] the `--author-demo` check.
//!
//! Fox: model by PixelMannen (CC0), rigging and animation by @tomkranis (CC-BY 4.0), from the
//! glTF Sample Assets.

mod authoring;
mod body;
mod clip;
use bevy_wii_deform_examples::cli;
mod files;
mod grab;
mod history;
mod hud;
mod library;
use bevy_wii_deform_examples::missing_textures;
use bevy_wii_deform_examples::remote_cursor;
mod scene;
use bevy_wii_deform_examples::springy_tails;
mod standing;
mod timeline;
mod ui;
mod unattended;
use bevy_wii_deform_examples::undo_keys;

use bevy::prelude::*;
use bevy_wii_deform::controllers::ControllerKind;
use bevy_wii_deform::prelude::*;

/// Command-line options.
#[derive(Resource, Debug, Clone)]
pub struct Args {
    /// The glTF file, as Bevy's asset server loads it (relative to `assets/`, or absolute).
    pub model: String,
    /// `--screenshot PATH`: script a grab, save frame `frames`, exit.
    pub screenshot: Option<String>,
    /// Frames before the screenshot.
    pub frames: u32,
    /// `--remote [emulated[=KIND]]`: drive a head handle with a motion controller.
    pub remote: Option<MotionControllerPlugin>,
    /// `--pointer [emulated[=KIND]]`: a motion controller as a pointer (a Wii Remote's IR
    /// camera with a sensor bar above a 42-inch screen seen from 2 m, a pad's gyro): point,
    /// hold A to grab, turn to turn, the clutch to turn only. `Some(Some(kind))`: an emulated
    /// controller sweeping over the screen.
    pub pointer: Option<Option<ControllerKind>>,
    /// `--author-demo OUT.glb`: author a three-key clip by script, export, play back, exit.
    pub author_demo: Option<String>,
    /// `--ground`: stand on the stage with contacts and balance from the start (G and B
    /// toggle them).
    pub ground: bool,
    /// `--clip PATH [--animation NAME] [--map FILE]`: a clip made for another skeleton,
    /// retargeted onto the character and played.
    pub clip: Option<ClipArgs>,
}

/// The `--clip` options.
#[derive(Debug, Clone)]
pub struct ClipArgs {
    /// A `.bvh` file, or a glTF/GLB character whose animation is the clip.
    pub source: std::path::PathBuf,
    /// The glTF animation by name (the first without it).
    pub animation: Option<String>,
    /// A chain map (RON) for skeletons that are not humanoids by their joints' names.
    pub map: Option<std::path::PathBuf>,
}

const USAGE: &str = "\
usage: character [MODEL.glb] [--model MODEL.glb] [--remote [emulated[=KIND]]] [--pointer [emulated[=KIND]]]
                 [--screenshot PATH [--frames N]] [--author-demo OUT.glb] [--ground]
                 [--clip PATH [--animation NAME] [--map FILE]]

  MODEL.glb             a rigged glTF (default: the Fox, assets/models/Fox.glb); a path
                        relative to the working directory, to assets/, or absolute
  --remote [emulated]   a motion controller turns a handle on the head (emulated: the built-in
                        emulator; emulated=KIND for a pad: dualsense, ds4, switch-pro, joycon-l,
                        joycon-r)
  --pointer [emulated]  a motion controller points (IR camera or gyro); A / Cross grabs
  --screenshot PATH     script a grab, save frame N to PATH, exit
  --frames N            the frame to save (default 120)
  --author-demo OUT.glb author a three-key clip by script, export it, play it back, exit
  --ground              stand on the stage with contacts and balance (G, B toggle them)
  --clip PATH           play a clip made for another skeleton (a .bvh, or a glTF character's
                        animation: --animation NAME), retargeted with the feet kept planted;
                        --map FILE maps non-humanoid skeletons by chains (assets/retarget/)";

impl Args {
    fn parse() -> Self {
        let mut args = Args {
            model: "models/Fox.glb".into(),
            screenshot: None,
            frames: 120,
            remote: None,
            pointer: None,
            author_demo: None,
            ground: false,
            clip: None,
        };
        let (mut animation, mut map) = (None, None);
        let mut parser = cli::Parser::from_env();
        while let Some(arg) = cli::next(&mut parser, USAGE) {
            match arg {
                cli::Arg::Value(path) => {
                    args.model = cli::asset_path(&cli::positional(path, USAGE))
                }
                cli::Arg::Long("model") => {
                    args.model = cli::asset_path(&cli::string(&mut parser, USAGE))
                }
                cli::Arg::Long("screenshot") => {
                    args.screenshot = Some(cli::string(&mut parser, USAGE))
                }
                cli::Arg::Long("frames") => args.frames = cli::value(&mut parser, USAGE),
                cli::Arg::Long("ground") => args.ground = true,
                cli::Arg::Long("clip") => {
                    args.clip = Some(ClipArgs {
                        source: cli::string(&mut parser, USAGE).into(),
                        animation: None,
                        map: None,
                    })
                }
                cli::Arg::Long("animation") => animation = Some(cli::string(&mut parser, USAGE)),
                cli::Arg::Long("map") => map = Some(cli::string(&mut parser, USAGE).into()),
                cli::Arg::Long("author-demo") => {
                    args.author_demo = Some(cli::string(&mut parser, USAGE))
                }
                cli::Arg::Long("pointer") => {
                    args.pointer = Some(cli::emulated_controller(&mut parser, None, USAGE))
                }
                cli::Arg::Long("remote") => {
                    let emulated = cli::emulated_controller(&mut parser, None, USAGE);
                    args.remote = Some(remote_cursor::controllers(emulated))
                }
                other => cli::unexpected(other, USAGE),
            }
        }
        match &mut args.clip {
            Some(clip) => (clip.animation, clip.map) = (animation, map),
            None if animation.is_some() || map.is_some() => {
                cli::fail("--animation and --map go with --clip", USAGE)
            }
            None => {}
        }
        args
    }
}

fn main() {
    let args = Args::parse();
    let mut app = App::new();
    if let Some(remote) = args.remote.clone() {
        app.add_plugins((remote, MotionControlPlugin, grab::RemoteHeadPlugin));
    } else if let Some(emulated) = args.pointer {
        app.add_plugins((
            remote_cursor::pointing_remote(emulated),
            remote_cursor::RemoteCursorPlugin {
                emulated: emulated.is_some(),
            },
        ));
    }
    app.add_plugins(DefaultPlugins.set(AssetPlugin {
        // A model may be given by any path (see `cli::asset_path`).
        unapproved_path_mode: bevy::asset::UnapprovedPathMode::Allow,
        // No `.meta` files beside the models (on the web each lookup would be a 404).
        meta_check: bevy::asset::AssetMetaCheck::Never,
        ..default()
    }))
    .add_plugins(PosePlugin)
    .insert_resource(args)
    .add_plugins((
        scene::ScenePlugin,
        grab::CharacterGrabPlugin,
        body::EffectorPlacementPlugin,
        files::PoseFilesPlugin,
        timeline::TimelinePlugin,
        history::UndoPlugin,
        ui::UiPlugin,
        hud::HudPlugin,
        unattended::UnattendedPlugin,
        authoring::AuthorDemoPlugin,
        missing_textures::MissingTexturesPlugin,
        standing::StandingPlugin,
        springy_tails::SpringyTailsPlugin,
        clip::ClipFromFilePlugin,
    ))
    .run();
}
