//! The apps' unattended runs (`--screenshot PATH --frames N`): save frame N of the primary
//! window to PATH, then exit 0 a few frames later (once the file is written). Whatever the
//! app shows at frame N is saved — a model that failed to load does not hold the run.

#![allow(dead_code)] // each app uses what it needs

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};

/// Frames between the screenshot request and the exit (the capture is written asynchronously).
pub const EXIT_DELAY: u32 = 15;

/// Saves frame `frames` to `path` and exits.
#[derive(Resource, Clone, Debug)]
pub struct ScreenshotPlugin {
    /// Where the PNG goes.
    pub path: String,
    /// The frame (counted from the first) to save.
    pub frames: u32,
}

impl Plugin for ScreenshotPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(self.clone())
            .init_resource::<UnattendedFrame>()
            .add_systems(First, shoot_and_exit);
    }
}

/// The frame counter of the unattended run (counted in `First`: 1 in the first frame).
#[derive(Resource, Default, Debug, Clone, Copy)]
pub struct UnattendedFrame(pub u32);

fn shoot_and_exit(
    mut commands: Commands,
    shot: Res<ScreenshotPlugin>,
    mut frame: ResMut<UnattendedFrame>,
    mut exit: MessageWriter<AppExit>,
) {
    frame.0 += 1;
    let frame = frame.0;
    if frame == shot.frames {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(shot.path.clone()));
    }
    if frame == shot.frames + EXIT_DELAY {
        exit.write(AppExit::Success);
    }
}
