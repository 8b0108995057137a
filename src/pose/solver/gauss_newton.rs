//! The numeric kernel of the pose solver: the Gauss–Newton system in the bone parameters
//! (twist generators, their closed-form quadratic blocks summed over subtrees), the hinge
//! restriction of that system, and the damped Cholesky solve of a Levenberg–Marquardt step.

use std::rc::Rc;

use glam::{DAffine3, DMat3, DMat4, DVec3};

use super::PoseSolver;
use super::block_cholesky::BlockCholesky;
pub(super) use super::block_cholesky::BlockPattern;
use super::block_cholesky::nonzero_lower_blocks;
use super::effector_terms::skew;
use super::holds::QBlocks;
use super::low_rank::{self, RankOne, dot};
use super::params::Param;
use super::solve::Posed;
use super::step::Objective;

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

/// The least damping weight of a coordinate, as a share of the median diagonal entry of `H`
/// among the coordinates of its kind (rotations; root translations): see [`solve_damped`].
const DAMPING_FLOOR: f64 = 1e-3;
/// The least damping weight of a coordinate the extra terms (effectors, the ground, balance)
/// act on, as a share of the largest diagonal entry of its kind: see [`solve_damped`].
const TOUCHED_FLOOR: f64 = 1e-3;

/// The damping weights `D` of [`solve_damped`]: the Gauss–Newton matrix's `diagonal` (its
/// rank-one parts' included; Marquardt's scaling, so rotations and translations of any scale
/// are damped alike), each entry raised to at least [`DAMPING_FLOOR`] of the median of its
/// kind and, where `acted_on` (the effector, ground and balance terms raised it; shorter than
/// `diagonal`: nowhere past its end), to [`TOUCHED_FLOOR`] of the largest of its kind.
///
/// Without a floor, a coordinate that moves a stiff term (balance, an effector) only a little
/// is damped by as little as it moves it: past a point, raising `μ` makes it as cheap a way
/// to lower that term as any other, and the step turns it `1/j` times as far (a rig dragged
/// against its balance took trial steps of 4–300 rad, longer as the damping rose, and
/// rejected 15–20 a solve). The floor from the largest entry only where those terms act: a
/// stiff effector on the wrist must not damp a knee that only the shape moves.
pub(super) fn damping_weights(diagonal: &[f64], params: &[Param], acted_on: &[bool]) -> Vec<f64> {
    let n = params.len() * 3;
    let diagonal = |i: usize| diagonal[i];
    let is_rotation = |i: usize| matches!(params.get(i / 3), Some(Param::Rotation(_)));
    let median = |rotation: bool| {
        let mut kind: Vec<f64> = (0..n)
            .filter(|&i| is_rotation(i) == rotation)
            .map(diagonal)
            .collect();
        let middle = kind.len() / 2;
        match kind.is_empty() {
            true => 0.0,
            false => *kind.select_nth_unstable_by(middle, f64::total_cmp).1,
        }
    };
    let largest = |rotation: bool| {
        (0..n)
            .filter(|&i| is_rotation(i) == rotation)
            .map(diagonal)
            .fold(0.0f64, f64::max)
    };
    let floors = [median(false), median(true)].map(|m| DAMPING_FLOOR * m);
    let acted_floors = [largest(false), largest(true)].map(|m| TOUCHED_FLOOR * m);
    (0..n)
        .map(|i| {
            let kind = usize::from(is_rotation(i));
            let floor = match acted_on.get(i) {
                Some(true) => floors[kind].max(acted_floors[kind]),
                _ => floors[kind],
            };
            diagonal(i).max(floor)
        })
        .collect()
}

/// The diagonal of the `n × n` row-major `h`.
pub(super) fn diagonal_of(h: &[f64], n: usize) -> Vec<f64> {
    (0..n).map(|i| h[i * n + i]).collect()
}

/// Solves `(H + U S Uᵀ + μ·D + ε I) x = −g` by a block-sparse Cholesky factorization
/// ([`BlockCholesky`]) of all but the rank-one parts `low_rank` (`U S Uᵀ`, solved with by
/// [`low_rank::solve_with`]), returned as per-parameter 3-vectors; raises the damping until
/// the matrix factors. All zeros if it never does. `D`: `weights` ([`damping_weights`]).
///
/// Parts with a bound (one-sided terms that hold now) are left out, unless the step found
/// without them carries one past its bound: those are then in the model as active (their
/// curvature and the pull `−scale · slack · u` of their shifted residual), and the step is
/// solved again with the same factor. The predicted decrease is the one-sided model's.
pub(super) fn solve_damped(
    (h, low_rank): (&[f64], &[RankOne]),
    g: &[f64],
    mu: f64,
    pattern: &BlockPattern,
    weights: &[f64],
) -> DampedStep {
    let n = g.len();
    let scale = (0..n)
        .map(|i| h[i * n + i])
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let always: Vec<RankOne> = low_rank
        .iter()
        .filter(|p| p.bound.is_none())
        .cloned()
        .collect();
    let mut mu = mu;
    for _ in 0..12 {
        let shift: Vec<f64> = weights.iter().map(|w| mu * w + 1e-12 * scale).collect();
        if let Some(factor) = BlockCholesky::factor(h, &shift, pattern) {
            let solve = |parts: &[RankOne], pull: &[f64]| {
                let mut x: Vec<f64> = g.iter().zip(pull).map(|(v, p)| -v - p).collect();
                factor.solve_in_place(&mut x);
                (low_rank::solve_with(parts, &factor, &mut x) && x.iter().all(|v| v.is_finite()))
                    .then_some(x)
            };
            let none = vec![0.0; n];
            let Some(mut x) = solve(&always, &none) else {
                mu = mu.max(1e-9) * 100.0;
                continue;
            };
            // The bounded parts this step would carry past their bound join the model.
            let crossed: Vec<&RankOne> = low_rank
                .iter()
                .filter(|p| p.bound.is_some_and(|slack| dot(&p.u, &x) > slack))
                .collect();
            let mut active = always.clone();
            let mut pull = none;
            if !crossed.is_empty() {
                for part in &crossed {
                    let slack = part.bound.unwrap_or(0.0);
                    for (pi, ui) in pull.iter_mut().zip(&part.u) {
                        *pi -= part.scale * slack * ui;
                    }
                    active.push(RankOne::always(part.scale, part.u.clone()));
                }
                match solve(&active, &pull) {
                    Some(again) => x = again,
                    None => {
                        mu = mu.max(1e-9) * 100.0;
                        continue;
                    }
                }
            }
            return DampedStep {
                predicted_decrease: predicted_decrease((g, &pull), &shift, (&active, low_rank), &x),
                step: x
                    .chunks_exact(3)
                    .map(|c| DVec3::new(c[0], c[1], c[2]))
                    .collect(),
            };
        }
        mu = mu.max(1e-9) * 100.0;
    }
    DampedStep {
        step: vec![DVec3::ZERO; n / 3],
        predicted_decrease: 0.0,
    }
}

/// The decrease of the one-sided model at `x`, solved from `(H + D + P) x = −(g + pull)`
/// (`P`: the `active` parts, the always-present ones and those a bound let in; `pull`: the
/// latter's shifted residuals' gradient). `xᵀ(H + P)x = −(g + pull)·x − xᵀDx` gives the
/// quadratic part in O(n); each bounded part (of `all`) then counts
/// `scale / 2 · max(0, u·x − slack)²` instead of its quadratic.
fn predicted_decrease(
    (g, pull): (&[f64], &[f64]),
    shift: &[f64],
    (active, all): (&[RankOne], &[RankOne]),
    x: &[f64],
) -> f64 {
    let gx = dot(g, x);
    let px = dot(pull, x);
    let dxx: f64 = shift.iter().zip(x).map(|(d, v)| d * v * v).sum();
    // ½ xᵀ(H + P)x, with P the active parts.
    let half_curvature = 0.5 * (-(gx + px) - dxx);
    // The parts let in by their bound are in P (and in `active`) as always-present copies:
    // take their quadratic back out and put their one-sided energy in.
    let always = all.iter().filter(|p| p.bound.is_none()).count();
    let let_in: f64 = active[always..]
        .iter()
        .map(|p| 0.5 * p.scale * dot(&p.u, x).powi(2))
        .sum();
    let one_sided: f64 = all
        .iter()
        .filter_map(|p| p.bound.map(|slack| (p, slack)))
        .map(|(p, slack)| 0.5 * p.scale * (dot(&p.u, x) - slack).max(0.0).powi(2))
        .sum();
    -(gx + half_curvature - let_in + one_sided)
}

/// A damped Gauss–Newton step and the decrease of the energy its quadratic model predicts,
/// `−(g·x + ½ xᵀHx)`.
pub(super) struct DampedStep {
    pub(super) step: Vec<DVec3>,
    pub(super) predicted_decrease: f64,
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

    /// Raising the damping shortens the step, also under a stiff term that one light
    /// coordinate barely moves: a heavy rank-one term `w (j·x + r)²` (`w = 1e4`) over a
    /// stiff coordinate (`j = 1`, a spring of 1) and a light one (`j = 1e-4`, a spring of
    /// 0.1), the other coordinates on typical springs (1e3). Marquardt's scaling alone damps
    /// the light one by its own small curvature, so past `μ ≈ 0.1` the step spreads the term's
    /// pull over both and turns the light one thousands of times as far per unit: the step
    /// grew from 0.9 to 2.5 as the damping rose.
    #[test]
    fn more_damping_gives_a_shorter_step() {
        let n = 6;
        let (w, r) = (1e4, 1.0);
        let mut j = [0.0; 6];
        (j[0], j[3]) = (1.0, 1e-4);
        let spring = |i: usize| match i {
            0 => 1.0,
            3 => 0.1,
            _ => 1e3,
        };
        let h: Vec<f64> = (0..n * n)
            .map(|k| {
                let (row, col) = (k / n, k % n);
                w * j[row] * j[col] + if row == col { spring(row) } else { 0.0 }
            })
            .collect();
        let g: Vec<f64> = j.iter().map(|v| w * r * v).collect();
        let params = [Param::Rotation(0), Param::Rotation(1)];
        let pattern = BlockPattern::of(&h, n);
        let longest = |mu: f64| {
            let weights = damping_weights(&diagonal_of(&h, g.len()), &params, &[]);
            let x = solve_damped((&h, &[]), &g, mu, &pattern, &weights).step;
            x.iter().map(|v| v.abs().max_element()).fold(0.0, f64::max)
        };
        // Barely damped: the Gauss–Newton step, by the stiff coordinate.
        assert!((longest(1e-9) - r).abs() < 2e-3, "{}", longest(1e-9));
        let mut last = longest(1e-9);
        for mu in [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0] {
            let now = longest(mu);
            assert!(now <= last * (1.0 + 1e-9), "μ = {mu}: {now} after {last}");
            last = now;
        }
    }

    /// Where the extra terms act, a coordinate is damped by at least a thousandth of the
    /// largest entry of its kind; where only the shape acts, by its own curvature: a spring of
    /// 1 beside an effector of 1e6 takes Marquardt's step, `g / (h (1 + μ))`, while the
    /// effector's coordinates are damped from the largest entry.
    #[test]
    fn only_coordinates_the_extra_terms_act_on_get_the_largest_floor() {
        let n = 6;
        let mut h = vec![0.0; n * n];
        let diagonal = [1e6, 1.0, 1.0, 1.0, 1.0, 1.0];
        for (i, d) in diagonal.iter().enumerate() {
            h[i * n + i] = *d;
        }
        let g = [1e6, 0.0, 0.0, 1.0, 0.0, 0.0];
        // The effector's 1e6 on the first parameter is an extra term; the shape's springs of
        // 1 were there before.
        let acted_on = [true, false, false, false, false, false];
        let params = [Param::Rotation(0), Param::Rotation(1)];
        let pattern = BlockPattern::of(&h, n);
        let mu = 0.5;
        let weights = damping_weights(&diagonal_of(&h, g.len()), &params, &acted_on);
        let step = solve_damped((&h, &[]), &g, mu, &pattern, &weights).step;
        let marquardt = -1.0 / (1.0 + mu);
        // (Within the solve's 1e-12 of the largest entry added to every coordinate.)
        assert!((step[1].x - marquardt).abs() < 1e-5, "{step:?}");
        assert!((step[0].x - marquardt).abs() < 1e-5, "{step:?}");
        // Marked as acted on, the spring's coordinate is damped from the effector's entry.
        let weights = damping_weights(&diagonal_of(&h, g.len()), &params, &[true; 6]);
        let step = solve_damped((&h, &[]), &g, mu, &pattern, &weights).step;
        let floored = -1.0 / (1.0 + mu * TOUCHED_FLOOR * 1e6);
        assert!((step[1].x - floored).abs() < 1e-5, "{step:?}");
    }

    /// A part with a bound stays out of a step that keeps within it and joins one that
    /// would cross it: the step then stops at the bound (the part's weight dominating), and
    /// the predicted decrease is the one-sided model's, as a dense evaluation gives it.
    #[test]
    fn a_bounded_part_joins_only_a_step_that_would_cross_its_bound() {
        let n: usize = 6;
        let h: Vec<f64> = (0..n * n)
            .map(|k| {
                let (row, col) = (k / n, k % n);
                if row == col {
                    2.0 + row as f64
                } else if row.abs_diff(col) == 3 {
                    0.5
                } else {
                    0.0
                }
            })
            .collect();
        let g: Vec<f64> = (0..n).map(|i| -1.0 - 0.3 * i as f64).collect();
        let u: Vec<f64> = (0..n).map(|i| if i % 2 == 0 { 1.0 } else { 0.2 }).collect();
        let pattern = BlockPattern::of(&h, n);
        let weights = vec![1.0; n];
        let flat = |x: &[DVec3]| x.iter().flat_map(|v| v.to_array()).collect::<Vec<f64>>();
        let free = flat(&solve_damped((&h, &[]), &g, 1e-12, &pattern, &weights).step);
        let reach = dot(&u, &free);
        assert!(reach > 0.5, "the free step moves along u: {reach}");
        let bounded = |slack: f64| RankOne {
            scale: 1e6,
            u: u.clone(),
            bound: Some(slack),
        };
        // A bound the step keeps within: the same step.
        let wide = [bounded(2.0 * reach)];
        let x = flat(&solve_damped((&h, &wide), &g, 1e-12, &pattern, &weights).step);
        let same = x
            .iter()
            .zip(&free)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(same < 1e-12, "{same}");
        // A bound it would cross: it stops there.
        let slack = 0.25 * reach;
        let narrow = [bounded(slack)];
        let step = solve_damped((&h, &narrow), &g, 1e-12, &pattern, &weights);
        let x = flat(&step.step);
        assert!(
            (dot(&u, &x) - slack).abs() < 1e-4 * reach,
            "{} vs {slack}",
            dot(&u, &x)
        );
        // The one-sided model, densely: −(g·x + ½ xᵀHx + s/2 max(0, u·x − slack)²). (The
        // solver reads xᵀHx off the solved system, where the part's 10⁶ cancels: to ~1e-5.
        // A part counted twice or not at all is off by ~10⁵.)
        let hx: Vec<f64> = (0..n).map(|r| dot(&h[r * n..(r + 1) * n], &x)).collect();
        let model =
            dot(&g, &x) + 0.5 * dot(&x, &hx) + 0.5e6 * (dot(&u, &x) - slack).max(0.0).powi(2);
        assert!(
            (step.predicted_decrease + model).abs() < 1e-4 * model.abs(),
            "{} vs {}",
            step.predicted_decrease,
            -model
        );
    }
}
