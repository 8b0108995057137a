//! Truncated Newton on the ARAP energy: each step solves `H d = −g` by conjugate gradients
//! preconditioned with the factored Laplacian (stopping at negative curvature, Steihaug), then
//! line-searches `d`. The Hessian-vector product differentiates the rotation fit: for a cell
//! with covariance `A = R Y` (polar), `dR = R [ω]×` with `(tr Y · I − Y) ω = vee(M − Mᵀ)`,
//! `M = Rᵀ dA`. Where the local/global iteration crawls along soft modes (a limb swinging on a
//! thin joint costs little energy but much Laplacian motion), Newton sees their true curvature.

use web_time::Instant;

use glam::{DMat3, DVec3};

use super::iterate::Iterate;
use super::{ArapSolver, CHUNK, CellKind, SolveError, SolveOptions};
use crate::deform::lbfgs::dot;
use crate::deform::parallel::for_chunks;

/// CG stops when the preconditioned residual has shrunk by this factor.
const CG_REDUCTION: f64 = 0.1;

/// Longest vertex move of one Newton step, as a fraction of the bounding-box diagonal.
const MAX_STEP: f64 = 0.02;

/// Scratch of the Hessian-vector products (solver memory order).
struct Scratch {
    /// The vector, per vertex (zero on known vertices).
    v: Vec<DVec3>,
    /// Rotation derivative per cell.
    dr: Vec<DMat3>,
    /// Product per vertex.
    out: Vec<DVec3>,
    /// `Y = Rᵀ A` per cell (symmetric part), fixed during one Newton step.
    y: Vec<DMat3>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Self {
            v: vec![DVec3::ZERO; n],
            dr: vec![DMat3::ZERO; n],
            out: vec![DVec3::ZERO; n],
            y: vec![DMat3::ZERO; n],
        }
    }
}

/// `[ω]×`.
fn cross_matrix(w: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, w.z, -w.y),
        DVec3::new(-w.z, 0.0, w.x),
        DVec3::new(w.y, -w.x, 0.0),
    )
}

/// Solves the symmetric 3×3 `k ω = b` by Cholesky; `None` unless `k` is positive definite
/// (a rotation fit that is not locally unique: the cell is then treated as rotation-fixed).
fn solve_spd3(k: &DMat3, b: DVec3) -> Option<DVec3> {
    let (a00, a10, a20) = (k.x_axis.x, k.x_axis.y, k.x_axis.z);
    let (a11, a21, a22) = (k.y_axis.y, k.y_axis.z, k.z_axis.z);
    let floor = 1e-12 * (a00 + a11 + a22).abs();
    // √d when the pivot `d` is clearly positive (false for NaN too).
    let pivot = |d: f64| (d > floor).then(|| d.sqrt());
    let l00 = pivot(a00)?;
    let (l10, l20) = (a10 / l00, a20 / l00);
    let l11 = pivot(a11 - l10 * l10)?;
    let l21 = (a21 - l20 * l10) / l11;
    let l22 = pivot(a22 - l20 * l20 - l21 * l21)?;
    let y0 = b.x / l00;
    let y1 = (b.y - l10 * y0) / l11;
    let y2 = (b.z - l20 * y0 - l21 * y1) / l22;
    let x2 = y2 / l22;
    let x1 = (y1 - l21 * x2) / l11;
    let x0 = (y0 - l10 * x1 - l20 * x2) / l00;
    Some(DVec3::new(x0, x1, x2))
}

impl ArapSolver {
    /// `Y = sym(Rᵀ A)` of every active cell at `x` (rotations in `mats` fitted to `x`).
    fn polar_factors(&self, x: &[DVec3], mats: &[DMat3], out: &mut [DMat3]) {
        for_chunks(self.parallel, out, CHUNK, |c, ys| {
            for (k, y_out) in ys.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                if self.cells[i] == CellKind::Active {
                    let y = mats[i].transpose() * self.cell_covariance(i, x);
                    *y_out = (y + y.transpose()) * 0.5;
                }
            }
        });
    }

    /// `H v` for the quarter-scaled energy (free vertices, elimination order).
    fn hessian_times(&self, v: &[DVec3], mats: &[DMat3], s: &mut Scratch, out: &mut [DVec3]) {
        s.v.iter_mut().for_each(|p| *p = DVec3::ZERO);
        for (&i, p) in self.free.iter().zip(v) {
            s.v[i as usize] = *p;
        }
        let (vv, ys) = (&s.v, &s.y);
        for_chunks(self.parallel, &mut s.dr, CHUNK, |c, drs| {
            for (k, dr) in drs.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                *dr = DMat3::ZERO;
                if self.cells[i] != CellKind::Active {
                    continue;
                }
                let m = mats[i].transpose() * self.cell_covariance(i, vv);
                let skew = m - m.transpose();
                let b = DVec3::new(skew.y_axis.z, skew.z_axis.x, skew.x_axis.y);
                let y = ys[i];
                let trace = y.x_axis.x + y.y_axis.y + y.z_axis.z;
                let kmat = DMat3::from_diagonal(DVec3::splat(trace)) - y;
                if let Some(w) = solve_spd3(&kmat, b) {
                    *dr = mats[i] * cross_matrix(w);
                }
            }
        });
        // The gradient's formula with (v, dR) in place of (x, R).
        self.laplacian_minus_rotated(&s.v, &s.dr, &mut s.out, out);
    }

    /// Truncated Newton iterations (each: CG of at most `max_cg` preconditioned steps, then a
    /// line search; the plain step when that fails).
    pub(super) fn iterate_newton(
        &self,
        it: &mut Iterate,
        max_cg: u32,
        options: &SolveOptions,
        should_cancel: &dyn Fn() -> bool,
    ) -> Result<(), SolveError> {
        let nf = self.free.len();
        let mut e = self.start_energy(it);
        let mut s = Scratch::new(self.layout.rest.len());
        let mut g = vec![DVec3::ZERO; nf];
        let mut xf = Vec::with_capacity(nf);
        let (mut d, mut r, mut z, mut p, mut hp) = (
            vec![DVec3::ZERO; nf],
            vec![DVec3::ZERO; nf],
            vec![DVec3::ZERO; nf],
            vec![DVec3::ZERO; nf],
            vec![DVec3::ZERO; nf],
        );
        for _ in 0..options.max_iterations {
            if Self::cancelled(it, should_cancel)? {
                break;
            }
            self.gradient(it, &mut g);
            let ta = Instant::now();
            self.polar_factors(&it.x, &it.mats, &mut s.y);
            // Steihaug CG on H d = −g, preconditioned by L.
            d.iter_mut().for_each(|v| *v = DVec3::ZERO);
            r.iter_mut().zip(&g).for_each(|(r, g)| *r = -*g);
            z.clone_from(&r);
            self.precondition(&mut it.stats, &mut z);
            p.clone_from(&z);
            let mut rz = dot(&r, &z, self.parallel);
            let rz0 = rz;
            for k in 0..max_cg.max(1) {
                // A newer request: finish this iteration with the direction found so far
                // (one Newton iteration is many back-substitutions; the caller must not wait).
                if k > 0 && should_cancel() {
                    break;
                }
                self.hessian_times(&p, &it.mats, &mut s, &mut hp);
                let php = dot(&p, &hp, self.parallel);
                if php.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    if k == 0 {
                        d.clone_from(&p); // the plain local/global step
                    }
                    break;
                }
                let alpha = rz / php;
                d.iter_mut().zip(&p).for_each(|(d, p)| *d += alpha * *p);
                r.iter_mut().zip(&hp).for_each(|(r, h)| *r -= alpha * *h);
                z.clone_from(&r);
                self.precondition(&mut it.stats, &mut z);
                let rz_new = dot(&r, &z, self.parallel);
                if rz_new <= CG_REDUCTION * CG_REDUCTION * rz0 {
                    break;
                }
                let beta = rz_new / rz;
                rz = rz_new;
                p.iter_mut().zip(&z).for_each(|(p, z)| *p = *z + beta * *p);
            }
            it.stats.acceleration_s += ta.elapsed().as_secs_f64();
            // Trust the quadratic model only so far: no vertex moves more than `MAX_STEP` of the
            // mesh's diagonal in one step (a long CG can propose a swing into another basin).
            let longest = d.iter().map(|v| v.length()).fold(0.0, f64::max);
            let limit = MAX_STEP * self.topology.bounding_diagonal();
            if longest > limit {
                let k = limit / longest;
                d.iter_mut().for_each(|v| *v *= k);
            }
            xf.clear();
            xf.extend(self.free.iter().map(|&i| it.x[i as usize]));
            self.line_search(it, &xf, &d, &g, e);
            // One plain local/global step: it removes, for one back-substitution, the stiff
            // (high-frequency) residual a long Newton step leaves behind, which the next CG
            // would otherwise spend its iterations on (26k armadillo: 6 instead of 11 Newton
            // iterations to settle, 188 instead of 218 back-substitutions).
            e = self.plain_step(it);
            if Self::finish_iteration(it, e, options) {
                break;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{DMat3, DQuat, DVec3};

    use super::super::iterate::Iterate;
    use super::super::{ArapSolver, SolveStats, SolverSettings};
    use super::Scratch;
    use crate::deform::synth::{bar, bend_problem};
    use crate::deform::topology::Topology;

    /// The Hessian-vector product matches central differences of the gradient (rotations
    /// refitted at each point) on a bent bar.
    #[test]
    fn hessian_times_matches_finite_differences_of_the_gradient() {
        let mesh = bar(8, 12, 0.1, 1.0);
        let topology = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap());
        let c = bend_problem(topology.positions(), 0.7, DVec3::new(0.1, 0.0, 0.0));
        let solver =
            ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
        let n = solver.layout.rest.len();
        let nf = solver.free.len();
        // A deformed state: rest bent by hand plus a deterministic wobble.
        let mut x: Vec<DVec3> = solver
            .layout
            .rest
            .iter()
            .map(|p| DQuat::from_rotation_z(0.5 * p.y) * *p)
            .collect();
        for (k, p) in x.iter_mut().enumerate() {
            *p += 0.01 * DVec3::new((k as f64 * 0.7).sin(), (k as f64 * 1.3).cos(), 0.0);
        }
        let mut it = Iterate {
            x,
            quats: vec![DQuat::IDENTITY; n],
            mats: vec![DMat3::IDENTITY; n],
            rhs: vec![DVec3::ZERO; nf],
            rhs_by_vertex: vec![DVec3::ZERO; n],
            trial: Vec::new(),
            constant_energy: 0.0,
            energy: None,
            stats: SolveStats::default(),
            contacts: None,
            inertial: None,
        };
        let gradient_at = |it: &mut Iterate, x: &[DVec3]| {
            it.x = x.to_vec();
            solver.refit(it);
            let mut g = vec![DVec3::ZERO; nf];
            solver.gradient(it, &mut g);
            g
        };
        let x0 = it.x.clone();
        gradient_at(&mut it, &x0);
        let mut s = Scratch::new(n);
        solver.polar_factors(&it.x, &it.mats, &mut s.y);
        let v: Vec<DVec3> = (0..nf)
            .map(|k| {
                DVec3::new(
                    (k as f64).sin(),
                    (2.0 * k as f64).cos(),
                    (0.3 * k as f64).sin(),
                )
            })
            .collect();
        let mut hv = vec![DVec3::ZERO; nf];
        let mats = it.mats.clone();
        solver.hessian_times(&v, &mats, &mut s, &mut hv);
        let h = 1e-6;
        let shifted = |sign: f64| {
            let mut x = x0.clone();
            for (&i, d) in solver.free.iter().zip(&v) {
                x[i as usize] += sign * h * *d;
            }
            x
        };
        let (xp, xm) = (shifted(1.0), shifted(-1.0));
        let gp = gradient_at(&mut it, &xp);
        let gm = gradient_at(&mut it, &xm);
        let (mut err, mut scale) = (0.0f64, 0.0f64);
        for ((a, b), hv) in gp.iter().zip(&gm).zip(&hv) {
            let fd = (*a - *b) / (2.0 * h);
            err = err.max((fd - *hv).length());
            scale = scale.max(hv.length());
        }
        assert!(err <= 1e-5 * scale, "H v off by {err} (scale {scale})");
        // Not the Laplacian alone: the rotation term matters here.
        let mut lv = vec![DVec3::ZERO; nf];
        s.y.iter_mut().for_each(|y| *y = DMat3::ZERO); // singular K: rotations held
        solver.hessian_times(&v, &mats, &mut s, &mut lv);
        let diff = lv
            .iter()
            .zip(&hv)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(diff > 1e-3 * scale, "rotation term vanished: {diff}");
    }
}
