//! Writing solved poses back to the mesh asset: positions, normals (repaired where a file's
//! were missing or broken) and tangents.

use super::*;

/// Number of values of a vertex attribute, if present.
pub(super) fn attribute_len(mesh: &Mesh, id: bevy::mesh::MeshVertexAttribute) -> Option<usize> {
    mesh.try_attribute(id).ok().map(|v| v.len())
}

pub(super) fn write_back(
    mut meshes: ResMut<Assets<Mesh>>,
    mut q: Query<(&Mesh3d, &mut DeformState)>,
) {
    for (mesh3d, mut state) in &mut q {
        let state = state.bypass_change_detection();
        let Some(pose) = state.ready.take() else {
            continue;
        };
        let Some(mut mesh) = meshes.get_mut(&mesh3d.0) else {
            continue;
        };
        // The worker built whole attribute buffers: move them in (no per-vertex copy on the
        // main thread), but only over attributes of the same length.
        if attribute_len(&mesh, Mesh::ATTRIBUTE_POSITION) == Some(pose.positions.len()) {
            let _ = mesh.try_insert_attribute(Mesh::ATTRIBUTE_POSITION, pose.positions);
        }
        if let Some(n) = pose.normals
            && attribute_len(&mesh, Mesh::ATTRIBUTE_NORMAL) == Some(n.len())
        {
            let _ = mesh.try_insert_attribute(Mesh::ATTRIBUTE_NORMAL, n);
        }
        if let Some(t) = pose.tangents
            && attribute_len(&mesh, Mesh::ATTRIBUTE_TANGENT) == Some(t.len())
        {
            let _ = mesh.try_insert_attribute(Mesh::ATTRIBUTE_TANGENT, t);
        }
    }
}

/// Whether a normal can be used: finite and not (nearly) zero.
pub(super) fn is_unit_like(n: Vec3) -> bool {
    n.is_finite() && n.length_squared() > 1e-12
}

/// `normals` with every unusable one (NaN, infinite, zero) replaced by the area-weighted
/// normal of the triangles around its vertex (or +Y where those are degenerate too).
pub(super) fn repair_normals(positions: &[Vec3], indices: &[u32], normals: &[Vec3]) -> Vec<Vec3> {
    let mut summed = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        if a.max(b).max(c) >= positions.len() {
            continue; // bad indices fail later with a typed error
        }
        let face = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        if face.is_finite() {
            for v in [a, b, c] {
                summed[v] += face;
            }
        }
    }
    normals
        .iter()
        .zip(summed)
        .map(|(&n, s)| {
            if is_unit_like(n) {
                n
            } else {
                s.try_normalize().unwrap_or(Vec3::Y)
            }
        })
        .collect()
}
