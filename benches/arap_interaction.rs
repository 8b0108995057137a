//! Interaction benchmark of the deformation core: how long a new constraint set takes to its
//! first pose, and how many iterations a pose needs to settle after a drag is released.
//!
//! ```text
//! cargo run --release --example arap_interaction -- --json
//! ```
//! Meshes: a 5k-vertex bar, the armadillo (26k) and the armadillo midpoint-subdivided (104k),
//! from `../shared/meshes` when present.
//! * `set_change_first_pose_ms`: the topology is built; the handle set changes (bottom → side
//!   slab held, top → other side moved), then what `DeformPlugin` shows first: on a mesh of
//!   more than 16 384 vertices a *preview* ([`PreviewRegion::default`]: only the vertices
//!   within 0.25 × the diagonal of the new handle along the surface, at most 8 192 of them,
//!   move; the rest is held where it is) with its precompute and one iteration from the
//!   current pose; on smaller meshes the whole mesh's. `preview_vertices`: how many vertices
//!   that first pose moves. Median of 9.
//! * `set_change_whole_mesh_first_pose_ms`: the same for the whole mesh (what the plugin
//!   shows once the whole system is factored, after the preview).
//! * `settle_iterations`: a handle is dragged for 60 frames (bend to 0.6 rad and 15 % of the
//!   diagonal, 2 warm iterations per frame), then released (held at its last target). Counted
//!   are the further iterations until the energy is within 1 % of the converged value and no
//!   vertex is farther than 5e-4 × the diagonal from the converged pose. Converged = the
//!   minimum *this method's* released pose settles into: the lower energy of 3000 L-BFGS
//!   iterations and of Newton run to stationarity, both from that release (on the 104k meshes
//!   different drags end near different local minima, within 0.2 % in energy and a few % of
//!   the diagonal apart; `settle_converged_energy` gives each one's energy so a method that
//!   falls into a worse minimum shows). Methods (drag / settle): `plain`,
//!   `anderson` (depth 3), `lbfgs` (depth 8, curvature pairs carried from frame to frame),
//!   `newton` (truncated Newton, ≤ 30 CG steps), and `best` = L-BFGS while dragging, Newton to
//!   settle: what `DeformPlugin` does. 4096 means "not settled within 2048 iterations".
//!   `settle_back_substitutions` and `settle_ms` give the work of those iterations (one
//!   back-substitution per plain, Anderson or L-BFGS iteration; up to 32 per Newton one).
//! * `rest_topology_ms` (`fresh`, `rebased`): a deformed pose becomes the rest pose of the
//!   next edit (a second grab): a fresh `Topology::from_render_mesh` of it, and
//!   `Topology::rebased` of the previous topology. Median of 9.
//! * `--only PREFIX` runs only the meshes whose name starts with it; `--methods a,b` settles
//!   only with the named methods (the others are reported as 0; at 104k each method takes
//!   minutes in the dev profile).
//!
//! `--set-change-only` skips the settling runs (reported as 0).
//!
//! A fourth mesh, `armadillo_loop_104k`, is the armadillo Loop-subdivided: the same
//! connectivity as the midpoint ×4 mesh but smooth, without the flat one-rings midpoint
//! subdivision leaves on every input triangle (to tell what the finer mesh costs from what
//! its flat patches cost).
//!
//! The last stdout line is `{"meshes": [{"name", "vertices", "set_change_first_pose_ms",
//! "set_change_whole_mesh_first_pose_ms", "preview_vertices", "rest_topology_ms", "settle_iterations": {"plain", "anderson",
//! "lbfgs", "newton", "best"}, "settle_back_substitutions": {…}, "settle_ms": {…},
//! "settle_converged_energy": {…}}]}`.

use bevy_wii_deform_examples::cli;

use std::sync::Arc;
use std::time::Instant;

use bevy_wii_deform::deform::*;
use glam::DVec3;

const NEVER: &dyn Fn() -> bool = &|| false;

fn options(iterations: u32, acceleration: Acceleration) -> SolveOptions {
    SolveOptions {
        max_iterations: iterations,
        tolerance: 0.0,
        acceleration,
    }
}

/// The L-BFGS of the runs (and of the plugin).
const LBFGS: Acceleration = Acceleration::Lbfgs { depth: 8 };
/// The truncated Newton of the runs (and of the plugin's settling).
const NEWTON: Acceleration = Acceleration::Newton { max_cg: 30 };

/// Precompute for a changed handle set + one warm iteration, median ms of 9 (and the number
/// of vertices the first pose moves). The mesh has been solved before with another set (bottom
/// and top slabs), as in an interaction. With `preview`, what `DeformPlugin` does on a set
/// change of a large mesh: only the vertices near the new handle
/// ([`PreviewRegion::default`]) are solved, the rest held where they are, while the whole
/// system is factored afterwards.
fn set_change_ms(topology: &Arc<Topology>, start: &Solution, preview: bool) -> (f64, usize) {
    let positions = topology.positions();
    let (bottom, top) = synth::slab_regions(positions, 1, 0.1, 0.1);
    let before = Constraints::with_handle(bottom, top, RigidTransform::IDENTITY);
    ArapSolver::precompute(topology.clone(), &before, SolverSettings::default())
        .expect("precompute");
    let (fixed, handle) = synth::slab_regions(positions, 0, 0.15, 0.15);
    let mut c = Constraints::with_handle(fixed, handle.clone(), RigidTransform::IDENTITY);
    c.handles[0].transform.translation = DVec3::Y * 0.05 * topology.bounding_diagonal();
    let mut moved = 0;
    let mut ms: Vec<f64> = (0..9)
        .map(|_| {
            let t0 = Instant::now();
            let solved = match preview {
                true => PreviewRegion::default()
                    .preview(topology, &c, &start.positions)
                    .map_or_else(|| c.clone(), |p| p.constraints().clone()),
                false => c.clone(),
            };
            moved = topology.vertex_count()
                - solved.fixed.len()
                - solved.targets.len()
                - solved
                    .handles
                    .iter()
                    .map(|h| h.vertices.len())
                    .sum::<usize>();
            let tg = t0.elapsed().as_secs_f64() * 1e3;
            let solver =
                ArapSolver::precompute(topology.clone(), &solved, SolverSettings::default())
                    .expect("precompute");
            let tp = t0.elapsed().as_secs_f64() * 1e3;
            let s = solver.solve(
                &solved,
                &options(1, Acceleration::None),
                InitialGuess::Warm(start),
                NEVER,
            );
            assert!(s.is_ok());
            if std::env::var_os("BENCH_DEBUG").is_some() {
                eprintln!(
                    "  region {tg:.1} pre {tp:.1} {:?}",
                    solver.precompute_stats()
                );
                eprintln!("  {:?}", s.as_ref().map(|s| &s.stats));
            }
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    (ms[4], moved)
}

/// Making a deformed pose the rest pose of the next edit (what a second grab does), median ms
/// of 9: a fresh [`Topology::from_render_mesh`] of the deformed render positions, and
/// [`Topology::rebased`] of the previous topology (same weld and adjacency, new weights).
fn rebake_ms(mesh: &TriMesh) -> (f64, f64) {
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let rest: Vec<glam::Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
    let previous = Topology::from_render_mesh(&rest, &indices).expect("mesh");
    // A smooth non-rigid pose.
    let posed: Vec<glam::Vec3> = rest
        .iter()
        .map(|p| *p + glam::Vec3::new(0.1 * p.y * p.y, 0.05 * p.z, -0.05 * p.x))
        .collect();
    let times = |f: &dyn Fn() -> Topology| {
        let mut ms: Vec<f64> = (0..9)
            .map(|_| {
                let t0 = Instant::now();
                std::hint::black_box(f());
                t0.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        ms.sort_by(f64::total_cmp);
        ms[4]
    };
    let fresh = times(&|| Topology::from_render_mesh(&posed, &indices).expect("mesh"));
    let rebased = times(&|| previous.rebased(&posed, &indices).expect("same mesh"));
    (fresh, rebased)
}

/// How one method settles after the release.
#[derive(Debug, Clone, Copy, Default)]
struct Settled {
    /// Iterations after release (4096 = not within 2048).
    iterations: u32,
    /// Back-substitutions of those iterations.
    back_substitutions: u32,
    /// Milliseconds of that solve.
    ms: f64,
    /// Energy of the minimum this method's release settles into.
    converged_energy: f64,
}

/// The drag of the settling benchmark on one mesh.
struct Drag {
    topology: Arc<Topology>,
    solver: ArapSolver,
    frames: Vec<Constraints>,
}

/// A released pose and the minimum it settles into.
struct Release {
    /// The pose at release.
    pose: Solution,
    /// The converged pose from there.
    converged: Solution,
    /// Its energy.
    e_star: f64,
}

impl Drag {
    /// A handle dragged for 60 frames (bend to 0.6 rad and 15 % of the diagonal).
    fn new(topology: &Arc<Topology>) -> Self {
        let diagonal = topology.bounding_diagonal();
        let frames: Vec<Constraints> = (0..=60)
            .map(|frame| {
                let f = frame as f64 / 60.0;
                synth::bend_problem(
                    topology.positions(),
                    0.6 * f,
                    DVec3::new(0.15 * diagonal * f, 0.0, 0.0),
                )
            })
            .collect();
        let solver =
            ArapSolver::precompute(topology.clone(), &frames[0], SolverSettings::default())
                .expect("precompute");
        Self {
            topology: topology.clone(),
            solver,
            frames,
        }
    }

    /// The pose at release after dragging with `acceleration`, and the minimum it settles
    /// into: the lower energy of 3000 L-BFGS iterations and of Newton (≤ 200 CG steps) run
    /// until an iteration lowers the energy by less than 1e-14 (at most 60), both from the
    /// released pose. The bend of a fine mesh has several local minima within 0.2 % of each
    /// other in energy and a few % of the diagonal apart (the 104k armadillo: three drags,
    /// three minima), so each drag is measured against the minimum of its own release.
    fn release(&self, acceleration: Acceleration) -> Release {
        let pose = self.released(acceleration);
        let last = self.frames.last().expect("frames");
        let newton = SolveOptions {
            tolerance: 1e-14,
            ..options(60, Acceleration::Newton { max_cg: 200 })
        };
        let converged = [options(3000, LBFGS), newton]
            .map(|o| {
                self.solver
                    .solve(last, &o, InitialGuess::Warm(&pose), NEVER)
                    .expect("solve")
            })
            .into_iter()
            .min_by(|a, b| {
                let energy = |s: &Solution| arap_energy(&self.topology, &s.positions);
                energy(a).total_cmp(&energy(b))
            })
            .expect("two solves");
        let e_star = arap_energy(&self.topology, &converged.positions);
        Release {
            pose,
            converged,
            e_star,
        }
    }

    /// The pose at release after dragging with `acceleration`, 2 warm iterations per frame.
    fn released(&self, acceleration: Acceleration) -> Solution {
        let mut pose = self
            .solver
            .solve(
                &self.frames[0],
                &options(2, Acceleration::None),
                InitialGuess::Laplacian,
                NEVER,
            )
            .expect("solve");
        for c in &self.frames[1..] {
            pose = self
                .solver
                .solve(
                    c,
                    &options(2, acceleration),
                    InitialGuess::Warm(&pose),
                    NEVER,
                )
                .expect("solve");
        }
        pose
    }

    /// Iterations of `settle` from `release` until within 1 % energy and 5e-4 × diagonal of
    /// the minimum it settles into.
    fn settle(&self, release: &Release, settle: Acceleration) -> Settled {
        let last = self.frames.last().expect("frames");
        let close = |x: &[DVec3]| {
            close(
                &self.topology,
                x,
                &release.converged.positions,
                release.e_star,
                self.topology.bounding_diagonal(),
            )
        };
        let run = |k: u32| {
            if k == 0 {
                let at_release = Settled {
                    converged_energy: release.e_star,
                    ..Default::default()
                };
                return (close(&release.pose.positions), at_release);
            }
            let s = self
                .solver
                .solve(
                    last,
                    &options(k, settle),
                    InitialGuess::Warm(&release.pose),
                    NEVER,
                )
                .expect("solve");
            let done = Settled {
                iterations: k,
                back_substitutions: s.stats.back_substitutions,
                ms: s.stats.total_s * 1e3,
                converged_energy: release.e_star,
            };
            (close(&s.positions), done)
        };
        // Exponential search, then bisection (the criterion tightens as iterations go on).
        let mut hi = 1;
        while !run(hi).0 {
            hi *= 2;
            if hi > 2048 {
                return Settled {
                    iterations: hi,
                    converged_energy: release.e_star,
                    ..Default::default()
                };
            }
        }
        let mut lo = hi / 2;
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if run(mid).0 { hi = mid } else { lo = mid }
        }
        let (at_lo, settled) = run(lo);
        if at_lo { settled } else { run(hi).1 }
    }
}

fn close(topology: &Topology, x: &[DVec3], star: &[DVec3], e_star: f64, diagonal: f64) -> bool {
    let e = arap_energy(topology, x);
    let worst = x
        .iter()
        .zip(star)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    e <= 1.01 * e_star && worst <= 5e-4 * diagonal
}

const USAGE: &str = "\
usage: arap_interaction [--json] [--set-change-only] [--only NAME] [--methods A,B,...]

  --json             print the JSON line
  --set-change-only  skip the (long) settling runs
  --only PREFIX      only the meshes whose name starts with it
  --methods A,B,...  the settling methods to run";

fn main() {
    let (mut json, mut settle) = (false, true);
    let (mut only, mut chosen) = (None::<String>, None::<String>);
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("json") => json = true,
            cli::Arg::Long("set-change-only") => settle = false,
            cli::Arg::Long("only") => only = Some(cli::string(&mut parser, USAGE)),
            cli::Arg::Long("methods") => chosen = Some(cli::string(&mut parser, USAGE)),
            other => cli::unexpected(other, USAGE),
        }
    }
    let settles = |method: &str| {
        chosen
            .as_ref()
            .is_none_or(|list| list.split(',').any(|m| m == method))
    };
    let mut meshes = vec![("bar_5k".to_string(), synth::bar_with_vertices(5_000))];
    match TriMesh::read("../shared/meshes/armadillo.off") {
        Ok(arm) => {
            meshes.push(("armadillo_26k".into(), arm.clone()));
            meshes.push(("armadillo_x4_104k".into(), synth::subdivide_midpoint(&arm)));
            meshes.push(("armadillo_loop_104k".into(), synth::subdivide_loop(&arm)));
        }
        Err(_) => eprintln!("SKIPPED armadillo: ../shared/meshes/armadillo.off not found"),
    }
    let mut rows = Vec::new();
    for (name, mesh) in meshes {
        if only.as_ref().is_some_and(|o| !name.starts_with(o.as_str())) {
            continue;
        }
        let topology = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).expect("mesh"));
        let rest = Solution::rest(&topology);
        let (whole_first_pose, _) = set_change_ms(&topology, &rest, false);
        let (first_pose, preview_vertices) = set_change_ms(&topology, &rest, true);
        let (fresh_ms, rebased_ms) = rebake_ms(&mesh);
        let methods = [
            ("plain", Acceleration::None, Acceleration::None),
            (
                "anderson",
                Acceleration::Anderson { depth: 3 },
                Acceleration::Anderson { depth: 3 },
            ),
            ("lbfgs", LBFGS, LBFGS),
            ("newton", NEWTON, NEWTON),
            ("best", LBFGS, NEWTON),
        ];
        let settled: Vec<(&str, Settled)> = match settle {
            true => {
                let drag = Drag::new(&topology);
                // One release (and its converged pose) per drag method: `best` shares L-BFGS's.
                let mut releases: Vec<(Acceleration, Release)> = Vec::new();
                methods
                    .iter()
                    .map(|&(name, d, s)| match settles(name) {
                        true => {
                            let at = match releases.iter().position(|(a, _)| *a == d) {
                                Some(at) => at,
                                None => {
                                    releases.push((d, drag.release(d)));
                                    releases.len() - 1
                                }
                            };
                            (name, drag.settle(&releases[at].1, s))
                        }
                        false => (name, Settled::default()),
                    })
                    .collect()
            }
            false => methods
                .iter()
                .map(|&(n, _, _)| (n, Settled::default()))
                .collect(),
        };
        let field = |f: fn(&Settled) -> serde_json::Value| {
            serde_json::Value::Object(settled.iter().map(|(n, s)| (n.to_string(), f(s))).collect())
        };
        eprintln!(
            "{name}: {} vertices, set change → first pose {first_pose:.1} ms (preview of {preview_vertices}; whole mesh {whole_first_pose:.1} ms), posed mesh → rest topology {fresh_ms:.1} ms fresh / {rebased_ms:.1} ms rebased, settle (iterations / back-substitutions / ms): {}",
            topology.vertex_count(),
            settled
                .iter()
                .map(|(n, s)| format!(
                    "{n} {} / {} / {:.0} (minimum {:.6e})",
                    s.iterations, s.back_substitutions, s.ms, s.converged_energy
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
        rows.push(serde_json::json!({
            "name": name,
            "vertices": topology.vertex_count(),
            "set_change_first_pose_ms": first_pose,
            "set_change_whole_mesh_first_pose_ms": whole_first_pose,
            "preview_vertices": preview_vertices,
            "rest_topology_ms": {"fresh": fresh_ms, "rebased": rebased_ms},
            "settle_iterations": field(|s| s.iterations.into()),
            "settle_back_substitutions": field(|s| s.back_substitutions.into()),
            "settle_ms": field(|s| s.ms.into()),
            "settle_converged_energy": field(|s| s.converged_energy.into()),
        }));
    }
    if json {
        println!("{}", serde_json::json!({ "meshes": rows }));
    }
}
