//! Rank-one parts of the Gauss–Newton matrix, kept out of its block-sparse rest and solved
//! with by the Woodbury identity.
//!
//! A term that reads the whole body — balance: the centre of mass moves with every joint —
//! has a Jacobian row `uᵀ` for every parameter, so its `JᵀJ = u uᵀ` couples every pair of
//! them. Added to the matrix it makes all of it dense: a 52-joint humanoid's factorization
//! went from its tree's fill to every block, and each damped trial of a step paid for it
//! again (balance active: ~0.1 ms more an iteration, before any rejected trial). Kept apart
//! as `s u uᵀ`, the sparse factor `A = H + μD` stays as it is and
//! `(A + U S Uᵀ)⁻¹ b = A⁻¹b − A⁻¹U (S⁻¹ + Uᵀ A⁻¹ U)⁻¹ Uᵀ A⁻¹ b`: one more solve with the
//! factor per part and a k × k system (k: one or two).
//!
//! A one-sided term that holds now (the centre of mass inside its region) but that a step
//! may break is a part with a bound ([`RankOne::bound`]): it is left out of the model unless
//! the step would carry it past its bound, and then solved with as active
//! ([`damped_step::solve_damped`](crate::pose::solver::damped_step)). Without it the model of a step did
//! not know the term at all: a step took the centre of mass resting on its margin straight
//! across it, the term's weight (a thousand times an effector's) made the energy rise by
//! 10⁵–10⁶ times what the model promised, and a dozen damped trials followed.

use crate::pose::solver::linalg::block_cholesky::BlockCholesky;

/// `scale · u uᵀ`, a rank-one part of a Gauss–Newton matrix (`u`: 3 numbers per parameter).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RankOne {
    pub(crate) scale: f64,
    pub(crate) u: Vec<f64>,
    /// `None`: always part of the matrix. `Some(slack)`: a one-sided term that holds now
    /// and acts once `u · x` exceeds `slack` (≥ 0); its energy is then
    /// `scale / 2 · (u · x − slack)²`.
    pub(crate) bound: Option<f64>,
}

impl RankOne {
    /// A part always in the matrix.
    pub(crate) fn always(scale: f64, u: Vec<f64>) -> Self {
        Self {
            scale,
            u,
            bound: None,
        }
    }
}

/// Adds each part's diagonal, `scale · u_i²`, to `diagonal` (parts with a bound are not in
/// the matrix until a step activates them: left out).
pub(crate) fn add_diagonal(parts: &[RankOne], diagonal: &mut [f64]) {
    for part in parts.iter().filter(|p| p.bound.is_none()) {
        for (d, u) in diagonal.iter_mut().zip(&part.u) {
            *d += part.scale * u * u;
        }
    }
}

/// Turns `x = A⁻¹ b` (`factor`: of `A`) into `(A + Σ sᵢ uᵢ uᵢᵀ)⁻¹ b` (Woodbury). `false`
/// (and `x` unchanged) when the small system does not solve (a part of no positive scale).
pub(crate) fn solve_with(parts: &[RankOne], factor: &BlockCholesky, x: &mut [f64]) -> bool {
    let k = parts.len();
    if k == 0 {
        return true;
    }
    // Z = A⁻¹ U, then M = S⁻¹ + Uᵀ Z and c = M⁻¹ Uᵀ x.
    let z: Vec<Vec<f64>> = parts
        .iter()
        .map(|p| {
            let mut z = p.u.clone();
            factor.solve_in_place(&mut z);
            z
        })
        .collect();
    let mut m = vec![0.0; k * k];
    let mut c = vec![0.0; k];
    for (i, pi) in parts.iter().enumerate() {
        if !(pi.scale > 0.0 && pi.scale.is_finite()) {
            return false;
        }
        for (j, zj) in z.iter().enumerate() {
            m[i * k + j] = dot(&pi.u, zj);
        }
        m[i * k + i] += 1.0 / pi.scale;
        c[i] = dot(&pi.u, x);
    }
    if !solve_small(&mut m, &mut c) {
        return false;
    }
    for (zj, cj) in z.iter().zip(&c) {
        for (xi, zi) in x.iter_mut().zip(zj) {
            *xi -= cj * zi;
        }
    }
    true
}

/// `a · b`.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solves the small symmetric positive definite `m c = b` in place (`c` holds `b`) by
/// Cholesky; `false` when `m` is not positive definite.
fn solve_small(m: &mut [f64], c: &mut [f64]) -> bool {
    let k = c.len();
    for j in 0..k {
        let d = m[j * k + j] - (0..j).map(|l| m[j * k + l] * m[j * k + l]).sum::<f64>();
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        m[j * k + j] = d;
        for i in j + 1..k {
            let s = m[i * k + j] - (0..j).map(|l| m[i * k + l] * m[j * k + l]).sum::<f64>();
            m[i * k + j] = s / d;
        }
    }
    for i in 0..k {
        let s = c[i] - (0..i).map(|l| m[i * k + l] * c[l]).sum::<f64>();
        c[i] = s / m[i * k + i];
    }
    for i in (0..k).rev() {
        let s = c[i] - (i + 1..k).map(|l| m[l * k + i] * c[l]).sum::<f64>();
        c[i] = s / m[i * k + i];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::solver::linalg::block_cholesky::BlockPattern;

    /// A block-tridiagonal SPD matrix of `nb` 3 × 3 blocks (row-major).
    fn sparse(nb: usize) -> Vec<f64> {
        let n = 3 * nb;
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            a[i * n + i] = 4.0 + (i % 5) as f64;
            if i + 3 < n {
                a[i * n + i + 3] = -1.0 + 0.1 * (i % 3) as f64;
                a[(i + 3) * n + i] = a[i * n + i + 3];
            }
        }
        a
    }

    /// The parts added to the matrix and solved densely give what the sparse factor and
    /// the parts give; without the parts' correction they do not.
    #[test]
    fn the_parts_solve_as_if_added_to_the_matrix() {
        let nb = 6;
        let n = 3 * nb;
        let a = sparse(nb);
        let parts: Vec<RankOne> = (0..2)
            .map(|k| {
                RankOne::always(
                    [50.0, 0.3][k],
                    (0..n).map(|i| ((i * (k + 2)) as f64 * 0.7).sin()).collect(),
                )
            })
            .collect();
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        // Reference: the dense matrix with the parts added, factored with every block kept.
        let mut dense = a.clone();
        for p in &parts {
            for i in 0..n {
                for j in 0..n {
                    dense[i * n + j] += p.scale * p.u[i] * p.u[j];
                }
            }
        }
        let zero = vec![0.0; n];
        let full = BlockPattern::of(&vec![1.0; n * n], n);
        let mut expected = b.clone();
        BlockCholesky::factor(&dense, &zero, &full)
            .expect("SPD")
            .solve_in_place(&mut expected);
        // The sparse factor of `a` alone (its own, tridiagonal pattern) and the parts.
        let pattern = BlockPattern::of(&a, n);
        let factor = BlockCholesky::factor(&a, &zero, &pattern).expect("SPD");
        let mut x = b.clone();
        factor.solve_in_place(&mut x);
        let uncorrected = x.clone();
        assert!(solve_with(&parts, &factor, &mut x));
        let error = x
            .iter()
            .zip(&expected)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(error < 1e-10, "Woodbury off by {error}");
        let without = uncorrected
            .iter()
            .zip(&expected)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(without > 1e-3, "the parts change the solution ({without})");
        // And the diagonal the damping reads includes theirs.
        let mut diagonal: Vec<f64> = (0..n).map(|i| a[i * n + i]).collect();
        add_diagonal(&parts, &mut diagonal);
        for (i, d) in diagonal.iter().enumerate() {
            assert!((d - dense[i * n + i]).abs() < 1e-12);
        }
    }

    /// A part without a positive scale is refused, and the step left as it was.
    #[test]
    fn a_part_of_no_scale_is_refused() {
        let n = 6;
        let a = sparse(2);
        let zero = vec![0.0; n];
        let pattern = BlockPattern::of(&a, n);
        let factor = BlockCholesky::factor(&a, &zero, &pattern).expect("SPD");
        let mut x = vec![1.0; n];
        let parts = [RankOne::always(0.0, vec![1.0; n])];
        assert!(!solve_with(&parts, &factor, &mut x));
        assert_eq!(x, vec![1.0; n]);
    }
}
