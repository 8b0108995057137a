//! The reduced ARAP energy of the pose solver: the local step (one best-fit rotation per
//! weight cluster), its linear terms, and the quadratic form `tr(XᵀQX) − 2 tr(XᵀB) + c` of the
//! stacked skinning matrices.

use glam::{DMat3, DQuat, DVec3};

use super::PoseSolver;
use crate::deform::{best_rotation_exact, fit_rotation_warm};
use crate::pose::model::mat3_from_rows;

impl PoseSolver {
    /// Fits each cluster's rotation to the current skinning matrices: `A_c = Xᵀ K_c`;
    /// exactly (Horn) or by Newton steps from the previous rotation, which is kept if the fit
    /// is not better (so the energy cannot rise).
    pub(super) fn local_step(&self, x: &[f64], rotations: &mut [DQuat], exact: bool) {
        let dim = x.len() / 3;
        for (c, r) in rotations.iter_mut().enumerate() {
            let k = &self.model.k[c * dim * 3..][..dim * 3];
            let mut a = [0.0; 9];
            for row in 0..dim {
                let xr = &x[row * 3..row * 3 + 3];
                let kr = &k[row * 3..row * 3 + 3];
                if kr[0] == 0.0 && kr[1] == 0.0 && kr[2] == 0.0 {
                    continue;
                }
                for i in 0..3 {
                    for j in 0..3 {
                        a[i * 3 + j] += xr[i] * kr[j];
                    }
                }
            }
            let a = mat3_from_rows(&a);
            if exact {
                *r = best_rotation_exact(&a);
            } else {
                let fitted = fit_rotation_warm(&a, *r, 4, 1e-10);
                let score = |q: DQuat| {
                    (DMat3::from_quat(q).transpose() * a)
                        .to_cols_array()
                        .iter()
                        .step_by(4)
                        .sum::<f64>()
                };
                if score(fitted) >= score(*r) {
                    *r = fitted;
                }
            }
        }
    }

    /// `B += Σ_c K_c R_cᵀ`.
    pub(super) fn add_rotation_terms(&self, rotations: &[DQuat], b: &mut [f64]) {
        let dim = b.len() / 3;
        for (c, q) in rotations.iter().enumerate() {
            let r = DMat3::from_quat(*q);
            let k = &self.model.k[c * dim * 3..][..dim * 3];
            for row in 0..dim {
                let kr = DVec3::new(k[row * 3], k[row * 3 + 1], k[row * 3 + 2]);
                if kr == DVec3::ZERO {
                    continue;
                }
                // (K Rᵀ)[row][col] = Σ_m K[row][m] R[col][m] = (R kr)[col]
                let v = r * kr;
                b[row * 3] += v.x;
                b[row * 3 + 1] += v.y;
                b[row * 3 + 2] += v.z;
            }
        }
    }

    /// `Q X` using the block structure.
    pub(super) fn q_times(&self, x: &[f64]) -> Vec<f64> {
        let dim = x.len() / 3;
        let joints = dim / 4;
        let mut out = vec![0.0; dim * 3];
        for k in 0..joints {
            for l in 0..joints {
                if !self.block_nonzero[k * joints + l] {
                    continue;
                }
                for r in 0..4 {
                    let row = 4 * k + r;
                    let qrow = &self.q[row * dim + 4 * l..][..4];
                    for (c, &qv) in qrow.iter().enumerate() {
                        let xr = &x[(4 * l + c) * 3..][..3];
                        out[row * 3] += qv * xr[0];
                        out[row * 3 + 1] += qv * xr[1];
                        out[row * 3 + 2] += qv * xr[2];
                    }
                }
            }
        }
        out
    }

    /// `tr(XᵀQX) − 2 tr(XᵀB) + constant`.
    pub(super) fn objective(&self, x: &[f64], b: &[f64], constant: f64) -> f64 {
        let qx = self.q_times(x);
        let mut f = constant;
        for ((xv, qv), bv) in x.iter().zip(&qx).zip(b) {
            f += xv * qv - 2.0 * xv * bv;
        }
        f.max(0.0)
    }
}
