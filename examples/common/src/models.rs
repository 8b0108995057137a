//! The sandbox's built-in models, generated from signed distance functions by our own
//! marching-tetrahedra code (`deform::synth::implicit_surface`). `make_assets` writes them to
//! `assets/models/*.obj`; the sandbox regenerates any that are missing.

use bevy_wii_deform::deform::{TriMesh, synth};
use glam::DVec3;

/// Built-in model names.
pub const MODELS: [&str; 3] = ["bar", "cactus", "mannequin"];

/// Generates a built-in model by name.
pub fn generate(name: &str) -> Option<TriMesh> {
    Some(match name {
        "bar" => synth::bar(40, 100, 0.1, 1.2),
        "cactus" => cactus(),
        "mannequin" => synth::mannequin(100),
        _ => return None,
    })
}

fn union(parts: &[f64], k: f64) -> f64 {
    parts
        .iter()
        .copied()
        .reduce(|a, b| synth::smooth_min(a, b, k))
        .unwrap_or(f64::MAX)
}

/// The cactus (`assets/models/cactus.obj` is this mesh written out): a ribbed trunk with two
/// arms in a pot, welded from one signed distance function.
pub fn cactus() -> TriMesh {
    let v = DVec3::new;
    let f = |p: DVec3| {
        let theta = p.z.atan2(p.x);
        let ribs = 0.012 * (theta * 10.0).cos();
        let trunk = synth::capsule(p, v(0.0, 0.0, 0.0), v(0.0, 1.55, 0.0), 0.16) + ribs;
        let left = union(
            &[
                synth::capsule(p, v(0.0, 0.65, 0.0), v(-0.34, 0.7, 0.0), 0.09),
                synth::capsule(p, v(-0.34, 0.7, 0.0), v(-0.36, 1.15, 0.0), 0.09) + ribs * 0.6,
            ],
            0.05,
        );
        let right = union(
            &[
                synth::capsule(p, v(0.0, 0.95, 0.0), v(0.3, 0.98, 0.0), 0.08),
                synth::capsule(p, v(0.3, 0.98, 0.0), v(0.31, 1.32, 0.0), 0.08) + ribs * 0.6,
            ],
            0.05,
        );
        let pot = synth::capsule(p, v(0.0, -0.05, 0.0), v(0.0, 0.05, 0.0), 0.22);
        union(&[trunk, left, right, pot], 0.06)
    };
    synth::implicit_surface(&f, v(-0.6, -0.35, -0.35), v(0.5, 1.8, 0.35), 100)
}
