//! `--screenshot PATH --frames N`: once the character is ready, keys its pose at 0 s, grabs the
//! highest point of the head region and drags it sideways and up over 30 frames, keys the
//! result at 1 s, saves frame N, exits 0. A character that cannot be posed (its file failed,
//! it has no skin) does not hold the run: the frame is saved as the app shows it (the status
//! line says why) and the app exits all the same.

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_wii_deform::prelude::*;

use crate::Args;
use crate::grab::{grab_at, top_point};
use crate::scene::Character;

/// Scripted grab and screenshot.
pub struct UnattendedPlugin;

impl Plugin for UnattendedPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Update, script.before(PoseSystems::Request));
    }
}

/// Frames (× `--frames`) the run waits for a character that is still loading before it
/// saves the frame without one.
const PATIENCE: u32 = 4;

#[derive(Default)]
struct Script {
    frame: u32,
    start: Option<u32>,
    shot: Option<u32>,
    grabbed: Option<(Entity, Vec3)>,
}

#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
fn script(
    mut commands: Commands,
    mut state: Local<Script>,
    args: Res<Args>,
    mut character: Query<(Entity, &PosedSkeleton, Option<&mut PoseTimeline>), With<Character>>,
    statuses: Query<&PoseStatus, With<Character>>,
    mut handles: Query<(&DeformHandle, &mut Transform)>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(path) = args.screenshot.clone() else {
        return;
    };
    state.frame += 1;
    let frame = state.frame;
    if let Some((entity, posed, timeline)) = character.iter_mut().next() {
        let start = *state.start.get_or_insert(frame + 10);
        let shot = *state.shot.get_or_insert(start.max(args.frames));
        if let Some(mut timeline) = timeline
            && (frame == start || frame + 5 == shot)
        {
            timeline.time = if frame == start { 0.0 } else { 1.0 };
            let _ = timeline.set_key(posed);
        }
        if frame == start {
            let top = top_point(posed);
            let size = posed.model.topology().bounding_diagonal() as f32;
            let hit = top - Vec3::Y * 0.05 * size;
            let handle = grab_at(&mut commands, entity, posed, hit);
            state.grabbed = Some((handle, Vec3::new(0.03, 0.07, 0.02) * size));
        }
    } else if state.shot.is_none() {
        let failed = statuses.iter().any(|s| s.phase == DeformPhase::Failed);
        if (failed && frame >= args.frames) || frame >= args.frames.max(1) * PATIENCE {
            warn!("no poseable character: saving the frame as it is");
            state.shot = Some(frame);
        }
    }
    if let Some((handle, shift)) = state.grabbed
        && let Some(start) = state.start
        && frame > start
        && let Ok((h, mut transform)) = handles.get_mut(handle)
        && let Some(pivot) = h.pivot
    {
        let s = ((frame - start) as f32 / 30.0).min(1.0);
        let target = pivot + shift * s;
        if transform.translation != target {
            transform.translation = target;
        }
    }
    let Some(shot) = state.shot else {
        return;
    };
    if frame == shot {
        commands
            .spawn(Screenshot::primary_window())
            .observe(save_to_disk(path));
    }
    if frame == shot + 15 {
        exit.write(AppExit::Success);
    }
}
