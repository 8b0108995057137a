//! Peer-benchmark CLI: runs the same ARAP problem as libigl/CGAL/Open3D harnesses.
//!
//! ```text
//! cargo run --release --example arap_peer -- MESH.off CONSTRAINTS.txt ITERS REPEATS OUT.bin [--init laplacian|rest]
//!     [--factorization auto|simplicial|supernodal] [--anderson DEPTH] [--weld none|seams|all]
//!     [--threading auto|serial|parallel]
//! ```
//! Constraint indices are input vertex indices; they are mapped through the weld map, and the
//! output is in input order. `--weld none` (the default) solves the mesh's own index topology,
//! the problem the peers solve, so coincident but unconnected vertices stay apart.
//! CONSTRAINTS.txt: `n_fixed n_handle`, then `index x y z` per constrained vertex (fixed first,
//! at rest; then handle vertices at their targets). Each repeat times precompute (topology,
//! weights, assembly, both factorizations — the uniform Laplacian of the initial guess is factored
//! explicitly, with `factor_initial_guess`, as the library would otherwise do it lazily inside
//! the first solve) and exactly ITERS iterations (no early stop).
//! OUT.bin: n×3 little-endian f64 positions of the last repeat, input vertex order. The last
//! stdout line is `{"precompute_s": [..], "solve_s": [..]}`; energies go to stderr.
//!
//! ```text
//! cargo run --release --example arap_peer -- problem SOURCE OUT.off OUT.txt
//! ```
//! writes the crate's benchmark problem (`synth::bend_problem`: the lowest 10 % along Y fixed,
//! the highest 10 % turned 0.6 rad about Z and moved 15 % of the bounding diagonal along X) for
//! a peer to solve: SOURCE is a mesh file (`.off`/`.obj`), `bar:N` (a generated bar of about N
//! vertices) or `sphere:S` (an icosphere subdivided S times, stretched along Y).

use bevy_wii_deform_examples::cli;

use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use bevy_wii_deform::deform::*;
use glam::DVec3;

/// Fixed vertex indices and handle (index, target) pairs.
type ParsedConstraints = (Vec<u32>, Vec<(u32, DVec3)>);

fn parse_constraints(text: &str) -> Result<ParsedConstraints, String> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let head = lines.next().ok_or("empty constraints file")?;
    let counts: Vec<usize> = head
        .split_whitespace()
        .map(|t| t.parse().map_err(|_| format!("bad count {t:?}")))
        .collect::<Result<_, _>>()?;
    let [nf, nh] = counts[..] else {
        return Err("line 1 must be `n_fixed n_handle`".into());
    };
    let mut fixed = Vec::with_capacity(nf);
    let mut handle = Vec::with_capacity(nh);
    for k in 0..nf + nh {
        let line = lines
            .next()
            .ok_or(format!("missing constraint line {}", k + 2))?;
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() != 4 {
            return Err(format!("line {}: expected `index x y z`", k + 2));
        }
        let i: u32 = f[0].parse().map_err(|_| format!("bad index {:?}", f[0]))?;
        let mut p = [0.0; 3];
        for c in 0..3 {
            p[c] = f[c + 1]
                .parse()
                .map_err(|_| format!("bad coordinate {:?}", f[c + 1]))?;
        }
        if k < nf {
            fixed.push(i);
        } else {
            handle.push((i, DVec3::from_array(p)));
        }
    }
    Ok((fixed, handle))
}

/// The peer comparison's flags.
struct PeerOptions {
    /// `--init laplacian|rest` (laplacian by default).
    init: &'static str,
    /// `--factorization auto|simplicial|supernodal`.
    factorization: Factorization,
    /// `--anderson DEPTH` (0: plain local/global).
    anderson_depth: usize,
    /// `--weld none|seams|all` (the peers solve the mesh's own index topology: none).
    weld: WeldPolicy,
    /// `--threading auto|serial|parallel`.
    threading: Threading,
}

const USAGE: &str = "\
usage: arap_peer MESH.off CONSTRAINTS.txt ITERS REPEATS OUT.bin [--init laplacian|rest]
                 [--factorization auto|simplicial|supernodal] [--anderson DEPTH]
                 [--weld none|seams|all] [--threading auto|serial|parallel]
       arap_peer problem SOURCE OUT.off OUT.txt   (SOURCE: a mesh file, bar:N or sphere:S)";

impl PeerOptions {
    /// Parses the command line: the five positional arguments and the flags.
    fn parse() -> Result<(Vec<String>, Self), String> {
        let mut positional = Vec::new();
        let mut options = PeerOptions {
            init: "laplacian",
            factorization: Factorization::Auto,
            anderson_depth: 0,
            // The peers solve the mesh's own index topology: weld nothing unless asked.
            weld: WeldPolicy::None,
            threading: Threading::Auto,
        };
        let mut parser = cli::Parser::from_env();
        while let Some(arg) = cli::next(&mut parser, USAGE) {
            match arg {
                cli::Arg::Value(v) => positional.push(cli::positional(v, USAGE)),
                cli::Arg::Long("init") => {
                    options.init = match cli::string(&mut parser, USAGE).as_str() {
                        "rest" => "rest",
                        "laplacian" => "laplacian",
                        v => return Err(format!("--init must be laplacian or rest, got {v:?}")),
                    }
                }
                cli::Arg::Long("factorization") => {
                    options.factorization = match cli::string(&mut parser, USAGE).as_str() {
                        "simplicial" => Factorization::Simplicial,
                        "supernodal" => Factorization::Supernodal,
                        "auto" => Factorization::Auto,
                        v => {
                            return Err(format!(
                                "--factorization must be auto, simplicial or supernodal, got {v:?}"
                            ));
                        }
                    }
                }
                cli::Arg::Long("anderson") => {
                    options.anderson_depth = cli::value(&mut parser, USAGE)
                }
                cli::Arg::Long("weld") => {
                    options.weld = match cli::string(&mut parser, USAGE).as_str() {
                        "none" => WeldPolicy::None,
                        "seams" => WeldPolicy::Seams,
                        "all" => WeldPolicy::AllCoincident,
                        v => return Err(format!("--weld must be none, seams or all, got {v:?}")),
                    }
                }
                cli::Arg::Long("threading") => {
                    options.threading = match cli::string(&mut parser, USAGE).as_str() {
                        "auto" => Threading::Auto,
                        "serial" => Threading::Serial,
                        "parallel" => Threading::Parallel,
                        v => {
                            return Err(format!(
                                "--threading must be auto, serial or parallel, got {v:?}"
                            ));
                        }
                    }
                }
                other => cli::unexpected(other, USAGE),
            }
        }
        if positional.len() != 5 {
            return Err(USAGE.into());
        }
        Ok((positional, options))
    }
}

/// Writes the solved positions in input (render) vertex order as little-endian f64 triples.
fn write_positions(path: &str, topology: &Topology, positions: &[DVec3]) -> Result<(), String> {
    let render = topology.to_render(positions);
    let mut bytes = Vec::with_capacity(render.len() * 24);
    for p in &render {
        for c in p.to_array() {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).map_err(|e| format!("{path}: {e}"))
}

/// The mesh a `problem` SOURCE names.
fn problem_mesh(source: &str) -> Result<TriMesh, String> {
    if let Some(n) = source.strip_prefix("bar:") {
        let n: u32 = n
            .parse()
            .map_err(|_| format!("bad vertex count in {source:?}"))?;
        return Ok(synth::bar_with_vertices(n));
    }
    if let Some(s) = source.strip_prefix("sphere:") {
        let s: u32 = s
            .parse()
            .map_err(|_| format!("bad subdivision in {source:?}"))?;
        let mut mesh = synth::icosphere(s.min(8), 0.5);
        for p in &mut mesh.positions {
            p.y *= 2.0;
        }
        return Ok(mesh);
    }
    TriMesh::read(source).map_err(|e| e.to_string())
}

/// `problem SOURCE OUT.off OUT.txt`: writes the benchmark problem on SOURCE for the peers.
fn write_problem(args: &[String]) -> Result<(), String> {
    let [source, off, txt] = args else {
        return Err("usage: arap_peer problem SOURCE OUT.off OUT.txt".into());
    };
    let mesh = problem_mesh(source)?;
    let (lo, hi) = bounding_box(&mesh.positions);
    let shift = 0.15 * (hi - lo).length();
    let constraints = synth::bend_problem(&mesh.positions, 0.6, DVec3::new(shift, 0.0, 0.0));
    let handle = &constraints.handles[0];
    let mut text = format!("{} {}\n", constraints.fixed.len(), handle.vertices.len());
    for &i in &constraints.fixed {
        let p = mesh.positions[i as usize];
        text += &format!("{i} {:.17e} {:.17e} {:.17e}\n", p.x, p.y, p.z);
    }
    for &i in &handle.vertices {
        let p = handle.transform.apply(mesh.positions[i as usize]);
        text += &format!("{i} {:.17e} {:.17e} {:.17e}\n", p.x, p.y, p.z);
    }
    std::fs::write(off, mesh.to_off()).map_err(|e| format!("{off}: {e}"))?;
    std::fs::write(txt, text).map_err(|e| format!("{txt}: {e}"))?;
    eprintln!(
        "{}: {} vertices, {} fixed, {} handle",
        source,
        mesh.positions.len(),
        constraints.fixed.len(),
        handle.vertices.len()
    );
    Ok(())
}

fn run() -> Result<(), String> {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    if raw.first().map(String::as_str) == Some("problem") {
        return write_problem(&raw[1..]);
    }
    let (args, options) = PeerOptions::parse()?;
    let mesh = TriMesh::read(&args[0]).map_err(|e| e.to_string())?;
    let text = std::fs::read_to_string(&args[1]).map_err(|e| format!("{}: {e}", args[1]))?;
    let (fixed, targets) = parse_constraints(&text)?;
    let iters: u32 = args[2].parse().map_err(|_| "ITERS must be an integer")?;
    let repeats: usize = args[3].parse().map_err(|_| "REPEATS must be an integer")?;
    let PeerOptions {
        init,
        factorization,
        anderson_depth,
        weld,
        threading,
    } = options;
    let settings = SolverSettings {
        factorization,
        threading,
        ..Default::default()
    };
    // In input (render) vertex order, as in the constraints file.
    let input_constraints = Constraints {
        fixed,
        handles: vec![],
        targets,
    };
    let options = SolveOptions {
        max_iterations: iters,
        tolerance: 0.0,
        acceleration: Acceleration::anderson(anderson_depth),
    };
    let (mut pre, mut sol_s) = (Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        let topology = Arc::new(
            Topology::with_weld(&mesh.positions, &mesh.triangles, weld)
                .map_err(|e| e.to_string())?,
        );
        let constraints = input_constraints
            .from_render(&topology)
            .map_err(|e| e.to_string())?;
        let solver = ArapSolver::precompute(topology.clone(), &constraints, settings.clone())
            .map_err(|e| e.to_string())?;
        if init != "rest" {
            // The peers factor both systems in their precompute: so do we, here.
            solver.factor_initial_guess().map_err(|e| e.to_string())?;
        }
        pre.push(t0.elapsed().as_secs_f64());
        let t1 = Instant::now();
        let guess = if init == "rest" {
            InitialGuess::Rest
        } else {
            InitialGuess::Laplacian
        };
        let sol = solver
            .solve(&constraints, &options, guess, &|| false)
            .map_err(|e| e.to_string())?;
        sol_s.push(t1.elapsed().as_secs_f64());
        eprintln!(
            "solve phases: init {:.2} ms, local {:.2} ms, rhs {:.2} ms, global {:.2} ms",
            sol.stats.init_s * 1e3,
            sol.stats.local_s * 1e3,
            sol.stats.rhs_s * 1e3,
            sol.stats.global_s * 1e3
        );
        eprintln!(
            "energies: {:?} (exact final {:.6}); precompute stats {:?}",
            sol.stats.energies,
            arap_energy(&topology, &sol.positions),
            solver.precompute_stats()
        );
        last = Some((topology, sol));
    }
    let (topology, sol) = last.expect("at least one repeat");
    write_positions(&args[4], &topology, &sol.positions)?;
    println!(
        "{}",
        serde_json::json!({ "precompute_s": pre, "solve_s": sol_s })
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("arap_peer: {e}");
            ExitCode::FAILURE
        }
    }
}
