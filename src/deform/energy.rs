//! The normalised ARAP energy used to compare solvers.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::rotation::{add_outer, best_rotation_exact};
use super::topology::{Topology, WeightMode};

/// Normalised ARAP energy of `deformed` (welded order) relative to the rest mesh:
///
/// `E = Σ_i Σ_{j∈N(i)} w_ij ‖(p'_i − p'_j) − R_i (p_i − p_j)‖² / Σ_i Σ_j w_ij ‖p_i − p_j‖²`
///
/// with clamped cotangent weights `max(0, ½(cot α + cot β))` of the rest mesh and `R_i` the
/// exact best-fit rotation of each cell (Horn's quaternion method). Every solver compared in
/// the benchmarks is scored with this one function. Returns `NaN` when `deformed` has the
/// wrong length or contains non-finite values.
pub fn arap_energy(topology: &Topology, deformed: &[DVec3]) -> f64 {
    if deformed.len() != topology.vertex_count() || !deformed.iter().all(|p| p.is_finite()) {
        return f64::NAN;
    }
    let w = topology.weights(WeightMode::ClampedCotangent);
    let rest = topology.positions();
    let offsets = topology.offsets();
    let nbrs = topology.neighbor_list();
    let (num, den) = (0..topology.vertex_count())
        .into_par_iter()
        .map(|i| {
            let range = offsets[i] as usize..offsets[i + 1] as usize;
            let mut a = DMat3::ZERO;
            for e in range.clone() {
                let j = nbrs[e] as usize;
                add_outer(&mut a, w[e], deformed[i] - deformed[j], rest[i] - rest[j]);
            }
            let r = DMat3::from_quat(best_rotation_exact(&a));
            let (mut num, mut den) = (0.0, 0.0);
            for e in range {
                let j = nbrs[e] as usize;
                let er = rest[i] - rest[j];
                num += w[e] * ((deformed[i] - deformed[j]) - r * er).length_squared();
                den += w[e] * er.length_squared();
            }
            (num, den)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    if den > 0.0 { num / den } else { 0.0 }
}
