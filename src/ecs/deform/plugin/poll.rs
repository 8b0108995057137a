//! Collecting landed solves (the pose handed to write-back, settling continued) and the whole
//! mesh's factorization that follows a preview.

use super::*;

pub(super) fn poll_tasks(
    config: Res<DeformConfig>,
    mut deformables: Query<(Entity, &Deformable, &mut DeformState, &mut DeformStatus)>,
    mut solved: MessageWriter<DeformSolved>,
    mut failed: MessageWriter<DeformFailed>,
) {
    for (entity, deformable, mut state, mut status) in &mut deformables {
        let state = state.bypass_change_detection();
        poll_factoring(entity, deformable, &config, state, &mut status, &mut failed);
        let Some(polled) = state.solve.poll() else {
            continue;
        };
        // Every landed solve is counted and reported; the newest is shown.
        let mut last = None;
        for out in polled.landed {
            last = Some(take_landed(
                entity,
                deformable,
                state,
                &mut status,
                out,
                (&mut solved, &mut failed),
            ));
        }
        if !polled.ended {
            // The chain goes on with the newer constraints it took.
            if status.error.is_none() {
                status.phase = DeformPhase::Solving;
            }
            continue;
        }
        if let Some(untaken) = polled.untaken
            && state.pending.is_none()
        {
            state.pending = Some(untaken.constraints);
        }
        // A newer request arrived while solving: start it now with the freshest constraints.
        // Otherwise, if that solve did not converge, settle on with the same constraints (a
        // preview does not settle: the whole mesh's solve follows it).
        let mut settling = false;
        if let Some(landed) = last {
            let settle = landed.unsettled
                && !landed.previewed
                && state.pending.is_none()
                && state.settle_left > 0;
            settling = settle && status.error.is_none();
            if settling {
                state.settle_left = state.settle_left.saturating_sub(status.iterations.max(1));
                state.pending = Some(landed.constraints);
            }
        }
        if state.pending.is_some()
            && let Some(rest) = state.rest.clone()
        {
            spawn_solve(state, &rest, deformable, &config, &mut status, settling);
        }
        if !state.solve.is_running() && state.factoring.is_some() {
            status.phase = DeformPhase::Factorizing;
        }
    }
}

/// What the poll keeps of a landed solve to decide what follows it.
struct Landed {
    /// The constraints it solved (a settling solve reuses them).
    constraints: Constraints,
    /// It ran all its iterations and was still converging.
    unsettled: bool,
    /// It was a preview's (the whole mesh's factorization follows, not settling).
    previewed: bool,
}

/// Takes one landed solve: a finite pose becomes the one shown (its solver or preview kept)
/// and is reported as [`DeformSolved`]; a failure or a non-finite pose is reported as
/// [`DeformFailed`] and the last good pose stays.
fn take_landed(
    entity: Entity,
    deformable: &Deformable,
    state: &mut DeformState,
    status: &mut DeformStatus,
    out: SolveOutput,
    (solved, failed): (
        &mut MessageWriter<DeformSolved>,
        &mut MessageWriter<DeformFailed>,
    ),
) -> Landed {
    let mut landed = Landed {
        constraints: out.constraints,
        unsettled: out.unsettled,
        previewed: false,
    };
    status.phase = DeformPhase::Idle;
    let s = match out.result {
        Ok(s) if finite(&s.pose) => s,
        Ok(_) => {
            report_failure(entity, status, DeformError::NonFinite, failed);
            return landed;
        }
        Err(e) => {
            report_failure(entity, status, DeformError::from(e), failed);
            return landed;
        }
    };
    status.iterations = s.solution.stats.iterations;
    status.energy = s.solution.stats.final_energy();
    status.ground_contacts = s.solution.stats.contacts;
    status.solve_ms = out.ms;
    status.solves += 1;
    status.error = None;
    status.preview = s.preview.is_some();
    solved.write(DeformSolved {
        entity,
        iterations: s.solution.stats.iterations,
        energy: status.energy,
        solve_ms: out.ms,
    });
    match s.preview {
        Some(preview) => {
            landed.previewed = true;
            state.preview = Some((preview, s.solver));
            factor_whole_mesh(state, deformable, &landed.constraints);
        }
        None => {
            state.solver = Some(s.solver);
            state.preview = None;
        }
    }
    state.last = Some(s.solution);
    state.ready = Some(s.pose);
    landed
}

/// Records a failed solve in the status and as a [`DeformFailed`] message.
fn report_failure(
    entity: Entity,
    status: &mut DeformStatus,
    error: DeformError,
    failed: &mut MessageWriter<DeformFailed>,
) {
    status.phase = DeformPhase::Idle;
    status.error = Some(error.clone());
    failed.write(DeformFailed { entity, error });
}

/// After a preview of `constraints`: factor the whole mesh for them in the background,
/// unless that is done or under way.
pub(super) fn factor_whole_mesh(
    state: &mut DeformState,
    deformable: &Deformable,
    constraints: &Constraints,
) {
    let Some(rest) = state.rest.clone() else {
        return;
    };
    let settings = solver_settings(deformable, &rest.topology);
    let factored = state
        .solver
        .as_ref()
        .is_some_and(|s| s.accepts(constraints) && *s.settings() == settings);
    let under_way = state
        .factoring
        .as_ref()
        .is_some_and(|(c, _)| c.same_sets(constraints));
    if factored || under_way {
        return;
    }
    let sets = constraints.clone();
    let task = AsyncComputeTaskPool::get()
        .spawn(async move { ArapSolver::precompute(rest.topology.clone(), &sets, settings) });
    // A factorization for older sets is dropped (cancelled if it has not started).
    state.factoring = Some((constraints.clone(), task));
}

/// A finished whole-mesh factorization replaces the preview and solves the latest
/// constraints from the displayed pose (at once, or when the running solve lands).
pub(super) fn poll_factoring(
    entity: Entity,
    deformable: &Deformable,
    config: &DeformConfig,
    state: &mut DeformState,
    status: &mut DeformStatus,
    failed: &mut MessageWriter<DeformFailed>,
) {
    let Some((_, task)) = state.factoring.as_mut() else {
        return;
    };
    let Some(result) = check_ready(task) else {
        return;
    };
    state.factoring = None;
    match result {
        Ok(solver) => {
            let latest = state.latest.clone();
            if !latest.as_ref().is_some_and(|c| solver.accepts(c)) {
                return; // the sets changed since: their own preview and factorization follow
            }
            state.solver = Some(Arc::new(solver));
            state.preview = None;
            if state.pending.is_none() {
                state.pending = latest;
                state.settle_left = config.settle_iterations;
            }
            if !state.solve.is_running()
                && let Some(rest) = state.rest.clone()
            {
                spawn_solve(state, &rest, deformable, config, status, false);
            }
        }
        Err(e) => {
            // The preview stays on screen; the next change of the sets tries again.
            if !state.solve.is_running() {
                status.phase = DeformPhase::Idle;
            }
            let error = DeformError::from(e);
            status.error = Some(error.clone());
            failed.write(DeformFailed { entity, error });
        }
    }
}
