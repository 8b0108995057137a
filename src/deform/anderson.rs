//! Anderson acceleration (type II) of the local/global fixed-point map `y ↦ G(y)` on the free
//! positions, after Peng et al. 2018, "Anderson Acceleration for Geometry Optimization and
//! Physics Simulation". The solver checks every extrapolated iterate against the energy and
//! falls back to the plain `G(y)` (and [`Anderson::reset`]) when it is not lower.

use std::collections::VecDeque;

use glam::DVec3;
use rayon::prelude::*;

use super::parallel::{for_chunks, sum_chunks_pair};

/// History of the last `depth` iterate differences.
#[derive(Debug, Clone, Default)]
pub(crate) struct Anderson {
    depth: usize,
    /// `G(y)` and `F(y) = G(y) − y` of the previous call (valid when `has_previous`).
    previous_g: Vec<DVec3>,
    previous_f: Vec<DVec3>,
    has_previous: bool,
    f: Vec<DVec3>,
    /// `ΔF_i · f` for the current `f`.
    rhs: Vec<f64>,
    /// `(ΔG, ΔF)` pairs, oldest first.
    history: VecDeque<(Vec<DVec3>, Vec<DVec3>)>,
    /// `gram[a][b] = ΔF_a · ΔF_b`, aligned with `history`.
    gram: VecDeque<VecDeque<f64>>,
    /// Whether the loops run on rayon's pool.
    parallel: bool,
}

/// Rows per parallel task.
const CHUNK: usize = 4096;

impl Anderson {
    /// Keeps up to `depth` differences (`depth ≥ 1`); its loops run on rayon's pool when
    /// `parallel`.
    pub fn new(depth: usize, parallel: bool) -> Self {
        Self {
            depth: depth.max(1),
            parallel,
            ..Default::default()
        }
    }

    /// Forgets the history (after a rejected extrapolation).
    pub fn reset(&mut self) {
        self.has_previous = false;
        self.history.clear();
        self.gram.clear();
    }

    /// Given the iterate `y` and its image `g = G(y)`, writes the extrapolated next iterate
    /// to `out` and returns whether it differs from `g` (false while there is no history or
    /// the small least-squares problem is degenerate).
    pub fn extrapolate(&mut self, y: &[DVec3], g: &[DVec3], out: &mut Vec<DVec3>) -> bool {
        let n = g.len();
        self.f.resize(n, DVec3::ZERO);
        for_chunks(self.parallel, &mut self.f, CHUNK, |c, f| {
            let at = c * CHUNK;
            for (k, f) in f.iter_mut().enumerate() {
                *f = g[at + k] - y[at + k];
            }
        });
        if self.has_previous && self.previous_g.len() == n {
            let (mut dg, mut df) = if self.history.len() == self.depth {
                self.gram.pop_front();
                for row in &mut self.gram {
                    row.pop_front();
                }
                self.history.pop_front().unwrap_or_default()
            } else {
                (Vec::new(), Vec::new())
            };
            dg.resize(n, DVec3::ZERO);
            df.resize(n, DVec3::ZERO);
            let (pg, pf, f) = (&self.previous_g, &self.previous_f, &self.f);
            sum_chunks_pair(self.parallel, &mut dg, &mut df, CHUNK, |c, dg, df| {
                let at = c * CHUNK;
                for k in 0..dg.len() {
                    dg[k] = g[at + k] - pg[at + k];
                    df[k] = f[at + k] - pf[at + k];
                }
                0.0
            });
            self.history.push_back((dg, df));
            // One pass over the history: the new Gram row and the least-squares right-hand
            // side `ΔF_i · f`.
            let (row, rhs) = self.dots_with_newest();
            for (r, &v) in self.gram.iter_mut().zip(row.iter()) {
                r.push_back(v);
            }
            self.gram.push_back(row.into_iter().collect());
            self.rhs = rhs;
        }
        self.previous_g.clear();
        self.previous_g.extend_from_slice(g);
        self.previous_f.clone_from(&self.f);
        self.has_previous = true;
        out.clear();
        out.extend_from_slice(g);
        let m = self.history.len();
        if m == 0 {
            return false;
        }
        let rhs = std::mem::take(&mut self.rhs);
        let mut a: Vec<Vec<f64>> = self
            .gram
            .iter()
            .map(|r| r.iter().copied().collect())
            .collect();
        let trace: f64 = (0..m).map(|i| a[i][i]).sum();
        for (i, r) in a.iter_mut().enumerate() {
            r[i] += 1e-10 * trace + f64::MIN_POSITIVE;
        }
        let Some(gamma) = solve_spd(a, rhs) else {
            return false;
        };
        let history = &self.history;
        for_chunks(self.parallel, out, CHUNK, |c, out| {
            let at = c * CHUNK;
            for ((dg, _), &coef) in history.iter().zip(&gamma) {
                for (o, d) in out.iter_mut().zip(&dg[at..]) {
                    *o -= coef * *d;
                }
            }
        });
        true
    }

    /// `(ΔF_i · ΔF_newest, ΔF_i · f)` for every `i`, reading each vector once.
    fn dots_with_newest(&self) -> (Vec<f64>, Vec<f64>) {
        let m = self.history.len();
        let newest = &self.history[m - 1].1;
        let f = &self.f;
        let history = &self.history;
        let zero = || vec![0.0; 2 * m];
        let piece = |c: usize| {
            let range = c * CHUNK..((c + 1) * CHUNK).min(f.len());
            let mut acc = zero();
            for (i, (_, df)) in history.iter().enumerate() {
                let (mut a, mut b) = (0.0, 0.0);
                for k in range.clone() {
                    a += df[k].dot(newest[k]);
                    b += df[k].dot(f[k]);
                }
                acc[2 * i] += a;
                acc[2 * i + 1] += b;
            }
            acc
        };
        let add = |mut x: Vec<f64>, y: Vec<f64>| {
            for (a, b) in x.iter_mut().zip(y) {
                *a += b;
            }
            x
        };
        let pieces = 0..f.len().div_ceil(CHUNK);
        let sums = if self.parallel {
            pieces.into_par_iter().map(piece).reduce(zero, add)
        } else {
            pieces.map(piece).fold(zero(), add)
        };
        (
            sums.iter().step_by(2).copied().collect(),
            sums.iter().skip(1).step_by(2).copied().collect(),
        )
    }
}

/// Solves the small SPD system `a x = b` by Cholesky; `None` if it is not numerically SPD or
/// the result is not finite.
fn solve_spd(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let m = b.len();
    for j in 0..m {
        let d = a[j][j] - (0..j).map(|k| a[j][k] * a[j][k]).sum::<f64>();
        if d.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..m {
            let s = a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>();
            a[i][j] = s / d;
        }
    }
    for i in 0..m {
        b[i] = (b[i] - (0..i).map(|k| a[i][k] * b[k]).sum::<f64>()) / a[i][i];
    }
    for i in (0..m).rev() {
        b[i] = (b[i] - (i + 1..m).map(|k| a[k][i] * b[k]).sum::<f64>()) / a[i][i];
    }
    b.iter().all(|v| v.is_finite()).then_some(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear contraction `G(y) = M y + c` with a slow mode: Anderson reaches the fixed
    /// point in far fewer steps than plain iteration.
    #[test]
    fn accelerates_a_slow_linear_fixed_point() {
        let c = DVec3::new(1.0, -2.0, 0.5);
        let scale = [0.99, 0.5, 0.9];
        let g_of = |y: &[DVec3]| -> Vec<DVec3> {
            y.iter()
                .enumerate()
                .map(|(k, v)| *v * scale[k % 3] + c)
                .collect()
        };
        let fixed: Vec<DVec3> = (0..6).map(|k| c / (1.0 - scale[k % 3])).collect();
        let error = |y: &[DVec3]| -> f64 {
            y.iter()
                .zip(&fixed)
                .map(|(a, b)| (*a - *b).length())
                .fold(0.0, f64::max)
        };
        let mut plain = vec![DVec3::ZERO; 6];
        let mut fast = plain.clone();
        let mut aa = Anderson::new(5, false);
        let mut next = Vec::new();
        for _ in 0..12 {
            plain = g_of(&plain);
            let g = g_of(&fast);
            aa.extrapolate(&fast, &g, &mut next);
            fast = next.clone();
        }
        assert!(
            error(&plain) > 1.0,
            "plain iteration is slow: {}",
            error(&plain)
        );
        assert!(error(&fast) < 1e-6, "Anderson error {}", error(&fast));
    }

    #[test]
    fn no_history_returns_the_plain_step_and_reset_forgets() {
        let mut aa = Anderson::new(3, true);
        let y = vec![DVec3::ZERO; 4];
        let g = vec![DVec3::ONE; 4];
        let mut out = Vec::new();
        assert!(!aa.extrapolate(&y, &g, &mut out));
        assert_eq!(out, g);
        aa.reset();
        assert!(!aa.extrapolate(&g, &y, &mut out));
        assert_eq!(out, y);
    }

    #[test]
    fn degenerate_history_falls_back_to_the_plain_step() {
        // Identical iterates: ΔF = 0, the least-squares system is singular-but-regularised;
        // the output must stay finite.
        let mut aa = Anderson::new(2, false);
        let y = vec![DVec3::ONE; 3];
        let mut out = Vec::new();
        for _ in 0..3 {
            aa.extrapolate(&y, &y, &mut out);
            assert!(out.iter().all(|v| v.is_finite()));
        }
    }
}
