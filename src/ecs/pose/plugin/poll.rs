//! Collecting landed pose solves (stored in `PosedSkeleton::pose`, settling re-queued) and
//! showing each timeline's pose at its time.

use bevy::prelude::*;

use super::super::blend::BlendMemory;
use super::super::{
    PoseBlend, PoseFailed, PoseGround, PoseSolved, PoseStatus, PoseTimeline, Poseable,
    PosedSkeleton,
};
use super::ground_contacts::FloorRecast;
use super::solve::{SolveJob, store_landed};
use super::state::{LastSolve, PoseDrivers, PoseSolves};
use crate::ecs::{DeformPhase, SceneGround};

/// What [`poll_pose_solves`] reads and writes of a character.
type PolledCharacter = (
    Entity,
    &'static Poseable,
    &'static mut PosedSkeleton,
    (
        &'static PoseDrivers,
        &'static mut PoseSolves,
        &'static mut LastSolve,
        &'static BlendMemory,
    ),
    &'static mut PoseStatus,
    (Option<&'static PoseBlend>, Option<&'static PoseGround>),
);

/// Stores finished background solves in [`PosedSkeleton::pose`]; starts the pending one.
pub(super) fn poll_pose_solves(
    mut characters: Query<PolledCharacter>,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
    ground: Option<Res<SceneGround>>,
) {
    for (entity, poseable, mut posed, parts, mut status, (blend, standing)) in &mut characters {
        let (drivers, mut solves, mut last, memory) = parts;
        let solves = solves.bypass_change_detection();
        let last = last.bypass_change_detection();
        let Some(result) = solves.task.poll() else {
            continue;
        };
        // Released (no handles left) and the app set a pose since: it wins over the settling
        // of the old targets.
        let set_by_app = last.written.as_ref().is_some_and(|w| *w != posed.pose);
        if drivers.key.is_none() && set_by_app {
            solves.pending = None;
            solves.running = None;
            status.phase = DeformPhase::Idle;
            continue;
        }
        match result {
            Ok(landed) => {
                // Not converged (every iteration used, still improving): keep settling with
                // the same targets until the tolerance stops it.
                let settling = !landed.solution.stats.cancelled
                    && landed.solution.stats.iterations >= poseable.max_iterations.max(1);
                if settling && solves.pending.is_none() {
                    solves.pending = solves.running.take();
                }
                let ms = landed.ms;
                let more = solves.pending.is_some();
                let blending = (blend, memory, None);
                store_landed(&mut posed, last, &mut status, blending, landed, more);
                solved.write(PoseSolved {
                    entity,
                    iterations: status.iterations,
                    energy: status.energy,
                    solve_ms: ms,
                });
            }
            Err(error) => {
                // The last good pose is kept.
                warn!("Poseable {entity}: {error}");
                status.error = Some(error.clone());
                status.phase = DeformPhase::Idle;
                failed.write(PoseFailed { entity, error });
            }
        }
        if solves.pending.is_some() {
            let options = poseable.solve_options();
            let recast = standing
                .zip(ground.as_deref())
                .map(|(settings, ground)| FloorRecast::new(settings, ground, &posed));
            let job = (options, recast);
            SolveJob::launch(solves, drivers, last, &posed, job, &mut status);
        }
    }
}

/// Advances playing timelines; writes the pose of every timeline that changed.
pub(super) fn show_timelines(
    time: Res<Time>,
    mut characters: Query<(&mut PoseTimeline, &mut PosedSkeleton)>,
) {
    for (mut timeline, mut posed) in &mut characters {
        if timeline.playing {
            timeline.advance(time.delta_secs());
        }
        if !timeline.is_changed() {
            continue;
        }
        if let Some(pose) = timeline.pose_now(&posed)
            && pose != posed.pose
        {
            posed.pose = pose;
        }
    }
}
