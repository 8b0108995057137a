//! A motion controller as a pointer in the example apps: the library's
//! `ControllerPointerPlugin` (point, hold A — Cross on a Sony pad, A on a Switch one — to grab
//! there, turn to turn the grab 1:1, add the clutch to turn only) and a ring drawn where the
//! controller points, filled while a sensor bar holds a Wii Remote's heading. A Wii Remote
//! points with its IR camera, a pad with its gyro (Home / PS recentres). `--pointer
//! emulated[=KIND]` aims an emulated controller in a slow figure-eight over the screen.

use std::sync::Arc;

use bevy::prelude::*;
use bevy_wii_deform::controllers::ControllerKind;
use bevy_wii_deform::controllers::wiimote::FnMotion;
use bevy_wii_deform::controllers::wiimote::ir::{PointerSetup, aimed_at};
use bevy_wii_deform::ecs::{
    ControllerEmulators, ControllerPointerPlugin, MotionController, MotionControllerPlugin,
};

/// The controllers: real ones (`None`), or one emulated controller of that kind.
pub fn controllers(emulated: Option<ControllerKind>) -> MotionControllerPlugin {
    match emulated {
        None => MotionControllerPlugin::default(),
        Some(ControllerKind::WiiRemote) => MotionControllerPlugin::emulated(),
        Some(pad) => MotionControllerPlugin::emulated_pad(pad),
    }
}

/// The controller source for `--pointer [emulated[=KIND]]`, with the IR pointer in the
/// default room (a 42-inch screen seen from 2 m, the bar above it) and the gyro pointer for
/// pads.
pub fn pointing_remote(emulated: Option<ControllerKind>) -> MotionControllerPlugin {
    controllers(emulated).with_pointer(PointerSetup::default())
}

/// The remote's picking pointer and its on-screen ring (add with [`pointing_remote`]).
pub struct RemoteCursorPlugin {
    /// Aim the emulated remote over the screen (with `pointing_remote(true)`).
    pub emulated: bool,
}

impl Plugin for RemoteCursorPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(ControllerPointerPlugin)
            .add_systems(Startup, spawn_cursor)
            .add_systems(Update, move_cursor);
        if self.emulated {
            app.add_systems(Startup, sweep_emulated_remote);
        }
    }
}

#[derive(Component)]
struct RemoteCursor;

/// Seconds the emulated controller rests before it sweeps.
const REST_S: f64 = 3.0;

const RING: f32 = 18.0;

fn spawn_cursor(mut commands: Commands) {
    commands.spawn((
        Node {
            position_type: PositionType::Absolute,
            width: px(RING),
            height: px(RING),
            border: UiRect::all(px(3)),
            border_radius: BorderRadius::MAX,
            ..default()
        },
        BorderColor::all(Color::srgb(0.3, 0.8, 1.0)),
        BackgroundColor(Color::NONE),
        Visibility::Hidden,
        RemoteCursor,
    ));
}

/// The ring follows the first remote that points somewhere; hidden when none does; filled
/// while the bar holds the heading.
fn move_cursor(
    remotes: Query<&MotionController>,
    window: Single<&Window, With<bevy::window::PrimaryWindow>>,
    mut cursor: Single<(&mut Node, &mut Visibility, &mut BackgroundColor), With<RemoteCursor>>,
) {
    let pointing = remotes.iter().find(|w| w.pointer.is_some());
    let (node, visibility, fill) = &mut *cursor;
    match pointing.and_then(|w| w.pointer.map(|p| (p, w.heading_from_bar))) {
        Some((p, held)) => {
            let at = p * Vec2::new(window.width(), window.height());
            node.left = px(at.x - RING / 2.0);
            node.top = px(at.y - RING / 2.0);
            **visibility = Visibility::Visible;
            fill.0 = if held {
                Color::srgba(0.3, 0.8, 1.0, 0.6)
            } else {
                Color::NONE
            };
        }
        None => **visibility = Visibility::Hidden,
    }
}

/// The emulated controller rests on the table for its first [`REST_S`] seconds (a pad's gyro
/// bias is estimated at rest: without a camera nothing else holds its heading), then aims at a
/// slow figure-eight over the screen's middle (standing at the room's standing point, rolled a
/// little), so the ring has something to show.
fn sweep_emulated_remote(emulators: Res<ControllerEmulators>) {
    let setup = PointerSetup::default();
    for controls in &emulators.0 {
        controls.set_motion(Arc::new(FnMotion(move |t: f64| {
            let t = (t - REST_S).max(0.0);
            let spot = glam::DVec2::new(0.5 + 0.25 * (0.2 * t).sin(), 0.5 + 0.15 * (0.4 * t).sin());
            let target = setup.screen_point(spot);
            let roll = 0.2 * (0.3 * t).sin();
            (aimed_at(glam::DVec3::ZERO, target, roll), glam::DVec3::ZERO)
        })));
    }
}
