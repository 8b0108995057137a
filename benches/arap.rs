//! ARAP core benchmarks: precompute, 1 and 10 plain iterations and 10 accelerated ones
//! (warm-started) on the peer-comparison meshes and on game-asset sizes (cactus 620, dino
//! 3.9k, bars of 500, 2k and 5k vertices). Run with `cargo bench --bench arap`; one mesh with
//! e.g. `cargo bench --bench arap -- dino_4k`.

use std::path::Path;
use std::sync::Arc;

use bevy_wii_deform::deform::*;
use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;

/// History depth of the accelerated benchmark.
const ANDERSON_DEPTH: usize = 3;

fn problem(mesh: &TriMesh) -> (Arc<Topology>, Constraints) {
    let topology = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap());
    let shift = 0.15 * topology.bounding_diagonal();
    let c = synth::bend_problem(topology.positions(), 0.6, DVec3::new(shift, 0.0, 0.0));
    (topology, c)
}

fn meshes() -> Vec<(String, TriMesh)> {
    let mut out = Vec::new();
    let dir = Path::new("../shared/meshes");
    // Game-asset sizes first: a regression there is what most users feel.
    for (name, file) in [("cactus_620", "cactus.off"), ("dino_4k", "dino.off")] {
        match TriMesh::read(dir.join(file)) {
            Ok(mesh) => out.push((name.into(), mesh)),
            Err(_) => eprintln!("../shared/meshes/{file} absent: skipped"),
        }
    }
    for (name, vertices) in [("bar_500", 500), ("bar_2k", 2_000), ("bar_5k", 5_000)] {
        out.push((name.into(), synth::bar_with_vertices(vertices)));
    }
    if let Ok(arm) = TriMesh::read(dir.join("armadillo.off")) {
        out.push(("armadillo_26k".into(), arm.clone()));
        out.push(("armadillo_x4_104k".into(), synth::subdivide_midpoint(&arm)));
    } else {
        eprintln!("../shared/meshes/armadillo.off absent: benchmarking synthetic meshes only");
    }
    out.push(("bar_20k".into(), synth::bar(100, 200, 0.1, 1.0)));
    out.push(("bar_100k".into(), synth::bar(170, 588, 0.1, 1.0)));
    out
}

fn bench(c: &mut Criterion) {
    let never = || false;
    for (name, mesh) in meshes() {
        let (topology, constraints) = problem(&mesh);
        let mut g = c.benchmark_group(&name);
        g.sample_size(10);
        g.bench_function("precompute", |b| {
            b.iter(|| {
                let t = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap());
                ArapSolver::precompute(t, &constraints, SolverSettings::default()).unwrap()
            })
        });
        let solver =
            ArapSolver::precompute(topology.clone(), &constraints, SolverSettings::default())
                .unwrap();
        let warm = solver
            .solve(
                &constraints,
                &SolveOptions {
                    max_iterations: 3,
                    tolerance: 0.0,
                    ..Default::default()
                },
                InitialGuess::Laplacian,
                &never,
            )
            .unwrap();
        // Plain local/global iterations (the per-iteration cost the peers are compared on)
        // and Anderson-accelerated ones (depth 3, the value the docs recommend; the default
        // is plain).
        for (label, iters, anderson_depth) in [
            ("iterations_1", 1u32, 0usize),
            ("iterations_10", 10, 0),
            ("iterations_10_anderson", 10, ANDERSON_DEPTH),
        ] {
            g.bench_function(label, |b| {
                b.iter(|| {
                    solver
                        .solve(
                            &constraints,
                            &SolveOptions {
                                max_iterations: iters,
                                tolerance: 0.0,
                                acceleration: Acceleration::anderson(anderson_depth),
                            },
                            InitialGuess::Warm(&warm),
                            &never,
                        )
                        .unwrap()
                })
            });
        }
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
