//! [`SlicedSolve`]: one solve spread over several calls, each running at most a budget of
//! iterations — how a frame bounds its solving where the solve cannot leave the frame's thread
//! (the web: Bevy's task pools run on the browser's main thread).
//!
//! Each slice warm-starts from the last one's positions and rotations and carries its L-BFGS
//! curvature pairs, so slicing a plain or L-BFGS solve changes nothing but when its iterations
//! run: the final positions equal one uninterrupted solve's (to rounding; tested). Anderson's
//! and Newton's inner state is not carried: sliced, they restart their acceleration each
//! slice, which lowers the energy as surely but along another path.

use super::{ArapSolver, InitialGuess, Solution, SolveError, SolveOptions};
use crate::deform::constraints::Constraints;

/// Where a sliced solve stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SliceProgress {
    /// Iterations remain: call [`SlicedSolve::advance`] again (next frame).
    Running {
        /// Iterations done so far.
        done: u32,
    },
    /// All iterations ran, or the tolerance stopped it.
    Finished {
        /// Iterations done.
        done: u32,
    },
}

/// A solve of `options.max_iterations` iterations run a budget at a time.
#[derive(Debug, Clone)]
pub struct SlicedSolve {
    constraints: Constraints,
    options: SolveOptions,
    laplacian_start: bool,
    done: u32,
    finished: bool,
    current: Option<Solution>,
}

impl SlicedSolve {
    /// A solve of `constraints` from `start` (`None`: the rest pose, or the paper's Laplacian
    /// guess when `laplacian_start`), to run `options.max_iterations` iterations in all.
    pub fn new(
        constraints: Constraints,
        options: SolveOptions,
        start: Option<Solution>,
        laplacian_start: bool,
    ) -> Self {
        Self {
            constraints,
            options,
            laplacian_start,
            done: 0,
            finished: options.max_iterations == 0,
            current: start,
        }
    }

    /// Runs up to `budget` more iterations (at least one) with `solver`.
    pub fn advance(
        &mut self,
        solver: &ArapSolver,
        budget: u32,
    ) -> Result<SliceProgress, SolveError> {
        if self.finished {
            return Ok(SliceProgress::Finished { done: self.done });
        }
        let slice = budget.max(1).min(self.options.max_iterations - self.done);
        let options = SolveOptions {
            max_iterations: slice,
            ..self.options
        };
        let initial = match &self.current {
            Some(previous) => InitialGuess::Warm(previous),
            None if self.laplacian_start => InitialGuess::Laplacian,
            None => InitialGuess::Rest,
        };
        let solution = solver.solve(&self.constraints, &options, initial, &|| false)?;
        let ran = solution.stats.iterations;
        self.done += ran;
        // Fewer iterations than asked: the tolerance stopped it.
        self.finished = ran < slice || self.done >= self.options.max_iterations;
        self.current = Some(solution);
        Ok(if self.finished {
            SliceProgress::Finished { done: self.done }
        } else {
            SliceProgress::Running { done: self.done }
        })
    }

    /// The latest slice's solution (`None` before the first).
    pub fn solution(&self) -> Option<&Solution> {
        self.current.as_ref()
    }

    /// Whether every iteration has run.
    pub fn is_finished(&self) -> bool {
        self.finished
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{DQuat, DVec3};

    use super::*;
    use crate::deform::{Acceleration, RigidTransform, SolverSettings, Topology, synth};

    /// A bar bent by a turned and moved handle, its solver and constraints.
    fn bent_bar() -> (ArapSolver, Constraints) {
        let bar = synth::bar(8, 24, 0.1, 1.0);
        let topology = Arc::new(Topology::new(&bar.positions, &bar.triangles).unwrap());
        let (fixed, handle) = synth::slab_regions(topology.positions(), 1, 0.1, 0.1);
        let mut c = Constraints::with_handle(fixed, handle, RigidTransform::IDENTITY);
        c.handles[0].transform =
            RigidTransform::new(DQuat::from_rotation_z(0.9), DVec3::X * 0.3, DVec3::Y);
        let solver = ArapSolver::precompute(topology, &c, SolverSettings::default()).unwrap();
        (solver, c)
    }

    fn max_difference(a: &Solution, b: &Solution) -> f64 {
        a.positions
            .iter()
            .zip(&b.positions)
            .map(|(p, q)| (*p - *q).length())
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_solve_split_across_frames_ends_where_one_uninterrupted_solve_does() {
        let (solver, c) = bent_bar();
        for acceleration in [Acceleration::None, Acceleration::Lbfgs { depth: 8 }] {
            let options = SolveOptions {
                max_iterations: 23,
                tolerance: 0.0,
                acceleration,
            };
            let whole = solver
                .solve(&c, &options, InitialGuess::Laplacian, &|| false)
                .unwrap();
            for budget in [1, 4, 7] {
                let mut sliced = SlicedSolve::new(c.clone(), options, None, true);
                let mut frames = 0;
                while !sliced.is_finished() {
                    sliced.advance(&solver, budget).unwrap();
                    frames += 1;
                }
                assert_eq!(frames, 23_u32.div_ceil(budget), "{acceleration:?}");
                let d = max_difference(sliced.solution().unwrap(), &whole);
                assert!(d < 1e-12, "{acceleration:?}, budget {budget}: {d:e}");
            }
            // The pose really moved over the slices: a solve of only the first slice is
            // elsewhere.
            let first = solver
                .solve(
                    &c,
                    &SolveOptions {
                        max_iterations: 4,
                        ..options
                    },
                    InitialGuess::Laplacian,
                    &|| false,
                )
                .unwrap();
            assert!(max_difference(&first, &whole) > 1e-6, "{acceleration:?}");
        }
    }

    #[test]
    fn a_tolerance_stop_finishes_the_sliced_solve() {
        let (solver, c) = bent_bar();
        let options = SolveOptions {
            max_iterations: 500,
            tolerance: 1e-4,
            acceleration: Acceleration::None,
        };
        let mut sliced = SlicedSolve::new(c, options, None, false);
        let mut frames = 0;
        while !sliced.is_finished() && frames < 1000 {
            sliced.advance(&solver, 5).unwrap();
            frames += 1;
        }
        assert!(sliced.is_finished() && frames < 100, "{frames} frames");
    }
}
