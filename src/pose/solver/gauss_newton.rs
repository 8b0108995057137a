//! The numeric kernel of the pose solver: the Gauss–Newton system in the bone parameters
//! (twist generators, their closed-form quadratic blocks summed over subtrees), the hinge
//! restriction of that system. The damped solve of a step is `damped_step.rs`.

use std::rc::Rc;

use glam::{DAffine3, DMat3, DMat4, DVec3};

use crate::pose::solver::PoseSolver;
use crate::pose::solver::energy::holds::QBlocks;
pub(super) use crate::pose::solver::linalg::block_cholesky::BlockPattern;
use crate::pose::solver::linalg::block_cholesky::nonzero_lower_blocks;
use crate::pose::solver::params::Param;
use crate::pose::solver::solve::Posed;
use crate::pose::solver::step::Objective;
use crate::pose::solver::terms::skew;

impl PoseSolver {
    /// The Gauss–Newton model of the objective in the bone parameters (rotation increments,
    /// root translations; 3 numbers each): `f(θ) ≈ f + gᵀθ + ½ θᵀHθ`, as `(H, g)`.
    pub(super) fn gauss_newton_system(
        &self,
        posed: &Posed,
        objective: &Objective,
        scratch: &mut HessianScratch,
    ) -> (Vec<f64>, Vec<f64>) {
        let joints = self.model.skeleton().len();
        let x = &posed.x;
        // S̄_k rows (4 × 4 homogeneous) from X.
        let s_bar: Vec<[[f64; 4]; 4]> = (0..joints)
            .map(|k| {
                let mut s = [[0.0; 4]; 4];
                for (r, row) in s.iter_mut().enumerate().take(3) {
                    for (p, v) in row.iter_mut().enumerate() {
                        *v = x[(4 * k + p) * 3 + r];
                    }
                }
                s[3][3] = 1.0;
                s
            })
            .collect();
        let gsum = self.subtree_gradients(&posed.qx, objective.b, &s_bar);
        self.subtree_hessian_blocks(objective.q_blocks, &s_bar, scratch);
        self.parameter_system(&gsum, scratch, &posed.globals)
    }

    /// Per joint, the gradient of the objective in that joint's twist, summed over its
    /// subtree: g_k[g] = 2 tr(G_g S̄_k Γ_k), Γ = QX − B.
    fn subtree_gradients(&self, qx: &[f64], b: &[f64], s_bar: &[[[f64; 4]; 4]]) -> Vec<[f64; 6]> {
        let skeleton = self.model.skeleton();
        let mut gsum: Vec<[f64; 6]> = (0..skeleton.len())
            .map(|k| {
                let mut p = [[0.0; 3]; 4];
                for (r, pr) in p.iter_mut().enumerate() {
                    for (c, v) in pr.iter_mut().enumerate() {
                        *v = (0..4)
                            .map(|m| {
                                let row = (4 * k + m) * 3 + c;
                                s_bar[k][r][m] * (qx[row] - b[row])
                            })
                            .sum();
                    }
                }
                let mut g = [0.0; 6];
                for (gi, generator) in GENERATORS.iter().enumerate() {
                    g[gi] = 2.0
                        * generator
                            .iter()
                            .map(|&(i, p_, a)| a * p[p_][i])
                            .sum::<f64>();
                }
                g
            })
            .collect();
        for k in (0..skeleton.len()).rev() {
            if let Some(p) = skeleton.joints()[k].parent {
                let gk = gsum[k];
                for (a, v) in gsum[p].iter_mut().zip(gk) {
                    *a += v;
                }
            }
        }
        gsum
    }

    /// Hessian blocks M_kl[g][h] = tr(G_g N_kl G_hᵀ), N_kl = S̄_k Q_kl S̄_lᵀ, summed over
    /// subtrees: Z[a][b] = Σ_{k∈sub(a), l∈sub(b)} M_kl, into `scratch` as the sums of the
    /// `N_kl` (M is linear in N); only the blocks it flags non-zero are written: joints on
    /// branches that share no edge stay uncoupled.
    fn subtree_hessian_blocks(
        &self,
        q_blocks: &QBlocks,
        s_bar: &[[[f64; 4]; 4]],
        scratch: &mut HessianScratch,
    ) {
        let skeleton = self.model.skeleton();
        let joints = skeleton.len();
        let s_mat: Vec<DMat4> = s_bar
            .iter()
            .map(|s| DMat4::from_cols_array_2d(s).transpose())
            .collect();
        scratch.reset(joints);
        let HessianScratch { z, nonzero, .. } = scratch;
        // Q is symmetric: N_lk = N_klᵀ, so each pair is multiplied once.
        for &(k, l, ref q_kl) in q_blocks.iter().filter(|(k, l, _)| k <= l) {
            let n = s_mat[k] * *q_kl * s_mat[l].transpose();
            z[k * joints + l] = n;
            nonzero[k * joints + l] = true;
            if k != l {
                z[l * joints + k] = n.transpose();
                nonzero[l * joints + k] = true;
            }
        }
        let mut accumulate = |from: usize, to: usize| {
            if !nonzero[from] {
                return;
            }
            let v = z[from];
            if nonzero[to] {
                z[to] += v;
            } else {
                z[to] = v;
                nonzero[to] = true;
            }
        };
        for l in (0..joints).rev() {
            if let Some(p) = skeleton.joints()[l].parent {
                for k in 0..joints {
                    accumulate(k * joints + l, k * joints + p);
                }
            }
        }
        for k in (0..joints).rev() {
            if let Some(p) = skeleton.joints()[k].parent {
                for l in 0..joints {
                    accumulate(k * joints + l, p * joints + l);
                }
            }
        }
    }

    /// The system in the solver's parameters, through the maps A (6 × 3): rotation about o:
    /// [I; [o]×]; root translation: [0; I].
    fn parameter_system(
        &self,
        gsum: &[[f64; 6]],
        scratch: &mut HessianScratch,
        globals: &[DAffine3],
    ) -> (Vec<f64>, Vec<f64>) {
        let joints = self.model.skeleton().len();
        let params = &self.params;
        let np = params.len() * 3;
        // The last iteration's matrix, zeroed: no fresh allocation (and page faults) per
        // iteration. The caller hands it back with `HessianScratch::return_matrix`.
        let mut h = std::mem::take(&mut scratch.h);
        h.clear();
        h.resize(np * np, 0.0);
        let blocks = params.len();
        scratch.pairs.clear();
        scratch.pairs.resize(blocks * blocks, false);
        let HessianScratch {
            z, nonzero, pairs, ..
        } = scratch;
        let mut g = vec![0.0; np];
        // A rotation parameter turns about its joint's origin; a translation has none.
        let origins: Vec<Option<DVec3>> = params
            .iter()
            .map(|&param| match param {
                Param::Rotation(j) => Some(globals[j].translation),
                Param::Translation(_) => None,
            })
            .collect();
        for (pa, &param_a) in params.iter().enumerate() {
            let ja = param_a.joint();
            let (gw, gv) = (
                DVec3::new(gsum[ja][0], gsum[ja][1], gsum[ja][2]),
                DVec3::new(gsum[ja][3], gsum[ja][4], gsum[ja][5]),
            );
            // A_aᵀ g = g_ω + [o]×ᵀ g_v (rotation) or g_v (translation).
            let ga = match (param_a, origins[pa]) {
                (Param::Rotation(_), Some(o)) => gw + skew(o).transpose() * gv,
                _ => gv,
            };
            g[pa * 3..pa * 3 + 3].copy_from_slice(&ga.to_array());
            // H is symmetric: fill the upper triangle of blocks and mirror it.
            for (pb, &param_b) in params.iter().enumerate().skip(pa) {
                let jb = param_b.joint();
                if !nonzero[ja * joints + jb] {
                    continue;
                }
                pairs[pb * blocks + pa] = true;
                let hab = parameter_block(&z[ja * joints + jb], origins[pa], origins[pb]);
                for r in 0..3 {
                    for c in 0..3 {
                        let v = 2.0 * hab.col(c)[r];
                        h[(pa * 3 + r) * np + pb * 3 + c] = v;
                        h[(pb * 3 + c) * np + pa * 3 + r] = v;
                    }
                }
            }
        }
        (h, g)
    }
}

/// The subtree-summed Hessian blocks of one iteration (joints × joints) and the system's
/// matrix, kept between iterations and solves (one per thread) so they are not reallocated.
/// A block is kept as the 4 × 4 `N` its quadratic form is linear in (16 numbers instead of
/// the 36 of a 6 × 6 twist block), and is meaningful only where `nonzero` says so.
#[derive(Default)]
pub(super) struct HessianScratch {
    z: Vec<DMat4>,
    nonzero: Vec<bool>,
    h: Vec<f64>,
    /// Which parameter blocks `(pb, pa)`, `pb ≥ pa`, the last system wrote.
    pairs: Vec<bool>,
    /// The last pattern made from `pairs`, with the pairs it was made from.
    pattern: Option<(Vec<bool>, Rc<BlockPattern>)>,
    /// The non-zero blocks read off the last system with effector terms, and the pattern
    /// made from them.
    read: Vec<bool>,
    effector_pattern: Option<(Vec<bool>, Rc<BlockPattern>)>,
}

thread_local! {
    /// The scratch of the last solve on this thread.
    static SCRATCH: std::cell::Cell<Option<HessianScratch>> = const { std::cell::Cell::new(None) };
}

impl HessianScratch {
    /// This thread's scratch (a new one the first time, or while another solve holds it).
    pub(super) fn take() -> Self {
        SCRATCH.with(|s| s.take()).unwrap_or_default()
    }

    /// Gives the scratch back for this thread's next solve.
    pub(super) fn keep(self) {
        SCRATCH.with(|s| s.set(Some(self)));
    }

    /// The block pattern of the last system [`PoseSolver::gauss_newton_system`] built (terms
    /// added to it afterwards must add no block of their own).
    /// The pattern is kept with the blocks it was made from and reused while they repeat
    /// (every iteration of a drag, usually).
    pub(super) fn pattern(&mut self) -> Rc<BlockPattern> {
        match &self.pattern {
            Some((pairs, pattern)) if *pairs == self.pairs => pattern.clone(),
            _ => {
                let blocks = self.pairs.len().isqrt();
                let pattern = Rc::new(BlockPattern::from_blocks(blocks, self.pairs.clone()));
                self.pattern = Some((self.pairs.clone(), pattern.clone()));
                pattern
            }
        }
    }

    /// The block pattern of a system whose effector terms may couple joints the shape energy
    /// does not: read off the matrix `h` (`n × n`), and kept while its blocks repeat (every
    /// iteration of a solve, and the next solve of the same set, usually).
    pub(super) fn pattern_of(&mut self, h: &[f64], n: usize) -> Rc<BlockPattern> {
        nonzero_lower_blocks(h, n, &mut self.read);
        match &self.effector_pattern {
            Some((blocks, pattern)) if *blocks == self.read => pattern.clone(),
            _ => {
                let pattern = Rc::new(BlockPattern::from_blocks(n / 3, self.read.clone()));
                self.effector_pattern = Some((self.read.clone(), pattern.clone()));
                pattern
            }
        }
    }

    /// Takes back an iteration's system matrix for the next iteration to reuse.
    pub(super) fn return_matrix(&mut self, h: Vec<f64>) {
        self.h = h;
    }

    /// Every block zero, for `joints` joints.
    fn reset(&mut self, joints: usize) {
        self.z.resize(joints * joints, DMat4::ZERO);
        self.nonzero.clear();
        self.nonzero.resize(joints * joints, false);
    }
}

/// The 6 twist generators (ω_x, ω_y, ω_z, v_x, v_y, v_z) as 3 × 4 matrices, listed as
/// (row, column, value) non-zeros: `dS = Σ ξ_g G_g S̄`.
const GENERATORS: [&[(usize, usize, f64)]; 6] = [
    &[(1, 2, -1.0), (2, 1, 1.0)],
    &[(0, 2, 1.0), (2, 0, -1.0)],
    &[(0, 1, -1.0), (1, 0, 1.0)],
    &[(0, 3, 1.0)],
    &[(1, 3, 1.0)],
    &[(2, 3, 1.0)],
];

/// One 3 × 3 block of the system in the solver's parameters, `A_aᵀ M(N) A_b` (half of `H_ab`),
/// straight from `N`: a rotation about `o` (`Some(o)`) is a rotation about the origin of points
/// shifted by `−o`, so with `N = [[N₃, n], [mᵀ, n₃₃]]` two rotations give
/// `tr(N₃') I − N₃'ᵀ` with `N₃' = N₃ − o_a mᵀ − n o_bᵀ + n₃₃ o_a o_bᵀ`; a rotation against a
/// translation `[n − n₃₃ o_a]×` (or `−[m − n₃₃ o_b]×`); two translations `n₃₃ I`. The same as
/// [`TwistBlock`] through the maps `[I; [o]×]`, at a fraction of the products.
fn parameter_block(n: &DMat4, oa: Option<DVec3>, ob: Option<DVec3>) -> DMat3 {
    let col = n.w_axis.truncate();
    let row = DVec3::new(n.x_axis.w, n.y_axis.w, n.z_axis.w);
    let n33 = n.w_axis.w;
    let outer = |u: DVec3, v: DVec3| DMat3::from_cols(u * v.x, u * v.y, u * v.z);
    match (oa, ob) {
        (Some(a), Some(b)) => {
            let shifted = DMat3::from_mat4(*n) - outer(a, row) - outer(col, b) + outer(a, b * n33);
            let trace = shifted.x_axis.x + shifted.y_axis.y + shifted.z_axis.z;
            DMat3::from_diagonal(DVec3::splat(trace)) - shifted.transpose()
        }
        (Some(a), None) => skew(col - a * n33),
        (None, Some(b)) => -skew(row - b * n33),
        (None, None) => DMat3::from_diagonal(DVec3::splat(n33)),
    }
}

/// The 6 × 6 quadratic form `M[g][h] = tr(G_g N G_hᵀ)` of the twist generators (ω then v)
/// for a 4 × 4 `N`, as four 3 × 3 blocks. With `N = [[N₃, n], [mᵀ, n₃₃]]` it is, in closed
/// form, `M_ωω = tr(N₃) I − N₃ᵀ`, `M_ωv = [n]×`, `M_vω = −[m]×`, `M_vv = n₃₃ I`.
#[cfg(test)]
#[derive(Debug, Clone, Copy, PartialEq)]
struct TwistBlock {
    ww: DMat3,
    wv: DMat3,
    vw: DMat3,
    vv: DMat3,
}

#[cfg(test)]
impl TwistBlock {
    fn of(n: &DMat4) -> Self {
        let n3 = DMat3::from_mat4(*n);
        let col = n.w_axis.truncate();
        let row = DVec3::new(n.x_axis.w, n.y_axis.w, n.z_axis.w);
        let trace = n3.x_axis.x + n3.y_axis.y + n3.z_axis.z;
        Self {
            ww: DMat3::from_diagonal(DVec3::splat(trace)) - n3.transpose(),
            wv: skew(col),
            vw: -skew(row),
            vv: DMat3::from_diagonal(DVec3::splat(n.w_axis.w)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`parameter_block`] equals the twist block taken through the maps `[I; [o]×]`
    /// (rotation about `o`) or `[0; I]` (translation), for every pairing of the two kinds.
    #[test]
    fn parameter_blocks_match_the_twist_block_through_the_maps() {
        let n = DMat4::from_cols_array(&std::array::from_fn(|i| ((i * 5 + 2) % 7) as f64 - 2.5));
        let TwistBlock { ww, wv, vw, vv } = TwistBlock::of(&n);
        let (oa, ob) = (DVec3::new(0.3, -1.2, 0.7), DVec3::new(-0.4, 0.9, 2.1));
        let (ma, mb) = (skew(oa), skew(ob));
        let cases = [
            (
                Some(oa),
                Some(ob),
                ww + wv * mb + ma.transpose() * (vw + vv * mb),
            ),
            (Some(oa), None, wv + ma.transpose() * vv),
            (None, Some(ob), vw + vv * mb),
            (None, None, vv),
        ];
        for (a, b, expected) in cases {
            let got = parameter_block(&n, a, b);
            assert!(
                got.abs_diff_eq(expected, 1e-12),
                "{a:?}, {b:?}: {got} vs {expected}"
            );
        }
    }

    /// The closed form of [`TwistBlock`] equals `tr(G_g N G_hᵀ)` computed from the
    /// generators.
    #[test]
    fn twist_block_closed_form_matches_the_generators() {
        let n = DMat4::from_cols_array(&std::array::from_fn(|i| ((i * 7 + 3) % 11) as f64 - 4.5));
        let at = |p: usize, q: usize| n.col(q)[p];
        let block = TwistBlock::of(&n);
        let get = |g: usize, h: usize| {
            let m = match (g < 3, h < 3) {
                (true, true) => block.ww,
                (true, false) => block.wv,
                (false, true) => block.vw,
                (false, false) => block.vv,
            };
            m.col(h % 3)[g % 3]
        };
        for (g, gg) in GENERATORS.iter().enumerate() {
            for (h, gh) in GENERATORS.iter().enumerate() {
                let mut direct = 0.0;
                for &(i, p, a) in gg.iter() {
                    for &(i2, q, b) in gh.iter() {
                        if i == i2 {
                            direct += a * b * at(p, q);
                        }
                    }
                }
                assert!(
                    (direct - get(g, h)).abs() < 1e-12,
                    "({g}, {h}): {direct} vs {}",
                    get(g, h)
                );
            }
        }
    }
}
