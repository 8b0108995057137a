//! A terrain mesh for characters to stand on: rolling hills no steeper than a given slope, cut
//! by terraces (steps) no higher than a given height, as one triangle grid. The apps mark it
//! `GroundMesh`; the characters find its height by casting down on it, never from this code.

use glam::{DVec2, DVec3};

/// What the terrain is made of.
pub struct TerrainSpec {
    /// Corner of the field (x, z) and its size along x and z.
    pub origin: DVec2,
    /// Size along x and z.
    pub size: DVec2,
    /// Grid cells along the longer side.
    pub cells: usize,
    /// Steepest slope of the hills, degrees.
    pub max_slope_deg: f64,
    /// Height of a terrace step.
    pub step: f64,
    /// Distance between terrace edges (along x).
    pub terrace: f64,
}

/// The terrain's positions and triangles (counter-clockwise seen from above).
pub fn terrain(spec: &TerrainSpec) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let long = spec.size.x.max(spec.size.y);
    let h = long / spec.cells.max(1) as f64;
    let (nx, nz) = (
        (spec.size.x / h).ceil() as usize + 1,
        (spec.size.y / h).ceil() as usize + 1,
    );
    // Hills: two waves whose combined gradient stays under the slope limit.
    let wavelength = long / 3.0;
    let k = std::f64::consts::TAU / wavelength;
    let amplitude = spec.max_slope_deg.to_radians().tan() * 0.9 / (2.0 * k);
    // A terrace edge is a steep ramp one cell wide (the mesh's own resolution).
    let terrace = |x: f64| {
        let t = (x - spec.origin.x) / spec.terrace;
        let (whole, part) = (t.floor(), t.fract());
        let ramp = ((part - (1.0 - h / spec.terrace)) / (h / spec.terrace)).clamp(0.0, 1.0);
        (whole + ramp) * spec.step
    };
    let height = |x: f64, z: f64| amplitude * ((k * x).sin() + (k * z * 0.8).cos()) + terrace(x);
    let mut positions = Vec::with_capacity(nx * nz);
    for j in 0..nz {
        for i in 0..nx {
            let x = spec.origin.x + i as f64 * h;
            let z = spec.origin.y + j as f64 * h;
            positions.push(DVec3::new(x, height(x, z), z));
        }
    }
    let mut triangles = Vec::with_capacity((nx - 1) * (nz - 1) * 2);
    let at = |i: usize, j: usize| (j * nx + i) as u32;
    for j in 0..nz - 1 {
        for i in 0..nx - 1 {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
        }
    }
    (positions, triangles)
}
