//! In-frame solves ([`PoseInFrame`]): the targets a frame's `Update` set are solved in
//! `PostUpdate`, after animation and before transform propagation, for every such character
//! in parallel on Bevy's compute pool; the pose is then written to the joints by `apply.rs`
//! in the same frame.

use std::sync::Arc;
use std::time::Instant;

use bevy::prelude::*;

use super::constraints::core_effector;
use super::plugin::PoseState;
use super::poll::store_landed;
use super::{
    PoseBlend, PoseFailed, PoseInFrame, PoseSolved, PoseStatus, Poseable, PoseableError,
    PosedSkeleton,
};
use crate::pose::{
    EffectorGoal, PoseSolution, PoseSolveOptions, PoseSolver, PoseSolverSettings, PoseStart,
    SkeletonPose,
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

/// The local transforms and parents of every entity: effector targets are composed from them
/// after animation, before propagation.
type Locals<'w, 's> = Query<'w, 's, (&'static Transform, Option<&'static ChildOf>)>;

/// Solves the pending targets of every in-frame character (in parallel) and stores the poses.
pub(super) fn solve_in_frame(
    mut characters: Query<InFrameCharacter>,
    locals: Locals,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
) {
    characters.par_iter_mut().for_each(
        |(_, poseable, in_frame, mut posed, mut state, mut status, blend)| {
            let state = state.bypass_change_detection();
            refresh_goals(state, &posed, &locals);
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

/// `entity`'s world transform composed from the local transforms up its hierarchy as they
/// are now (after animation: `GlobalTransform` is last frame's until propagation runs);
/// `None` when an ancestor has no `Transform` or the chain is implausibly deep.
fn current_global(entity: Entity, locals: &Locals) -> Option<GlobalTransform> {
    let mut chain = Vec::new();
    let mut at = Some(entity);
    while let Some(e) = at {
        let (transform, parent) = locals.get(e).ok()?;
        chain.push(*transform);
        at = parent.map(ChildOf::parent);
        if chain.len() > 512 {
            return None;
        }
    }
    let mut global = GlobalTransform::IDENTITY;
    for t in chain.iter().rev() {
        global = global.mul_transform(*t);
    }
    Some(global)
}

/// Reads the effectors' goals again from their entities as they are now (after this frame's
/// animation), in character space: into the pending constraints, or — when nothing was asked
/// in `Update` but a target moved since (an animated carrier) — into a new request made from
/// the last solved constraints.
fn refresh_goals(state: &mut PoseState, posed: &PosedSkeleton, locals: &Locals) {
    if state.effector_sources.is_empty() {
        return;
    }
    let Some(base) = state.pending.as_ref().or(state.solved.as_ref()) else {
        return;
    };
    // The goals that changed, read without touching (or copying) the constraints: most frames
    // of a character whose targets stand still change nothing.
    let to_character = posed.placement.inverse();
    let changed: Vec<(usize, EffectorGoal)> = state
        .effector_sources
        .iter()
        .filter_map(|(index, entity, effector)| {
            let global = current_global(*entity, locals)?;
            let fresh = core_effector(posed, effector, &global)?.transformed(&to_character);
            (base.effectors.get(*index)?.goal != fresh.goal).then_some((*index, fresh.goal))
        })
        .collect();
    if changed.is_empty() {
        return;
    }
    let Some(mut constraints) = state.pending.take().or_else(|| state.solved.clone()) else {
        return;
    };
    for (index, goal) in changed {
        constraints.effectors[index].goal = goal;
    }
    // Mirrored effectors (symmetric editing) follow their originals.
    if let Some(symmetry) = &state.symmetry {
        for &(original, mirrored) in &symmetry.mirrored_effectors {
            let image = constraints
                .effectors
                .get(original)
                .and_then(|e| symmetry.mirror_effector(e));
            if let (Some(image), Some(slot)) = (image, constraints.effectors.get_mut(mirrored)) {
                slot.goal = image.goal;
            }
        }
    }
    state.pending = Some(constraints);
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
        // Only a solution of the reused solver seeds this one (a start given: an additive
        // layer's pose on screen).
        let last = state.last.as_deref().filter(|_| reuse.is_some());
        let solver = match reuse {
            Some(s) => s,
            None => Arc::new(PoseSolver::new(
                posed.model.clone(),
                &constraints,
                &reference,
                PoseSolverSettings::default(),
            )?),
        };
        let current = start.as_ref().unwrap_or(&posed.pose);
        let from = PoseStart::following(last, current, start.is_some());
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
    let again = matches!(&outcome, Ok((_, solution, _))
        if solution.stats.iterations >= in_frame.iterations.max(1))
        && state.pending.is_none();
    // Kept (with effectors) so that a target moved after `Update` can ask again.
    let keep = !state.effector_sources.is_empty();
    match (again, keep) {
        (true, true) => {
            state.solved = Some(constraints.clone());
            state.pending = Some(constraints);
        }
        (true, false) => state.pending = Some(constraints),
        (false, true) => state.solved = Some(constraints),
        (false, false) => {}
    }
    Some(outcome)
}
