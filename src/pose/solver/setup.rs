//! Setting a solver up: checking the constraints' indices, the vertex sets' sums and penalties,
//! the joint constraints' frames, and the nonzero blocks of the quadratic form.

use glam::{DMat4, DVec3, DVec4};

use crate::pose::constraints::PoseConstraints;
use crate::pose::error::PoseError;
use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::model::add_outer4x3;
use crate::pose::solver::energy::penalties::{SetSums, affine_rows};

/// Every vertex and joint a constraint names exists.
pub(super) fn check_indices(
    constraints: &PoseConstraints,
    vertex_count: usize,
    joint_count: usize,
) -> Result<(), PoseError> {
    for &v in constraints
        .fixed_vertices
        .iter()
        .chain(constraints.handles.iter().flat_map(|h| &h.vertices))
    {
        if v as usize >= vertex_count {
            return Err(PoseError::VertexOutOfRange {
                vertex: v,
                vertex_count,
            });
        }
    }
    for &j in constraints
        .fixed_joints
        .iter()
        .chain(constraints.joint_handles.iter().map(|h| &h.joint))
    {
        if j >= joint_count {
            return Err(PoseError::JointOutOfRange {
                joint: j,
                joint_count,
            });
        }
    }
    Ok(())
}

/// The sums of a vertex set at the reference pose, its penalty added to `q` (weight
/// `vertex_weight`).
pub(super) fn set_sums(
    model: &SkinnedModel,
    reference_positions: &[DVec3],
    vertices: &[u32],
    vertex_weight: f64,
    q: &mut [f64],
) -> SetSums {
    let dim = 4 * model.skeleton().len();
    let mut s = SetSums {
        mp: vec![0.0; dim * 3],
        m: vec![0.0; dim],
        p: DVec3::ZERO,
        pp: 0.0,
        count: vertices.len() as f64,
    };
    for &v in vertices {
        let p = reference_positions[v as usize];
        let row: Vec<(usize, DVec4)> = model.row(v as usize).collect();
        for &(a, ua) in &row {
            add_outer4x3(&mut s.mp, a, ua, p);
            for p in 0..4 {
                s.m[4 * a + p] += ua[p];
            }
            for &(b, ub) in &row {
                let base = 4 * a * dim + 4 * b;
                for r in 0..4 {
                    for c in 0..4 {
                        q[base + r * dim + c] += vertex_weight * ua[r] * ub[c];
                    }
                }
            }
        }
        s.p += p;
        s.pp += p.length_squared();
    }
    s
}

/// Per joint, the rows of U = N D for the joint constraints ‖(S_j N_j − G*) D‖², with
/// N_j = inverse_bind⁻¹ and D = diag(ℓ, ℓ, ℓ, 1).
pub(super) fn joint_frames(
    skeleton: &crate::pose::rig::skeleton::Skeleton,
    length_scale: f64,
) -> Vec<[DVec4; 4]> {
    skeleton
        .joints()
        .iter()
        .map(|joint| {
            let n4 = affine_rows(&joint.inverse_bind.inverse());
            std::array::from_fn(|r| {
                DVec4::new(
                    n4[r][0] * length_scale,
                    n4[r][1] * length_scale,
                    n4[r][2] * length_scale,
                    n4[r][3],
                )
            })
        })
        .collect()
}

/// Which 4×4 blocks of the joint-major `q` are nonzero, and those blocks.
pub(super) fn nonzero_blocks(q: &[f64], joints: usize) -> (Vec<bool>, Vec<(usize, usize, DMat4)>) {
    let dim = 4 * joints;
    let block_nonzero: Vec<bool> = (0..joints * joints)
        .map(|b| {
            let (k, l) = (b / joints, b % joints);
            (0..4).any(|r| (0..4).any(|c| q[(4 * k + r) * dim + 4 * l + c] != 0.0))
        })
        .collect();
    let q_blocks = (0..joints * joints)
        .filter(|&b| block_nonzero[b])
        .map(|b| {
            let (k, l) = (b / joints, b % joints);
            let m = DMat4::from_cols_array_2d(&std::array::from_fn(|c| {
                std::array::from_fn(|r| q[(4 * k + r) * dim + 4 * l + c])
            }));
            (k, l, m)
        })
        .collect();
    (block_nonzero, q_blocks)
}
