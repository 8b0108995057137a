//! Plugin benchmark: a headless app in which a handle is dragged every frame; measures the
//! main-thread time spent in the plugin's systems and completed solves per second.
//!
//! ```text
//! cargo run --release --example plugin_bench -- [--mesh PATH | --bar VERTICES] [--seconds 5] [--iterations 1] [--fps 120] [--grab | --set-changes [--no-preview]] [--plain] --json
//! ```
//! Default mesh: ../shared/meshes/armadillo.off (26k vertices), else a 26k-vertex bar.
//! `--plain`: the plugin with plain local/global iterations and no settling (default: L-BFGS
//! while dragging, Newton settling after).
//! Last stdout line: `{"vertices": N, "frames": F, "main_ms_median": x, "main_ms_p99": y,
//! "solves_per_s": z, "ms_per_solve": m, "solver_bound": b}` (`ms_per_solve`: the worker's
//! median time per solve; `solver_bound`: `solves_per_s` ≥ 0.9 × 1000 / `ms_per_solve`, the
//! drag limited by the solver, not by how solves are handed to it).
//! `--many N`: N meshes (~2k-vertex bars unless `--mesh`/`--bar` says otherwise) each dragged
//! at once; adds `meshes`, `solves_per_s_per_mesh_min` (`solves_per_s` is across all).
//! `--grab`: no fixed region; a new pointer grab (`GrabStart`, patch radius 3 % and region 30 %
//! of the bounding-box diagonal) every second at a pseudo-random vertex, its handle dragged in
//! between; adds `grab_to_first_pose_ms_median` / `_p95` (press → first written pose, which
//! includes re-preparing the rest pose from the current one and factorizing the region).
//! `--set-changes`: the bottom slab held (`FixedRegion`), a new handle set every second (the
//! vertices within 8 % of the diagonal of a pseudo-random vertex), turned for 0.6 s, then let
//! go until the plugin is idle (so the first pose after a change is the new set's);
//! `--no-preview` turns the preview off for a side-by-side figure; adds
//! `set_change_to_first_pose_ms_median` / `_p95` (change → first written pose: the preview of
//! `DeformConfig::preview` on a large mesh) and `set_change_to_whole_pose_ms_median` (→ first
//! pose solved on the whole mesh).
//! `--dynamics`: the drag solved statically (one iteration per solve) and stepped in time
//! (`DeformDynamics`, `--iterations` per step), in four alternating rounds; adds `poses_per_s`,
//! `ms_per_step` (median of the worker's time per step), `ms_per_static_iteration` (median of
//! its time per one-iteration static solve, same run; both include the pose for the mesh) and
//! `dynamics_step_ratio` (their ratio).
//! `--collider` (feature `avian`): a ~10k-triangle plank whose Avian collider is rebuilt after
//! each settled bend; `triangles`, `rebuilds`, `collider_frames_median` / `_max` (frames from
//! a settled solve to its collider swapped in), `main_ms_median` / `_max` (the deform and
//! collider systems), `frame_ms_median` / `_max` (the whole frame, Avian's step included),
//! and the machine's own noise measured after the run for as long: `idle_wake_late_ms_p99` /
//! `_max` and `idle_wakes_late_over_1ms` (how late a thread that only sleeps 1 ms wakes).

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_wii_deform::deform::{TriMesh, synth};
use bevy_wii_deform::prelude::*;

use bevy_wii_deform_examples::cli;
#[cfg(feature = "avian")]
mod collider_rebuild;
mod dynamics_drag;

#[derive(Resource, Default)]
struct Timing {
    start: Option<Instant>,
    frames_ms: Vec<f64>,
    measuring: bool,
    /// The handle is let go (`--set-changes`, before a new set).
    released: bool,
}

#[derive(Component)]
struct Dragged;

fn start_timer(mut t: ResMut<Timing>) {
    t.start = Some(Instant::now());
}

fn stop_timer(mut t: ResMut<Timing>) {
    if let Some(s) = t.start.take()
        && t.measuring
    {
        t.frames_ms.push(s.elapsed().as_secs_f64() * 1e3);
    }
}

/// `--grab`: drags the current grab's handle (a circle about its pivot).
fn drag_grab(
    time: Res<Time>,
    meshes: Query<&bevy_wii_deform::ecs::GrabHandle>,
    mut handles: Query<(&DeformHandle, &mut Transform)>,
    diagonal: Res<Diagonal>,
) {
    let t = time.elapsed_secs();
    for grab in &meshes {
        if let Ok((h, mut tr)) = handles.get_mut(grab.0)
            && let Some(pivot) = h.pivot
        {
            let r = 0.05 * diagonal.0;
            tr.translation =
                pivot + Vec3::new(r * (t * 3.0).sin(), r * (1.0 - (t * 3.0).cos()), 0.0);
        }
    }
}

/// The `p`-quantile (0–1, nearest rank) of ascending `sorted` values; NaN when there are none.
fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted
        .get(((sorted.len().max(1) - 1) as f64 * p).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// Sleeps out the rest of a frame of length `frame` that began at `began`.
fn pace(frame: Duration, began: Instant) {
    if let Some(rest) = frame.checked_sub(began.elapsed()) {
        std::thread::sleep(rest);
    }
}

/// The JSON fields every mode reports: the mesh's vertices and the main thread's frame times
/// (count, median, p99) while measuring; each mode adds its own.
fn main_thread_report(app: &App, e: Entity) -> serde_json::Map<String, serde_json::Value> {
    let mut ms = app.world().resource::<Timing>().frames_ms.clone();
    ms.sort_by(f64::total_cmp);
    object(serde_json::json!({
        "vertices": app.world().get::<DeformStatus>(e).unwrap().vertices,
        "frames": ms.len(),
        "update_executor": update_executor(app),
        "main_ms_median": percentile(&ms, 0.5),
        "main_ms_p99": percentile(&ms, 0.99),
    }))
}

/// The fields of a JSON object literal.
fn object(value: serde_json::Value) -> serde_json::Map<String, serde_json::Value> {
    match value {
        serde_json::Value::Object(fields) => fields,
        _ => unreachable!("a JSON object literal"),
    }
}

/// Bounding-box diagonal of the benchmark mesh.
#[derive(Resource)]
struct Diagonal(f32);

fn drag(time: Res<Time>, timing: Res<Timing>, mut q: Query<&mut Transform, With<Dragged>>) {
    if !timing.measuring || timing.released {
        return;
    }
    let t = time.elapsed_secs();
    for mut tr in &mut q {
        tr.rotation = Quat::from_rotation_z(0.6 * (t * 0.7).sin())
            * Quat::from_rotation_x(0.3 * (t * 0.5).sin());
    }
}

const USAGE: &str = "\
usage: plugin_bench [--mesh PATH | --bar VERTICES] [--seconds S] [--iterations N] [--fps F]
                    [--grab | --set-changes [--no-preview] | --many N] [--plain]
                    [--async-threads N] [--single-threaded-update]
                    [--collider | --dynamics] [--json]

  --mesh PATH     an OBJ/OFF mesh (default ../shared/meshes/armadillo.off, else a 26k bar)
  --bar VERTICES  a generated bar of about that many vertices
  --seconds S     measured seconds (default 5)
  --iterations N  iterations per solve (default 1)
  --fps F         the simulated game's frame rate (default 120)
  --grab          a new pointer grab every second (grab latency)
  --set-changes   a new handle set every second (first-pose latency)
  --no-preview    no preview pose for a new constraint set
  --many N        N meshes dragged at once (~2k-vertex bars unless --mesh or --bar)
  --async-threads N  threads of Bevy's async compute pool (default: Bevy's, 1 on 2 cores)
  --single-threaded-update  run `Update` on Bevy's single-threaded executor (the main thread
                  alone) instead of the multi-threaded one
  --plain         plain local/global iterations, no settling
  --collider      (feature avian) a plank's collider rebuilt after each settled bend
  --dynamics      the mesh stepped in time (DeformDynamics, --iterations per step)
  --json          accepted for older command lines: the JSON is always the last line";

/// The command line.
#[derive(Debug, Clone)]
struct Args {
    seconds: f64,
    iterations: u32,
    /// Frame rate of the simulated game (the handle moves every frame).
    fps: f64,
    mesh: Option<String>,
    bar: Option<u32>,
    grab: bool,
    set_changes: bool,
    no_preview: bool,
    plain: bool,
    /// `--many N`: N meshes dragged at once.
    many: usize,
    /// `--async-threads N`: threads of Bevy's async compute pool (the solves').
    async_threads: Option<usize>,
    /// `--single-threaded-update`: `Update` on the single-threaded executor.
    single_threaded_update: bool,
    /// `--collider`: the Avian collider rebuild benchmark.
    collider: bool,
    /// `--dynamics`: the dragged mesh stepped in time.
    dynamics: bool,
}

impl Args {
    fn parse() -> Self {
        let mut args = Args {
            seconds: 5.0,
            iterations: 1,
            fps: 120.0,
            mesh: None,
            bar: None,
            grab: false,
            set_changes: false,
            no_preview: false,
            plain: false,
            many: 1,
            async_threads: None,
            single_threaded_update: false,
            collider: false,
            dynamics: false,
        };
        let mut parser = cli::Parser::from_env();
        while let Some(arg) = cli::next(&mut parser, USAGE) {
            match arg {
                cli::Arg::Long("seconds") => args.seconds = cli::value(&mut parser, USAGE),
                cli::Arg::Long("iterations") => args.iterations = cli::value(&mut parser, USAGE),
                cli::Arg::Long("fps") => args.fps = cli::value(&mut parser, USAGE),
                cli::Arg::Long("mesh") => args.mesh = Some(cli::string(&mut parser, USAGE)),
                cli::Arg::Long("bar") => args.bar = Some(cli::value(&mut parser, USAGE)),
                cli::Arg::Long("grab") => args.grab = true,
                cli::Arg::Long("set-changes") => args.set_changes = true,
                cli::Arg::Long("no-preview") => args.no_preview = true,
                cli::Arg::Long("plain") => args.plain = true,
                cli::Arg::Long("many") => args.many = cli::value(&mut parser, USAGE),
                cli::Arg::Long("async-threads") => {
                    args.async_threads = Some(cli::value(&mut parser, USAGE))
                }
                cli::Arg::Long("single-threaded-update") => args.single_threaded_update = true,
                cli::Arg::Long("collider") => args.collider = true,
                cli::Arg::Long("dynamics") => args.dynamics = true,
                cli::Arg::Long("json") => {}
                other => cli::unexpected(other, USAGE),
            }
        }
        args
    }
}

fn main() {
    let args = Args::parse();
    let (seconds, iterations, fps) = (args.seconds, args.iterations, args.fps);
    if args.collider {
        #[cfg(feature = "avian")]
        return collider_rebuild::run(seconds, fps, args.single_threaded_update);
        #[cfg(not(feature = "avian"))]
        cli::fail(
            "--collider needs the avian feature: cargo run --release --features avian --example plugin_bench -- --collider",
            USAGE,
        );
    }
    let tri = match args.many {
        // Many small bendables: ~2k-vertex bars unless a mesh is named.
        n if n > 1 && args.mesh.is_none() => synth::bar_with_vertices(args.bar.unwrap_or(2000)),
        _ => bench_mesh(args.mesh.clone(), args.bar),
    };
    let deform_plugin = deform_plugin(&args);
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins.set(task_pools(args.async_threads)),
        bevy::asset::AssetPlugin::default(),
        bevy::mesh::MeshPlugin,
        bevy::transform::TransformPlugin,
        deform_plugin,
    ))
    .init_resource::<Timing>()
    .add_systems(
        Update,
        drag.before(DeformSystems::Request).before(start_timer),
    )
    .add_systems(Update, start_timer.before(DeformSystems::Prepare))
    .add_systems(Update, stop_timer.after(DeformSystems::Writeback));
    if args.single_threaded_update {
        single_threaded_update(&mut app);
    }
    let grab = args.grab;
    if grab {
        app.add_plugins(GrabPlugin);
    }
    app.finish();
    app.cleanup();
    let diagonal = bevy_wii_deform::deform::Topology::new(&tri.positions, &tri.triangles)
        .map(|t| t.bounding_diagonal() as f32)
        .unwrap_or(1.0);
    let deformable = Deformable {
        max_iterations: Some(iterations),
        tolerance: Some(0.0),
        ..default()
    };
    let e = if grab {
        app.insert_resource(Diagonal(diagonal))
            .add_systems(Update, drag_grab.before(DeformSystems::Request));
        let grabbable = Grabbable {
            radius: 0.03 * diagonal,
            region_radius: 0.3 * diagonal,
            ..default()
        };
        let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
        let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        app.world_mut()
            .spawn((Mesh3d(h), deformable.clone(), grabbable))
            .id()
    } else {
        spawn_dragged_bar(&mut app, &tri, &deformable)
    };
    if grab {
        return run_grabs(&mut app, e, &tri, seconds, fps);
    }
    if args.set_changes {
        let (fixed, _) = synth::slab_regions(&tri.positions, 1, 0.1, 0.1);
        return run_set_changes(&mut app, e, &tri, &fixed, diagonal, seconds, fps);
    }
    if args.dynamics {
        return dynamics_drag::run(&mut app, e, iterations, seconds, fps);
    }
    if args.many > 1 {
        let mut meshes = vec![e];
        meshes.extend((1..args.many).map(|_| spawn_dragged_bar(&mut app, &tri, &deformable)));
        return run_many(&mut app, &meshes, seconds, fps);
    }
    run_drag(&mut app, e, seconds, fps);
}

/// Marks an app whose `Update` runs on the single-threaded executor (`--single-threaded-update`).
#[derive(Resource)]
struct SingleThreadedUpdate;

/// Runs `Update` on Bevy's single-threaded executor: every system on the main thread, in
/// order, with no hand-off to the compute pool's threads between them.
fn single_threaded_update(app: &mut App) {
    app.insert_resource(SingleThreadedUpdate)
        .edit_schedule(Update, |schedule| {
            schedule.set_executor(bevy::ecs::schedule::SingleThreadedExecutor::new());
        });
}

/// Which executor ran `Update` (the JSON's `"update_executor"`).
fn update_executor(app: &App) -> &'static str {
    if app.world().contains_resource::<SingleThreadedUpdate>() {
        "single-threaded"
    } else {
        "multi-threaded"
    }
}

/// Bevy's task pools, with `async_threads` threads for the background solves when given (Bevy's
/// default is a quarter of the cores, at least one: one on a 2-core machine).
fn task_pools(async_threads: Option<usize>) -> bevy::app::TaskPoolPlugin {
    let mut options = bevy::app::TaskPoolOptions::default();
    if let Some(n) = async_threads {
        options.async_compute.min_threads = n;
        options.async_compute.max_threads = n;
    }
    bevy::app::TaskPoolPlugin {
        task_pool_options: options,
    }
}

/// The benchmark mesh, held at its bottom slab and dragged by its top one (`--many`: one
/// copy of several).
fn spawn_dragged_bar(app: &mut App, tri: &TriMesh, deformable: &Deformable) -> Entity {
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let (fixed, handle) = synth::slab_regions(&tri.positions, 1, 0.1, 0.1);
    let bundle_src = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((Mesh3d(h), deformable.clone(), FixedRegion(fixed)))
        .id();
    let (handle, transform) = DeformHandle::bundle(&bundle_src, e, handle);
    app.world_mut().spawn((handle, transform, Dragged));
    e
}

/// `--many N`: N meshes dragged at once; prints the JSON line with the solves per second
/// across all and per mesh (the slowest), and the main thread's frame times.
fn run_many(app: &mut App, meshes: &[Entity], seconds: f64, fps: f64) {
    let solves = |app: &App| -> Vec<u64> {
        meshes
            .iter()
            .map(|&e| app.world().get::<DeformStatus>(e).map_or(0, |s| s.solves))
            .collect()
    };
    let setup = Instant::now();
    while solves(app).contains(&0) {
        app.update();
        std::thread::sleep(Duration::from_millis(1));
        assert!(
            setup.elapsed() < Duration::from_secs(120),
            "setup did not finish"
        );
    }
    let before = solves(app);
    let (elapsed, mut solve_ms) = measure_frames(app, seconds, fps);
    let per_mesh: Vec<f64> = solves(app)
        .iter()
        .zip(&before)
        .map(|(a, b)| (a - b) as f64 / elapsed)
        .collect();
    let total: f64 = per_mesh.iter().sum();
    solve_ms.sort_by(f64::total_cmp);
    let mut ms = app.world().resource::<Timing>().frames_ms.clone();
    ms.sort_by(f64::total_cmp);
    let mut report = object(serde_json::json!({
        "meshes": meshes.len(),
        "vertices": app.world().get::<DeformStatus>(meshes[0]).unwrap().vertices,
        "frames": ms.len(),
        "update_executor": update_executor(app),
        "main_ms_median": percentile(&ms, 0.5),
        "main_ms_p99": percentile(&ms, 0.99),
        "solves_per_s": total,
        "solves_per_s_per_mesh_min": per_mesh.iter().copied().fold(f64::INFINITY, f64::min),
    }));
    report.extend(solver_bound_report(total, &solve_ms));
    println!("{}", serde_json::Value::Object(report));
}

/// The default run: the handle moved every frame for `seconds`; prints the JSON line with the
/// main thread's frame times and the solves per second.
fn run_drag(app: &mut App, e: Entity, seconds: f64, fps: f64) {
    // Wait for topology + factorization (the first solve).
    let setup = Instant::now();
    while app
        .world()
        .get::<DeformStatus>(e)
        .map(|s| s.solves)
        .unwrap_or(0)
        == 0
    {
        app.update();
        std::thread::sleep(Duration::from_millis(1));
        if setup.elapsed() > Duration::from_secs(120) {
            panic!("setup did not finish");
        }
    }
    eprintln!(
        "setup (topology + factorization + first solve): {:.0} ms",
        setup.elapsed().as_secs_f64() * 1e3
    );
    let solves0 = app.world().get::<DeformStatus>(e).unwrap().solves;
    let (elapsed, mut solve_ms) = measure_frames(app, seconds, fps);
    let status = app.world().get::<DeformStatus>(e).unwrap().clone();
    eprintln!(
        "last solve: {} iterations, energy {:.5}, {:.2} ms",
        status.iterations, status.energy, status.solve_ms
    );
    solve_ms.sort_by(f64::total_cmp);
    let solves_per_s = (status.solves - solves0) as f64 / elapsed;
    let mut report = main_thread_report(app, e);
    report.extend(object(serde_json::json!({
        "solves_per_s": solves_per_s,
    })));
    report.extend(solver_bound_report(solves_per_s, &solve_ms));
    println!("{}", serde_json::Value::Object(report));
}

/// Runs the app paced at `fps` for `seconds` while measuring; returns the seconds elapsed and
/// the worker's time of every solve that landed meanwhile (`DeformSolved::solve_ms`).
fn measure_frames(app: &mut App, seconds: f64, fps: f64) -> (f64, Vec<f64>) {
    app.world_mut()
        .resource_mut::<Messages<DeformSolved>>()
        .clear();
    app.world_mut().resource_mut::<Timing>().measuring = true;
    let start = Instant::now();
    let frame = Duration::from_secs_f64(1.0 / fps.max(1.0));
    let mut solve_ms = Vec::new();
    while start.elapsed().as_secs_f64() < seconds {
        let f0 = Instant::now();
        app.update();
        solve_ms.extend(
            app.world_mut()
                .resource_mut::<Messages<DeformSolved>>()
                .drain()
                .map(|m| m.solve_ms),
        );
        pace(frame, f0);
    }
    (start.elapsed().as_secs_f64(), solve_ms)
}

/// `ms_per_solve` (the worker's median time per solve, this run) and `solver_bound` (the
/// solves per second reach 90 % of what back-to-back solves of that length would give: the
/// drag is limited by the solver, not by how the plugin hands solves to it).
fn solver_bound_report(
    solves_per_s: f64,
    sorted_solve_ms: &[f64],
) -> serde_json::Map<String, serde_json::Value> {
    let ms_per_solve = percentile(sorted_solve_ms, 0.5);
    object(serde_json::json!({
        "ms_per_solve": ms_per_solve,
        "solver_bound": solves_per_s >= 0.9 * 1000.0 / ms_per_solve,
    }))
}

/// The mesh to deform: `--mesh PATH`, `--bar N` (a generated bar of about N vertices), or the
/// armadillo (a 26k-vertex bar when `../shared` is absent).
fn bench_mesh(path: Option<String>, bar: Option<u32>) -> TriMesh {
    if let Some(path) = path {
        TriMesh::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    } else if let Some(n) = bar {
        synth::bar_with_vertices(n)
    } else {
        TriMesh::read("../shared/meshes/armadillo.off").unwrap_or_else(|_| {
            eprintln!("../shared/meshes/armadillo.off absent: using a 26k-vertex bar");
            synth::bar_with_vertices(26_002)
        })
    }
}

/// The plugin as the flags ask: `--plain` (plain local/global and no settling, the plugin
/// before L-BFGS, for side-by-side comparisons), `--no-preview` (a new constraint set waits
/// for the whole mesh, `DeformConfig::preview`).
fn deform_plugin(args: &Args) -> DeformPlugin {
    let mut config = DeformConfig::default();
    if args.plain || args.dynamics {
        config.acceleration = bevy_wii_deform::deform::Acceleration::None;
        config.settle_iterations = 0;
    }
    if args.no_preview {
        config.preview = None;
    }
    DeformPlugin { config }
}

/// `--grab`: a new grab every second; prints the JSON line with grab latencies.
fn run_grabs(app: &mut App, e: Entity, tri: &TriMesh, seconds: f64, fps: f64) {
    use bevy::picking::pointer::PointerId;
    let pointer = PointerId::Mouse;
    while app.world().get::<DeformStatus>(e).unwrap().vertices == 0 {
        app.update();
    }
    app.world_mut().resource_mut::<Timing>().measuring = true;
    let frame = Duration::from_secs_f64(1.0 / fps.max(1.0));
    let (mut latencies, mut pressed, mut seed) = (Vec::new(), None::<Instant>, 0x2545F491u64);
    let mut worker_ms: Vec<f64> = Vec::new();
    let (start, mut next_grab, mut solves) = (Instant::now(), 0.0, 0u64);
    while start.elapsed().as_secs_f64() < seconds {
        let f0 = Instant::now();
        let now = start.elapsed().as_secs_f64();
        if now >= next_grab - 1.5 / fps && now < next_grab {
            app.world_mut().write_message(GrabEnd { pointer });
        } else if now >= next_grab {
            next_grab += 1.0;
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let v = (seed >> 33) as usize % tri.positions.len();
            let point = tri.positions[v].as_vec3();
            app.world_mut().write_message(GrabStart {
                pointer,
                entity: e,
                point,
                camera: e,
            });
            pressed = Some(Instant::now());
        }
        app.update();
        let done = app
            .world_mut()
            .resource_mut::<Messages<DeformSolved>>()
            .drain()
            .count();
        solves += done as u64;
        if done > 0
            && let Some(t) = pressed.take()
        {
            latencies.push(t.elapsed().as_secs_f64() * 1e3);
            worker_ms.push(app.world().get::<DeformStatus>(e).unwrap().solve_ms);
        }
        pace(frame, f0);
    }
    latencies.sort_by(f64::total_cmp);
    eprintln!("grab → first pose, ms: {latencies:.1?}");
    eprintln!(
        "of which the first solve on the worker (factorization of the region + iterations), ms: {worker_ms:.1?}"
    );
    let mut report = main_thread_report(app, e);
    report.extend(object(serde_json::json!({
        "solves_per_s": solves as f64 / start.elapsed().as_secs_f64(),
        "grabs": latencies.len(),
        "grab_to_first_pose_ms_median": percentile(&latencies, 0.5),
        "grab_to_first_pose_ms_p95": percentile(&latencies, 0.95),
    })));
    println!("{}", serde_json::Value::Object(report));
}

/// `--set-changes`: a new handle set every second; prints the JSON line with the latencies to
/// the first pose and to the first whole-mesh pose.
fn run_set_changes(
    app: &mut App,
    e: Entity,
    tri: &TriMesh,
    fixed: &[u32],
    diagonal: f32,
    seconds: f64,
    fps: f64,
) {
    while app.world().get::<DeformStatus>(e).unwrap().solves == 0 {
        app.update();
        std::thread::yield_now();
    }
    // The set-up's own solve messages are not a set change's.
    app.world_mut()
        .resource_mut::<Messages<DeformSolved>>()
        .clear();
    app.world_mut().resource_mut::<Timing>().measuring = true;
    let frame = Duration::from_secs_f64(1.0 / fps.max(1.0));
    let held: std::collections::HashSet<u32> = fixed.iter().copied().collect();
    let (mut first, mut whole) = (Vec::new(), Vec::new());
    let (mut changed, mut previewed, mut seed) = (None::<Instant>, 0, 0x2545F491u64);
    let (start, mut next_change) = (Instant::now(), 0.0);
    while start.elapsed().as_secs_f64() < seconds {
        let f0 = Instant::now();
        let now = start.elapsed().as_secs_f64();
        let idle = app.world().get::<DeformStatus>(e).unwrap().phase == DeformPhase::Idle;
        app.world_mut().resource_mut::<Timing>().released = now + 0.4 >= next_change;
        if now >= next_change && idle && changed.is_none() {
            next_change = now.floor() + 1.0;
            let mut vertices = Vec::new();
            while vertices.is_empty() {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let centre = tri.positions[(seed >> 33) as usize % tri.positions.len()];
                let r = 0.08 * diagonal as f64;
                vertices = (0..tri.positions.len() as u32)
                    .filter(|v| {
                        !held.contains(v) && tri.positions[*v as usize].distance(centre) < r
                    })
                    .collect();
            }
            let mut q = app
                .world_mut()
                .query_filtered::<(&mut DeformHandle, &mut Transform), With<Dragged>>();
            for (mut h, mut t) in q.iter_mut(app.world_mut()) {
                // A new set at rest: the plugin puts its pivot at the set's centroid.
                h.vertices = vertices.clone();
                h.pivot = None;
                *t = Transform::IDENTITY;
            }
            changed = Some(Instant::now());
            first.push(f64::NAN);
            whole.push(f64::NAN);
        }
        app.update();
        let done = app
            .world_mut()
            .resource_mut::<Messages<DeformSolved>>()
            .drain()
            .count();
        let status = app.world().get::<DeformStatus>(e).unwrap();
        if done > 0
            && let Some(t) = changed
        {
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let n = first.len() - 1;
            if first[n].is_nan() {
                first[n] = ms;
                previewed += status.preview as usize;
            }
            if !status.preview {
                whole[n] = ms;
                changed = None;
            }
        }
        pace(frame, f0);
    }
    let (mut first, mut whole): (Vec<f64>, Vec<f64>) = (
        first.into_iter().filter(|m| !m.is_nan()).collect(),
        whole.into_iter().filter(|m| !m.is_nan()).collect(),
    );
    first.sort_by(f64::total_cmp);
    whole.sort_by(f64::total_cmp);
    eprintln!("set change → first pose, ms ({previewed} previews): {first:.1?}");
    eprintln!("set change → first whole-mesh pose, ms: {whole:.1?}");
    let mut report = main_thread_report(app, e);
    report.extend(object(serde_json::json!({
        "set_changes": first.len(),
        "previews": previewed,
        "set_change_to_first_pose_ms_median": percentile(&first, 0.5),
        "set_change_to_first_pose_ms_p95": percentile(&first, 0.95),
        "set_change_to_whole_pose_ms_median": percentile(&whole, 0.5),
    })));
    println!("{}", serde_json::Value::Object(report));
}
