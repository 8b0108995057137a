//! Where the time of an ARAP iteration goes, and how fast the energy falls, printed as JSON
//! (one object per mesh, one per line). The problems are the criterion benchmark's
//! (`benches/arap.rs`): bottom 10 % fixed, top 10 % turned 0.6 rad about Z and moved by 15 % of
//! the bounding diagonal.
//!
//! ```text
//! cargo run --release --example arap_profile -- [--repeats N] [--mesh FILE.off|obj]...
//!     [--factorization auto|simplicial|supernodal] [--ordering halves|amd]
//!     [--anderson DEPTH]
//! ```
//!
//! Without `--mesh` it profiles the benchmark set: armadillo (26k) and armadillo subdivided
//! once (104k) from `../shared/meshes` when present, and the 20k and 100k synthetic bars.
//! Phase times are medians over the repeats of warm-started 10-iteration solves, per iteration.
//! Energies are exact ([`arap_energy`]) after 1, 3 and 10 iterations from the Laplacian start,
//! and after 300 (as "converged").

use bevy_wii_deform_examples::cli;

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use bevy_wii_deform::deform::*;
use glam::DVec3;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn default_meshes() -> Vec<(String, TriMesh)> {
    let mut out = Vec::new();
    if let Ok(arm) = TriMesh::read(Path::new("../shared/meshes/armadillo.off")) {
        out.push(("armadillo_x4_104k".into(), synth::subdivide_midpoint(&arm)));
        out.push(("armadillo_26k".into(), arm));
    } else {
        eprintln!("../shared/meshes/armadillo.off absent: profiling synthetic meshes only");
    }
    out.push(("bar_20k".into(), synth::bar(100, 200, 0.1, 1.0)));
    out.push(("bar_100k".into(), synth::bar(170, 588, 0.1, 1.0)));
    out
}

fn profile(
    name: &str,
    mesh: &TriMesh,
    repeats: usize,
    settings: &SolverSettings,
    anderson_depth: usize,
) -> Result<serde_json::Value, String> {
    let topology =
        Arc::new(Topology::new(&mesh.positions, &mesh.triangles).map_err(|e| e.to_string())?);
    let shift = 0.15 * topology.bounding_diagonal();
    let constraints = synth::bend_problem(topology.positions(), 0.6, DVec3::new(shift, 0.0, 0.0));
    let (mut precompute, mut topology_ms) = (Vec::new(), Vec::new());
    let mut solver = None;
    for _ in 0..repeats {
        let t0 = Instant::now();
        let t =
            Arc::new(Topology::new(&mesh.positions, &mesh.triangles).map_err(|e| e.to_string())?);
        topology_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        let s =
            ArapSolver::precompute(t, &constraints, settings.clone()).map_err(|e| e.to_string())?;
        precompute.push(t0.elapsed().as_secs_f64() * 1e3);
        solver = Some(s);
    }
    let solver = solver.ok_or("no repeats")?;
    let never = || false;
    let fixed = |iterations| SolveOptions {
        max_iterations: iterations,
        tolerance: 0.0,
        acceleration: Acceleration::anderson(anderson_depth),
    };
    let energy_after = |iterations| -> Result<f64, String> {
        let s = solver
            .solve(
                &constraints,
                &fixed(iterations),
                InitialGuess::Laplacian,
                &never,
            )
            .map_err(|e| e.to_string())?;
        Ok(arap_energy(&topology, &s.positions))
    };
    let warm = solver
        .solve(&constraints, &fixed(3), InitialGuess::Laplacian, &never)
        .map_err(|e| e.to_string())?;
    let (mut local, mut rhs, mut global, mut total) = (vec![], vec![], vec![], vec![]);
    let (mut extrapolation, mut rejected) = (vec![], 0);
    for _ in 0..repeats {
        let t0 = Instant::now();
        let s = solver
            .solve(&constraints, &fixed(10), InitialGuess::Warm(&warm), &never)
            .map_err(|e| e.to_string())?;
        total.push(t0.elapsed().as_secs_f64() * 1e3 / 10.0);
        local.push(s.stats.local_s * 1e3 / 10.0);
        rhs.push(s.stats.rhs_s * 1e3 / 10.0);
        global.push(s.stats.global_s * 1e3 / 10.0);
        extrapolation.push(s.stats.acceleration_s * 1e3 / 10.0);
        rejected += s.stats.rejected_extrapolations;
    }
    let stats = solver.precompute_stats();
    Ok(serde_json::json!({
        "mesh": name,
        "vertices": topology.vertex_count(),
        "free": stats.free_vertices,
        "supernodal": stats.supernodal,
        "parallel_solves": stats.parallel_solves,
        "topology_ms": median(topology_ms),
        "assembly_ms": stats.assembly_s * 1e3,
        "symbolic_ms": stats.symbolic_s * 1e3,
        "numeric_ms": stats.numeric_s * 1e3,
        "factor_nonzeros": stats.factor_nonzeros,
        "anderson_depth": anderson_depth,
        "rejected_extrapolations_per_solve": rejected as f64 / repeats as f64,
        "precompute_ms": median(precompute),
        "iteration_ms": {
            "total": median(total),
            "local": median(local),
            "rhs": median(rhs),
            "global": median(global),
            "extrapolation": median(extrapolation),
        },
        "energy": {
            "k1": energy_after(1)?,
            "k3": energy_after(3)?,
            "k10": energy_after(10)?,
            "k300": energy_after(300)?,
        },
    }))
}

const USAGE: &str = "\
usage: arap_profile [--mesh PATH]... [--repeats N] [--anderson DEPTH] [--ordering amd|halves]
                    [--factorization auto|simplicial|supernodal]";

fn main() -> std::process::ExitCode {
    let mut repeats = 7;
    let mut meshes = Vec::new();
    let mut settings = SolverSettings::default();
    let mut depth = 0;
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("repeats") => repeats = cli::value(&mut parser, USAGE),
            cli::Arg::Long("anderson") => depth = cli::value(&mut parser, USAGE),
            cli::Arg::Long("ordering") => {
                settings.ordering = match cli::string(&mut parser, USAGE).as_str() {
                    "amd" => FillOrdering::MinimumDegree,
                    "halves" => FillOrdering::Halves,
                    v => cli::fail(
                        format!("--ordering must be amd or halves, got {v:?}"),
                        USAGE,
                    ),
                }
            }
            cli::Arg::Long("factorization") => {
                settings.factorization = match cli::string(&mut parser, USAGE).as_str() {
                    "simplicial" => Factorization::Simplicial,
                    "supernodal" => Factorization::Supernodal,
                    "auto" => Factorization::Auto,
                    v => cli::fail(
                        format!(
                            "--factorization must be auto, simplicial or supernodal, got {v:?}"
                        ),
                        USAGE,
                    ),
                }
            }
            cli::Arg::Long("mesh") => {
                let path = cli::string(&mut parser, USAGE);
                match TriMesh::read(Path::new(&path)) {
                    Ok(m) => meshes.push((path, m)),
                    Err(e) => {
                        eprintln!("arap_profile: {path}: {e}");
                        return std::process::ExitCode::FAILURE;
                    }
                }
            }
            other => cli::unexpected(other, USAGE),
        }
    }
    if meshes.is_empty() {
        meshes = default_meshes();
    }
    for (name, mesh) in &meshes {
        match profile(name, mesh, repeats.max(1), &settings, depth) {
            Ok(v) => println!("{v}"),
            Err(e) => {
                eprintln!("arap_profile: {name}: {e}");
                return std::process::ExitCode::FAILURE;
            }
        }
    }
    std::process::ExitCode::SUCCESS
}
