//! In-frame solves ([`PoseInFrame`]): the targets a frame's `Update` set are solved in
//! `PostUpdate`, after animation and before transform propagation, for every such character
//! in parallel on Bevy's compute pool; the pose is then written to the joints by `apply.rs`
//! in the same frame.

use std::sync::Arc;
use std::time::Instant;

use bevy::prelude::*;

use super::plugin::PoseState;
use super::poll::store_landed;
use super::{
    PoseBlend, PoseFailed, PoseInFrame, PoseSolved, PoseStatus, Poseable, PoseableError,
    PosedSkeleton,
};
use crate::pose::{
    PoseSolution, PoseSolveOptions, PoseSolver, PoseSolverSettings, PoseStart, SkeletonPose,
};

/// What an in-frame solve reads and writes of a character.
type InFrameCharacter = (
    Entity,
    &'static Poseable,
    &'static PoseInFrame,
    &'static mut PosedSkeleton,
    &'static mut PoseState,
    &'static mut PoseStatus,
    Option<&'static PoseBlend>,
);

/// Solves the pending targets of every in-frame character (in parallel) and stores the poses.
pub(super) fn solve_in_frame(
    mut characters: Query<InFrameCharacter>,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
) {
    characters.par_iter_mut().for_each(
        |(_, poseable, in_frame, mut posed, mut state, mut status, blend)| {
            let state = state.bypass_change_detection();
            let Some(outcome) = solve_pending(state, &posed, poseable, in_frame) else {
                return;
            };
            state.in_frame_outcome = Some(match outcome {
                Ok((solver, solution, ms)) => {
                    store_landed(&mut posed, state, &mut status, blend, solver, solution, ms);
                    Ok(ms)
                }
                Err(error) => {
                    status.error = Some(error.clone());
                    Err(error)
                }
            });
        },
    );
    for (entity, .., mut state, status, _) in &mut characters {
        match state.bypass_change_detection().in_frame_outcome.take() {
            Some(Ok(ms)) => {
                solved.write(PoseSolved {
                    entity,
                    iterations: status.iterations,
                    energy: status.energy,
                    solve_ms: ms,
                });
            }
            Some(Err(error)) => {
                // The last good pose is kept.
                warn!("Poseable {entity}: {error}");
                failed.write(PoseFailed { entity, error });
            }
            None => {}
        }
    }
}

type Solved = Result<(Arc<PoseSolver>, PoseSolution, f64), PoseableError>;

/// Solves the pending constraints within the frame's iteration budget (`None`: nothing
/// pending), warm-started from the last solve when its solver still fits.
fn solve_pending(
    state: &mut PoseState,
    posed: &PosedSkeleton,
    poseable: &Poseable,
    in_frame: &PoseInFrame,
) -> Option<Solved> {
    let constraints = state.pending.take()?;
    let reference = state.reference.clone()?;
    let t0 = Instant::now();
    let reuse = state.solver.clone().filter(|s| s.accepts(&constraints));
    let start: Option<SkeletonPose> = state.start.take();
    let solve = || -> Solved {
        let warm = reuse.is_some() && start.is_none();
        let solver = match reuse {
            Some(s) => s,
            None => Arc::new(PoseSolver::new(
                posed.model.clone(),
                &constraints,
                &reference,
                PoseSolverSettings::default(),
            )?),
        };
        let current = start.unwrap_or_else(|| posed.pose.clone());
        let from = match state.last.as_deref() {
            Some(last) if warm => PoseStart::Warm(last),
            _ => PoseStart::Pose(&current),
        };
        let options = PoseSolveOptions {
            max_iterations: in_frame.iterations.max(1),
            tolerance: poseable.tolerance.max(0.0) as f64,
        };
        let solution = solver.solve(&constraints, &options, from, &|| false)?;
        Ok((solver, solution, t0.elapsed().as_secs_f64() * 1e3))
    };
    let outcome = solve();
    // The whole budget used and still improving: the same targets go on next frame
    // (warm-started), so a pose whose targets stop moving settles over a few frames.
    if let Ok((_, solution, _)) = &outcome
        && solution.stats.iterations >= in_frame.iterations.max(1)
        && state.pending.is_none()
    {
        state.pending = Some(constraints);
    }
    Some(outcome)
}
