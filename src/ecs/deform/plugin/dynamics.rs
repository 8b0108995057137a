//! [`DeformDynamics`]: meshes stepped in time instead of solved to rest. Constraints come from
//! the handles as for static solves; each constraint set gets its dynamic factorization on the
//! compute pool (the static one's lowest eigenvalue sets the inertia); every frame runs the
//! steps its time holds, in the frame for small meshes and on the compute pool for large ones
//! (one step batch in flight; the time of frames meanwhile is added to the next).

use std::sync::Arc;

use bevy::tasks::{AsyncComputeTaskPool, Task};

use super::*;
use crate::deform::{DynamicsSettings, MeshMotion};

/// The motion of one [`DeformDynamics`] mesh (runtime state, not reflected).
#[derive(Component, Default)]
pub(super) struct DynamicsRuntime {
    /// The dynamic factorization and the settings and constraint sets it is for.
    solver: Option<(Arc<ArapSolver>, DynamicsSettings, Constraints)>,
    /// A factorization under way, for these settings and sets.
    factoring: Option<Factoring>,
    motion: Option<MeshMotion>,
    /// A batch of steps on the compute pool (large meshes): the motion after it, the pose it
    /// makes and its milliseconds per step.
    stepping: Option<Task<(MeshMotion, Stepped)>>,
    /// Frame time not yet handed to a step batch.
    waiting: f64,
}

/// A dynamic factorization under way: the settings and constraint sets it is for.
type Factoring = (
    DynamicsSettings,
    Constraints,
    Task<Result<ArapSolver, SolveError>>,
);

/// What a batch of steps made, when a step was due (`None` when none was).
struct Steps {
    /// The pose to show.
    pose: RenderPose,
    /// The last step's solution once the mesh has come to rest (the next static solve's warm
    /// start; not copied while it moves).
    at_rest: Option<Arc<Solution>>,
    /// The last step's statistics.
    stats: SolveStats,
    /// Milliseconds per step.
    ms: f64,
}

/// A batch's outcome.
type Stepped = Result<Option<Steps>, SolveError>;

/// Runs the steps `dt` holds (above the ground when `ground` is given: handles lifted onto
/// it, vertices kept above it) and builds what the frame shows.
fn run_steps(motion: &mut MeshMotion, job: &StepJob, dt: f64) -> Stepped {
    let t0 = web_time::Instant::now();
    let positions = job.rest.topology.positions();
    let obstacle = job.ground.as_ref().and_then(|g| g.obstacle(positions));
    let lifted;
    let constraints = match obstacle {
        Some(ground) => {
            lifted = job.constraints.lifted_above(positions, ground);
            &lifted
        }
        None => &job.constraints,
    };
    let obstacle = obstacle.map(|g| g as &dyn crate::deform::Obstacle);
    let steps = motion.advance(&job.solver, constraints, &job.settings, dt, obstacle)?;
    let Some(solution) = motion.solution().filter(|_| steps > 0) else {
        return Ok(None);
    };
    let pose = render_pose(&job.rest, solution);
    let speed = motion.max_speed();
    let at_rest = (speed <= RESTING_SPEED * job.rest.topology.bounding_diagonal())
        .then(|| Arc::new(solution.clone()));
    let ms = t0.elapsed().as_secs_f64() * 1e3 / f64::from(steps);
    Ok(Some(Steps {
        pose,
        at_rest,
        stats: solution.stats.clone(),
        ms,
    }))
}

/// Below this speed (bounding diagonals per second) a mesh counts as at rest.
const RESTING_SPEED: f64 = 1e-6;

/// What a batch of steps works with.
struct StepJob {
    solver: Arc<ArapSolver>,
    rest: Arc<Rest>,
    constraints: Constraints,
    settings: DynamicsSettings,
    ground: Option<ground::GroundCache>,
}

/// The factorization of `constraints` for `settings`: the static system's lowest eigenvalue
/// gives the inertia of the dynamic one.
fn factor(
    topology: Arc<Topology>,
    constraints: &Constraints,
    base: SolverSettings,
    settings: &DynamicsSettings,
) -> Result<ArapSolver, SolveError> {
    let lambda =
        ArapSolver::precompute(topology.clone(), constraints, base.clone())?.lowest_eigenvalue();
    ArapSolver::precompute(
        topology,
        constraints,
        SolverSettings {
            inertia: settings.inertia(lambda),
            ..base
        },
    )
}

/// Steps every [`DeformDynamics`] mesh by the frame's time.
#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
pub(super) fn step_dynamics(
    mut commands: Commands,
    time: Res<Time>,
    mut meshes: Query<(
        Entity,
        &Deformable,
        Ref<DeformDynamics>,
        Option<&FixedRegion>,
        &mut DeformState,
        &mut DeformStatus,
        Option<&mut DynamicsRuntime>,
    )>,
    handles: Query<(&DeformHandle, &Transform)>,
) {
    let dt = f64::from(time.delta_secs());
    for (entity, deformable, dynamics, fixed, mut state, mut status, runtime) in &mut meshes {
        let Some(rest) = state.rest.clone() else {
            continue;
        };
        let Some(mut runtime) = runtime else {
            commands
                .entity(entity)
                .try_insert(DynamicsRuntime::default());
            continue;
        };
        let runtime = &mut *runtime;
        if dynamics.is_added() {
            // Turned on again: start from the pose on screen, not where it was turned off.
            runtime.motion = None;
            runtime.stepping = None;
            runtime.waiting = 0.0;
        }
        let settings = dynamics.settings();
        let mine: Vec<(&DeformHandle, &Transform)> = handles
            .iter()
            .filter(|(h, _)| h.target == entity && h.pivot.is_some())
            .collect();
        let constraints = build_constraints(&rest.topology, fixed, &mine);
        let base = solver_settings(deformable, &rest.topology);
        // A new constraint set (or new settings): factor it on the pool.
        let current =
            |s: &DynamicsSettings, c: &Constraints| *s == settings && c.same_sets(&constraints);
        let fits = runtime
            .solver
            .as_ref()
            .is_some_and(|(_, s, c)| current(s, c));
        let under_way = runtime
            .factoring
            .as_ref()
            .is_some_and(|(s, c, _)| current(s, c));
        if !fits && !under_way {
            let (topology, sets, base) = (rest.topology.clone(), constraints.clone(), base.clone());
            let task = AsyncComputeTaskPool::get()
                .spawn(async move { factor(topology, &sets, base, &settings) });
            runtime.factoring = Some((settings, constraints.clone(), task));
            status.phase = DeformPhase::Factorizing;
        }
        if let Some((s, c, task)) = runtime.factoring.as_mut()
            && let Some(result) = check_ready(task)
        {
            match result {
                Ok(solver) => runtime.solver = Some((Arc::new(solver), *s, c.clone())),
                Err(e) => status.error = Some(DeformError::Solve(e)),
            }
            runtime.factoring = None;
        }
        let Some(solver) = runtime
            .solver
            .as_ref()
            .filter(|(_, s, c)| current(s, c))
            .map(|(solver, _, _)| solver.clone())
        else {
            continue;
        };
        let start = || match &state.last {
            Some(last) => MeshMotion::from_solution((**last).clone()),
            None => MeshMotion::at_rest(rest.topology.positions().to_vec()),
        };
        let job = StepJob {
            solver,
            rest: rest.clone(),
            constraints,
            settings,
            ground: state.ground.clone(),
        };
        runtime.waiting += dt;
        let landed = if rest.topology.vertex_count() < DeformDynamics::IN_FRAME_BELOW {
            let waiting = std::mem::take(&mut runtime.waiting);
            let motion = runtime.motion.get_or_insert_with(start);
            Some(run_steps(motion, &job, waiting))
        } else {
            // A batch on the pool: land the last one, start the next with the time since.
            // The motion goes with the batch (no copy on the main thread).
            let mut landed = None;
            if let Some(task) = runtime.stepping.as_mut()
                && let Some((moved, result)) = check_ready(task)
            {
                runtime.motion = Some(moved);
                runtime.stepping = None;
                landed = Some(result);
            }
            if runtime.stepping.is_none() {
                let mut moving = runtime.motion.take().unwrap_or_else(start);
                let waiting = std::mem::take(&mut runtime.waiting);
                runtime.stepping = Some(AsyncComputeTaskPool::get().spawn(async move {
                    let result = run_steps(&mut moving, &job, waiting);
                    (moving, result)
                }));
            }
            landed
        };
        match landed {
            Some(Ok(Some(steps))) if finite(&steps.pose) => {
                status.solve_ms = steps.ms;
                status.iterations = steps.stats.iterations;
                status.energy = steps.stats.final_energy();
                status.ground_contacts = steps.stats.contacts;
                status.solves += 1;
                status.error = None;
                status.phase = match steps.at_rest {
                    Some(_) => DeformPhase::Idle,
                    None => DeformPhase::Solving,
                };
                let state = state.bypass_change_detection();
                state.ready = Some(steps.pose);
                if let Some(solution) = steps.at_rest {
                    state.last = Some(solution);
                }
            }
            Some(Err(e)) => {
                // The last good pose stays; the motion starts again from it.
                status.error = Some(DeformError::Solve(e));
                runtime.motion = None;
            }
            _ => {}
        }
    }
}
