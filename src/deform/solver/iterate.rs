//! The iterations of a solve: plain or Anderson-accelerated local/global, and L-BFGS on the
//! energy. All keep the energy from rising: an accelerated iterate that does not lower it is
//! replaced by the plain local/global step, which never raises it.

use web_time::Instant;

use glam::{DMat3, DQuat, DVec3};

use super::contacts::ContactSet;
use super::{ArapSolver, SolveError, SolveOptions, SolveStats};
use crate::deform::anderson::Anderson;
use crate::deform::lbfgs::{Lbfgs, dot};

/// Backtracking halvings of an L-BFGS step before the plain step is taken instead.
const LINE_SEARCH_TRIALS: u32 = 4;
/// Sufficient-decrease constant of the line search (Armijo).
const ARMIJO: f64 = 1e-4;
/// Relative energy change below which a step is rounding noise.
const ROUNDING: f64 = 1e-12;

/// The state a solve iterates on (solver memory order).
pub(super) struct Iterate<'a> {
    /// All positions; free ones are the unknowns.
    pub x: Vec<DVec3>,
    /// Cell rotations.
    pub quats: Vec<DQuat>,
    /// The same as matrices.
    pub mats: Vec<DMat3>,
    /// Scratch: right-hand side in elimination order.
    pub rhs: Vec<DVec3>,
    /// Scratch: right-hand side per vertex.
    pub rhs_by_vertex: Vec<DVec3>,
    /// Scratch: a line search's trial positions (free vertices).
    pub trial: Vec<DVec3>,
    /// Un-normalised energy of the cells with no free vertex.
    pub constant_energy: f64,
    /// Normalised energy of `x` with its fitted rotations, when known.
    pub energy: Option<f64>,
    /// Statistics so far.
    pub stats: SolveStats,
    /// The obstacle the free vertices stay above, and its active set.
    pub contacts: Option<ContactSet<'a>>,
    /// The inertial target of the free vertices (elimination order), weighted by
    /// [`super::SolverSettings::inertia`] in every global step.
    pub inertial: Option<Vec<DVec3>>,
}

impl ArapSolver {
    /// Normalised energy of `it.x`, fitting the rotations of the active cells to it.
    pub(super) fn refit(&self, it: &mut Iterate) -> f64 {
        let tl = Instant::now();
        let e = (it.constant_energy + self.local_step(&it.x, &mut it.quats, &mut it.mats, true))
            / self.layout.rest_norm.max(f64::MIN_POSITIVE);
        it.stats.local_s += tl.elapsed().as_secs_f64();
        e
    }

    /// Writes the plain local/global image `G(x)` of the free positions into `it.rhs`.
    pub(super) fn global_step(&self, it: &mut Iterate) {
        let tr = Instant::now();
        self.arap_rhs(&it.x, &it.mats, &mut it.rhs_by_vertex, &mut it.rhs);
        if let Some(target) = &it.inertial {
            let w = self.settings.inertia;
            for (r, y) in it.rhs.iter_mut().zip(target) {
                *r += w * *y;
            }
        }
        let tg = Instant::now();
        self.cot_factor.solve_in_place(&mut it.rhs, self.parallel);
        if let Some(contacts) = it.contacts.as_mut() {
            self.project_above(&mut it.rhs, contacts);
        }
        it.stats.back_substitutions += 1;
        it.stats.rhs_s += (tg - tr).as_secs_f64();
        it.stats.global_s += tg.elapsed().as_secs_f64();
    }

    /// Records an iteration's energy; true when the tolerance says stop.
    pub(super) fn finish_iteration(it: &mut Iterate, e: f64, options: &SolveOptions) -> bool {
        it.stats.iterations += 1;
        it.stats.energies.push(e);
        let stop = it.energy.is_some_and(|pe| {
            let decrease = (pe - e) / f64::max(pe, 1e-300);
            options.tolerance > 0.0 && decrease < options.tolerance
        });
        it.energy = Some(e);
        stop
    }

    /// Whether to stop before the next iteration (`Err` when none was done yet).
    pub(super) fn cancelled(
        it: &mut Iterate,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<bool, SolveError> {
        if !should_cancel() {
            return Ok(false);
        }
        if it.stats.iterations == 0 {
            return Err(SolveError::Cancelled);
        }
        it.stats.cancelled = true;
        Ok(true)
    }

    /// Local/global iterations, Anderson-accelerated when `depth > 0`.
    pub(super) fn iterate_local_global(
        &self,
        it: &mut Iterate,
        depth: usize,
        options: &SolveOptions,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<(), SolveError> {
        let mut anderson = (depth > 0).then(|| Anderson::new(depth, self.parallel));
        let (mut proposal, mut current) = (Vec::new(), Vec::new());
        for _ in 0..options.max_iterations {
            if Self::cancelled(it, should_cancel)? {
                break;
            }
            self.global_step(it);
            // `it.rhs` now holds G(y): the plain next iterate.
            let ta = Instant::now();
            let extrapolated = match anderson.as_mut() {
                Some(aa) if it.energy.is_some() => {
                    current.clear();
                    current.extend(self.free.iter().map(|&i| it.x[i as usize]));
                    aa.extrapolate(&current, &it.rhs, &mut proposal)
                }
                _ => false,
            };
            it.stats.acceleration_s += ta.elapsed().as_secs_f64();
            let mut e = f64::INFINITY;
            if extrapolated {
                if let Some(contacts) = it.contacts.as_mut() {
                    self.project_above(&mut proposal, contacts);
                }
                self.write_free(&proposal, &mut it.x);
                e = self.refit(it);
            }
            // An extrapolation must lower the energy; otherwise take the plain step,
            // which never raises it.
            let accepted = extrapolated && it.energy.is_some_and(|pe| e < pe);
            if !accepted {
                if extrapolated {
                    it.stats.rejected_extrapolations += 1;
                    if let Some(aa) = anderson.as_mut() {
                        aa.reset();
                    }
                }
                self.write_free(&it.rhs, &mut it.x);
                e = self.refit(it);
            }
            if Self::finish_iteration(it, e, options) {
                break;
            }
        }
        Ok(())
    }

    /// L-BFGS iterations on the energy, preconditioned by the factored Laplacian: with an
    /// empty `history` the first direction is the plain local/global step, later ones add the
    /// curvature pairs (a warm start may bring pairs from the previous solve). Each
    /// direction is line-searched (Armijo, halving); when that fails the plain step is taken
    /// and the history forgotten.
    pub(super) fn iterate_lbfgs(
        &self,
        it: &mut Iterate,
        history: &mut Lbfgs,
        options: &SolveOptions,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<(), SolveError> {
        let mut e = self.start_energy(it);
        let mut g = vec![DVec3::ZERO; self.free.len()];
        let mut g_new = g.clone();
        self.gradient(it, &mut g);
        let mut xf: Vec<DVec3> = self.free.iter().map(|&i| it.x[i as usize]).collect();
        let mut direction = Vec::with_capacity(g.len());
        let mut trial = Vec::with_capacity(g.len());
        for _ in 0..options.max_iterations {
            if Self::cancelled(it, should_cancel)? {
                break;
            }
            // `direction` = H g; the step is −direction.
            let ta = Instant::now();
            direction.clone_from(&g);
            history.apply(&mut direction, self.parallel, |q| {
                self.precondition(&mut it.stats, q)
            });
            if dot(&g, &direction, self.parallel).partial_cmp(&0.0)
                != Some(std::cmp::Ordering::Greater)
                && history.len() > 0
            {
                // Not a descent direction (or NaN): restart from the plain step.
                history.reset();
                direction.clone_from(&g);
                self.precondition(&mut it.stats, &mut direction);
            }
            direction.iter_mut().for_each(|d| *d = -*d);
            it.stats.acceleration_s += ta.elapsed().as_secs_f64();
            let (e_new, plain) = self.line_search(it, &xf, &direction, &g, e);
            if plain {
                history.reset();
            }
            trial.clear();
            trial.extend(self.free.iter().map(|&i| it.x[i as usize]));
            self.gradient(it, &mut g_new);
            let ta = Instant::now();
            // A step that changed the energy only at rounding level (at rest, or converged)
            // measures noise, not curvature.
            if e - e_new > ROUNDING * e {
                let (mut s, mut y) = history.spare_buffers();
                s.extend(trial.iter().zip(&xf).map(|(a, b)| *a - *b));
                y.extend(g_new.iter().zip(&g).map(|(a, b)| *a - *b));
                history.push(s, y, self.parallel);
            }
            it.stats.acceleration_s += ta.elapsed().as_secs_f64();
            std::mem::swap(&mut xf, &mut trial);
            std::mem::swap(&mut g, &mut g_new);
            e = e_new;
            if Self::finish_iteration(it, e, options) {
                break;
            }
        }
        Ok(())
    }

    /// Line search from the free positions `xf` (energy `e`, gradient `g`) along the step `d`:
    /// `xf + α d` for α = 1, ½, ¼, … until the energy falls enough (Armijo); when none does,
    /// the plain local/global step from `xf`, which never raises it. Leaves the accepted
    /// positions and their fitted rotations in `it`; returns their energy and whether the plain
    /// step was taken.
    pub(super) fn line_search(
        &self,
        it: &mut Iterate,
        xf: &[DVec3],
        d: &[DVec3],
        g: &[DVec3],
        e: f64,
    ) -> (f64, bool) {
        // ∇E = 4 g in un-normalised energy.
        let slope = 4.0 * dot(g, d, self.parallel) / self.layout.rest_norm.max(f64::MIN_POSITIVE);
        let mut alpha = 1.0;
        let mut trial = std::mem::take(&mut it.trial);
        if slope < 0.0 {
            for _ in 0..LINE_SEARCH_TRIALS {
                trial.clear();
                trial.extend(xf.iter().zip(d).map(|(x, d)| *x + alpha * *d));
                self.write_free(&trial, &mut it.x);
                let et = self.refit(it);
                if et <= e + ARMIJO * alpha * slope {
                    it.trial = trial;
                    return (et, false);
                }
                it.stats.rejected_extrapolations += 1;
                alpha *= 0.5;
            }
        }
        it.trial = trial;
        self.write_free(xf, &mut it.x);
        self.refit(it);
        (self.plain_step(it), true)
    }

    /// `g = L x − b(R)` on the free vertices in elimination order: a quarter of the energy's
    /// gradient (rotations fitted to `x`, so they contribute nothing by optimality).
    pub(super) fn gradient(&self, it: &mut Iterate, out: &mut [DVec3]) {
        let tr = Instant::now();
        self.laplacian_minus_rotated(&it.x, &it.mats, &mut it.rhs_by_vertex, out);
        it.stats.rhs_s += tr.elapsed().as_secs_f64();
    }

    /// Applies the inverse of the factored Laplacian to `v` in place (counted).
    pub(super) fn precondition(&self, stats: &mut SolveStats, v: &mut [DVec3]) {
        let tg = Instant::now();
        self.cot_factor.solve_in_place(v, self.parallel);
        stats.global_s += tg.elapsed().as_secs_f64();
        stats.back_substitutions += 1;
    }

    /// One plain local/global step from `it.x` (rotations fitted to it): the free positions
    /// become `G(x)`, the rotations are refitted; returns the new energy.
    pub(super) fn plain_step(&self, it: &mut Iterate) -> f64 {
        self.global_step(it);
        self.write_free(&it.rhs, &mut it.x);
        self.refit(it)
    }

    /// Fits the rotations to the starting positions (a warm start carries the previous
    /// solve's) and records the starting energy.
    pub(super) fn start_energy(&self, it: &mut Iterate) -> f64 {
        let e = self.refit(it);
        if it.stats.initial_energy.is_none() {
            it.stats.initial_energy = Some(e);
        }
        it.energy = Some(e);
        e
    }
}
