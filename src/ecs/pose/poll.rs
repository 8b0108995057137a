//! Collecting landed pose solves (stored in `PosedSkeleton::pose`, settling re-queued) and
//! showing each timeline's pose at its time.

use std::sync::Arc;

use bevy::prelude::*;

use super::apply::additive_layer;
use super::plugin::PoseState;
use super::request::spawn_pose_solve;
use super::{
    PoseBlend, PoseBlendMode, PoseFailed, PoseSolved, PoseStatus, PoseTimeline, Poseable,
    PosedSkeleton,
};
use crate::ecs::DeformPhase;
use crate::pose::{PoseSolution, PoseSolver};

/// What [`poll_pose_solves`] reads and writes of a character.
type PolledCharacter = (
    Entity,
    &'static Poseable,
    &'static mut PosedSkeleton,
    &'static mut PoseState,
    &'static mut PoseStatus,
    Option<&'static PoseBlend>,
);

/// Stores finished solves in [`PosedSkeleton::pose`]; starts the pending one.
pub(super) fn poll_pose_solves(
    mut characters: Query<PolledCharacter>,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
) {
    for (entity, poseable, mut posed, mut state, mut status, blend) in &mut characters {
        let state = state.bypass_change_detection();
        let Some(result) = state.solve.poll() else {
            continue;
        };
        // Released (no handles left) and the app set a pose since: it wins over the settling
        // of the old targets.
        let set_by_app = state.written.as_ref().is_some_and(|w| *w != posed.pose);
        if state.key.is_none() && set_by_app {
            state.pending = None;
            state.running = None;
            status.phase = DeformPhase::Idle;
            continue;
        }
        match result {
            Ok((solver, solution, ms)) => {
                // Not converged (every iteration used, still improving): keep settling with
                // the same targets until the tolerance stops it.
                let settling = !solution.stats.cancelled
                    && solution.stats.iterations >= poseable.max_iterations.max(1);
                if settling && state.pending.is_none() {
                    state.pending = state.running.take();
                }
                store_landed(&mut posed, state, &mut status, blend, solver, solution, ms);
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
        if state.pending.is_some() {
            spawn_pose_solve(state, &posed, poseable, &mut status);
        }
    }
}

/// Stores a landed solve: the status, the pose (as the layer over the animation under an
/// additive blend), and the solver and solution the next solve warm-starts from.
pub(super) fn store_landed(
    posed: &mut PosedSkeleton,
    state: &mut PoseState,
    status: &mut PoseStatus,
    blend: Option<&PoseBlend>,
    solver: Arc<PoseSolver>,
    solution: PoseSolution,
    ms: f64,
) {
    status.iterations = solution.stats.iterations;
    status.energy = solution
        .stats
        .energies
        .last()
        .copied()
        .unwrap_or(solution.stats.initial_energy);
    status.solve_ms = ms;
    status.solves += 1;
    status.error = None;
    status.phase = if state.pending.is_some() {
        DeformPhase::Solving
    } else {
        DeformPhase::Idle
    };
    let pose = match blend {
        Some(b) if b.mode == PoseBlendMode::Additive => {
            additive_layer(posed, &state.blend, b, &solution.pose)
        }
        _ => solution.pose.clone(),
    };
    posed.pose = pose.clone();
    state.written = Some(pose);
    state.solver = Some(solver);
    state.last = Some(Arc::new(solution));
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
