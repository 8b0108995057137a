//! A shape at rest other than the bind pose: the ARAP energy tilted so that a given pose is
//! one of its stationary points ([`crate::pose::constraints::PoseConstraints::shape_rest`]).
//!
//! The skinning-space energy measures how far every edge is from a rotation of its *bind*
//! shape. An additive layer over a playing clip wants the layer's zero — the animation as
//! it is — to cost nothing to keep: otherwise every solve pulls the animated body a little
//! towards its bind shape (a bent knee straightens where nothing but a weak stiffness holds
//! it). The tilt subtracts the energy's gradient at the rest pose `X_a`:
//!
//! `E'(X) = E(X) − 2 tr(Tᵀ (X − X_a))`, `T = Q X_a − Σ_c K_c R_cᵀ` with `R_c` fitted to `X_a`,
//!
//! a linear term, so the system, its factorization and its curvature (what makes the solve
//! shape-aware) are unchanged; by the envelope theorem `X_a` is stationary for the energy
//! minimized over the cluster rotations too. Nothing pulling leaves the rest pose as it is;
//! an effector bends the body away from it as the bind-pose energy would bend it away from
//! the bind pose.

use glam::DQuat;

use crate::pose::rig::skeleton::SkeletonPose;
use crate::pose::solver::PoseSolver;
use crate::pose::solver::energy::arap::ClusterFit;

impl PoseSolver {
    /// The linear term `T` (4J × 3, added to `B`) and the constant `2 tr(Tᵀ X_a)` that tilt
    /// the shape energy so that `rest` is at rest, with the clusters' rotations fitted to
    /// `rest` — from scratch, or refined from `guess` (the last solve's, for a rest pose that
    /// moved little since: Newton steps instead of an eigen-solve per cluster).
    pub(crate) fn shape_tilt(
        &self,
        rest: &SkeletonPose,
        guess: Option<&[DQuat]>,
    ) -> (Vec<f64>, f64, Vec<DQuat>) {
        let posed = self.posed(rest.clone(), &self.q_blocks);
        // Up to 8 Newton steps from a guess: converged clusters stop after one; a guess far
        // from a cluster's fit (a layer turned a joint a lot) gets there.
        let (mut rotations, fit) = match guess {
            Some(g) => (g.to_vec(), ClusterFit::Newton(8)),
            None => (
                vec![DQuat::IDENTITY; self.model.cluster_count()],
                ClusterFit::Exact,
            ),
        };
        self.local_step(&posed.x, &mut rotations, fit);
        let mut tilt = vec![0.0; posed.x.len()];
        self.add_rotation_terms(&rotations, &mut tilt);
        for (t, qx) in tilt.iter_mut().zip(&posed.qx) {
            *t = qx - *t;
        }
        let constant = 2.0 * tilt.iter().zip(&posed.x).map(|(t, x)| t * x).sum::<f64>();
        (tilt, constant, rotations)
    }
}
