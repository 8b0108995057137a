//! A solve: the starting state, the iterations of the chosen acceleration, the result.

use web_time::Instant;

use glam::{DMat3, DQuat, DVec3};

use super::contacts::ContactSet;
use super::iterate::Iterate;
use super::{
    Acceleration, ArapSolver, CarriedHistory, InitialGuess, Solution, SolveError, SolveOptions,
    SolveStats,
};
use crate::deform::constraints::{Constraints, Role};
use crate::deform::lbfgs::Lbfgs;
use crate::deform::obstacle::Obstacle;

impl ArapSolver {
    /// Solves for the given constraint values. `should_cancel` is polled before every
    /// iteration (and between Newton's conjugate-gradient steps, which then end that iteration
    /// with the direction found so far); when it returns true the solve stops: with
    /// [`SolveError::Cancelled`] if no iteration was done yet, otherwise with the last
    /// completed iteration and [`SolveStats::cancelled`] set.
    pub fn solve(
        &self,
        constraints: &Constraints,
        options: &SolveOptions,
        initial: InitialGuess<'_>,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<Solution, SolveError> {
        self.solve_with(constraints, options, initial, None, None, should_cancel)
    }

    /// [`ArapSolver::solve`] keeping every free vertex on or above `obstacle` (in the mesh's
    /// coordinates; [`crate::deform::obstacle`]). Give it constraints lifted onto the surface
    /// ([`Constraints::lifted_above`]) so that handles do not drag vertices below it. With an
    /// obstacle, L-BFGS and Anderson run as Anderson-accelerated local/global iterations and
    /// Newton as plain ones (each global step is the projected one);
    /// [`SolveStats::contacts`] counts the vertices held on the surface at the end.
    pub fn solve_above(
        &self,
        constraints: &Constraints,
        options: &SolveOptions,
        initial: InitialGuess<'_>,
        obstacle: &dyn Obstacle,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<Solution, SolveError> {
        self.solve_with(
            constraints,
            options,
            initial,
            Some(obstacle),
            None,
            should_cancel,
        )
    }

    /// One implicit time step's solve: the ARAP energy plus
    /// [`SolverSettings::inertia`](super::SolverSettings::inertia)` · |x − target|²` over the
    /// free vertices (`target`: welded positions, the inertial prediction `x + h v`), as
    /// projective dynamics does — the same local/global iterations with the mass term in the
    /// factored system. Runs plain local/global iterations whatever `options.acceleration`
    /// says; the reported energies are the ARAP part. `obstacle`, when given, is kept above as
    /// in [`ArapSolver::solve_above`].
    pub fn solve_inertial(
        &self,
        constraints: &Constraints,
        options: &SolveOptions,
        initial: InitialGuess<'_>,
        target: &[DVec3],
        obstacle: Option<&dyn Obstacle>,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<Solution, SolveError> {
        if target.len() != self.layout.rest.len() {
            return Err(SolveError::WarmStartMismatch {
                got: target.len(),
                expected: self.layout.rest.len(),
            });
        }
        if !target.iter().all(|p| p.is_finite()) {
            return Err(SolveError::NonFinite);
        }
        self.solve_with(
            constraints,
            options,
            initial,
            obstacle,
            Some(target),
            should_cancel,
        )
    }

    /// The lowest eigenvalue of the factored system (the free vertices' Laplacian, plus
    /// [`SolverSettings::inertia`](super::SolverSettings::inertia)), by inverse iteration from a
    /// fixed start: the slowest mode's stiffness per unit mass ([`crate::deform::dynamics`]).
    /// 0 without free vertices.
    pub fn lowest_eigenvalue(&self) -> f64 {
        let m = self.free.len();
        if m == 0 {
            return 0.0;
        }
        // Three starts at once (one per coordinate), smooth and not orthogonal to the
        // slowest mode of a mesh held anywhere.
        let mut v: Vec<DVec3> = (0..m)
            .map(|k| {
                let t = k as f64 / m as f64;
                DVec3::new(1.0, 1.0 + t, 1.0 + (7.0 * t).sin())
            })
            .collect();
        let mut estimate = DVec3::ZERO;
        for _ in 0..40 {
            let before: DVec3 = v.iter().map(|p| *p * *p).sum::<DVec3>();
            self.cot_factor.solve_in_place(&mut v, self.parallel);
            let after: DVec3 = v.iter().map(|p| *p * *p).sum::<DVec3>();
            estimate = DVec3::new(
                (before.x / after.x).sqrt(),
                (before.y / after.y).sqrt(),
                (before.z / after.z).sqrt(),
            );
            let scale = DVec3::ONE / DVec3::new(after.x.sqrt(), after.y.sqrt(), after.z.sqrt());
            for p in &mut v {
                *p *= scale;
            }
        }
        estimate.min_element()
    }

    fn solve_with(
        &self,
        constraints: &Constraints,
        options: &SolveOptions,
        initial: InitialGuess<'_>,
        obstacle: Option<&dyn Obstacle>,
        inertial: Option<&[DVec3]>,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<Solution, SolveError> {
        let t0 = Instant::now();
        if !self.accepts(constraints) {
            return Err(SolveError::ConstraintSetChanged);
        }
        constraints.check_values()?;
        let layout = &self.layout;
        let n = layout.rest.len();
        let mut stats = SolveStats::default();
        let (mut x, mut quats) = self.starting_state(constraints, initial)?;
        let mut mats: Vec<DMat3> = quats.iter().map(|q| DMat3::from_quat(*q)).collect();
        let mut rhs = vec![DVec3::ZERO; self.free.len()];
        let rhs_by_vertex = vec![DVec3::ZERO; n];

        // Inactive cells (no free vertex in the one-ring) never change during the solve.
        let tl = Instant::now();
        let constant_energy = self.local_step(&x, &mut quats, &mut mats, false);
        stats.local_s += tl.elapsed().as_secs_f64();

        let ti = Instant::now();
        let mut prev_energy = None;
        match initial {
            InitialGuess::Laplacian if !self.free.is_empty() => {
                self.uniform_rhs(&x, &mut rhs);
                self.back_substitute(self.uniform.get()?, &mut rhs, &mut x);
            }
            _ => {}
        }
        stats.init_s = ti.elapsed().as_secs_f64();
        if !matches!(initial, InitialGuess::Warm(_) | InitialGuess::Rest) {
            let tl = Instant::now();
            let e = (constant_energy + self.local_step(&x, &mut quats, &mut mats, true))
                / self.layout.rest_norm.max(f64::MIN_POSITIVE);
            stats.local_s += tl.elapsed().as_secs_f64();
            stats.initial_energy = Some(e);
            prev_energy = Some(e);
        }

        let mut it = Iterate {
            x,
            quats,
            mats,
            rhs,
            rhs_by_vertex,
            trial: Vec::new(),
            constant_energy,
            energy: prev_energy,
            stats,
            contacts: obstacle.map(ContactSet::new),
            inertial: inertial.map(|target| {
                let welded = &self.layout.to_welded;
                self.free
                    .iter()
                    .map(|&i| target[welded[i as usize] as usize])
                    .collect()
            }),
        };
        let carry = self.iterate(&mut it, initial, options, should_cancel)?;
        let Iterate {
            x,
            mut quats,
            mut mats,
            mut stats,
            contacts,
            ..
        } = it;
        stats.contacts = contacts.map_or(0, |c| c.active());
        if matches!(initial, InitialGuess::Rest | InitialGuess::Warm(_)) && stats.iterations == 0 {
            // Rotations of free cells were never fitted for these positions.
            let e = constant_energy + self.local_step(&x, &mut quats, &mut mats, true);
            stats.initial_energy = Some(e / self.layout.rest_norm.max(f64::MIN_POSITIVE));
        }
        if !x.iter().all(|p| p.is_finite()) || !quats.iter().all(|q| q.is_finite()) {
            return Err(SolveError::NonFinite);
        }
        stats.total_s = t0.elapsed().as_secs_f64();
        Ok(Solution {
            positions: layout.scatter(&x),
            rotations: layout.scatter(&quats),
            stats,
            history: carry,
        })
    }

    /// The positions a solve starts from (known ones placed, free ones at rest or the warm
    /// start's) and the rotations (identity, or the warm start's), in solver order.
    fn starting_state(
        &self,
        constraints: &Constraints,
        initial: InitialGuess<'_>,
    ) -> Result<(Vec<DVec3>, Vec<DQuat>), SolveError> {
        let layout = &self.layout;
        let n = layout.rest.len();
        let rest = &layout.rest[..];
        let mut x: Vec<DVec3> = match initial {
            InitialGuess::Warm(prev) => {
                if prev.positions.len() != n || prev.rotations.len() != n {
                    return Err(SolveError::WarmStartMismatch {
                        got: prev.positions.len(),
                        expected: n,
                    });
                }
                layout.gather(&prev.positions)
            }
            _ => rest.to_vec(),
        };
        for i in 0..n {
            let role = self.roles[i];
            if role != Role::Free {
                x[i] = constraints.position_of(role, rest[i]);
            }
        }
        let quats = match initial {
            InitialGuess::Warm(prev) => layout.gather(&prev.rotations),
            _ => vec![DQuat::IDENTITY; n],
        };
        Ok((x, quats))
    }

    /// Runs the iterations of `options.acceleration`; the L-BFGS history to carry into a warm
    /// start of this factorization.
    fn iterate(
        &self,
        it: &mut Iterate,
        initial: InitialGuess<'_>,
        options: &SolveOptions,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<CarriedHistory, SolveError> {
        if self.free.is_empty() {
            return Ok(CarriedHistory::default());
        }
        if it.inertial.is_some() {
            // A time step: the global step carries the inertial target.
            self.iterate_local_global(it, 0, options, should_cancel)?;
            return Ok(CarriedHistory::default());
        }
        if it.contacts.is_some() {
            // Projected global steps: local/global iterations only.
            let depth = match options.acceleration {
                Acceleration::Lbfgs { depth } | Acceleration::Anderson { depth } => depth,
                Acceleration::None | Acceleration::Newton { .. } => 0,
            };
            self.iterate_local_global(it, depth, options, should_cancel)?;
            return Ok(CarriedHistory::default());
        }
        match options.acceleration {
            Acceleration::Lbfgs { depth } => {
                let carried = match initial {
                    InitialGuess::Warm(prev) => match &prev.history.0 {
                        Some((id, h)) if *id == self.id && h.depth() == depth => Some(h),
                        _ => None,
                    },
                    _ => None,
                };
                let mut history = carried.cloned().unwrap_or_else(|| Lbfgs::new(depth));
                self.iterate_lbfgs(it, &mut history, options, should_cancel)?;
                return Ok(CarriedHistory(Some((self.id, history))));
            }
            Acceleration::Newton { max_cg } => {
                self.iterate_newton(it, max_cg, options, should_cancel)?
            }
            Acceleration::None => self.iterate_local_global(it, 0, options, should_cancel)?,
            Acceleration::Anderson { depth } => {
                self.iterate_local_global(it, depth, options, should_cancel)?
            }
        }
        Ok(CarriedHistory::default())
    }
}
