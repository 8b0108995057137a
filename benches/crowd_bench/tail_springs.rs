//! `crowd_bench --springs`: every Fox's tail on spring bones (`springy_tails::tail_springs`:
//! the joints named "tail"); the wall time of `SpringSystems::Simulate` in each frame.

use std::time::Instant;

use bevy::prelude::*;
use bevy::transform::TransformSystems;
use bevy_wii_deform::ecs::{SpringPlugin, SpringStatus, SpringSystems};
use bevy_wii_deform::prelude::PoseSystems;

/// When this frame's springs started, and every measured frame's spring time, ms.
#[derive(Resource, Default)]
pub struct SpringClock {
    started: Option<Instant>,
    frames_ms: Vec<f64>,
    /// Frames are recorded only while this is set.
    pub measuring: bool,
}

/// Adds the spring plugin and its clock (before the app is finished).
pub fn add(app: &mut App) {
    app.add_plugins(SpringPlugin)
        .init_resource::<SpringClock>()
        .add_systems(
            PostUpdate,
            (
                start
                    .after(PoseSystems::Apply)
                    .before(SpringSystems::Simulate),
                stop.after(SpringSystems::Simulate)
                    .before(TransformSystems::Propagate),
            ),
        );
}

fn start(mut clock: ResMut<SpringClock>) {
    clock.started = Some(Instant::now());
}

fn stop(mut clock: ResMut<SpringClock>) {
    if let (true, Some(t0)) = (clock.measuring, clock.started) {
        clock.frames_ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
}

/// The JSON keys of the spring run: chains and joints across the characters, and the median
/// spring time per frame.
pub fn report(app: &mut App, roots: &[Entity]) -> serde_json::Map<String, serde_json::Value> {
    let (chains, joints) = roots
        .iter()
        .filter_map(|&r| app.world().get::<SpringStatus>(r))
        .fold((0, 0), |(c, j), s| (c + s.chains, j + s.joints));
    let mut frames = std::mem::take(&mut app.world_mut().resource_mut::<SpringClock>().frames_ms);
    frames.sort_by(f64::total_cmp);
    let median = frames.get(frames.len() / 2).copied().unwrap_or(f64::NAN);
    let mut out = serde_json::Map::new();
    out.insert("spring_chains".into(), chains.into());
    out.insert("spring_joints".into(), joints.into());
    out.insert("spring_ms_per_frame_median".into(), median.into());
    out
}
