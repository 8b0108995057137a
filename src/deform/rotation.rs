//! Best-fit rotations of 3×3 covariance matrices.
//!
//! Both functions find the rotation `R ∈ SO(3)` maximising `tr(Rᵀ A)` — for an ARAP cell with
//! `A = Σ_j w_ij e'_ij e_ijᵀ` that is the rotation taking rest edges `e` closest to deformed
//! edges `e'`. Reflections are never returned.

use glam::{DMat3, DQuat, DVec3};

/// Fast warm-started rotation fit: maximises `tr(Rᵀ A)` by Newton steps on the rotation
/// manifold, `R ← R·Exp(ω)` with `ω = H⁻¹ g`, where `B = Rᵀ A`, `g` is the axial vector of
/// `B − Bᵀ` and `H = tr(B)·I − sym(B)`. Where `H` is not positive definite (far from the
/// optimum) it takes the scaled-gradient step of Müller et al. 2016 instead. Quadratic
/// convergence near the optimum: from last iteration's rotation one or two steps reach
/// `tol` radians, also on flat one-rings where gradient-only methods crawl.
pub fn fit_rotation_warm(a: &DMat3, q: DQuat, max_iterations: u32, tol: f64) -> DQuat {
    let mut q = if q.length_squared() > 0.0 {
        q.normalize()
    } else {
        DQuat::IDENTITY
    };
    for _ in 0..max_iterations {
        let r = DMat3::from_quat(q);
        let b = r.transpose() * *a;
        // b.col(c)[r] = B[r][c]
        let (b00, b01, b02) = (b.x_axis.x, b.y_axis.x, b.z_axis.x);
        let (b10, b11, b12) = (b.x_axis.y, b.y_axis.y, b.z_axis.y);
        let (b20, b21, b22) = (b.x_axis.z, b.y_axis.z, b.z_axis.z);
        let g = DVec3::new(b21 - b12, b02 - b20, b10 - b01);
        let tr = b00 + b11 + b22;
        // H = tr·I − sym(B)
        let (h00, h11, h22) = (tr - b00, tr - b11, tr - b22);
        let (h01, h02, h12) = (-0.5 * (b01 + b10), -0.5 * (b02 + b20), -0.5 * (b12 + b21));
        let m00 = h11 * h22 - h12 * h12;
        let m01 = h02 * h12 - h01 * h22;
        let m02 = h01 * h12 - h02 * h11;
        let det = h00 * m00 + h01 * m01 + h02 * m02;
        let scale = tr.abs() + 1e-300;
        let newton_ok =
            h00 > 0.0 && h00 * h11 - h01 * h01 > 0.0 && det > 1e-12 * scale * scale * scale;
        let mut w = if newton_ok {
            let m11 = h00 * h22 - h02 * h02;
            let m12 = h01 * h02 - h00 * h12;
            let m22 = h00 * h11 - h01 * h01;
            DVec3::new(
                m00 * g.x + m01 * g.y + m02 * g.z,
                m01 * g.x + m11 * g.y + m12 * g.z,
                m02 * g.x + m12 * g.y + m22 * g.z,
            ) * det.recip()
        } else {
            g * scale.recip()
        };
        // Square roots only where needed: convergence and the small-angle exponential work on
        // the squared step length.
        let mut angle_sq = w.length_squared();
        // Stops on convergence and on NaN (degenerate covariance).
        if angle_sq.partial_cmp(&(tol * tol)) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        if angle_sq > 1.0 {
            w /= angle_sq.sqrt();
            angle_sq = 1.0;
        }
        let inc = if angle_sq < 1e-6 {
            // Exp(ω) to third order without trig.
            DQuat::from_xyzw(w.x * 0.5, w.y * 0.5, w.z * 0.5, 1.0 - angle_sq / 8.0)
        } else {
            DQuat::from_scaled_axis(w)
        };
        q *= inc;
        // |q| stays within ~1e-14 of 1 (the increment is unit to third order): one Newton
        // step of the normalisation replaces the square root.
        q = q * (1.5 - 0.5 * q.length_squared());
        // Newton converges quadratically: after a step of size ε the next would be ~ε², so a
        // step below √tol already lands within tol — skip the verifying iteration.
        if newton_ok && angle_sq <= tol {
            break;
        }
    }
    q
}

/// Exact best-fit rotation (Horn 1987): the unit quaternion is the eigenvector of the largest
/// eigenvalue of a symmetric 4×4 matrix built from `A`, found with cyclic Jacobi sweeps.
/// Slower than [`fit_rotation_warm`]; used for reporting energies.
#[allow(clippy::needless_range_loop)] // 4×4 Jacobi sweeps read clearest with indices
pub fn best_rotation_exact(a: &DMat3) -> DQuat {
    // Horn's S = Σ rest·deformedᵀ = Aᵀ; S[x][y] = A[y][x] (A column-major: A.col(c).row(r)).
    let s = |x: usize, y: usize| a.col(x)[y];
    let (sxx, sxy, sxz) = (s(0, 0), s(0, 1), s(0, 2));
    let (syx, syy, syz) = (s(1, 0), s(1, 1), s(1, 2));
    let (szx, szy, szz) = (s(2, 0), s(2, 1), s(2, 2));
    let mut n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let mut v = [[0.0f64; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let scale: f64 = n.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    if scale.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !scale.is_finite() {
        return DQuat::IDENTITY;
    }
    for _sweep in 0..50 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| n[i][j] * n[i][j])
            .sum();
        if off.sqrt() <= 1e-15 * scale {
            break;
        }
        for p in 0..3 {
            for q in p + 1..4 {
                if n[p][q].abs() <= 1e-300 {
                    continue;
                }
                let theta = (n[q][q] - n[p][p]) / (2.0 * n[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * c;
                for k in 0..4 {
                    let (nkp, nkq) = (n[k][p], n[k][q]);
                    n[k][p] = c * nkp - sn * nkq;
                    n[k][q] = sn * nkp + c * nkq;
                }
                for k in 0..4 {
                    let (npk, nqk) = (n[p][k], n[q][k]);
                    n[p][k] = c * npk - sn * nqk;
                    n[q][k] = sn * npk + c * nqk;
                }
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - sn * vq;
                    row[q] = sn * vp + c * vq;
                }
            }
        }
    }
    let best = (0..4)
        .max_by(|&i, &j| n[i][i].total_cmp(&n[j][j]))
        .unwrap_or(0);
    let q = DQuat::from_xyzw(v[1][best], v[2][best], v[3][best], v[0][best]);
    if q.length_squared() > 0.0 {
        q.normalize()
    } else {
        DQuat::IDENTITY
    }
}

/// Covariance `Σ w e' eᵀ` helper: adds `w · deformed · restᵀ` to `acc`.
#[inline]
pub fn add_outer(acc: &mut DMat3, w: f64, deformed: DVec3, rest: DVec3) {
    let d = deformed * w;
    acc.x_axis += d * rest.x;
    acc.y_axis += d * rest.y;
    acc.z_axis += d * rest.z;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform in [−1, 1) from a 64-bit LCG (shared with `svd_reference`).
    pub(super) fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    fn random_case(seed: &mut u64) -> (DQuat, DMat3) {
        let axis = DVec3::new(lcg(seed), lcg(seed), lcg(seed)).normalize();
        let r = DQuat::from_axis_angle(axis, lcg(seed) * 3.1);
        let mut a = DMat3::ZERO;
        for _ in 0..6 {
            let e = DVec3::new(lcg(seed), lcg(seed), lcg(seed));
            add_outer(&mut a, 0.5 + lcg(seed).abs(), r * e, e);
        }
        (r, a)
    }

    fn same(a: DQuat, b: DQuat) -> bool {
        a.dot(b).abs() > 1.0 - 1e-10
    }

    #[test]
    fn exact_recovers_random_rotations() {
        let mut seed = 7;
        for _ in 0..200 {
            let (r, a) = random_case(&mut seed);
            assert!(same(best_rotation_exact(&a), r), "exact fit missed {r:?}");
        }
    }

    #[test]
    fn warm_fit_recovers_rotations_from_identity() {
        let mut seed = 11;
        for _ in 0..200 {
            let (r, a) = random_case(&mut seed);
            let q = fit_rotation_warm(&a, DQuat::IDENTITY, 100, 1e-14);
            assert!(same(q, r), "warm fit {q:?} vs {r:?}");
        }
    }

    #[test]
    fn never_returns_a_reflection() {
        // A pure reflection covariance: the best rotation has determinant +1.
        let a = DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0));
        let q = best_rotation_exact(&a);
        assert!((DMat3::from_quat(q).determinant() - 1.0).abs() < 1e-12);
        let q = fit_rotation_warm(&a, DQuat::IDENTITY, 50, 1e-14);
        assert!((DMat3::from_quat(q).determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_covariance_is_identity_and_finite() {
        assert_eq!(best_rotation_exact(&DMat3::ZERO), DQuat::IDENTITY);
        let q = fit_rotation_warm(&DMat3::ZERO, DQuat::IDENTITY, 10, 1e-12);
        assert!(q.is_finite());
    }
}

/// The rotation fit against an SVD reference (`R = U·diag(1, 1, det(U Vᵀ))·Vᵀ`, the reflection
/// fix) on covariances that stress it: random full rank, rank 1, rank 2, reflected
/// (det < 0), and nearly equal singular values.
///
/// Finding (for the note on 2e-3 differences to a reference model): where the optimum is
/// unique (full rank, reflected, rank 2) both fits return the SVD rotation to 1e-7 from any
/// start and the objective to 1e-11, so the fit is not inexact; where it is not unique (rank
/// 1, equal singular values, a reflected covariance whose two smallest singular values tie)
/// each method returns *an* optimal rotation — which one depends on the start — with the
/// objective within the tie's own size (the warm fit stopped 1.2e-9 below the optimum on a
/// tie of 1e-9): tie-breaking in degenerate cells.
#[cfg(test)]
mod svd_reference {
    use super::tests::lcg;
    use super::*;

    fn random_rotation(seed: &mut u64) -> DMat3 {
        let axis = DVec3::new(lcg(seed), lcg(seed), lcg(seed)).normalize();
        DMat3::from_quat(DQuat::from_axis_angle(axis, lcg(seed) * 3.1))
    }

    /// `U · diag(s) · Vᵀ` with random rotations U, V.
    fn covariance(seed: &mut u64, s: [f64; 3]) -> DMat3 {
        random_rotation(seed)
            * DMat3::from_diagonal(DVec3::from_array(s))
            * random_rotation(seed).transpose()
    }

    /// The best rotation by faer's SVD, with the reflection fix.
    fn svd_rotation(a: &DMat3) -> DMat3 {
        let m = faer::Mat::<f64>::from_fn(3, 3, |r, c| a.col(c)[r]);
        let svd = m.svd().expect("3×3 SVD");
        let (u, v) = (svd.U(), svd.V());
        let to_glam = |m: faer::MatRef<'_, f64>| {
            DMat3::from_cols_array(&std::array::from_fn(|k| m[(k % 3, k / 3)]))
        };
        let (u, v) = (to_glam(u), to_glam(v));
        let d = (u * v.transpose()).determinant().signum();
        u * DMat3::from_diagonal(DVec3::new(1.0, 1.0, d)) * v.transpose()
    }

    fn objective(r: &DMat3, a: &DMat3) -> f64 {
        let b = r.transpose() * *a;
        b.x_axis.x + b.y_axis.y + b.z_axis.z
    }

    /// Checks both fits on `a`; `unique`: the optimum is unique, so the rotations must match.
    fn check(a: &DMat3, unique: bool, seed: &mut u64, label: &str) {
        let reference = svd_rotation(a);
        let best = objective(&reference, a);
        let scale = a
            .to_cols_array()
            .iter()
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt()
            .max(1e-300);
        let starts = [DQuat::IDENTITY, DQuat::from_mat3(&random_rotation(seed))];
        let exact = DMat3::from_quat(best_rotation_exact(a));
        let warm: Vec<DMat3> = starts
            .iter()
            .map(|q| DMat3::from_quat(fit_rotation_warm(a, *q, 40, 1e-10)))
            .collect();
        for (name, r) in std::iter::once(("exact", &exact)).chain(warm.iter().map(|r| ("warm", r)))
        {
            assert!(
                (r.determinant() - 1.0).abs() < 1e-9,
                "{label}/{name}: not a rotation"
            );
            // Where the optimum is not unique the landscape is flat along the tie: stopping
            // at the tolerance in angle leaves up to about the tie's size (1e-9) in objective.
            let gap = (best - objective(r, a)) / scale;
            let allowed = if unique { 1e-11 } else { 1e-8 };
            assert!(
                gap < allowed,
                "{label}/{name}: objective {gap:e} below the optimum"
            );
            if unique {
                let diff = (*r - reference)
                    .to_cols_array()
                    .iter()
                    .fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(diff < 1e-7, "{label}/{name}: rotation differs by {diff:e}");
            }
        }
    }

    #[test]
    fn fits_match_the_svd_rotation_on_hard_covariances() {
        let mut seed = 99;
        for _ in 0..200 {
            let s = [
                1.0 + lcg(&mut seed).abs(),
                0.5 + 0.4 * lcg(&mut seed).abs(),
                0.1 + 0.3 * lcg(&mut seed).abs(),
            ];
            let a = covariance(&mut seed, s);
            check(&a, true, &mut seed, "full rank");
            let reflected = covariance(&mut seed, [s[0], s[1], -s[2]]);
            check(&reflected, true, &mut seed, "reflected");
            let rank2 = covariance(&mut seed, [s[0], s[1], 0.0]);
            check(&rank2, true, &mut seed, "rank 2");
            let rank1 = covariance(&mut seed, [s[0], 0.0, 0.0]);
            check(&rank1, false, &mut seed, "rank 1");
            let near = covariance(&mut seed, [1.0, 1.0 + 1e-9, 1.0 + 2e-9]);
            check(&near, false, &mut seed, "nearly equal");
            let near_reflected = covariance(&mut seed, [1.0, 0.5, -(0.5 - 1e-9)]);
            check(
                &near_reflected,
                false,
                &mut seed,
                "reflected, two smallest tie",
            );
        }
    }
}
