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
        let Some(out) = state.solve.poll() else {
            continue;
        };
        let mut previewed = false;
        match out.result {
            Ok(s) if finite(&s.pose) => {
                status.iterations = s.solution.stats.iterations;
                status.energy = s.solution.stats.final_energy();
                status.solve_ms = out.ms;
                status.solves += 1;
                status.error = None;
                status.phase = DeformPhase::Idle;
                status.preview = s.preview.is_some();
                solved.write(DeformSolved {
                    entity,
                    iterations: s.solution.stats.iterations,
                    energy: status.energy,
                    solve_ms: out.ms,
                });
                match s.preview {
                    Some(preview) => {
                        previewed = true;
                        state.preview = Some((preview, s.solver));
                        factor_whole_mesh(state, deformable, &out.constraints);
                    }
                    None => {
                        state.solver = Some(s.solver);
                        state.preview = None;
                    }
                }
                state.last = Some(s.solution);
                state.ready = Some(s.pose);
            }
            Ok(_) => {
                status.phase = DeformPhase::Idle;
                status.error = Some(DeformError::NonFinite);
                failed.write(DeformFailed {
                    entity,
                    error: DeformError::NonFinite,
                });
            }
            Err(e) => {
                status.phase = DeformPhase::Idle;
                let error = DeformError::from(e);
                status.error = Some(error.clone());
                failed.write(DeformFailed { entity, error });
            }
        }
        // A newer request arrived while solving: start it now with the freshest constraints.
        // Otherwise, if that solve did not converge, settle on with the same constraints (a
        // preview does not settle: the whole mesh's solve follows it).
        let settle =
            out.unsettled && !previewed && state.pending.is_none() && state.settle_left > 0;
        let settling = settle && status.error.is_none();
        if settling {
            state.settle_left = state.settle_left.saturating_sub(status.iterations.max(1));
            state.pending = Some(out.constraints);
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
