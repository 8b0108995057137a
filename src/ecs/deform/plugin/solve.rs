//! Solving: constraints from handles and regions, background solves (latest wins), previews
//! of large meshes, the whole-mesh factorization, settling a released pose.

use super::*;

/// Builds core constraints (welded indices) for one deformable.
pub(super) fn build_constraints(
    topology: &Topology,
    fixed: Option<&FixedRegion>,
    handles: &[(&DeformHandle, &Transform)],
) -> Constraints {
    Constraints {
        fixed: fixed.map(|f| topology.welded_set(&f.0)).unwrap_or_default(),
        handles: handles
            .iter()
            .map(|(h, t)| CoreHandle {
                vertices: topology.welded_set(&h.vertices),
                transform: h.rigid_transform(t),
            })
            .collect(),
        targets: Vec::new(),
    }
}

#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
pub(super) fn request_solves(
    config: Res<DeformConfig>,
    mut deformables: Query<(
        Entity,
        &Deformable,
        Option<Ref<FixedRegion>>,
        &mut DeformState,
        &mut DeformStatus,
    )>,
    mut handles: Query<(Entity, &mut DeformHandle, &mut Transform)>,
    mut removed: RemovedComponents<DeformHandle>,
    changed_deformable: Query<(), Changed<Deformable>>,
) {
    // Fill in missing pivots (rest centroid) once the topology exists; a handle left at the
    // identity Transform is put at its pivot, its rest pose (else it would jump by −pivot).
    for (_, mut h, mut transform) in &mut handles {
        if h.pivot.is_some() {
            continue;
        }
        let Ok((_, _, _, state, _)) = deformables.get(h.target) else {
            continue;
        };
        let Some(rest) = &state.rest else { continue };
        let topo = &rest.topology;
        let map = topo.render_to_welded();
        let welded: Vec<u32> = h
            .vertices
            .iter()
            .filter_map(|&v| map.get(v as usize).copied())
            .collect();
        let c = centroid(topo.positions(), &welded).as_vec3();
        h.pivot = Some(c);
        if *transform == Transform::IDENTITY {
            transform.translation = c;
        }
    }
    // Consume the removals so each one triggers exactly one re-solve.
    let any_removed = removed.read().count() > 0;
    for (entity, deformable, fixed, mut state, mut status) in &mut deformables {
        let Some(rest) = state.rest.clone() else {
            continue;
        };
        // (Mutable access only to read change ticks: nothing is written here.)
        let mine: Vec<(Entity, Mut<DeformHandle>, Mut<Transform>)> = handles
            .iter_mut()
            .filter(|(_, h, _)| h.target == entity)
            .collect();
        let changed = mine
            .iter()
            .any(|(_, h, t)| t.is_changed() || h.pivot.is_none())
            || fixed.as_ref().is_some_and(|f| f.is_changed())
            || changed_deformable.contains(entity)
            || any_removed
            || !state.attempted && !mine.is_empty();
        if !changed && state.pending.is_none() {
            continue;
        }
        if mine.iter().any(|(_, h, _)| h.pivot.is_none()) {
            continue; // next frame, once the pivots exist
        }
        let mut sorted: Vec<(Entity, &DeformHandle, &Transform)> =
            mine.iter().map(|(e, h, t)| (*e, &**h, &**t)).collect();
        sorted.sort_by_key(|(e, _, _)| *e);
        let pairs: Vec<(&DeformHandle, &Transform)> =
            sorted.iter().map(|(_, h, t)| (*h, *t)).collect();
        let constraints = build_constraints(&rest.topology, fixed.as_deref(), &pairs);
        let state = state.bypass_change_detection();
        state.attempted = true;
        state.pending = Some(constraints);
        state.settle_left = config.settle_iterations;
        state.solve.supersede();
        if state.solve.is_running() {
            continue; // the running task is cancelled at its next iteration; respawn on landing
        }
        spawn_solve(state, &rest, deformable, &config, &mut status, false);
    }
}

/// Starts a solve of the pending constraints (`settling`: the handles have not changed since
/// the last solve, which did not converge).
pub(super) fn spawn_solve(
    state: &mut DeformState,
    rest: &Arc<Rest>,
    deformable: &Deformable,
    config: &DeformConfig,
    status: &mut DeformStatus,
    settling: bool,
) {
    let Some(constraints) = state.pending.take() else {
        return;
    };
    let rest = rest.clone();
    let settings = solver_settings(deformable, &rest.topology);
    // The factorization depends on the constraint sets *and* the settings (weights, region
    // of interest): reuse it only when both are unchanged.
    let reuse = state
        .solver
        .clone()
        .filter(|s| s.accepts(&constraints) && *s.settings() == settings);
    // Without the whole mesh's factorization: the current preview follows the handles, or a
    // new constraint set gets a preview of its own (a large mesh, no region of interest).
    let follow = match reuse {
        Some(_) => None,
        None => state.preview.as_ref().and_then(|(preview, solver)| {
            let followed = preview.follow(&constraints)?;
            Some((preview.clone(), solver.clone(), followed))
        }),
    };
    let region = match deformable.region_of_interest {
        None if !settling => config.preview,
        _ => None,
    };
    status.phase = match (&reuse, &follow, settling) {
        (None, None, _) => DeformPhase::Factorizing,
        (_, _, false) => DeformPhase::Solving,
        (_, _, true) => DeformPhase::Settling,
    };
    state.latest = Some(constraints.clone());
    // A new factorization (set change) still continues from the displayed pose; the solver
    // drops acceleration history that belongs to another factorization.
    let warm = state.last.clone();
    let laplacian_start = warm.is_none()
        && constraints.largest_displacement(rest.topology.positions())
            > f64::from(config.laplacian_start_displacement) * rest.topology.bounding_diagonal();
    let max_iterations = deformable
        .max_iterations
        .unwrap_or(config.max_iterations)
        .max(1);
    let options = match (settling, config.settle_acceleration) {
        // One Newton iteration is already several back-substitutions: land each one.
        (true, newton @ Acceleration::Newton { .. }) => SolveOptions {
            max_iterations: 1,
            tolerance: 0.0,
            acceleration: newton,
        },
        (true, acceleration) => SolveOptions {
            max_iterations,
            tolerance: 0.0,
            acceleration,
        },
        (false, _) => SolveOptions {
            max_iterations,
            tolerance: deformable.tolerance.unwrap_or(config.tolerance).max(0.0) as f64,
            acceleration: config.acceleration,
        },
    };
    state.solve.spawn(move |cancellation| {
        let t0 = std::time::Instant::now();
        let result = (|| {
            let (solver, preview, followed) = match (reuse, follow) {
                (Some(solver), _) => (solver, None, None),
                (None, Some((preview, solver, followed))) => {
                    (solver, Some(preview), Some(followed))
                }
                (None, None) => {
                    let current = warm
                        .as_ref()
                        .map_or(rest.topology.positions(), |w| &w.positions[..]);
                    let preview = region
                        .and_then(|r| r.preview(&rest.topology, &constraints, current))
                        .map(Arc::new);
                    let factored = preview.as_ref().map_or(&constraints, |p| p.constraints());
                    let solver = ArapSolver::precompute(rest.topology.clone(), factored, settings)?;
                    (Arc::new(solver), preview, None)
                }
            };
            let solving = match (&followed, &preview) {
                (Some(followed), _) => followed,
                (None, Some(preview)) => preview.constraints(),
                (None, None) => &constraints,
            };
            let init = match &warm {
                Some(w) => InitialGuess::Warm(w),
                None if laplacian_start => InitialGuess::Laplacian,
                None => InitialGuess::Rest,
            };
            let cancel = || cancellation.superseded();
            let solution = solver.solve(solving, &options, init, &cancel)?;
            let pose = render_pose(&rest, &solution);
            Ok(Solved {
                solver,
                solution: Arc::new(solution),
                pose,
                preview,
            })
        })();
        let unsettled = result
            .as_ref()
            .is_ok_and(|s| still_converging(&s.solution.stats, &options));
        SolveOutput {
            result,
            ms: t0.elapsed().as_secs_f64() * 1e3,
            constraints,
            unsettled,
        }
    });
}

/// Relative energy decrease per iteration below which a pose counts as converged for settling.
const SETTLED_DECREASE: f64 = 1e-9;
/// Normalised energy below which a pose counts as converged (rounding noise, e.g. at rest).
const SETTLED_ENERGY: f64 = 1e-14;

/// Whether a solve stopped short of convergence: it ran all its iterations (no cancel, no
/// tolerance stop) and its last iteration still lowered the energy noticeably.
pub(super) fn still_converging(stats: &SolveStats, options: &SolveOptions) -> bool {
    if stats.iterations < options.max_iterations || stats.cancelled {
        return false;
    }
    let before = match stats.energies.len() {
        0 => return false,
        1 => stats.initial_energy,
        n => Some(stats.energies[n - 2]),
    };
    let last = stats.final_energy();
    match before {
        Some(b) => b > SETTLED_ENERGY && b - last > SETTLED_DECREASE * b,
        None => last > SETTLED_ENERGY,
    }
}

/// The solver settings a [`Deformable`] asks for (welded region-of-interest mask).
pub(super) fn solver_settings(deformable: &Deformable, topology: &Topology) -> SolverSettings {
    SolverSettings {
        weights: if deformable.raw_cotangent_weights {
            WeightMode::RawCotangent
        } else {
            WeightMode::ClampedCotangent
        },
        region_of_interest: deformable.region_of_interest.as_ref().map(|roi| {
            let mut mask = vec![false; topology.vertex_count()];
            for w in topology.welded_set(roi) {
                mask[w as usize] = true;
            }
            mask
        }),
        ..Default::default()
    }
}

/// Positions, rotated rest normals and tangents in render order (f32), validated finite.
pub(super) fn render_pose(rest: &Rest, solution: &Solution) -> RenderPose {
    let map = rest.topology.render_to_welded();
    let positions: Vec<[f32; 3]> = map
        .iter()
        .map(|&w| solution.positions[w as usize].as_vec3().to_array())
        .collect();
    let rot = |w: u32| -> Quat { solution.rotations[w as usize].as_quat() };
    let normals = rest.normals.as_ref().map(|n| {
        n.iter()
            .zip(map)
            .map(|(n, &w)| (rot(w) * *n).normalize_or_zero().to_array())
            .collect()
    });
    let tangents = rest.tangents.as_ref().map(|t| {
        t.iter()
            .zip(map)
            .map(|(t, &w)| {
                let v = (rot(w) * t.truncate()).normalize_or_zero();
                [v.x, v.y, v.z, t.w]
            })
            .collect()
    });
    RenderPose {
        positions,
        normals,
        tangents,
    }
}

pub(super) fn finite(pose: &RenderPose) -> bool {
    pose.positions.iter().flatten().all(|x| x.is_finite())
        && pose
            .normals
            .iter()
            .flatten()
            .flatten()
            .all(|x| x.is_finite())
        && pose
            .tangents
            .iter()
            .flatten()
            .flatten()
            .all(|x| x.is_finite())
}

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
