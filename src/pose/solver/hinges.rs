//! Joint limits inside the step: a hinge's rotation parameter is restricted to its axis in
//! the Gauss–Newton system, so the step turns a hinge about its axis only (swing cones and
//! twist ranges are projected into each trial step in `step.rs`).

use glam::DAffine3;

use crate::pose::constraints::limits::JointLimits;
use crate::pose::rig::skeleton::rotation_of;
use crate::pose::solver::PoseSolver;
use crate::pose::solver::linalg::low_rank::RankOne;
use crate::pose::solver::params::Param;

impl PoseSolver {
    /// Restricts each hinge joint's own rotation parameter to its hinge axis (world `a`):
    /// `H ← TᵀHT + (I − T)·s`, `g ← Tᵀg` with `T = a aᵀ` on that parameter's block, so the
    /// step turns a hinge about its axis only (the matrix's rank-one parts `u ← Tᵀu`).
    pub(super) fn restrict_hinges(
        &self,
        limits: &JointLimits,
        globals: &[DAffine3],
        (h, low_rank): (&mut [f64], &mut [RankOne]),
        g: &mut [f64],
    ) {
        let np = g.len();
        for (p, &param) in self.params.iter().enumerate() {
            let Param::Rotation(j) = param else {
                continue;
            };
            let Some(axis) = limits.hinge_axis(j) else {
                continue;
            };
            let a = (rotation_of(&globals[j].matrix3) * axis).normalize();
            let t = [a.x, a.y, a.z];
            let proj = |v: &[f64]| -> [f64; 3] {
                let d = v[0] * t[0] + v[1] * t[1] + v[2] * t[2];
                [d * t[0], d * t[1], d * t[2]]
            };
            let scale = (0..3).map(|k| h[(3 * p + k) * np + 3 * p + k]).sum::<f64>() / 3.0;
            // Rows of the block row p, then columns of the block column p.
            for col in 0..np {
                let v = [
                    h[(3 * p) * np + col],
                    h[(3 * p + 1) * np + col],
                    h[(3 * p + 2) * np + col],
                ];
                let w = proj(&v);
                for k in 0..3 {
                    h[(3 * p + k) * np + col] = w[k];
                }
            }
            for row in 0..np {
                let v = [
                    h[row * np + 3 * p],
                    h[row * np + 3 * p + 1],
                    h[row * np + 3 * p + 2],
                ];
                let w = proj(&v);
                for k in 0..3 {
                    h[row * np + 3 * p + k] = w[k];
                }
            }
            for r in 0..3 {
                for c in 0..3 {
                    let identity = if r == c { 1.0 } else { 0.0 };
                    h[(3 * p + r) * np + 3 * p + c] +=
                        (identity - t[r] * t[c]) * scale.abs().max(1e-12);
                }
            }
            let w = proj(&g[3 * p..3 * p + 3]);
            g[3 * p..3 * p + 3].copy_from_slice(&w);
            for part in low_rank.iter_mut() {
                let w = proj(&part.u[3 * p..3 * p + 3]);
                part.u[3 * p..3 * p + 3].copy_from_slice(&w);
            }
        }
    }
}
