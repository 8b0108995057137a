//! Synthetic meshes generated in code (for tests, benchmarks and the sandbox's assets).

use glam::{DQuat, DVec3};

use super::constraints::{Constraints, RigidTransform};
use super::io::TriMesh;

/// A closed octahedron (6 vertices, 8 outward-facing triangles) of circumradius `radius`
/// centred at `centre`: vertices ±X, ±Y, ±Z in that order.
pub fn octahedron(centre: DVec3, radius: f64) -> TriMesh {
    let positions = [
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ]
    .map(|d| centre + d * radius)
    .to_vec();
    let triangles = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    TriMesh {
        positions,
        triangles,
    }
}

/// A closed cylinder ("bar") along +Y from `y = 0` to `y = length`, with `radial` vertices per
/// ring, `rings` rings and one centre vertex per cap: `radial · rings + 2` vertices.
pub fn bar(radial: u32, rings: u32, radius: f64, length: f64) -> TriMesh {
    let radial = radial.max(3);
    let rings = rings.max(2);
    let mut positions = Vec::with_capacity((radial * rings + 2) as usize);
    for r in 0..rings {
        let y = length * r as f64 / (rings - 1) as f64;
        for k in 0..radial {
            let a = std::f64::consts::TAU * k as f64 / radial as f64;
            positions.push(DVec3::new(radius * a.cos(), y, radius * a.sin()));
        }
    }
    let bottom = positions.len() as u32;
    positions.push(DVec3::ZERO);
    let top = positions.len() as u32;
    positions.push(DVec3::new(0.0, length, 0.0));
    let id = |r: u32, k: u32| r * radial + k % radial;
    let mut triangles = Vec::new();
    for r in 0..rings - 1 {
        for k in 0..radial {
            let (a, b, c, d) = (id(r, k), id(r, k + 1), id(r + 1, k + 1), id(r + 1, k));
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
        }
    }
    for k in 0..radial {
        triangles.push([bottom, id(0, k), id(0, k + 1)]);
        triangles.push([top, id(rings - 1, k + 1), id(rings - 1, k)]);
    }
    TriMesh {
        positions,
        triangles,
    }
}

/// A closed box ("plank") along +Y from `y = 0` to `y = length`, `thickness` across X and
/// `width` across Z (centred), each face a grid: `cells` cells per unit of length, at least
/// one per side. Faces share their edge vertices by position (bit-identical), so the seams
/// weld ([`crate::deform::WeldPolicy::Seams`]); triangles wind counter-clockwise from outside.
pub fn plank(length: f64, width: f64, thickness: f64, cells: f64) -> TriMesh {
    let levels = |lo: f64, hi: f64| -> Vec<f64> {
        let n = (((hi - lo) * cells).round() as usize).max(1);
        (0..=n)
            .map(|i| lo + (hi - lo) * i as f64 / n as f64)
            .collect()
    };
    let axes = [
        levels(-0.5 * thickness, 0.5 * thickness),
        levels(0.0, length),
        levels(-0.5 * width, 0.5 * width),
    ];
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for k in 0..3 {
        for outward in [false, true] {
            // The face's two axes, ordered so that their cross product is its normal.
            let (mut u, mut v) = ((k + 1) % 3, (k + 2) % 3);
            if !outward {
                std::mem::swap(&mut u, &mut v);
            }
            let fixed = if outward {
                *axes[k].last().unwrap_or(&0.0)
            } else {
                axes[k][0]
            };
            let base = positions.len() as u32;
            let (nu, nv) = (axes[u].len(), axes[v].len());
            for j in 0..nv {
                for i in 0..nu {
                    let mut p = [0.0; 3];
                    p[k] = fixed;
                    p[u] = axes[u][i];
                    p[v] = axes[v][j];
                    positions.push(DVec3::from_array(p));
                }
            }
            let id = |i: usize, j: usize| base + (j * nu + i) as u32;
            for j in 0..nv - 1 {
                for i in 0..nu - 1 {
                    let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                    triangles.push([a, b, c]);
                    triangles.push([a, c, d]);
                }
            }
        }
    }
    TriMesh {
        positions,
        triangles,
    }
}

/// A bar with about `target_vertices` vertices and a 1:10 radius:length ratio.
pub fn bar_with_vertices(target_vertices: u32) -> TriMesh {
    let radial = ((target_vertices as f64 / 2.0).sqrt()).round().max(3.0) as u32;
    let rings = (target_vertices.saturating_sub(2) / radial).max(2);
    bar(radial, rings, 0.1, 1.0)
}

/// An icosphere of radius `radius` subdivided `subdivisions` times (12, 42, 162, 642, … vertices).
pub fn icosphere(subdivisions: u32, radius: f64) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let positions: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut mesh = TriMesh {
        positions,
        triangles,
    };
    for _ in 0..subdivisions {
        mesh = subdivide_midpoint(&mesh);
        for p in &mut mesh.positions {
            *p = p.normalize();
        }
    }
    for p in &mut mesh.positions {
        *p *= radius;
    }
    mesh
}

/// Splits every triangle into its own three vertices (like a flat-shaded render mesh).
pub fn split_per_face(mesh: &TriMesh) -> TriMesh {
    let mut positions = Vec::with_capacity(mesh.triangles.len() * 3);
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let base = positions.len() as u32;
        positions.extend(t.iter().map(|&i| mesh.positions[i as usize]));
        triangles.push([base, base + 1, base + 2]);
    }
    TriMesh {
        positions,
        triangles,
    }
}

/// Every triangle split into four at its edge midpoints: the original vertices, one vertex per
/// edge, and for each triangle the indices of its edges' vertices (`ab`, `bc`, `ca`).
struct EdgeSplit {
    /// Endpoints of each edge; edge `e` becomes vertex `original vertex count + e`.
    edges: Vec<(u32, u32)>,
    /// Per triangle, its edges `ab`, `bc`, `ca` as indices into `edges`.
    triangle_edges: Vec<[u32; 3]>,
}

impl EdgeSplit {
    fn new(mesh: &TriMesh) -> Self {
        let mut index = std::collections::HashMap::new();
        let mut edges = Vec::new();
        let mut edge = |a: u32, b: u32| -> u32 {
            *index.entry((a.min(b), a.max(b))).or_insert_with(|| {
                edges.push((a.min(b), a.max(b)));
                edges.len() as u32 - 1
            })
        };
        let triangle_edges = mesh
            .triangles
            .iter()
            .map(|&[a, b, c]| [edge(a, b), edge(b, c), edge(c, a)])
            .collect();
        Self {
            edges,
            triangle_edges,
        }
    }

    /// The four triangles of each triangle of `mesh` (the mesh this split was made from).
    fn triangles(&self, mesh: &TriMesh) -> Vec<[u32; 3]> {
        let base = mesh.positions.len() as u32;
        let mut triangles = Vec::with_capacity(mesh.triangles.len() * 4);
        for (&[a, b, c], &[ab, bc, ca]) in mesh.triangles.iter().zip(&self.triangle_edges) {
            let (ab, bc, ca) = (base + ab, base + bc, base + ca);
            triangles.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles
    }
}

/// Midpoint subdivision (each triangle → 4, no smoothing): ~4× the vertices, and every new
/// vertex lies in the plane of an input triangle (so most one-rings are flat).
pub fn subdivide_midpoint(mesh: &TriMesh) -> TriMesh {
    let split = EdgeSplit::new(mesh);
    let mut positions = mesh.positions.clone();
    positions.extend(
        split
            .edges
            .iter()
            .map(|&(a, b)| (mesh.positions[a as usize] + mesh.positions[b as usize]) * 0.5),
    );
    TriMesh {
        triangles: split.triangles(mesh),
        positions,
    }
}

/// Loop subdivision (Loop 1987; Warren's vertex weights are not used, Loop's own β is): each
/// triangle → 4 like [`subdivide_midpoint`], but the surface is smoothed — an interior edge's
/// vertex is 3/8 of each endpoint plus 1/8 of each opposite vertex, and an original vertex of
/// valence n moves to (1 − nβ)·v + β·Σ neighbours with β = (5/8 − (3/8 + cos(2π/n)/4)²)/n.
/// Vertices on boundary or non-manifold edges keep their position and such edges get their
/// midpoint (the surface is held there rather than given boundary rules). The refined mesh
/// of a real model, without the flat patches midpoint subdivision leaves.
pub fn subdivide_loop(mesh: &TriMesh) -> TriMesh {
    let split = EdgeSplit::new(mesh);
    let n = mesh.positions.len();
    // Per edge: the sum of its opposite vertices and how many triangles share it.
    let mut opposite = vec![(DVec3::ZERO, 0u32); split.edges.len()];
    for (&[a, b, c], edges) in mesh.triangles.iter().zip(&split.triangle_edges) {
        for (e, o) in edges.iter().zip([c, a, b]) {
            let slot = &mut opposite[*e as usize];
            slot.0 += mesh.positions[o as usize];
            slot.1 += 1;
        }
    }
    let mut neighbour_sum = vec![DVec3::ZERO; n];
    let mut valence = vec![0u32; n];
    let mut held = vec![false; n];
    for (&(a, b), &(_, sharing)) in split.edges.iter().zip(&opposite) {
        let (a, b) = (a as usize, b as usize);
        neighbour_sum[a] += mesh.positions[b];
        neighbour_sum[b] += mesh.positions[a];
        valence[a] += 1;
        valence[b] += 1;
        if sharing != 2 {
            held[a] = true;
            held[b] = true;
        }
    }
    let mut positions: Vec<DVec3> = (0..n)
        .map(|v| {
            let p = mesh.positions[v];
            if held[v] || valence[v] == 0 {
                return p;
            }
            let k = valence[v] as f64;
            let c = 0.375 + 0.25 * (std::f64::consts::TAU / k).cos();
            let beta = (0.625 - c * c) / k;
            p * (1.0 - k * beta) + neighbour_sum[v] * beta
        })
        .collect();
    positions.extend(
        split
            .edges
            .iter()
            .zip(&opposite)
            .map(|(&(a, b), &(sum, sharing))| {
                let ends = mesh.positions[a as usize] + mesh.positions[b as usize];
                if sharing == 2 {
                    ends * 0.375 + sum * 0.125
                } else {
                    ends * 0.5
                }
            }),
    );
    TriMesh {
        triangles: split.triangles(mesh),
        positions,
    }
}

/// Splits vertices into a fixed "bottom" slab and a handle "top" slab along `axis`:
/// vertices whose coordinate is within the lowest `fixed_fraction` of the bounding box are
/// fixed, those within the highest `handle_fraction` are the handle. Used by benchmarks and
/// the sandbox to build reproducible problems on any mesh.
pub fn slab_regions(
    positions: &[DVec3],
    axis: usize,
    fixed_fraction: f64,
    handle_fraction: f64,
) -> (Vec<u32>, Vec<u32>) {
    let axis = axis.min(2);
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for p in positions {
        lo = lo.min(p[axis]);
        hi = hi.max(p[axis]);
    }
    let span = (hi - lo).max(f64::MIN_POSITIVE);
    let mut fixed = Vec::new();
    let mut handle = Vec::new();
    for (i, p) in positions.iter().enumerate() {
        let t = (p[axis] - lo) / span;
        if t <= fixed_fraction {
            fixed.push(i as u32);
        } else if t >= 1.0 - handle_fraction {
            handle.push(i as u32);
        }
    }
    (fixed, handle)
}

/// The benchmark problem used throughout the crate's benchmarks and tests: the lowest 10 % of
/// the mesh along Y is fixed, the highest 10 % is a handle turned by `angle` radians about Z
/// around its centroid and moved by `shift`.
pub fn bend_problem(positions: &[DVec3], angle: f64, shift: DVec3) -> Constraints {
    let (fixed, handle) = slab_regions(positions, 1, 0.1, 0.1);
    let pivot = super::centroid(positions, &handle);
    Constraints::with_handle(
        fixed,
        handle,
        RigidTransform::new(DQuat::from_rotation_z(angle), shift, pivot),
    )
}

/// Extracts the zero level set of `f` (negative inside) inside the box `[lo, hi]` sampled on a
/// grid of `cells` cells along its longest side, by marching tetrahedra. The result is a
/// closed, welded, consistently oriented (outward) triangle mesh; used to generate the
/// sandbox models.
pub fn implicit_surface(f: &dyn Fn(DVec3) -> f64, lo: DVec3, hi: DVec3, cells: u32) -> TriMesh {
    let size = hi - lo;
    let h = size.max_element() / cells.max(2) as f64;
    let n = [
        (size.x / h).ceil() as usize + 1,
        (size.y / h).ceil() as usize + 1,
        (size.z / h).ceil() as usize + 1,
    ];
    let id = |i: usize, j: usize, k: usize| (k * n[1] + j) * n[0] + i;
    let point = |i: usize, j: usize, k: usize| lo + DVec3::new(i as f64, j as f64, k as f64) * h;
    let mut values = vec![0.0; n[0] * n[1] * n[2]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                values[id(i, j, k)] = f(point(i, j, k));
            }
        }
    }
    let pos_of = |g: usize| {
        let i = g % n[0];
        let j = (g / n[0]) % n[1];
        let k = g / (n[0] * n[1]);
        point(i, j, k)
    };
    let mut edge_vertex = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut vertex_on = |a: usize, b: usize, positions: &mut Vec<DVec3>| -> u32 {
        let key = (a.min(b), a.max(b));
        *edge_vertex.entry(key).or_insert_with(|| {
            let (va, vb) = (values[a], values[b]);
            let t = if (va - vb).abs() > 1e-300 {
                va / (va - vb)
            } else {
                0.5
            };
            positions.push(pos_of(a).lerp(pos_of(b), t.clamp(0.0, 1.0)));
            (positions.len() - 1) as u32
        })
    };
    // Cube corners (x, y, z bits) and the 6 tetrahedra around the 0–7 diagonal.
    const TETS: [[usize; 4]; 6] = [
        [0, 1, 3, 7],
        [0, 3, 2, 7],
        [0, 2, 6, 7],
        [0, 6, 4, 7],
        [0, 4, 5, 7],
        [0, 5, 1, 7],
    ];
    for k in 0..n[2] - 1 {
        for j in 0..n[1] - 1 {
            for i in 0..n[0] - 1 {
                let corner = |c: usize| id(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                for tet in TETS {
                    let g = tet.map(corner);
                    let inside: Vec<usize> = (0..4).filter(|&v| values[g[v]] < 0.0).collect();
                    let outside: Vec<usize> = (0..4).filter(|&v| values[g[v]] >= 0.0).collect();
                    match inside.len() {
                        1 | 3 => {
                            let (apex, others) = if inside.len() == 1 {
                                (inside[0], outside)
                            } else {
                                (outside[0], inside)
                            };
                            let t = others
                                .iter()
                                .map(|&o| vertex_on(g[apex], g[o], &mut positions));
                            let t: Vec<u32> = t.collect();
                            triangles.push([t[0], t[1], t[2]]);
                        }
                        2 => {
                            let (a, b) = (inside[0], inside[1]);
                            let (c, d) = (outside[0], outside[1]);
                            let ac = vertex_on(g[a], g[c], &mut positions);
                            let ad = vertex_on(g[a], g[d], &mut positions);
                            let bc = vertex_on(g[b], g[c], &mut positions);
                            let bd = vertex_on(g[b], g[d], &mut positions);
                            triangles.push([ac, ad, bd]);
                            triangles.push([ac, bd, bc]);
                        }
                        _ => {}
                    }
                }
            }
        }
    }
    orient_outward(f, &positions, &mut triangles, h * 0.1);
    // Drop slivers whose corners collapsed onto one grid point.
    triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    TriMesh {
        positions,
        triangles,
    }
}

/// Turns every triangle outward, along the gradient of `f` (central differences of step
/// `eps`) at its centre.
fn orient_outward(
    f: &dyn Fn(DVec3) -> f64,
    positions: &[DVec3],
    triangles: &mut [[u32; 3]],
    eps: f64,
) {
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let centre = (a + b + c) / 3.0;
        let grad = DVec3::new(
            f(centre + DVec3::X * eps) - f(centre - DVec3::X * eps),
            f(centre + DVec3::Y * eps) - f(centre - DVec3::Y * eps),
            f(centre + DVec3::Z * eps) - f(centre - DVec3::Z * eps),
        );
        if (b - a).cross(c - a).dot(grad) < 0.0 {
            t.swap(1, 2);
        }
    }
}

/// The sandbox's humanoid "mannequin": a smooth union of capsules and spheres, 1.8 units tall
/// (feet at y ≈ 0, arms hanging forward), meshed with [`implicit_surface`] on `cells` cells
/// along its width (100 cells ≈ 25k vertices; vertex count grows with `cells²`). The
/// skeleton of `pose::rig::synth_rig::mannequin_rig` follows the same capsules.
pub fn mannequin(cells: u32) -> TriMesh {
    let f = |p: DVec3| {
        let parts: Vec<f64> = MANNEQUIN_PARTS
            .iter()
            .flat_map(|&(a, b, r)| {
                let mirrored = (DVec3::new(-a.x, a.y, a.z), DVec3::new(-b.x, b.y, b.z));
                let one = capsule(p, a, b, r);
                let off_centre = a.x >= 0.0 && b.x >= 0.0 && (a.x > 0.0 || b.x > 0.0);
                let other = off_centre.then(|| capsule(p, mirrored.0, mirrored.1, r));
                std::iter::once(one).chain(other)
            })
            .collect();
        parts
            .into_iter()
            .reduce(|a, b| smooth_min(a, b, 0.035))
            .unwrap_or(f64::MAX)
    };
    implicit_surface(
        &f,
        DVec3::new(-0.75, -0.05, -0.22),
        DVec3::new(0.75, 1.82, 0.25),
        cells,
    )
}

/// The mannequin's capsules `(a, b, radius)`; parts off the centre line are mirrored in x.
const MANNEQUIN_PARTS: [(DVec3, DVec3, f64); 11] = [
    (DVec3::new(0.0, 1.66, 0.0), DVec3::new(0.0, 1.66, 0.0), 0.12),
    (DVec3::new(0.0, 1.45, 0.0), DVec3::new(0.0, 1.56, 0.0), 0.06),
    (DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, 1.36, 0.0), 0.16),
    (
        DVec3::new(-0.09, 0.92, 0.0),
        DVec3::new(0.09, 0.92, 0.0),
        0.13,
    ),
    (DVec3::new(0.0, 1.4, 0.0), DVec3::new(0.2, 1.4, 0.0), 0.07),
    (
        DVec3::new(0.22, 1.4, 0.0),
        DVec3::new(0.42, 1.14, 0.0),
        0.055,
    ),
    (
        DVec3::new(0.42, 1.14, 0.0),
        DVec3::new(0.56, 0.9, 0.05),
        0.045,
    ),
    (
        DVec3::new(0.58, 0.86, 0.06),
        DVec3::new(0.58, 0.86, 0.06),
        0.055,
    ),
    (
        DVec3::new(0.1, 0.85, 0.0),
        DVec3::new(0.12, 0.48, 0.0),
        0.075,
    ),
    (
        DVec3::new(0.12, 0.48, 0.0),
        DVec3::new(0.13, 0.1, 0.0),
        0.06,
    ),
    (
        DVec3::new(0.13, 0.05, 0.0),
        DVec3::new(0.13, 0.05, 0.13),
        0.05,
    ),
];

/// Signed distance to a capsule from `a` to `b` with radius `r`.
pub fn capsule(p: DVec3, a: DVec3, b: DVec3, r: f64) -> f64 {
    (p - closest_on_segment(p, a, b)).length() - r
}

/// The point of the segment `a`–`b` nearest `p` (`a` when the segment is a point).
pub fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + ab * t
}

/// Polynomial smooth minimum (blend radius `k`), for smooth unions of distance fields.
pub fn smooth_min(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bar_counts() {
        let m = bar(100, 200, 0.1, 1.0);
        assert_eq!(m.positions.len(), 20_002);
        assert_eq!(m.triangles.len(), 2 * 100 * 199 + 200);
    }

    /// The Euler characteristic of `m` once welded (2: one closed surface) and its signed
    /// volume (positive: triangles wind outward).
    fn euler_and_volume(m: &TriMesh) -> (i64, f64, usize) {
        let t = crate::deform::Topology::new(&m.positions, &m.triangles).unwrap();
        let edges = t.neighbor_list().len() / 2;
        let chi = t.vertex_count() as i64 - edges as i64 + t.triangles().len() as i64;
        let vol: f64 = t
            .triangles()
            .iter()
            .map(|tr| {
                let [a, b, c] = tr.map(|i| t.positions()[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        (chi, vol, t.vertex_count())
    }

    #[test]
    fn implicit_sphere_is_closed_and_outward() {
        let m = implicit_surface(
            &|p: DVec3| p.length() - 1.0,
            DVec3::splat(-1.3),
            DVec3::splat(1.3),
            20,
        );
        // Closed: every edge has exactly two triangles (Euler characteristic 2); outward:
        // positive signed volume ≈ 4/3 π.
        let (chi, vol, _) = euler_and_volume(&m);
        assert_eq!(chi, 2);
        assert!((vol - 4.18879).abs() < 0.15, "{vol}");
    }

    #[test]
    fn a_plank_welds_closed_and_winds_outward() {
        let m = plank(2.0, 0.6, 0.1, 20.0);
        let (chi, vol, welded) = euler_and_volume(&m);
        assert_eq!(chi, 2, "the six faces weld into one closed surface");
        assert!(welded < m.positions.len());
        assert!((vol - 2.0 * 0.6 * 0.1).abs() < 1e-12, "{vol}");
    }

    #[test]
    fn icosphere_counts() {
        assert_eq!(icosphere(2, 1.0).positions.len(), 162);
        assert_eq!(subdivide_midpoint(&icosphere(1, 1.0)).positions.len(), 162);
        assert_eq!(subdivide_loop(&icosphere(1, 1.0)).positions.len(), 162);
    }

    #[test]
    fn loop_subdivision_uses_loops_weights() {
        // Octahedron: valence 4 everywhere, β = (5/8 − (3/8)²)/4 = 31/256, and each vertex's
        // neighbours sum to zero; an edge's two opposite vertices also sum to zero.
        let octa = octahedron(DVec3::ZERO, 1.0);
        let fine = subdivide_loop(&octa);
        assert_eq!(fine.triangles.len(), 32);
        assert_eq!(fine.positions.len(), 6 + 12);
        for (old, new) in octa.positions.iter().zip(&fine.positions) {
            assert!(
                (*new - *old * (1.0 - 4.0 * 31.0 / 256.0)).length() < 1e-15,
                "{new}"
            );
        }
        // Every edge vertex: 3/8 of each endpoint (the opposites cancel): length 3/8 · √2.
        for p in &fine.positions[6..] {
            assert!((p.length() - 0.375 * 2f64.sqrt()).abs() < 1e-15, "{p}");
        }
        // Same connectivity as midpoint subdivision.
        assert_eq!(fine.triangles, subdivide_midpoint(&octa).triangles);
        // On an open mesh the boundary is held: one triangle only gets its midpoints.
        let tri = TriMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            triangles: vec![[0, 1, 2]],
        };
        assert_eq!(
            subdivide_loop(&tri).positions,
            subdivide_midpoint(&tri).positions
        );
    }

    #[test]
    fn loop_subdivision_smooths_an_icosphere_towards_a_sphere() {
        // Midpoint vertices sit inside the sphere on flat faces; Loop's spread less in radius.
        let ico = icosphere(1, 1.0);
        let spread = |m: &TriMesh| {
            let r: Vec<f64> = m.positions.iter().map(|p| p.length()).collect();
            r.iter().cloned().fold(f64::MIN, f64::max) - r.iter().cloned().fold(f64::MAX, f64::min)
        };
        let (mid, smooth) = (
            spread(&subdivide_midpoint(&ico)),
            spread(&subdivide_loop(&ico)),
        );
        assert!(
            smooth < 0.5 * mid,
            "Loop radius spread {smooth}, midpoint {mid}"
        );
    }
}
