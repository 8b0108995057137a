//! Limited-memory BFGS directions for the ARAP energy, with the factored cotangent Laplacian as
//! the initial inverse Hessian, after Liu, Bouaziz & Kavan 2017, "Quasi-Newton Methods for
//! Real-Time Simulation of Hyperelastic Materials". With an empty history the direction is the
//! plain local/global step; the stored curvature pairs then bend it toward the soft (bending)
//! modes the plain iteration converges slowly along. The solver line-searches every direction on
//! the energy and falls back to the plain step when it fails.

use std::collections::VecDeque;
use std::sync::Arc;

use super::parallel::{sum_zip, zip_chunks};
use glam::DVec3;

/// Rows per parallel task.
const CHUNK: usize = 4096;

/// One curvature pair: a step `s`, the gradient change `y` along it and `1 / (s · y)`.
#[derive(Debug, Clone)]
struct Pair {
    s: Vec<DVec3>,
    y: Vec<DVec3>,
    rho: f64,
}

/// The last `depth` curvature pairs (shared: cloning a history copies no vectors).
#[derive(Debug, Clone, Default)]
pub(crate) struct Lbfgs {
    depth: usize,
    pairs: VecDeque<Arc<Pair>>,
    /// The buffers of the last pair dropped (when no clone shared it), for the next pair.
    spare: Option<(Vec<DVec3>, Vec<DVec3>)>,
}

/// `a · b` over all rows (on rayon's pool when `parallel`).
pub(crate) fn dot(a: &[DVec3], b: &[DVec3], parallel: bool) -> f64 {
    sum_zip(parallel, a, b, CHUNK, |a, b| {
        a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum::<f64>()
    })
}

/// `out += k · v`.
fn add_scaled(out: &mut [DVec3], k: f64, v: &[DVec3], parallel: bool) {
    zip_chunks(parallel, out, v, CHUNK, |o, v| {
        o.iter_mut().zip(v).for_each(|(o, v)| *o += k * *v)
    });
}

impl Lbfgs {
    /// Keeps up to `depth` pairs (`depth ≥ 1`).
    pub fn new(depth: usize) -> Self {
        Self {
            depth: depth.max(1),
            pairs: VecDeque::new(),
            spare: None,
        }
    }

    /// Forgets the history.
    pub fn reset(&mut self) {
        self.pairs.clear();
    }

    /// Pairs kept at most.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Number of stored pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Overwrites `q` (the gradient on entry) with `H q`, the approximate inverse Hessian applied
    /// to it (two-loop recursion); `initial` applies the initial inverse Hessian in place.
    /// The loops run on rayon's pool when `parallel`.
    pub fn apply(&self, q: &mut [DVec3], parallel: bool, initial: impl FnOnce(&mut [DVec3])) {
        let mut alphas = vec![0.0; self.pairs.len()];
        for (k, p) in self.pairs.iter().enumerate().rev() {
            alphas[k] = p.rho * dot(&p.s, q, parallel);
            add_scaled(q, -alphas[k], &p.y, parallel);
        }
        initial(q);
        for (k, p) in self.pairs.iter().enumerate() {
            let beta = p.rho * dot(&p.y, q, parallel);
            add_scaled(q, alphas[k] - beta, &p.s, parallel);
        }
    }

    /// Two empty buffers for the next pair: those of the last pair dropped when no clone of
    /// the history shares it (so a long solve allocates no new pair once the history is full).
    pub fn spare_buffers(&mut self) -> (Vec<DVec3>, Vec<DVec3>) {
        let (mut s, mut y) = self.spare.take().unwrap_or_default();
        s.clear();
        y.clear();
        (s, y)
    }

    /// Stores the pair (`s`, `y`) when its curvature is positive (a step along which the energy
    /// is locally convex); returns whether it was stored (if not, its buffers are kept for the
    /// next). The oldest pair goes when full.
    pub fn push(&mut self, s: Vec<DVec3>, y: Vec<DVec3>, parallel: bool) -> bool {
        let sy = dot(&s, &y, parallel);
        let scale = dot(&s, &s, parallel).sqrt() * dot(&y, &y, parallel).sqrt();
        if !(sy > 1e-12 * scale && sy.is_finite()) {
            self.spare = Some((s, y));
            return false;
        }
        if self.pairs.len() == self.depth
            && let Some(oldest) = self.pairs.pop_front()
            && let Ok(pair) = Arc::try_unwrap(oldest)
        {
            self.spare = Some((pair.s, pair.y));
        }
        self.pairs.push_back(Arc::new(Pair {
            s,
            y,
            rho: 1.0 / sy,
        }));
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a quadratic `½ xᵀ A x` with a diagonal `A`, pairs from steps along each axis make the
    /// two-loop recursion the exact inverse Hessian.
    #[test]
    fn pairs_on_every_axis_give_the_exact_inverse_hessian() {
        let a = [DVec3::new(4.0, 0.5, 2.0), DVec3::new(0.01, 3.0, 1.0)];
        let mut h = Lbfgs::new(6);
        for row in 0..2 {
            for axis in 0..3 {
                let mut s = vec![DVec3::ZERO; 2];
                s[row][axis] = 1.0;
                let y: Vec<DVec3> = s.iter().zip(&a).map(|(s, a)| *s * *a).collect();
                assert!(h.push(s, y, false));
            }
        }
        let g = vec![DVec3::new(1.0, -2.0, 3.0), DVec3::new(0.5, 0.25, -1.0)];
        let mut q = g.clone();
        h.apply(&mut q, false, |_| {});
        for ((q, g), a) in q.iter().zip(&g).zip(&a) {
            assert!((*q - *g / *a).length() < 1e-12, "{q} vs {}", *g / *a);
        }
    }

    /// Without pairs the direction is the initial inverse Hessian's; a pair of negative
    /// curvature is refused; a full history drops its oldest pair.
    #[test]
    fn empty_history_is_the_initial_step_and_bad_pairs_are_refused() {
        let mut h = Lbfgs::new(1);
        let mut q = vec![DVec3::new(2.0, 4.0, 6.0)];
        h.apply(&mut q, true, |q| q.iter_mut().for_each(|v| *v *= 0.5));
        assert_eq!(q[0], DVec3::new(1.0, 2.0, 3.0));
        assert!(!h.push(vec![DVec3::X], vec![-DVec3::X], false));
        assert_eq!(h.len(), 0);
        assert!(h.push(vec![DVec3::X], vec![DVec3::X], true));
        assert!(h.push(vec![DVec3::Y], vec![DVec3::Y * 2.0], false));
        assert_eq!(h.len(), 1);
    }
}
