//! Benchmark of the skinning-space pose solver (`pose`): precompute, warm solves during a
//! drag, and the quality of the converged pose against the full-mesh ARAP solver.
//!
//! ```text
//! cargo run --release --example character_bench -- [--model PATH | --cells N [--humanoid]] [--json]
//! ```
//! Without `--model`: the generated mannequin auto-rigged to 16 joints, meshed on `--cells`
//! cells (default 200 ≈ 100k vertices; 110 ≈ 30k); `--humanoid`: the same mannequin rigged to
//! 52 joints with Mixamo names and five three-bone fingers per hand (`synth_rig::humanoid_rig`),
//! the joint count of game characters. With `--model`: the first skin of a rigged glTF (e.g.
//! `assets/models/Fox.glb`), loaded through Bevy's glTF loader and read by the pose plugin's
//! own code (`CharacterSkin::read`: every skinned mesh node of that skin, the joints'
//! frames, the pose the file places them in), so the model measured is the one `Poseable`
//! builds; it is posed from that pose.
//!
//! Constraints (vertex sets, so the full-mesh solver gets exactly the same problem): the
//! lowest 6 % of the model's height is fixed (the feet); the handle is the vertices near one
//! end (the mannequin's left hand; for a glTF model the 4 % of vertices farthest along +z,
//! the Fox's head); its target turns 25° and moves 8 % of the bounding diagonal. Both start
//! in the bind pose.
//! * `precompute_ms`: `SkinnedModel::new` (weld, clusters, reduced matrices) + `PoseSolver::new`.
//! * `ms_per_solve`, `ms_per_iteration`: a 30-frame drag to the target, 3 warm-started
//!   iterations per frame; median solve.
//! * `energy_subspace`: full-mesh normalised ARAP energy (`arap_energy`) of the skinned mesh
//!   after converging (300 iterations) at the target; `energy_full_arap`: the same energy for
//!   the full-mesh solver (`ArapSolver`, same welded mesh and constraints, 400 iterations).
//! * `max_bone_length_error`: largest bone length change / bounding diagonal.
//! * `handle_error`: mean distance of the handle vertices from their targets / diagonal.
//! * Full-body constraints, the same drag again with: a position effector on every foot (the
//!   first `foot`/`ankle` joint of each leg, and a quadruped's `hand` paws) at its bind
//!   position, a head look-at at a point ahead and to the side, limits on every joint (the
//!   humanoid preset where names say, else a 45° cone with ±30° twist) and the handle's turn
//!   pulling against them: `constrained_ms_per_solve` (median of 3-iteration warm solves),
//!   `max_limit_violation_deg` (after every frame), `effector_error` (mean distance of the feet
//!   from their targets / diagonal, after converging).
//!
//! * `--ground slope|steps [--balance]` (`character_ground.rs`): instead, the model stood on a
//!   25° slope or on steps by automatic contacts, its handle dragged over 30 frames of 3 warm
//!   iterations (up to 3 more while skin is through the ground) by the first drag that topples
//!   it without balance — across its feet, outwards through the handle or back across them,
//!   30, 45 or 60 % of its size (`drag_direction`, `drag_reach`): `constrained_ms_per_solve`
//!   (median, contacts and balance active), `penetration_max` (deepest skin vertex below the ground / size),
//!   `sole_normal_error_deg_p95` (planted joints' up against their ground's normal),
//!   `soles_at_limit_share` (planted soles more than 3° off the normal), `planted_slide_max`
//!   (/ size per frame), `com_supported_share`, `com_margin_min` (/ size), the same share
//!   without balance, `replants`; `bare_ms_per_solve` (the same drag with no ground,
//!   contacts, floor or balance, in the same process) and `ground_cost_ratio` (the first
//!   over it); the price without the floor, the part no floor can take off: the same drag
//!   with the contacts alone (`contacts_ms_per_solve`, `contacts_cost_ratio` over the bare)
//!   and, with `--balance`, with the contacts and balance (`without_floor_ms_per_solve`,
//!   `without_floor_cost_ratio`; `null` without it).
//!
//! The last stdout line is the JSON object.

mod character_ground;
use bevy_wii_deform_examples::cli;
use bevy_wii_deform_examples::headless_gltf;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use bevy_wii_deform::deform::{
    Acceleration, ArapSolver, Constraints, Handle, InitialGuess, RigidTransform, SolveOptions,
    SolverSettings, arap_energy, centroid,
};
use bevy_wii_deform::ecs::{CharacterSkin, Poseable};
use bevy_wii_deform::pose::rig::synth_rig::{humanoid_rig, mannequin_rig};
use bevy_wii_deform::pose::*;
use glam::{DQuat, DVec3};

struct Args {
    model: Option<PathBuf>,
    cells: u32,
    /// The 52-joint humanoid instead of the 16-joint mannequin.
    humanoid: bool,
    json: bool,
    /// `--ground slope|steps`: the drag on that ground with automatic contacts.
    ground: Option<character_ground::GroundKind>,
    /// `--balance`: with the centre of mass kept over the planted feet.
    balance: bool,
}

const USAGE: &str = "\
usage: character_bench [--model PATH] [--cells N] [--humanoid] [--ground slope|steps [--balance]] [--json]

  --model PATH  a rigged glTF (default: a generated 16-joint mannequin)
  --cells N     the generated rig's grid resolution (default 200)
  --humanoid    the generated 52-joint humanoid instead of the mannequin
  --ground G    stand it on a 25° slope or steps (automatic contacts) and drag it over
  --balance     with --ground: keep the centre of mass over the planted feet
  --json        the JSON line only";

fn args() -> Args {
    let mut out = Args {
        model: None,
        cells: 200,
        humanoid: false,
        json: false,
        ground: None,
        balance: false,
    };
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("model") => {
                out.model = Some(PathBuf::from(cli::string(&mut parser, USAGE)))
            }
            cli::Arg::Long("cells") => out.cells = cli::value(&mut parser, USAGE),
            cli::Arg::Long("json") => out.json = true,
            cli::Arg::Long("humanoid") => out.humanoid = true,
            cli::Arg::Long("balance") => out.balance = true,
            cli::Arg::Long("ground") => {
                out.ground = Some(match cli::string(&mut parser, USAGE).as_str() {
                    "slope" => character_ground::GroundKind::Slope,
                    "steps" => character_ground::GroundKind::Steps,
                    other => {
                        eprintln!("--ground must be slope or steps, got {other:?}\n{USAGE}");
                        std::process::exit(2);
                    }
                })
            }
            other => cli::unexpected(other, USAGE),
        }
    }
    out
}

fn main() {
    let args = args();
    let (name, skeleton, mesh, bind, settings) = load_rig(&args);
    let t0 = Instant::now();
    let model =
        Arc::new(SkinnedModel::new(skeleton.clone(), &mesh, &bind, settings).expect("model"));
    let model_ms = t0.elapsed().as_secs_f64() * 1e3;
    // Where the welded vertices are in the pose the drag starts from (for a file whose mesh
    // node is turned or scaled, not where its vertex data lies).
    let rest = model.skin_welded(&bind);
    let diagonal = model.topology().bounding_diagonal();
    let (fixed, handle) = drag_regions(&model, &rest, args.model.is_none());
    if let Some(kind) = args.ground {
        let mut report = character_ground::run(&model, &bind, &handle, kind, args.balance);
        report["model"] = serde_json::Value::from(name);
        report["joints"] = serde_json::Value::from(model.skeleton().len());
        println!("{report}");
        return;
    }
    let pivot = centroid(&rest, &handle);
    let target = RigidTransform::new(
        DQuat::from_rotation_z(25f64.to_radians()),
        DVec3::new(0.06, 0.05, 0.02) * diagonal,
        pivot,
    );
    let mut constraints = PoseConstraints {
        fixed_vertices: fixed.clone(),
        handles: vec![Handle {
            vertices: handle.clone(),
            transform: RigidTransform::IDENTITY,
        }],
        ..Default::default()
    };
    let t1 = Instant::now();
    let solver = PoseSolver::new(
        model.clone(),
        &constraints,
        &bind,
        PoseSolverSettings::default(),
    )
    .expect("solver");
    let precompute_ms = model_ms + t1.elapsed().as_secs_f64() * 1e3;

    let mut iterations = 0;
    let mut rejected = 0;
    let (mut solve_ms, last) = drag(&solver, &mut constraints, target, &bind, |solved| {
        iterations += solved.stats.iterations;
        rejected += solved.stats.rejected_steps;
    });
    let total_ms: f64 = solve_ms.iter().sum();
    solve_ms.sort_by(f64::total_cmp);
    let ms_per_solve = solve_ms[solve_ms.len() / 2];
    let ms_per_iteration = total_ms / iterations.max(1) as f64;

    let converged = converge(&solver, &constraints, &last);
    let energy_subspace = model.full_arap_energy(&converged.pose);
    if std::env::var("BENCH_DEBUG").is_ok() {
        debug_report(&converged, &last, iterations, rejected);
    }
    let skinned = model.skin_welded(&converged.pose);
    let handle_error = handle
        .iter()
        .map(|&i| skinned[i as usize].distance(target.apply(rest[i as usize])))
        .sum::<f64>()
        / handle.len() as f64
        / diagonal;
    let bone_error = max_bone_length_error(model.skeleton(), &bind, &converged.pose) / diagonal;

    // The full-mesh solver works on the vertex data as the file stores it: the same drag
    // (turn and move) about the handle's centroid there.
    let raw = model.topology().positions();
    let raw_target =
        RigidTransform::new(target.rotation, target.translation, centroid(raw, &handle));
    let energy_full = full_mesh_energy(&model, fixed, handle, raw_target);
    let constrained = constrained_drag(&model, &bind, &constraints, diagonal);

    if !args.json {
        println!(
            "{name}: {} render vertices, {} joints, {} clusters; precompute {precompute_ms:.0} ms; {ms_per_solve:.3} ms/solve; energy {energy_subspace:.5} (full-mesh ARAP {energy_full:.5})",
            mesh.positions.len(),
            model.skeleton().len(),
            model.cluster_count()
        );
    }
    println!(
        "{{\"model\": \"{name}\", \"render_vertices\": {}, \"welded_vertices\": {}, \"joints\": {}, \"clusters\": {}, \"precompute_ms\": {precompute_ms:.1}, \"ms_per_iteration\": {ms_per_iteration:.4}, \"ms_per_solve\": {ms_per_solve:.4}, \"energy_subspace\": {energy_subspace:.6}, \"energy_full_arap\": {energy_full:.6}, \"max_bone_length_error\": {bone_error:.3e}, \"handle_error\": {handle_error:.3e}, \"converge_iterations\": {}, \"constrained_ms_per_solve\": {:.4}, \"max_limit_violation_deg\": {:.4}, \"effector_error\": {:.3e}}}",
        mesh.positions.len(),
        model.topology().vertex_count(),
        model.skeleton().len(),
        model.cluster_count(),
        converged.stats.iterations,
        constrained.ms_per_solve,
        constrained.max_violation_deg,
        constrained.effector_error,
    );
}

/// The rig to pose, the pose it is built and dragged from, and the model settings: `--model`'s
/// file read as the pose plugin reads it, or a generated rig in its bind pose.
fn load_rig(args: &Args) -> (String, Skeleton, SkinnedMesh, SkeletonPose, ModelSettings) {
    match &args.model {
        Some(path) => match read_with_the_plugin(path) {
            Ok(skin) => {
                // The settings the plugin builds a default `Poseable`'s model with.
                let settings = ModelSettings {
                    clusters: Poseable::default().clusters.max(1) as usize,
                    ..Default::default()
                };
                let name = path.display().to_string();
                (name, skin.skeleton, skin.mesh, skin.reference, settings)
            }
            Err(e) => {
                eprintln!("{}: {e}", path.display());
                std::process::exit(2);
            }
        },
        None => {
            let rig = if args.humanoid {
                humanoid_rig(args.cells)
            } else {
                mannequin_rig(args.cells)
            };
            let kind = if args.humanoid {
                "humanoid"
            } else {
                "mannequin"
            };
            let bind = rig.skeleton.bind_pose();
            let name = format!("{kind}_rig({})", args.cells);
            (name, rig.skeleton, rig.mesh, bind, ModelSettings::default())
        }
    }
}

/// Loads `path` through Bevy's glTF loader (headless, without materials: a missing texture
/// is not needed) and reads its character with the pose plugin's own code
/// ([`CharacterSkin::read`]): the model measured is the one `Poseable` builds.
fn read_with_the_plugin(path: &Path) -> Result<CharacterSkin, String> {
    use bevy::prelude::*;
    let absolute = std::fs::canonicalize(path).map_err(|e| format!("cannot open: {e}"))?;
    let (Some(dir), Some(file)) = (absolute.parent(), absolute.file_name()) else {
        return Err("not a file".into());
    };
    let mut app = App::new();
    app.add_plugins(MinimalPlugins);
    headless_gltf::add_gltf_plugins(&mut app, dir);
    app.init_asset::<StandardMaterial>();
    app.finish();
    app.cleanup();
    let gltf = headless_gltf::load_gltf_without_materials(&app, &file.to_string_lossy());
    let deadline = Instant::now() + std::time::Duration::from_secs(60);
    let scene = loop {
        app.update();
        if let Some(loaded) = app.world().resource::<Assets<Gltf>>().get(&gltf) {
            break loaded
                .scenes
                .first()
                .cloned()
                .ok_or("the file has no scene")?;
        }
        if let Some(bevy::asset::LoadState::Failed(e)) =
            app.world().resource::<AssetServer>().get_load_state(&gltf)
        {
            // The loader's message names the file that failed (a backtrace may follow).
            return Err(e.to_string().lines().next().unwrap_or_default().to_string());
        }
        if Instant::now() > deadline {
            return Err("did not load within 60 s".into());
        }
    };
    let root = app
        .world_mut()
        .spawn((WorldAssetRoot(scene), Transform::default()))
        .id();
    loop {
        app.update();
        let spawned = app
            .world()
            .get::<Children>(root)
            .is_some_and(|c| !c.is_empty());
        if spawned {
            // Global transforms of the spawned nodes: one more frame propagates them.
            app.update();
            match CharacterSkin::read(app.world_mut(), root) {
                Ok(Some(skin)) => return Ok(skin),
                Ok(None) => {}
                Err(e) => return Err(e.to_string()),
            }
        }
        if Instant::now() > deadline {
            return Err("its scene did not spawn within 60 s".into());
        }
    }
}

/// The drag's fixed vertices (the lowest 6 % of the height: the feet) and handle (the
/// mannequin's right hand, or the front 4 % of a file's model).
fn drag_regions(model: &SkinnedModel, rest: &[DVec3], mannequin: bool) -> (Vec<u32>, Vec<u32>) {
    let (lo, hi) = rest.iter().fold((DVec3::MAX, DVec3::MIN), |(lo, hi), p| {
        (lo.min(*p), hi.max(*p))
    });
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&i| rest[i as usize].y < lo.y + 0.06 * (hi.y - lo.y))
        .collect();
    let handle: Vec<u32> = if mannequin {
        let hand = DVec3::new(0.58, 0.86, 0.06) * model.rest_scale();
        (0..rest.len() as u32)
            .filter(|&i| rest[i as usize].distance(hand) < 0.1)
            .collect()
    } else {
        let mut by_z: Vec<u32> = (0..rest.len() as u32)
            .filter(|i| !fixed.contains(i))
            .collect();
        by_z.sort_by(|&a, &b| rest[b as usize].z.total_cmp(&rest[a as usize].z));
        by_z.truncate((rest.len() / 25).max(1));
        by_z.sort_unstable();
        by_z
    };
    (fixed, handle)
}

/// `BENCH_DEBUG`: where the last drag solve spent its time and how the energies went.
fn debug_report(converged: &PoseSolution, last: &PoseSolution, iterations: u32, rejected: u32) {
    let e = &converged.stats.energies;
    let w = &last.stats;
    eprintln!(
        "last drag solve: local {:.3} ms global {:.3} ms (systems {:.3} ms) rejected {}",
        w.local_s * 1e3,
        w.global_s * 1e3,
        w.system_s * 1e3,
        w.rejected_steps
    );
    eprintln!(
        "drag: {iterations} iterations, {rejected} rejected trial steps, final drag energy {:?}",
        last.stats.energies.last()
    );
    eprintln!(
        "converge energies: first {:?} … last {:?}",
        &e[..e.len().min(8)],
        &e[e.len().saturating_sub(4)..]
    );
}

/// The ARAP energy of the same drag solved on the whole mesh (free vertices, no bones): what
/// skinning space gives up.
fn full_mesh_energy(
    model: &SkinnedModel,
    fixed: Vec<u32>,
    handle: Vec<u32>,
    target: RigidTransform,
) -> f64 {
    let full = Constraints {
        fixed,
        handles: vec![Handle {
            vertices: handle,
            transform: target,
        }],
        targets: Vec::new(),
    };
    let full_solver =
        ArapSolver::precompute(model.topology().clone(), &full, SolverSettings::default())
            .expect("full precompute");
    let full_solution = full_solver
        .solve(
            &full,
            &SolveOptions {
                max_iterations: 400,
                tolerance: 1e-9,
                acceleration: Acceleration::None,
            },
            InitialGuess::Laplacian,
            &|| false,
        )
        .expect("full solve");
    arap_energy(model.topology(), &full_solution.positions)
}

/// Figures of the drag under full-body constraints.
struct Constrained {
    ms_per_solve: f64,
    max_violation_deg: f64,
    effector_error: f64,
}

/// The joints a character stands on: the first `foot`/`ankle` joint of each chain, and
/// `hand` paws when there are fewer than four (a quadruped's front legs).
fn standing_joints(skeleton: &Skeleton) -> Vec<usize> {
    let named = |j: usize, words: &[&str]| {
        let n = skeleton.joints()[j].name.to_lowercase();
        words.iter().any(|w| n.contains(w))
    };
    let first_of = |words: &[&str]| -> Vec<usize> {
        (0..skeleton.len())
            .filter(|&j| named(j, words))
            .filter(|&j| skeleton.joints()[j].parent.is_none_or(|p| !named(p, words)))
            .collect()
    };
    let mut feet = first_of(&["foot", "ankle"]);
    if feet.len() < 4 {
        feet.extend(first_of(&["hand"]));
    }
    feet
}

/// Limits on every joint: the humanoid preset where names say, a 45° cone elsewhere.
fn limits_everywhere(skeleton: &Skeleton, bind: &SkeletonPose) -> JointLimits {
    let (mut limits, _) = JointLimits::humanoid(skeleton, bind);
    for j in 0..skeleton.len() {
        if !limits.is_limited(j) {
            limits
                .set(j, JointLimit::cone_deg((45.0, 45.0), (-30.0, 30.0)))
                .expect("valid limit");
        }
    }
    limits
}

/// The drag of `base` again with feet effectors, a head look-at and limits everywhere.
fn constrained_drag(
    model: &Arc<SkinnedModel>,
    bind: &SkeletonPose,
    base: &PoseConstraints,
    diagonal: f64,
) -> Constrained {
    let skeleton = model.skeleton();
    let globals = skeleton.global_transforms(bind);
    let feet = standing_joints(skeleton);
    let mut effectors: Vec<Effector> = feet
        .iter()
        .map(|&j| Effector {
            joint: j,
            goal: EffectorGoal::Position(globals[j].translation),
            weight: 1.0,
        })
        .collect();
    if let Some(head) =
        (0..skeleton.len()).find(|&j| skeleton.joints()[j].name.to_lowercase().contains("head"))
    {
        let frame = DQuat::from_mat3(
            &globals[head]
                .matrix3
                .mul_scalar(1.0 / globals[head].matrix3.x_axis.length().max(1e-12)),
        );
        effectors.push(Effector {
            joint: head,
            goal: EffectorGoal::Aim {
                axis: frame.inverse() * DVec3::Z,
                target: globals[head].translation + DVec3::new(0.3, 0.1, 1.0) * diagonal,
                up: None,
            },
            weight: 1.0,
        });
    }
    let limits = Arc::new(limits_everywhere(skeleton, bind));
    let mut constraints = PoseConstraints {
        fixed_vertices: Vec::new(),
        effectors,
        limits: Some(limits.clone()),
        ..base.clone()
    };
    let target = base.handles[0].transform;
    let solver = PoseSolver::new(
        model.clone(),
        &constraints,
        bind,
        PoseSolverSettings::default(),
    )
    .expect("constrained solver");
    let mut max_violation_deg = 0.0f64;
    // The handle keeps the unconstrained drag's full target: it pulls against the limits.
    let (mut solve_ms, last) = drag(&solver, &mut constraints, target, bind, |solved| {
        max_violation_deg = max_violation_deg.max(limits.max_violation_deg(&solved.pose));
    });
    let converged = converge(&solver, &constraints, &last);
    max_violation_deg = max_violation_deg.max(limits.max_violation_deg(&converged.pose));
    let now = skeleton.global_transforms(&converged.pose);
    let effector_error = feet
        .iter()
        .map(|&j| now[j].translation.distance(globals[j].translation))
        .sum::<f64>()
        / feet.len().max(1) as f64
        / diagonal;
    solve_ms.sort_by(f64::total_cmp);
    Constrained {
        ms_per_solve: solve_ms[solve_ms.len() / 2],
        max_violation_deg,
        effector_error,
    }
}

/// A 30-frame drag of handle 0 from rest to `target`, 3 warm-started iterations per frame,
/// starting in `bind`; `each` sees every frame's solution. Returns each frame's solve time
/// (ms, frame order) and the last solution.
fn drag(
    solver: &PoseSolver,
    constraints: &mut PoseConstraints,
    target: RigidTransform,
    bind: &SkeletonPose,
    mut each: impl FnMut(&PoseSolution),
) -> (Vec<f64>, PoseSolution) {
    let frames = 30;
    let three = PoseSolveOptions {
        max_iterations: 3,
        tolerance: 0.0,
        ground_iterations: 0,
    };
    let mut last: Option<PoseSolution> = None;
    let mut solve_ms = Vec::with_capacity(frames);
    for f in 1..=frames {
        let s = f as f64 / frames as f64;
        constraints.handles[0].transform = RigidTransform::new(
            DQuat::IDENTITY.slerp(target.rotation, s),
            target.translation * s,
            target.pivot,
        );
        let t = Instant::now();
        let start = last.as_ref().map_or(PoseStart::Pose(bind), PoseStart::Warm);
        let solved = solver
            .solve(constraints, &three, start, &|| false)
            .expect("solve");
        solve_ms.push(t.elapsed().as_secs_f64() * 1e3);
        each(&solved);
        last = Some(solved);
    }
    (solve_ms, last.expect("30 frames"))
}

/// The pose a drag settles into: 300 warm iterations from its last frame.
fn converge(
    solver: &PoseSolver,
    constraints: &PoseConstraints,
    last: &PoseSolution,
) -> PoseSolution {
    solver
        .solve(
            constraints,
            &PoseSolveOptions {
                max_iterations: 300,
                tolerance: 1e-12,
                ground_iterations: 0,
            },
            PoseStart::Warm(last),
            &|| false,
        )
        .expect("converge")
}
