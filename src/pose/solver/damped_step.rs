//! The damped solve of a Levenberg–Marquardt step: the damping weights (Marquardt's scaling
//! with floors), the block-sparse Cholesky solve with the rank-one parts beside it, the bounded
//! parts a step would cross let in, and the decrease the one-sided model predicts.

use glam::DVec3;

use crate::pose::solver::linalg::block_cholesky::{BlockCholesky, BlockPattern};
use crate::pose::solver::linalg::low_rank;
use crate::pose::solver::linalg::low_rank::{RankOne, dot};
use crate::pose::solver::params::Param;

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
