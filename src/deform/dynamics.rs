//! Bends that wobble: the ARAP energy given inertia, stepped in time as projective dynamics
//! does (Bouaziz et al. 2014) — each implicit step minimises
//! `k · E_ARAP(x) + Σ m/(2h²) |x − (x₀ + h v₀)|²` by the same local/global iterations, with the
//! mass term in the factored system ([`SolverSettings::inertia`](super::SolverSettings::inertia)): one more factorization per
//! constraint set, steps that cost what a static iteration costs, stable for any step.
//!
//! Without gravity only the ratio of mass to stiffness matters, so the settings give it as a
//! frequency: [`DynamicsSettings::frequency`] is the ringing of the mesh's slowest mode *as
//! its Laplacian sees it* (the lowest eigenvalue `λ` of the free vertices' Laplacian, so
//! `k/m = (2π f)² / λ`), and [`DynamicsSettings::damping`] the damping ratio of that mode
//! (velocities are divided by `1 + 2 ζ ω h` every step). ARAP resists bending less than the
//! Laplacian does (the cells turn), so a slender part rings slower than `frequency` — a bar
//! ten times as long as it is thick, about five times slower — and a damping of 1, critical
//! for the Laplacian's mode, leaves every bending mode over-damped: no overshoot. Few
//! iterations per step damp the motion further (an implicit step that stops early). Steps are
//! fixed (`step`, 1/60 s); a frame runs the steps its time holds, at most `max_steps` (a hitch
//! drops the rest), so the motion is the same at any frame rate. Vertex masses are equal.

use std::f64::consts::TAU;

use glam::DVec3;

use super::{
    Acceleration, ArapSolver, Constraints, InitialGuess, Obstacle, Solution, SolveError,
    SolveOptions,
};

/// How a bend moves in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicsSettings {
    /// Ringing of the slowest mode, Hz (linearised).
    pub frequency: f64,
    /// Damping ratio of the slowest mode (1: critical).
    pub damping: f64,
    /// Seconds per step.
    pub step: f64,
    /// Steps per frame at most.
    pub max_steps: u32,
    /// Local/global iterations per step.
    pub iterations: u32,
}

impl Default for DynamicsSettings {
    fn default() -> Self {
        Self {
            frequency: 2.0,
            damping: 0.05,
            step: 1.0 / 60.0,
            max_steps: 8,
            iterations: 3,
        }
    }
}

impl DynamicsSettings {
    /// [`SolverSettings::inertia`](super::SolverSettings::inertia) for a constraint set whose
    /// static system's lowest eigenvalue is `lambda` ([`ArapSolver::lowest_eigenvalue`]):
    /// `m / (k h²) = λ / (2π f h)²`.
    pub fn inertia(&self, lambda: f64) -> f64 {
        lambda / (TAU * self.frequency * self.step).powi(2)
    }

    /// Whether the settings can step (positive, finite frequency and step; damping ≥ 0).
    pub fn is_valid(&self) -> bool {
        self.frequency > 0.0
            && self.frequency.is_finite()
            && self.step > 0.0
            && self.step.is_finite()
            && self.damping >= 0.0
            && self.damping.is_finite()
            && self.max_steps > 0
            && self.iterations > 0
    }
}

/// A mesh in motion: positions, velocities and the last step's solution (its rotations start
/// the next step), and the frame time not yet stepped.
#[derive(Debug, Clone)]
pub struct MeshMotion {
    positions: Vec<DVec3>,
    velocities: Vec<DVec3>,
    last: Option<Solution>,
    accumulated: f64,
}

impl MeshMotion {
    /// Still, at `positions` (welded).
    pub fn at_rest(positions: Vec<DVec3>) -> Self {
        Self {
            velocities: vec![DVec3::ZERO; positions.len()],
            positions,
            last: None,
            accumulated: 0.0,
        }
    }

    /// Still, at a solve's pose (its rotations start the first step).
    pub fn from_solution(solution: Solution) -> Self {
        let mut motion = Self::at_rest(solution.positions.clone());
        motion.last = Some(solution);
        motion
    }

    /// The positions now (welded).
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// The last step's solution (positions and cell rotations), once a step was made.
    pub fn solution(&self) -> Option<&Solution> {
        self.last.as_ref()
    }

    /// The fastest vertex's speed.
    pub fn max_speed(&self) -> f64 {
        self.velocities
            .iter()
            .map(|v| v.length())
            .fold(0.0, f64::max)
    }

    /// Runs the steps `dt` seconds hold under `constraints` with `solver` (factored with
    /// [`DynamicsSettings::inertia`] of the set's lowest eigenvalue); returns how many were
    /// made. A failed step leaves the motion at the last good one (the error says why).
    pub fn advance(
        &mut self,
        solver: &ArapSolver,
        constraints: &Constraints,
        settings: &DynamicsSettings,
        dt: f64,
        obstacle: Option<&dyn Obstacle>,
    ) -> Result<u32, SolveError> {
        if !(dt.is_finite() && dt >= 0.0 && settings.is_valid()) {
            return Err(SolveError::NonFinite);
        }
        let h = settings.step;
        self.accumulated += dt;
        let mut steps = (self.accumulated / h + 1e-9).floor() as u32;
        if steps > settings.max_steps {
            steps = settings.max_steps;
            self.accumulated = h * f64::from(steps);
        }
        let omega = TAU * settings.frequency;
        let decay = 1.0 / (1.0 + 2.0 * settings.damping * omega * h);
        let options = SolveOptions {
            max_iterations: settings.iterations,
            tolerance: 0.0,
            acceleration: Acceleration::None,
        };
        for _ in 0..steps {
            let target: Vec<DVec3> = self
                .positions
                .iter()
                .zip(&self.velocities)
                .map(|(x, v)| *x + *v * h)
                .collect();
            // The last step's solution starts this one (its rotations; positions moved to the
            // prediction), without a copy.
            let mut start = self.last.take().unwrap_or_else(|| Solution {
                positions: Vec::new(),
                rotations: vec![glam::DQuat::IDENTITY; target.len()],
                stats: Default::default(),
                history: Default::default(),
            });
            let previous = std::mem::replace(&mut start.positions, target);
            let result = solver.solve_inertial(
                constraints,
                &options,
                InitialGuess::Warm(&start),
                &start.positions,
                obstacle,
                &|| false,
            );
            let next = match result {
                Ok(next) => next,
                Err(e) => {
                    start.positions = previous;
                    self.last = Some(start);
                    return Err(e);
                }
            };
            for ((v, x), n) in self
                .velocities
                .iter_mut()
                .zip(&self.positions)
                .zip(&next.positions)
            {
                *v = (*n - *x) / h * decay;
            }
            self.positions.clone_from(&next.positions);
            self.last = Some(next);
            self.accumulated -= h;
        }
        Ok(steps)
    }
}
