//! A first pose for a new constraint set without waiting for the whole mesh's factorization.
//!
//! On a large mesh the precompute of a new constraint set (a click on a painted region, a
//! grab of a mesh with a fixed region) costs several frames: with one iteration, ~40–50 ms at
//! 26k vertices and ~170–240 ms at 104k on two cores. A *preview* solves only the vertices
//! near the handles, along the surface, and holds every other vertex where the displayed pose
//! has it; its system is small, so the first pose comes within a frame or two while the whole
//! mesh is factored in the background (the figures are in docs/benchmarks.md, `arap_interaction`).

use glam::DVec3;

use super::constraints::Constraints;
use super::topology::Topology;

/// The region a preview solves: the vertices within `radius` × the bounding-box diagonal of
/// the handles, along the surface, at most `max_vertices` of them (the nearest), on meshes of
/// more than `min_mesh_vertices` vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreviewRegion {
    /// Radius along the surface, as a fraction of the mesh's bounding-box diagonal.
    pub radius: f64,
    /// At most this many vertices move (the nearest to the handles).
    pub max_vertices: usize,
    /// Meshes with no more vertices than this get no preview: their whole factorization is
    /// about as quick.
    pub min_mesh_vertices: usize,
}

impl Default for PreviewRegion {
    /// A quarter of the diagonal, at most 8 192 vertices, on meshes of more than 16 384 (a
    /// first pose in ~12 ms at 26k and ~35–45 ms at 104k on two cores, see docs/benchmarks.md).
    fn default() -> Self {
        Self {
            radius: 0.25,
            max_vertices: 8_192,
            min_mesh_vertices: 16_384,
        }
    }
}

impl PreviewRegion {
    /// A preview of `constraints`: the same sets, plus every free vertex outside the region
    /// held where `current` (the displayed pose, welded order) has it — in the fixed set when
    /// that is its rest position (a cell of such vertices costs nothing to solve), else as a
    /// target — so the preview moves only the region and the rest of the pose stays as shown.
    ///
    /// `None` when no preview is needed or possible: the mesh has at most
    /// `min_mesh_vertices` (or `max_vertices`) vertices, the constraints have no handle or
    /// target to grow the region from, the region already holds every free vertex, or
    /// `current` does not have one position per vertex.
    pub fn preview(
        &self,
        topology: &Topology,
        constraints: &Constraints,
        current: &[DVec3],
    ) -> Option<Preview> {
        let n = topology.vertex_count();
        if n <= self.min_mesh_vertices.max(self.max_vertices) || current.len() != n {
            return None;
        }
        let seeds: Vec<u32> = constraints
            .handles
            .iter()
            .flat_map(|h| h.vertices.iter().copied())
            .chain(constraints.targets.iter().map(|&(v, _)| v))
            .filter(|&v| (v as usize) < n)
            .collect();
        if seeds.is_empty() {
            return None;
        }
        let limit = self.radius.max(0.0) * topology.bounding_diagonal();
        // The seeds count against the cap too: the cap bounds the preview's free vertices.
        let cap = self.max_vertices + seeds.len();
        let mut inside = vec![false; n];
        for (v, _) in topology.geodesic_distances(&seeds, limit, cap) {
            inside[v as usize] = true;
        }
        for &v in &constraints.fixed {
            if let Some(slot) = inside.get_mut(v as usize) {
                *slot = true; // already held
            }
        }
        let mut held = constraints.clone();
        let rest = topology.positions();
        for v in (0..n).filter(|&v| !inside[v]) {
            match current[v] == rest[v] {
                true => held.fixed.push(v as u32),
                false => held.targets.push((v as u32, current[v])),
            }
        }
        if held.fixed.len() == constraints.fixed.len()
            && held.targets.len() == constraints.targets.len()
        {
            return None;
        }
        Some(Preview {
            request: constraints.clone(),
            constraints: held,
        })
    }
}

/// A preview of one constraint set ([`PreviewRegion::preview`]): the request's constraints
/// with the vertices outside the region held.
#[derive(Debug, Clone, PartialEq)]
pub struct Preview {
    /// The constraints the preview was made for.
    request: Constraints,
    /// Those with the held vertices added.
    constraints: Constraints,
}

impl Preview {
    /// The constraints to precompute and solve.
    pub fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// The preview's constraints for new values (handle transforms, target positions) of the
    /// request's sets, so one preview factorization serves a drag; `None` when `request` has
    /// other sets than the one the preview was made for.
    pub fn follow(&self, request: &Constraints) -> Option<Constraints> {
        if !self.request.same_sets(request) {
            return None;
        }
        let mut c = self.constraints.clone();
        for (h, new) in c.handles.iter_mut().zip(&request.handles) {
            h.transform = new.transform;
        }
        for (t, new) in c.targets.iter_mut().zip(&request.targets) {
            t.1 = new.1;
        }
        Some(c)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::DVec3;

    use super::PreviewRegion;
    use crate::deform::synth::{bar, bend_problem};
    use crate::deform::{
        Acceleration, ArapSolver, Constraints, InitialGuess, SolveOptions, SolverSettings, Topology,
    };

    fn options(iterations: u32, acceleration: Acceleration) -> SolveOptions {
        SolveOptions {
            max_iterations: iterations,
            tolerance: 0.0,
            acceleration,
        }
    }

    /// A bar of 12 × 60 rings (722 vertices), bent at its top; a preview of at most 200
    /// vertices.
    fn setup() -> (Arc<Topology>, Constraints, PreviewRegion) {
        let mesh = bar(12, 60, 0.1, 1.0);
        let topology = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap());
        let c = bend_problem(topology.positions(), 0.5, DVec3::new(0.2, 0.0, 0.0));
        let region = PreviewRegion {
            radius: 0.25,
            max_vertices: 200,
            min_mesh_vertices: 200,
        };
        (topology, c, region)
    }

    #[test]
    fn no_preview_on_a_mesh_no_larger_than_the_region() {
        let (topology, c, mut region) = setup();
        let rest = topology.positions();
        region.min_mesh_vertices = topology.vertex_count();
        assert!(region.preview(&topology, &c, rest).is_none());
        // Nor without a handle to grow from, nor with a pose of the wrong length.
        region.min_mesh_vertices = 200;
        let mut fixed_only = c.clone();
        fixed_only.handles.clear();
        assert!(region.preview(&topology, &fixed_only, rest).is_none());
        assert!(region.preview(&topology, &c, &rest[1..]).is_none());
        assert!(region.preview(&topology, &c, rest).is_some());
    }

    /// The vertices a preview holds beyond the request's, and where.
    fn held_by(c: &Constraints, p: &Constraints) -> Vec<(u32, DVec3)> {
        let fixed = p.fixed[c.fixed.len()..].iter().map(|&v| (v, DVec3::NAN));
        p.targets.iter().copied().chain(fixed).collect()
    }

    /// The region is near the handle and capped; everything else free is held where the
    /// current pose has it, so the preview of a converged pose is that pose, and a preview
    /// from rest moves only the region (its held vertices all fixed: they are at rest).
    #[test]
    fn the_preview_moves_only_the_region_and_holds_the_rest_where_it_is() {
        let (topology, c, region) = setup();
        let n = topology.vertex_count();
        let rest = topology.positions();
        let whole =
            ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
        let converged = whole
            .solve(
                &c,
                &options(200, Acceleration::Newton { max_cg: 100 }),
                InitialGuess::Laplacian,
                &|| false,
            )
            .unwrap();
        let preview = region
            .preview(&topology, &c, &converged.positions)
            .expect("a preview");
        let p = preview.constraints();
        assert_eq!(p.fixed[..c.fixed.len()], c.fixed[..]);
        let held = held_by(&c, p);
        let constrained = c.fixed.len() + c.handles[0].vertices.len();
        let free = n - constrained - held.len();
        assert!(free > 50 && free <= region.max_vertices, "{free} free");
        // Held vertices are far from the handle (the region grows from it).
        let y_top = rest[c.handles[0].vertices[0] as usize].y;
        for &(v, at) in &held {
            assert!(at.is_nan() || at == converged.positions[v as usize]);
            assert!(y_top - rest[v as usize].y > 0.2);
        }
        let solver =
            ArapSolver::precompute(topology.clone(), p, SolverSettings::default()).unwrap();
        let again = solver
            .solve(
                p,
                &options(20, Acceleration::None),
                InitialGuess::Warm(&converged),
                &|| false,
            )
            .unwrap();
        let drift = again
            .positions
            .iter()
            .zip(&converged.positions)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        assert!(drift < 1e-6 * topology.bounding_diagonal(), "drift {drift}");
        // From rest: the held vertices are fixed and stay, the region bends toward the handle.
        let preview = region.preview(&topology, &c, rest).unwrap();
        let p = preview.constraints();
        assert!(p.targets.is_empty());
        let held = held_by(&c, p);
        assert!(!held.is_empty());
        let solver =
            ArapSolver::precompute(topology.clone(), p, SolverSettings::default()).unwrap();
        let first = solver
            .solve(
                p,
                &options(4, Acceleration::None),
                InitialGuess::Rest,
                &|| false,
            )
            .unwrap();
        for &(v, _) in &held {
            assert_eq!(first.positions[v as usize], rest[v as usize]);
        }
        let moved = (0..n)
            .filter(|&v| first.positions[v].distance(rest[v]) > 1e-3)
            .count();
        assert!(moved > 50, "{moved} vertices moved");
        // The same preview follows the handle: new values, same sets, same factorization.
        let mut next = c.clone();
        next.handles[0].transform.translation.x += 0.05;
        let followed = preview.follow(&next).expect("same sets");
        assert!(solver.accepts(&followed));
        assert_eq!(followed.handles[0].transform, next.handles[0].transform);
        next.fixed.pop();
        assert!(preview.follow(&next).is_none());
    }
}
