//! The reduced ARAP energy of the pose solver: the local step (one best-fit rotation per
//! weight cluster), its linear terms, and the quadratic form `tr(XᵀQX) − 2 tr(XᵀB) + c` of the
//! stacked skinning matrices.

use glam::{DMat3, DQuat, DVec3};

use crate::deform::{best_rotation_exact, fit_rotation_warm};
use crate::pose::rig::model::mat3_from_rows;
use crate::pose::solver::PoseSolver;
use crate::pose::solver::energy::holds::QBlocks;

/// How [`PoseSolver::local_step`] fits each cluster's rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ClusterFit {
    /// From scratch (Horn's eigen-solve).
    Exact,
    /// At most this many Newton steps from the rotation given.
    Newton(u32),
}

impl PoseSolver {
    /// Fits each cluster's rotation to the current skinning matrices: `A_c = Xᵀ K_c`;
    /// exactly (Horn) or by Newton steps from the previous rotation, which is kept if the fit
    /// is not better (so the energy cannot rise).
    pub(crate) fn local_step(&self, x: &[f64], rotations: &mut [DQuat], fit: ClusterFit) {
        for (c, r) in rotations.iter_mut().enumerate() {
            let mut a = [0.0; 9];
            for &(row, kr) in self.cluster_rows(c) {
                let xr = &x[row as usize * 3..][..3];
                for i in 0..3 {
                    for j in 0..3 {
                        a[i * 3 + j] += xr[i] * kr[j];
                    }
                }
            }
            let a = mat3_from_rows(&a);
            if let ClusterFit::Newton(steps) = fit {
                let fitted = fit_rotation_warm(&a, *r, steps, 1e-10);
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
            } else {
                *r = best_rotation_exact(&a);
            }
        }
    }

    /// Cluster `c`'s non-zero rows of `K_c` (row index, row).
    fn cluster_rows(&self, c: usize) -> &[(u32, DVec3)] {
        &self.cluster_rows[self.cluster_row_start[c]..self.cluster_row_start[c + 1]]
    }

    /// `B += Σ_c K_c R_cᵀ`.
    pub(crate) fn add_rotation_terms(&self, rotations: &[DQuat], b: &mut [f64]) {
        for (c, q) in rotations.iter().enumerate() {
            let r = DMat3::from_quat(*q);
            for &(row, kr) in self.cluster_rows(c) {
                // (K Rᵀ)[row][col] = Σ_m K[row][m] R[col][m] = (R kr)[col]
                let v = r * kr;
                let out = &mut b[row as usize * 3..][..3];
                out[0] += v.x;
                out[1] += v.y;
                out[2] += v.z;
            }
        }
    }

    /// `tr(XᵀQX) − 2 tr(XᵀB) + constant`, with `qx = Q X`.
    pub(crate) fn objective(&self, x: &[f64], qx: &[f64], b: &[f64], constant: f64) -> f64 {
        let mut f = constant;
        for ((xv, qv), bv) in x.iter().zip(qx).zip(b) {
            f += xv * qv - 2.0 * xv * bv;
        }
        f
    }
}

/// `Q X` using the block structure.
/// (`out` is resized; its allocation is reused.)
pub(crate) fn q_times_into(q_blocks: &QBlocks, x: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.resize(x.len(), 0.0);
    for &(k, l, ref q_kl) in q_blocks {
        let xl = &x[12 * l..][..12];
        let out_k = &mut out[12 * k..][..12];
        for c in 0..4 {
            let column = q_kl.col(c);
            let xr = &xl[3 * c..][..3];
            for r in 0..4 {
                let qv = column[r];
                out_k[3 * r] += qv * xr[0];
                out_k[3 * r + 1] += qv * xr[1];
                out_k[3 * r + 2] += qv * xr[2];
            }
        }
    }
}
