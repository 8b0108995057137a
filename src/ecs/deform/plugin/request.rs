//! Requesting solves: constraints from handles and regions, background solves (latest wins)
//! with a preview of a large mesh first, settling a released pose.

use super::*;
use crate::deform::PreviewRegion;
use crate::ecs::SceneGround;
use crate::ecs::tasks::{Cancellation, ChainLink};
use ground::GroundCache;

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
        Option<(&DeformGround, &GlobalTransform)>,
        Has<DeformDynamics>,
    )>,
    scene_ground: Option<Res<SceneGround>>,
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
        let Ok((_, _, _, state, _, _, _)) = deformables.get(h.target) else {
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
    for (entity, deformable, fixed, mut state, mut status, on_ground, dynamic) in &mut deformables {
        let ground_changed = refresh_ground(
            state.bypass_change_detection(),
            on_ground,
            scene_ground.as_deref(),
        );
        if dynamic {
            continue; // stepped in time instead (`dynamics.rs`), on the same ground
        }
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
            || ground_changed
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
        state.settle_left = config.settle_iterations;
        // A running solve stops at its next iteration and goes on with these constraints
        // itself when its factorization fits them.
        state.solve.supersede();
        state.pending = None;
        let offered = FollowOn {
            settings: solver_settings(deformable, &rest.topology),
            options: solve_options(false, deformable, &config),
            constraints: constraints.clone(),
            ground: state.ground.clone(),
        };
        let Some(untaken) = state.solve.offer(offered) else {
            state.latest = Some(constraints);
            if status.phase == DeformPhase::Idle {
                status.phase = DeformPhase::Solving;
            }
            continue;
        };
        state.pending = Some(untaken.constraints);
        if state.solve.is_running() {
            continue; // it has ended: the poll starts the next solve with these
        }
        spawn_solve(state, &rest, deformable, &config, &mut status, false);
    }
}

/// Keeps `state`'s ground current for a deformable with [`DeformGround`] (and its placement)
/// on `scene`; true when it changed (the mesh is solved again against the new ground).
fn refresh_ground(
    state: &mut DeformState,
    on_ground: Option<(&DeformGround, &GlobalTransform)>,
    scene: Option<&SceneGround>,
) -> bool {
    match (on_ground, scene) {
        (Some((settings, placement)), Some(scene)) => {
            if state
                .ground
                .as_ref()
                .is_some_and(|g| g.is_for(scene, settings, placement))
            {
                return false;
            }
            state.ground = Some(GroundCache::new(scene.clone(), *settings, *placement));
            true
        }
        _ => state.ground.take().is_some(),
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
    let job = SolveJob {
        rest: rest.clone(),
        constraints,
        settings,
        solver: match (reuse, follow) {
            (Some(solver), _) => JobSolver::Reuse(solver),
            (None, Some((preview, solver, followed))) => {
                JobSolver::FollowPreview(preview, solver, followed)
            }
            (None, None) => JobSolver::Factor {
                region: match deformable.region_of_interest {
                    None if !settling => config.preview,
                    _ => None,
                },
            },
        },
        warm,
        laplacian_start,
        options: solve_options(settling, deformable, config),
        ground: state.ground.clone(),
    };
    let mut job = job;
    state.solve.spawn(move |link| job.step(link));
}

/// How a solve iterates: the settings' acceleration and tolerance, or the settling ones.
fn solve_options(settling: bool, deformable: &Deformable, config: &DeformConfig) -> SolveOptions {
    let max_iterations = deformable
        .max_iterations
        .unwrap_or(config.max_iterations)
        .max(1);
    match (settling, config.settle_acceleration) {
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
    }
}

/// Where a background solve gets its factorization.
enum JobSolver {
    /// The current one (same constraint sets and settings).
    Reuse(Arc<ArapSolver>),
    /// The current preview's, with the constraints it follows.
    FollowPreview(Arc<Preview>, Arc<ArapSolver>, Constraints),
    /// A new one: of a preview region when `region` makes one, else of the whole mesh.
    Factor { region: Option<PreviewRegion> },
}

/// Everything a background solve needs, moved into its task.
struct SolveJob {
    rest: Arc<Rest>,
    constraints: Constraints,
    settings: SolverSettings,
    solver: JobSolver,
    warm: Option<Arc<Solution>>,
    laplacian_start: bool,
    options: SolveOptions,
    ground: Option<GroundCache>,
}

impl SolveJob {
    /// Solves and posts the output; when a request arrived meanwhile that the factorization
    /// fits, makes it the next step's (warm from the pose just made) and returns true, else
    /// gives it back and returns false.
    fn step(&mut self, link: &mut ChainLink<FollowOn, SolveOutput>) -> bool {
        let out = self.run(link.cancellation());
        // A preview's solve is followed by the whole mesh's factorization (the plugin's).
        let reusable = match &out.result {
            Ok(s) if s.preview.is_none() => Some((s.solver.clone(), s.solution.clone())),
            _ => None,
        };
        let Some(next) = link.land(out) else {
            return false;
        };
        match reusable {
            Some((solver, solution))
                if solver.accepts(&next.constraints) && *solver.settings() == next.settings =>
            {
                self.solver = JobSolver::Reuse(solver);
                self.warm = Some(solution);
                self.laplacian_start = false;
                self.constraints = next.constraints;
                self.settings = next.settings;
                self.options = next.options;
                self.ground = next.ground;
                true
            }
            _ => {
                link.give_back(next);
                false
            }
        }
    }

    /// Factors (if needed) and solves; stops early when `cancellation` says a newer request
    /// arrived.
    fn run(&self, cancellation: &Cancellation) -> SolveOutput {
        let t0 = web_time::Instant::now();
        let result = self.solve(cancellation);
        let unsettled = result
            .as_ref()
            .is_ok_and(|s| still_converging(&s.solution.stats, &self.options));
        SolveOutput {
            result,
            ms: t0.elapsed().as_secs_f64() * 1e3,
            constraints: self.constraints.clone(),
            unsettled,
        }
    }

    fn solve(&self, cancellation: &Cancellation) -> Result<Solved, SolveError> {
        let rest = &self.rest;
        let (solver, preview, followed) = match &self.solver {
            JobSolver::Reuse(solver) => (solver.clone(), None, None),
            JobSolver::FollowPreview(preview, solver, followed) => {
                (solver.clone(), Some(preview.clone()), Some(followed))
            }
            JobSolver::Factor { region } => {
                let current = self
                    .warm
                    .as_ref()
                    .map_or(rest.topology.positions(), |w| &w.positions[..]);
                let preview = region
                    .and_then(|r| r.preview(&rest.topology, &self.constraints, current))
                    .map(Arc::new);
                let factored = preview
                    .as_ref()
                    .map_or(&self.constraints, |p| p.constraints());
                let solver =
                    ArapSolver::precompute(rest.topology.clone(), factored, self.settings.clone())?;
                (Arc::new(solver), preview, None)
            }
        };
        let solving = match (followed, &preview) {
            (Some(followed), _) => followed,
            (None, Some(preview)) => preview.constraints(),
            (None, None) => &self.constraints,
        };
        let init = match &self.warm {
            Some(w) => InitialGuess::Warm(w),
            None if self.laplacian_start => InitialGuess::Laplacian,
            None => InitialGuess::Rest,
        };
        let cancel = || cancellation.superseded();
        let rest_positions = rest.topology.positions();
        let solution = match self
            .ground
            .as_ref()
            .and_then(|g| g.obstacle(rest_positions))
        {
            Some(ground) => {
                // A handle dragged into the ground slides along it.
                let lifted = solving.lifted_above(rest_positions, ground);
                solver.solve_above(&lifted, &self.options, init, ground, &cancel)?
            }
            None => solver.solve(solving, &self.options, init, &cancel)?,
        };
        let pose = render_pose(rest, &solution);
        Ok(Solved {
            solver,
            solution: Arc::new(solution),
            pose,
            preview,
        })
    }
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
