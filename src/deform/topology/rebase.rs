//! A topology carried over to new rest positions: same weld and adjacency, new weights.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{MeshError, Topology, half_cotangents};

impl Topology {
    /// The same mesh with new rest positions (render order and index buffer, as
    /// [`Topology::from_render_mesh`] takes them; the indices must be the ones this topology
    /// was built from, [`MeshError::TrianglesChanged`] otherwise): the weld, triangles and
    /// adjacency are kept, the positions and cotangent weights are new. For making a deformed
    /// pose the rest pose of the next edit (a grab), where welded copies were written the same
    /// position; each welded vertex takes its first render copy's position. Gives exactly what
    /// a fresh build from these positions gives whenever that build welds the same way, at
    /// about half its cost (`arap_interaction`'s `rest_topology_ms`: 26k 10.0 → 4.6 ms).
    pub fn rebased(
        &self,
        render_positions: &[Vec3],
        indices: &[u32],
    ) -> Result<Topology, MeshError> {
        if render_positions.len() != self.render_to_welded.len() {
            return Err(MeshError::VertexCountChanged {
                expected: self.render_to_welded.len(),
                got: render_positions.len(),
            });
        }
        let map = &self.render_to_welded;
        let welded = indices.chunks_exact(3).filter_map(|t| {
            let w = [t[0], t[1], t[2]].map(|i| map.get(i as usize).copied().unwrap_or(u32::MAX));
            (w[0] != w[1] && w[1] != w[2] && w[0] != w[2]).then_some(w)
        });
        if !indices.len().is_multiple_of(3) || !welded.eq(self.triangles.iter().copied()) {
            return Err(MeshError::TrianglesChanged);
        }
        if let Some(vertex) = render_positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFinitePosition { vertex });
        }
        let mut positions = vec![DVec3::ZERO; self.positions.len()];
        let mut placed = vec![false; self.positions.len()];
        for (&w, p) in self.render_to_welded.iter().zip(render_positions) {
            if !std::mem::replace(&mut placed[w as usize], true) {
                positions[w as usize] = p.as_dvec3();
            }
        }
        // Per triangle (in parallel): each corner's weight and the CSR slots of its two edges
        // at both ends.
        let scattered: Vec<([f64; 3], [[u32; 2]; 3])> = self
            .triangles
            .par_iter()
            .map(|t| {
                let slots = std::array::from_fn(|k| {
                    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                    [self.slot(a, b) as u32, self.slot(a, c) as u32]
                });
                (half_cotangents(t.map(|i| positions[i as usize])), slots)
            })
            .collect();
        // Added in triangle order, as the full build merges them: both ends of an edge sum the
        // same contributions in the same order, so `w_ij == w_ji` exactly.
        let mut cotangent = vec![0.0; self.neighbors.len()];
        for (half_cot, slots) in &scattered {
            for k in 0..3 {
                cotangent[slots[k][0] as usize] += half_cot[(k + 2) % 3];
                cotangent[slots[k][1] as usize] += half_cot[(k + 1) % 3];
            }
        }
        Ok(Topology {
            positions,
            triangles: self.triangles.clone(),
            render_to_welded: self.render_to_welded.clone(),
            offsets: self.offsets.clone(),
            neighbors: self.neighbors.clone(),
            cotangent,
            derived: Default::default(),
            elimination: self.elimination.clone(),
        })
    }

    /// CSR slot of edge `i → j` (both ends of a triangle edge).
    pub(super) fn slot(&self, i: u32, j: u32) -> usize {
        let start = self.offsets[i as usize] as usize;
        let row = &self.neighbors[start..self.offsets[i as usize + 1] as usize];
        // Always found (every triangle edge is in both of its rows); no panic path regardless.
        start
            + row
                .binary_search(&j)
                .unwrap_or_else(|at| at.min(row.len().saturating_sub(1)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rebasing_equals_a_fresh_build_of_the_deformed_mesh() {
        // Every edge a split seam: the weld is what makes this one closed sphere.
        let mesh = crate::deform::synth::split_per_face(&crate::deform::synth::icosphere(2, 1.0));
        let render: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
        let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let rest = Topology::from_render_mesh(&render, &indices).unwrap();
        assert!(rest.vertex_count() < render.len());
        // A smooth non-rigid deformation, the same for every copy of a vertex.
        let bent: Vec<Vec3> = render
            .iter()
            .map(|p| {
                Vec3::new(
                    p.x + 0.3 * p.y * p.y,
                    p.y * (1.0 + 0.2 * p.z),
                    p.z - 0.1 * p.x,
                )
            })
            .collect();
        let fresh = Topology::from_render_mesh(&bent, &indices).unwrap();
        let rebased = rest.rebased(&bent, &indices).unwrap();
        assert_eq!(rebased.render_to_welded(), fresh.render_to_welded());
        assert_eq!(rebased.offsets(), fresh.offsets());
        assert_eq!(rebased.neighbor_list(), fresh.neighbor_list());
        assert_eq!(rebased.positions(), fresh.positions());
        let bits = |t: &Topology| {
            t.raw_cotangents()
                .iter()
                .map(|w| w.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&rebased), bits(&fresh));
        assert_ne!(
            bits(&rebased),
            bits(&rest),
            "the weights follow the new shape"
        );
        // Bad input: a typed error, nothing built.
        assert_eq!(
            rest.rebased(&bent[1..], &indices).unwrap_err(),
            MeshError::VertexCountChanged {
                expected: render.len(),
                got: render.len() - 1
            }
        );
        let mut nan = bent.clone();
        nan[5].z = f32::NAN;
        assert_eq!(
            rest.rebased(&nan, &indices).unwrap_err(),
            MeshError::NonFinitePosition { vertex: 5 }
        );
        let mut flipped = indices.clone();
        flipped.swap(0, 1);
        assert_eq!(
            rest.rebased(&bent, &flipped).unwrap_err(),
            MeshError::TrianglesChanged
        );
        assert_eq!(
            rest.rebased(&bent, &indices[..indices.len() - 3])
                .unwrap_err(),
            MeshError::TrianglesChanged
        );
    }
}
