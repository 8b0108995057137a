//! The two steps every path of a solve shares, background (`request.rs` → `poll.rs`) or in the
//! frame (`in_frame.rs`): [`SolveJob::take`] takes the pending constraints with everything a
//! solve needs (the solver when it still fits, the last solution to warm-start from, the start
//! pose) and [`SolveJob::run`] runs it; [`store_landed`] stores the result.

use std::sync::Arc;
use web_time::Instant;

use super::super::blend::{BlendMemory, additive_layer};
use super::super::{PoseBlend, PoseBlendMode, PoseStatus, PoseableError, PosedSkeleton};
use super::ground_contacts::FloorRecast;
use super::state::{LastSolve, PoseDrivers, PoseSolves};
use crate::ecs::DeformPhase;
use crate::pose::{
    PoseConstraints, PoseSolution, PoseSolveOptions, PoseSolver, PoseSolverSettings, PoseStart,
    SkeletonPose, SkinnedModel,
};

/// A solve that landed: its solver (kept for the next solve of the same set), its solution and
/// its wall time in milliseconds.
pub(super) struct Landed {
    pub(super) solver: Arc<PoseSolver>,
    pub(super) solution: PoseSolution,
    pub(super) ms: f64,
}

/// What a solve gives.
pub(super) type SolveResult = Result<Landed, PoseableError>;

/// Where a job's solver comes from.
enum SolverSource {
    /// The last solver: built for these constraint sets.
    Reuse(Arc<PoseSolver>),
    /// A new one, built for this reference pose.
    Build(SkeletonPose),
}

/// One solve, ready to run anywhere: owns what it reads.
pub(super) struct SolveJob {
    model: Arc<SkinnedModel>,
    /// The constraints solved for.
    pub(super) constraints: PoseConstraints,
    /// The last solver when it was built for these constraint sets, else the pose a new one
    /// is built for.
    solver: SolverSource,
    /// The last solution of a reused solver (only its own solutions seed it).
    last: Option<Arc<PoseSolution>>,
    /// Where the solve starts.
    current: SkeletonPose,
    /// `current` was given (an additive layer's pose on screen), not the held pose.
    given: bool,
    options: PoseSolveOptions,
    /// With the character standing on the ground: the floor cast again where the skin ended.
    recast: Option<FloorRecast>,
}

/// How many times a solve whose skin ended in ground that was not under it at its start is
/// taken on with the floor cast where it ended ([`FloorRecast`]).
const FLOOR_PASSES: usize = 2;

impl SolveJob {
    /// Takes the pending constraints of `solves` (`None`: nothing pending, or no reference
    /// pose yet) with what their solve needs.
    pub(super) fn take(
        solves: &mut PoseSolves,
        drivers: &PoseDrivers,
        last: &LastSolve,
        posed: &PosedSkeleton,
        (options, recast): (PoseSolveOptions, Option<FloorRecast>),
    ) -> Option<Self> {
        drivers.reference.as_ref()?;
        let constraints = solves.pending.take()?;
        let reuse = last.solver.clone().filter(|s| s.accepts(&constraints));
        let solution = last.solution.clone().filter(|_| reuse.is_some());
        // Only a new solver needs the reference pose (no copy per solve otherwise).
        let solver = match (reuse, &drivers.reference) {
            (Some(s), _) => SolverSource::Reuse(s),
            (None, Some(reference)) => SolverSource::Build(reference.clone()),
            (None, None) => return None,
        };
        let given = solves.start.is_some();
        let current = solves.start.take().unwrap_or_else(|| posed.pose.clone());
        Some(Self {
            model: posed.model.clone(),
            constraints,
            solver,
            last: solution,
            current,
            given,
            options,
            recast,
        })
    }

    /// Runs the solve (building the solver when the last one does not fit); `cancel` is
    /// polled between iterations.
    pub(super) fn run(&self, cancel: &dyn Fn() -> bool) -> SolveResult {
        let t0 = Instant::now();
        let solver = match &self.solver {
            SolverSource::Reuse(s) => s.clone(),
            SolverSource::Build(reference) => Arc::new(PoseSolver::new(
                self.model.clone(),
                &self.constraints,
                reference,
                PoseSolverSettings::default(),
            )?),
        };
        let start = PoseStart::following(self.last.as_deref(), &self.current, self.given);
        let mut solution = solver.solve(&self.constraints, &self.options, start, cancel)?;
        // Skin carried into ground that was not under it where the solve started: the floor
        // cast where it ended, and the solve taken on from there (a pass or two).
        if let Some(recast) = self.recast.as_ref().filter(|_| !solution.stats.cancelled) {
            let mut constraints = None;
            for _ in 0..FLOOR_PASSES {
                let Some(floor) = recast.floor_where_it_ended(&self.model, &solution.pose) else {
                    break;
                };
                let constraints = constraints.get_or_insert_with(|| self.constraints.clone());
                // The planes of the last pass's floor it meets in a valley stay: a vertex
                // pushed out of one face of a riser's foot is not pushed into the other.
                let floor = match constraints.floor.take() {
                    Some(earlier) => floor.with_valleys_of(&earlier),
                    None => floor,
                };
                constraints.floor = Some(floor);
                let options = PoseSolveOptions {
                    max_iterations: 1,
                    ..self.options
                };
                // A failed pass keeps the last pose.
                let Ok(mut next) =
                    solver.solve(constraints, &options, PoseStart::Warm(&solution), cancel)
                else {
                    break;
                };
                next.stats.iterations += solution.stats.iterations;
                solution = next;
                if solution.stats.cancelled {
                    break;
                }
            }
        }
        Ok(Landed {
            solver,
            solution,
            ms: t0.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// Starts the pending solve of a character in the background (the latest request wins);
    /// its constraints are kept as the running ones, to be queued again while it settles.
    pub(super) fn launch(
        solves: &mut PoseSolves,
        drivers: &PoseDrivers,
        last: &LastSolve,
        posed: &PosedSkeleton,
        options: (PoseSolveOptions, Option<FloorRecast>),
        status: &mut PoseStatus,
    ) {
        let Some(job) = Self::take(solves, drivers, last, posed, options) else {
            return;
        };
        solves.running = Some(job.constraints.clone());
        status.phase = DeformPhase::Solving;
        solves
            .task
            .spawn(move |cancellation| job.run(&|| cancellation.superseded()));
    }
}

/// Stores a landed solve: the status, the pose (as the layer over the animation under an
/// additive blend: over `animated`, this frame's animation for a solve inside the frame, else
/// the one the blend last read), and the solver and solution the next solve warm-starts from.
/// `more`: a solve is still pending (the status stays `Solving`).
pub(super) fn store_landed(
    posed: &mut PosedSkeleton,
    last: &mut LastSolve,
    status: &mut PoseStatus,
    (blend, memory, animated): (Option<&PoseBlend>, &BlendMemory, Option<SkeletonPose>),
    landed: Landed,
    more: bool,
) {
    let Landed {
        solver,
        solution,
        ms,
    } = landed;
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
    status.phase = if more {
        DeformPhase::Solving
    } else {
        DeformPhase::Idle
    };
    let pose = match blend {
        Some(b) if b.mode == PoseBlendMode::Additive => {
            let animated = animated.unwrap_or_else(|| memory.animated_pose());
            additive_layer(posed, (memory, &animated), b, &solution.pose)
        }
        _ => solution.pose.clone(),
    };
    posed.pose = pose.clone();
    last.written = Some(pose);
    last.solver = Some(solver);
    last.solution = Some(Arc::new(solution));
}
