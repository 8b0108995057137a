//! Free vertices kept above an [`Obstacle`]: after each global step, the free positions are
//! projected onto the half-spaces of the vertices that went below, in the norm of the factored
//! Laplacian `L`. For the plain local/global step this projection *is* the constrained global
//! step (the minimiser of the step's quadratic `½ xᵀLx − bᵀx` subject to `n·x_v ≥ d` for the
//! active vertices), so the iteration stays a block descent on the energy, contacts included.
//!
//! Each active vertex `v` contributes one column `g_v = L⁻¹ e_v` (three columns per triangular
//! solve: one per coordinate of a [`DVec3`]); they are cached on the solver, so a drag that
//! keeps touching the floor pays for a column once. With `k` active vertices a projection costs
//! a `k × k` dense solve and `k` passes over the free vertices. Vertices whose multiplier would
//! pull them down (the bend lifts them off) leave the active set; vertices pushed below by the
//! correction join it (a few rounds at most).

use std::collections::HashMap;
use std::sync::Arc;

use glam::DVec3;

use super::ArapSolver;
use crate::deform::obstacle::Obstacle;

/// Rounds of adding and releasing active vertices per projection.
const ACTIVE_SET_ROUNDS: usize = 24;
/// Cached columns are dropped all at once beyond this many `f64`s (64 MB).
const COLUMN_CACHE_LIMIT: usize = 8 << 20;

/// `L⁻¹ e_k` for free vertices `k` (elimination order), kept across solves.
#[derive(Debug, Default)]
pub(super) struct ColumnCache {
    columns: HashMap<u32, Arc<[f64]>>,
    stored: usize,
}

/// A vertex held on the surface: `normal · x ≥ offset`.
#[derive(Debug, Clone, Copy)]
struct Active {
    /// Free index (elimination order).
    k: u32,
    normal: DVec3,
    offset: f64,
}

/// The obstacle of a solve and its active set.
pub(super) struct ContactSet<'a> {
    obstacle: &'a dyn Obstacle,
    active: Vec<Active>,
    /// Scratch of every projection (kept between iterations): the positions it started from,
    /// and which vertices are held.
    start: Vec<DVec3>,
    held: Vec<bool>,
}

impl<'a> ContactSet<'a> {
    pub(super) fn new(obstacle: &'a dyn Obstacle) -> Self {
        Self {
            obstacle,
            active: Vec::new(),
            start: Vec::new(),
            held: Vec::new(),
        }
    }

    /// Vertices held on the surface after the last projection.
    pub(super) fn active(&self) -> usize {
        self.active.len()
    }
}

impl ArapSolver {
    /// Projects the free positions `y` (elimination order) onto the obstacle's allowed side in
    /// the Laplacian's norm (module docs).
    pub(super) fn project_above(&self, y: &mut [DVec3], contacts: &mut ContactSet<'_>) {
        let (mut y0, mut held) = (
            std::mem::take(&mut contacts.start),
            std::mem::take(&mut contacts.held),
        );
        y0.clear();
        y0.extend_from_slice(y);
        held.clear();
        held.resize(y.len(), false);
        self.project_from(y, &y0, &mut held, contacts);
        (contacts.start, contacts.held) = (y0, held);
    }

    /// [`Self::project_above`] from the positions `y0` (a copy of `y`), `held` all false.
    fn project_from(
        &self,
        y: &mut [DVec3],
        y0: &[DVec3],
        held: &mut [bool],
        contacts: &mut ContactSet<'_>,
    ) {
        let obstacle = contacts.obstacle;
        // Vertices held by the last projection start held, on the surface where they are now.
        contacts.active.retain_mut(|a| {
            let k = a.k as usize;
            let sample = obstacle
                .surface_at(y0[k])
                .filter(|s| s.point.is_finite() && s.normal.is_finite());
            match sample {
                Some(s) if !held[k] => {
                    held[k] = true;
                    a.normal = s.normal;
                    a.offset = s.normal.dot(s.point);
                    true
                }
                _ => false,
            }
        });
        hold_below(obstacle, y, held, &mut contacts.active);
        for _ in 0..ACTIVE_SET_ROUNDS {
            if contacts.active.is_empty() {
                y.copy_from_slice(y0);
                return;
            }
            let columns = self.columns(contacts.active.iter().map(|a| a.k));
            let Some(lambda) = multipliers(&contacts.active, &columns, y0) else {
                contacts.active.clear();
                y.copy_from_slice(y0);
                return;
            };
            // A positive multiplier pulls its vertex down onto the surface: let those go.
            if lambda.iter().any(|l| *l > 0.0) {
                let mut j = 0;
                contacts.active.retain(|a| {
                    let keep = lambda[j] <= 0.0;
                    j += 1;
                    held[a.k as usize] &= keep;
                    keep
                });
                continue;
            }
            y.copy_from_slice(y0);
            correct(&contacts.active, &columns, &lambda, y);
            if !hold_below(obstacle, y, held, &mut contacts.active) {
                return;
            }
        }
        // Out of rounds: every held vertex on its plane, whatever its multiplier.
        let columns = self.columns(contacts.active.iter().map(|a| a.k));
        if let Some(lambda) = multipliers(&contacts.active, &columns, y0) {
            y.copy_from_slice(y0);
            correct(&contacts.active, &columns, &lambda, y);
        }
    }

    /// The cached columns `L⁻¹ e_k` for `ks`, solving for the missing ones three at a time.
    fn columns(&self, ks: impl Iterator<Item = u32>) -> Vec<Arc<[f64]>> {
        let ks: Vec<u32> = ks.collect();
        let m = self.free.len();
        let mut cache = self
            .columns
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let mut missing: Vec<u32> = ks
            .iter()
            .copied()
            .filter(|k| !cache.columns.contains_key(k))
            .collect();
        missing.sort_unstable();
        missing.dedup();
        if cache.stored + missing.len() * m > COLUMN_CACHE_LIMIT {
            cache.columns.clear();
            cache.stored = 0;
            missing = ks.clone();
            missing.sort_unstable();
            missing.dedup();
        }
        let mut rhs = vec![DVec3::ZERO; m];
        for three in missing.chunks(3) {
            rhs.iter_mut().for_each(|r| *r = DVec3::ZERO);
            for (c, &k) in three.iter().enumerate() {
                rhs[k as usize][c] = 1.0;
            }
            self.cot_factor.solve_in_place(&mut rhs, self.parallel);
            for (c, &k) in three.iter().enumerate() {
                let column: Arc<[f64]> = rhs.iter().map(|r| r[c]).collect();
                cache.columns.insert(k, column);
                cache.stored += m;
            }
        }
        ks.iter().map(|k| cache.columns[k].clone()).collect()
    }
}

/// Adds the free vertices of `y` that are below the obstacle and not yet held; true when
/// any was.
fn hold_below(
    obstacle: &dyn Obstacle,
    y: &[DVec3],
    held: &mut [bool],
    active: &mut Vec<Active>,
) -> bool {
    let mut added = false;
    for (k, p) in y.iter().enumerate() {
        if held[k] {
            continue;
        }
        let Some(s) = obstacle.surface_at(*p) else {
            continue;
        };
        if s.point.is_finite() && s.normal.is_finite() && s.gap(*p) < 0.0 {
            held[k] = true;
            added = true;
            active.push(Active {
                k: k as u32,
                normal: s.normal,
                offset: s.normal.dot(s.point),
            });
        }
    }
    added
}

/// Multipliers `λ` of `S λ = n·y − d` with `S_ij = (n_i·n_j) g_j[k_i]`: the correction
/// `y − Σ λ_j n_j g_j` puts every active vertex on its plane. `None` when `S` is singular.
fn multipliers(active: &[Active], columns: &[Arc<[f64]>], y: &[DVec3]) -> Option<Vec<f64>> {
    let k = active.len();
    let mut s = vec![0.0; k * k];
    let mut r: Vec<f64> = active
        .iter()
        .map(|a| a.normal.dot(y[a.k as usize]) - a.offset)
        .collect();
    for (i, ai) in active.iter().enumerate() {
        for (j, aj) in active.iter().enumerate() {
            s[i * k + j] = ai.normal.dot(aj.normal) * columns[j][ai.k as usize];
        }
    }
    // S is symmetric positive definite (L⁻¹ is, and the rows are independent): Cholesky.
    for j in 0..k {
        let mut d = s[j * k + j];
        for p in 0..j {
            d -= s[j * k + p] * s[j * k + p];
        }
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let d = d.sqrt();
        s[j * k + j] = d;
        for i in j + 1..k {
            let mut v = s[i * k + j];
            for p in 0..j {
                v -= s[i * k + p] * s[j * k + p];
            }
            s[i * k + j] = v / d;
        }
    }
    for i in 0..k {
        for p in 0..i {
            r[i] -= s[i * k + p] * r[p];
        }
        r[i] /= s[i * k + i];
    }
    for i in (0..k).rev() {
        for p in i + 1..k {
            r[i] -= s[p * k + i] * r[p];
        }
        r[i] /= s[i * k + i];
    }
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// `y −= Σ_j λ_j n_j g_j`.
fn correct(active: &[Active], columns: &[Arc<[f64]>], lambda: &[f64], y: &mut [DVec3]) {
    for ((a, g), l) in active.iter().zip(columns).zip(lambda) {
        let step = a.normal * *l;
        for (p, gv) in y.iter_mut().zip(g.iter()) {
            *p -= step * *gv;
        }
    }
}
