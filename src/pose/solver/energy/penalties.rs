//! The quadratic penalties of handles, fixed vertices, pinned joints and joint handles: their
//! linear and constant terms for the current targets (their quadratic part is added to `Q` in
//! [`PoseSolver::new`]).

use glam::{DAffine3, DMat3, DVec3, DVec4};

use crate::deform::RigidTransform;
use crate::pose::constraints::PoseConstraints;
use crate::pose::solver::PoseSolver;

/// A vertex set's precomputed sums for a rigid target: `Σ M_iᵀ p_iᵀ`, `Σ M_iᵀ`, `Σ p_i`,
/// `Σ ‖p_i‖²` with `p_i` the reference positions.
#[derive(Debug, Clone)]
pub(crate) struct SetSums {
    pub(crate) mp: Vec<f64>,
    pub(crate) m: Vec<f64>,
    pub(crate) p: DVec3,
    pub(crate) pp: f64,
    pub(crate) count: f64,
}

impl PoseSolver {
    /// The linear (`B`, 4J × 3) and constant terms of the constraint penalties for the
    /// current targets.
    pub(crate) fn penalty_terms(&self, constraints: &PoseConstraints) -> (Vec<f64>, f64) {
        let mut b = self.fixed_b.clone();
        let mut c = self.fixed_c;
        for (h, s) in constraints.handles.iter().zip(&self.handle_sums) {
            c += set_target(s, &h.transform, self.vertex_weight, &mut b);
        }
        let dim = 4 * self.model.skeleton().len();
        let fixed = self
            .constraints
            .fixed_joints
            .iter()
            .map(|&j| (j, RigidTransform::IDENTITY));
        let moved = constraints
            .joint_handles
            .iter()
            .map(|h| (h.joint, h.transform));
        for (j, t) in fixed.chain(moved) {
            let g = self.reference_globals[j];
            // Rigid motion p ↦ pivot + R(p − pivot) + T as an affine: R p + (pivot − R pivot + T).
            let motion = DAffine3::from_mat3_translation(
                DMat3::from_quat(t.rotation),
                t.pivot - t.rotation * t.pivot + t.translation,
            );
            let target = motion * g;
            let v = affine_rows(&target); // 3 × 4 rows of G*
            // V = G* D; B_j += λ U Vᵀ; const += λ‖V‖².
            let vd: [DVec4; 3] = std::array::from_fn(|r| {
                DVec4::new(
                    v[r][0] * self.length_scale,
                    v[r][1] * self.length_scale,
                    v[r][2] * self.length_scale,
                    v[r][3],
                )
            });
            let u = &self.joint_u[j];
            for r in 0..4 {
                for col in 0..3 {
                    b[(4 * j + r) * 3 + col] += self.joint_weight * u[r].dot(vd[col]);
                }
            }
            c += self.joint_weight * vd.iter().map(|r| r.length_squared()).sum::<f64>();
        }
        debug_assert_eq!(dim * 3, b.len());
        (b, c)
    }
}

/// Rows of an affine as a 4 × 4 matrix (last row 0 0 0 1).
pub(crate) fn affine_rows(a: &DAffine3) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for (r, row) in m.iter_mut().enumerate().take(3) {
        for (c, v) in row.iter_mut().enumerate().take(3) {
            *v = a.matrix3.col(c)[r];
        }
        row[3] = a.translation[r];
    }
    m[3][3] = 1.0;
    m
}

/// Adds `λ Σ M_iᵀ t_iᵀ` for targets `t_i = motion(p_i)` to `b`; returns `λ Σ ‖t_i‖²`.
pub(crate) fn set_target(s: &SetSums, motion: &RigidTransform, weight: f64, b: &mut [f64]) -> f64 {
    if s.count == 0.0 {
        return 0.0;
    }
    let r = DMat3::from_quat(motion.rotation);
    let c = motion.pivot - r * motion.pivot + motion.translation;
    // Σ M_iᵀ (R p_i + c)ᵀ = (Σ M_iᵀ p_iᵀ) Rᵀ + (Σ M_iᵀ) cᵀ
    for (row, m) in s.m.iter().enumerate() {
        let mp = DVec3::new(s.mp[row * 3], s.mp[row * 3 + 1], s.mp[row * 3 + 2]);
        let v = r * mp + c * *m;
        b[row * 3] += weight * v.x;
        b[row * 3 + 1] += weight * v.y;
        b[row * 3 + 2] += weight * v.z;
    }
    weight * (s.pp + 2.0 * c.dot(r * s.p) + s.count * c.length_squared())
}
