//! What the playground needs besides the game itself: its command line, a motion
//! controller as a pointer (`--pointer [emulated[=KIND]]`: a Wii Remote's IR camera or a
//! pad's gyro; point at a thing, hold A / Cross, move and turn the controller, release — the
//! library's `WiimotePointerPlugin`, with a ring drawn where it points),
//! and the unattended run (`--screenshot PATH --frames N`: a scripted grab bends the bar, frame
//! N is saved, the app exits).

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::controllers::ControllerKind;
use bevy_wii_deform::prelude::*;

use crate::screenshot::{ScreenshotPlugin, UnattendedFrame};
use crate::{Bar, cli, remote_cursor};

const USAGE: &str = "\
usage: playground [--pointer [emulated[=KIND]]] [--wobble] [--screenshot PATH [--frames N]]

  --pointer [emulated]  a motion controller points: a Wii Remote with its IR camera, a pad
                        with its gyro (emulated: a scripted Wii Remote; emulated=KIND: a
                        scripted dualsense, ds4, switch-pro, joycon-l or joycon-r)
  --wobble              things wobble and spring back when let go (W switches it)
  --screenshot PATH     bend the bar by a scripted grab, save frame N to PATH, exit
  --frames N            the frame to save (default 60)";

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
                other => cli::unexpected(other, USAGE),
            }
        }
        options
    }
}

/// The pointer and the unattended run, as the options ask.
pub struct HarnessPlugin(pub Options);

impl Plugin for HarnessPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(Wobble(self.0.wobble))
            .add_systems(Update, (switch_wobble, make_things_wobble).chain());
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

/// Grabs the bar's tip at a third of the run and drags it for ten frames.
fn grab_the_bar(
    frame: Res<UnattendedFrame>,
    shot: Res<ScreenshotPlugin>,
    bar: Single<(Entity, &GlobalTransform), With<Bar>>,
    camera: Single<(Entity, &Camera, &GlobalTransform)>,
    mut grab: MessageWriter<GrabStart>,
    mut moves: MessageWriter<GrabMove>,
) {
    let frame = frame.0;
    let start = shot.frames / 3;
    let (bar, bar_transform) = *bar;
    let (camera, cam, cam_transform) = *camera;
    let tip = bar_transform.transform_point(Vec3::new(0.0, 1.2, 0.0));
    let pointer = PointerId::Mouse;
    if frame == start {
        grab.write(GrabStart {
            pointer,
            entity: bar,
            point: tip,
            camera,
        });
    }
    if frame > start
        && frame <= start + 10
        && let Ok(from) = cam.world_to_viewport(cam_transform, tip)
    {
        moves.write(GrabMove {
            pointer,
            from,
            to: from + Vec2::new(14.0, 6.0),
            rotate: false,
        });
    }
}
