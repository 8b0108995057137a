//! Crowd benchmark: N Foxes loaded through Bevy's glTF loader, each solved inside the frame
//! (`PoseInFrame`) with a position effector on each foot and paw whose target bobs every
//! frame — the feet-on-uneven-ground case of a game.
//!
//! ```text
//! cargo run --release --example crowd_bench -- [--characters N] [--frames F] [--iterations I] [--model PATH] [--playing] --json
//! ```
//! Defaults: 100 characters, 120 measured frames (after 20 warm-up frames), 3 iterations per
//! character and frame, `assets/models/Fox.glb`. Headless (no renderer). Without
//! `--playing` no animation plays; with it every character plays the file's first clip (each
//! at its own phase and speed) and the pose is an additive layer over it (`PoseBlend::additive`,
//! `PoseStiffness(0.3)`: the solve starts from and is held towards the animation of the
//! frame). The solver time of a frame is the wall time of `PoseSystems::Request` in `Update`
//! (the requests: with `PoseGround` the ground's casts, the contacts and the floor) plus that
//! of `PoseSystems::Apply` in `PostUpdate` (every in-frame solve of the frame, in parallel on
//! the compute pool, and the write to the joints). The last stdout line is one JSON object: `characters`,
//! `effectors_per_character`, `solver_ms_per_frame_median`, `solver_ms_per_frame_p95`,
//! `request_ms_per_frame_median` (the `Request` share, on the main thread),
//! `ms_per_solve` (median wall time of one character's solve), `frames`, `models_built` (the
//! characters share one model per asset: 1), `playing`, `peak_rss_mb` (the process's peak
//! resident memory) and `rss_growth_kb_per_frame` (resident memory from frame 500 — or half
//! the run, when shorter — to the end, per frame: flat under in-frame posing).
//!
//! `--springs` (`tail_springs.rs`): every Fox's tail on spring bones; adds `spring_chains`,
//! `spring_joints` (across the characters) and `spring_ms_per_frame_median` (the wall time of
//! `SpringSystems::Simulate`).
//!
//! `--terrain` (`walking_field.rs`): the characters stand on the crowd example's hilly,
//! terraced terrain mesh (`GroundMesh`; hills up to 30°, steps 10 units, about a third of the Fox's
//! leg) with `PoseGround` and `PoseBalance` instead of foot effectors, play the file's "Walk"
//! clip (its first clip without one) under an additive pose layer, face +X and walk along it
//! (40 units/s, the root kept on the ground under it by a cast), so their paws plant, lift
//! and plant again. Adds, measured on the pose on screen every frame: `penetration_max`
//! (deepest skinned vertex below the terrain, along the normal of the face above it, / size,
//! every 5th frame), `penetration_p90` and
//! `penetration_p99` (of each sampled character and frame's deepest vertex),
//! `sole_normal_error_deg_p95` (planted soles' bind-pose up, carried by the joint, against the
//! ground's normal), `soles_at_limit_share` (planted soles more than 3° off),
//! `planted_slide_max` and `planted_slide_p99` (largest motion of a planted patch's vertex
//! across its ground from one frame to the next / size, while held at the same points: a
//! patch released and planted again within a frame is a new plant), `com_supported_share` ((character, frame) pairs with the centre
//! of mass over the planted patches), `no_support_share` (pairs with nothing planted, counted
//! unsupported), `planted_per_character` (at the end), `replants` (plants after the first
//! stance, all characters) and `iterations_per_solve_mean` (each character's last solve each
//! frame: the budget, the iterations past it while skin is in the ground or a planted paw off
//! its holds, and the passes with the floor cast where the skin ended). Then the same crowd,
//! clip and frames again with no ground, contacts, floor or balance — as `--playing`, a
//! bobbing effector on each paw — in the same process: `solver_ms_per_frame_median_no_ground`,
//! and `ground_cost_ratio` (the grounded median over it).

use bevy_wii_deform_examples::cli;
use bevy_wii_deform_examples::headless_gltf;
use bevy_wii_deform_examples::springy_tails;
mod tail_springs;
use bevy_wii_deform_examples::terrain;
mod walking_field;

use std::time::{Duration, Instant};

use bevy::app::AnimationSystems;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::transform::TransformSystems;
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::prelude::*;

/// Command-line settings.
#[derive(Clone)]
struct Args {
    characters: usize,
    frames: usize,
    iterations: u32,
    model: String,
    playing: bool,
    /// `--terrain`: on the crowd example's terrain mesh, walking, standing by `PoseGround`.
    terrain: bool,
    /// `--springs`: every character's tail on spring bones.
    springs: bool,
}

const USAGE: &str = "\
usage: crowd_bench [--characters N] [--frames N] [--iterations N] [--model PATH] [--playing]
                   [--terrain] [--springs] [--json]

  --characters N  Foxes (default 100)
  --frames N      measured frames (default 120)
  --iterations N  solver iterations per frame (default 3)
  --model PATH    the rigged glTF (default assets/models/Fox.glb)
  --playing       each plays its clip; the pose is an additive layer over it
  --terrain       on a hilly, terraced terrain mesh (GroundMesh), walking, stood by PoseGround and
                  PoseBalance (no foot effectors)
  --springs       every tail on spring bones (SpringBones by name); adds the spring time
  --json          accepted for older command lines: the JSON is always the last line";

fn args() -> Args {
    let mut args = Args {
        characters: 100,
        frames: 120,
        iterations: 3,
        model: "assets/models/Fox.glb".into(),
        playing: false,
        terrain: false,
        springs: false,
    };
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Long("characters") => args.characters = cli::value(&mut parser, USAGE),
            cli::Arg::Long("frames") => args.frames = cli::value(&mut parser, USAGE),
            cli::Arg::Long("iterations") => args.iterations = cli::value(&mut parser, USAGE),
            cli::Arg::Long("model") => args.model = cli::string(&mut parser, USAGE),
            cli::Arg::Long("playing") => args.playing = true,
            cli::Arg::Long("terrain") => args.terrain = true,
            cli::Arg::Long("springs") => args.springs = true,
            cli::Arg::Long("json") => {}
            other => cli::unexpected(other, USAGE),
        }
    }
    args
}

/// When this frame's `PoseSystems::Request` and `Apply` started, and the measured durations,
/// ms.
#[derive(Resource, Default)]
struct SolverClock {
    started: Option<Instant>,
    frames_ms: Vec<f64>,
    measuring: bool,
    /// This frame's `PoseSystems::Request` (the requests, and the ground's casts, contacts and
    /// floor with `PoseGround`), added to the frame's solver time.
    request_started: Option<Instant>,
    request_ms: f64,
    /// `PoseSystems::Request`'s share of each measured frame (main thread).
    request_frames_ms: Vec<f64>,
}

/// A foot target: the effector entity, where it rests, and its phase.
#[derive(Component)]
struct Bob {
    rest: Vec3,
    phase: f32,
    amplitude: f32,
}

fn main() {
    let args = args();
    // On the terrain the characters walk: the file's "Walk" clip when it has one.
    let prefer = args.terrain.then_some("Walk");
    let mut report = run(&args, prefer);
    if args.terrain {
        // The same crowd, clip and frames with nothing under it — no ground, contacts, floor
        // or balance: `--playing`, a bobbing effector on each paw — side by side in this
        // process: the ground's price.
        let playing = Args {
            terrain: false,
            playing: true,
            ..args.clone()
        };
        let bare = run(&playing, prefer);
        let median = |r: &serde_json::Value| r["solver_ms_per_frame_median"].as_f64();
        let (with, without) = (median(&report), median(&bare));
        if let (Some(fields), Some(with), Some(without)) = (report.as_object_mut(), with, without) {
            fields.insert(
                "solver_ms_per_frame_median_no_ground".into(),
                without.into(),
            );
            fields.insert("ground_cost_ratio".into(), (with / without).into());
        }
    }
    println!("{report}");
}

/// One crowd run, playing the clip named `prefer` when the file has it.
fn run(args: &Args, prefer: Option<&str>) -> serde_json::Value {
    let path = std::path::Path::new(&args.model);
    let (Some(dir), Some(file)) = (path.parent(), path.file_name()) else {
        eprintln!("--model needs a file path");
        std::process::exit(2);
    };
    if !path.exists() {
        eprintln!("{} not found", path.display());
        std::process::exit(2);
    }
    // Bevy resolves a relative asset folder against the executable's; make it absolute.
    let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let mut app = headless_app(&dir, args.springs);
    let (scene, clip) = load_scene(&mut app, &file.to_string_lossy(), prefer);
    if args.playing && clip.is_none() {
        eprintln!("--playing: {} has no animation", path.display());
        std::process::exit(2);
    }
    let clip = clip.filter(|_| args.playing || args.terrain);
    let clip_playing = clip.is_some();
    let side = (args.characters as f32).sqrt().ceil() as usize;
    let mut field = args
        .terrain
        .then(|| walking_field::spawn(&mut app, side, args.frames));
    let roots: Vec<Entity> = (0..args.characters)
        .map(|k| {
            let mut at = Vec3::new((k % side) as f32, 0.0, (k / side) as f32) * 150.0;
            if let Some(field) = &field {
                at.y = field.height(at);
            }
            let mut fox = app.world_mut().spawn((
                WorldAssetRoot(scene.clone()),
                // On the terrain they face +X, the way they walk (the Fox faces +Z).
                Transform::from_translation(at).with_rotation(if field.is_some() {
                    Quat::from_rotation_y(std::f32::consts::FRAC_PI_2)
                } else {
                    Quat::IDENTITY
                }),
                Poseable {
                    max_iterations: args.iterations,
                    ..default()
                },
                PoseInFrame {
                    iterations: args.iterations,
                },
            ));
            if args.springs {
                fox.insert(springy_tails::tail_springs());
            }
            if field.is_some() {
                fox.insert((
                    PoseGround::default(),
                    PoseBalance::default(),
                    // A paw a step releases swings back under the body.
                    PoseStiffness(0.3),
                ));
            }
            fox.id()
        })
        .collect();
    let setup = Instant::now();
    while roots
        .iter()
        .any(|&r| app.world().get::<PosedSkeleton>(r).is_none())
    {
        if let Some(error) = roots
            .iter()
            .find_map(|&r| app.world().get::<PoseStatus>(r)?.error.clone())
        {
            eprintln!("a character cannot be posed: {error}");
            std::process::exit(1);
        }
        app.update();
        std::thread::sleep(Duration::from_millis(1));
        if setup.elapsed() > Duration::from_secs(300) {
            eprintln!("the characters never became poseable");
            std::process::exit(1);
        }
    }
    eprintln!(
        "{} characters prepared in {:.1} s",
        roots.len(),
        setup.elapsed().as_secs_f64()
    );
    if field.is_some() {
        // Walking from here on, every character from the same frame: how many updates the
        // loading took (it varies from run to run) does not move them.
        for &root in &roots {
            app.world_mut()
                .entity_mut(root)
                .insert(walking_field::Walker);
        }
    }
    if let Some(clip) = clip {
        play_clip_on_every_player(&mut app, clip, field.is_some());
        for &root in &roots {
            app.world_mut()
                .entity_mut(root)
                .insert((PoseBlend::additive(1.0), PoseStiffness(0.3)));
        }
    }
    let effectors = if field.is_some() {
        0
    } else {
        plant_feet(&mut app, &roots)
    };
    for _ in 0..20 {
        app.update();
    }
    {
        let mut clock = app.world_mut().resource_mut::<SolverClock>();
        clock.measuring = true;
        clock.frames_ms.reserve_exact(args.frames);
    }
    if args.springs {
        app.world_mut()
            .resource_mut::<tail_springs::SpringClock>()
            .measuring = true;
    }
    // Every character's solve time every frame, kept as a histogram: a list of them grew by
    // 800 bytes a frame for 100 characters (the growth the in-frame memory check found).
    let mut solve_ms = LogHistogram::default();
    // Resident memory from frame `from` to the end: flat when nothing grows per frame.
    let from = 500.min(args.frames / 2);
    let mut rss_from = None;
    for frame in 0..args.frames {
        if frame == from {
            rss_from = resident_kb();
        }
        app.update();
        for status in roots
            .iter()
            .filter_map(|&r| app.world().get::<PoseStatus>(r))
        {
            solve_ms.add(status.solve_ms);
        }
        if let Some(field) = field.as_mut() {
            field.sample(&app, &roots, frame % 5 == 0);
        }
    }
    let rss_growth_kb_per_frame = match (rss_from, resident_kb()) {
        (Some(a), Some(b)) if args.frames > from => {
            Some((b as f64 - a as f64) / (args.frames - from) as f64)
        }
        _ => None,
    };
    let ground_report = field.as_ref().map(|f| f.report(&app, &roots));
    let spring_report = args.springs.then(|| tail_springs::report(&mut app, &roots));
    let mut frames = std::mem::take(&mut app.world_mut().resource_mut::<SolverClock>().frames_ms);
    frames.sort_by(f64::total_cmp);
    let mut requests = std::mem::take(
        &mut app
            .world_mut()
            .resource_mut::<SolverClock>()
            .request_frames_ms,
    );
    requests.sort_by(f64::total_cmp);
    let pick = |v: &[f64], p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    let mut report = serde_json::json!({
            "characters": roots.len(),
            "effectors_per_character": effectors as f64 / roots.len() as f64,
            "solver_ms_per_frame_median": pick(&frames, 0.5),
            "solver_ms_per_frame_p95": pick(&frames, 0.95),
            "request_ms_per_frame_median": pick(&requests, 0.5),
            "ms_per_solve": solve_ms.quantile(0.5),
            "frames": frames.len(),
            "models_built": app.world().resource::<PoseModels>().built(),
            "playing": args.playing || (args.terrain && clip_playing),
            "peak_rss_mb": peak_resident_kb().map(|kb| kb as f64 / 1024.0),
            "rss_growth_kb_per_frame": rss_growth_kb_per_frame,
    });
    if let Some(fields) = report.as_object_mut() {
        fields.extend(ground_report.into_iter().flatten());
        fields.extend(spring_report.into_iter().flatten());
    }
    report
}

/// A histogram of positive durations on a log scale (0.1 µs to 10 s, 0.23 % wide bins):
/// quantiles within a quarter of a percent, in constant memory however long the run.
struct LogHistogram {
    counts: Vec<u64>,
    total: u64,
}

impl LogHistogram {
    const LOW_MS: f64 = 1e-4;
    const PER_DECADE: f64 = 1000.0;
    const DECADES: f64 = 8.0;

    fn add(&mut self, ms: f64) {
        if !ms.is_finite() {
            return;
        }
        let bin = ((ms.max(Self::LOW_MS) / Self::LOW_MS).log10() * Self::PER_DECADE) as usize;
        let last = self.counts.len() - 1;
        self.counts[bin.min(last)] += 1;
        self.total += 1;
    }

    /// The `q` quantile (the centre of its bin), 0 when empty.
    fn quantile(&self, q: f64) -> f64 {
        let rank = ((self.total.max(1) - 1) as f64 * q).round() as u64;
        let mut seen = 0;
        for (bin, &count) in self.counts.iter().enumerate() {
            seen += count;
            if seen > rank {
                return Self::LOW_MS * 10f64.powf((bin as f64 + 0.5) / Self::PER_DECADE);
            }
        }
        0.0
    }
}

impl Default for LogHistogram {
    fn default() -> Self {
        Self {
            counts: vec![0; (Self::PER_DECADE * Self::DECADES) as usize + 1],
            total: 0,
        }
    }
}

/// A field of `/proc/self/status`, in kB (Linux; `None` elsewhere).
fn proc_status_kb(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Resident memory now, kB.
fn resident_kb() -> Option<u64> {
    proc_status_kb("VmRSS:")
}

/// Peak resident memory, kB.
fn peak_resident_kb() -> Option<u64> {
    proc_status_kb("VmHWM:")
}

/// Loads the whole file (no materials: nothing is drawn) and returns its first scene and its
/// first clip, if it has one.
/// Loads `file`'s first scene and its clip named `prefer` (or its first clip).
fn load_scene(
    app: &mut App,
    file: &str,
    prefer: Option<&str>,
) -> (Handle<WorldAsset>, Option<Handle<AnimationClip>>) {
    let gltf = headless_gltf::load_gltf_without_materials(app, file);
    let start = Instant::now();
    loop {
        app.update();
        if let Some(loaded) = app
            .world()
            .resource::<Assets<bevy::gltf::Gltf>>()
            .get(&gltf)
        {
            let scene = loaded.scenes[0].clone();
            let clip = prefer
                .and_then(|name| loaded.named_animations.get(name))
                .or(loaded.animations.first())
                .cloned();
            app.insert_resource(KeepLoaded(gltf));
            return (scene, clip);
        }
        if start.elapsed() > Duration::from_secs(60) {
            eprintln!("{file} did not load");
            std::process::exit(1);
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Keeps the loaded file alive.
#[derive(Resource)]
struct KeepLoaded(#[allow(dead_code)] Handle<bevy::gltf::Gltf>);

/// A headless app that loads glTF scenes and poses characters, time stepped 16 ms a frame.
fn headless_app(dir: &std::path::Path, springs: bool) -> App {
    let mut app = App::new();
    // Two threads for the compute pool on a two-core machine (Bevy's default gives it what IO
    // and async compute leave: one): in-frame solves run on it, when those pools are idle.
    app.add_plugins(MinimalPlugins.set(bevy::app::TaskPoolPlugin {
        task_pool_options: bevy::app::TaskPoolOptions::with_num_threads(
            bevy::tasks::available_parallelism().max(2) + 2,
        ),
    }));
    headless_gltf::add_gltf_plugins(&mut app, dir);
    app.add_plugins(PosePlugin)
        .init_asset::<StandardMaterial>()
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
            16,
        )))
        .init_resource::<SolverClock>()
        .add_systems(
            PostUpdate,
            (
                start_clock
                    .after(AnimationSystems)
                    .before(PoseSystems::Apply),
                stop_clock
                    .after(PoseSystems::Apply)
                    .before(bevy_wii_deform::ecs::SpringSystems::Simulate)
                    .before(TransformSystems::Propagate),
            ),
        )
        .add_systems(
            Update,
            (
                bob_targets.before(PoseSystems::Request),
                start_request_clock
                    .after(bob_targets)
                    .before(PoseSystems::Request),
                stop_request_clock.after(PoseSystems::Request),
            ),
        );
    if springs {
        tail_springs::add(&mut app);
    }
    app.finish();
    app.cleanup();
    app
}

fn start_clock(mut clock: ResMut<SolverClock>) {
    clock.started = Some(Instant::now());
}

fn stop_clock(mut clock: ResMut<SolverClock>) {
    if let (true, Some(t0)) = (clock.measuring, clock.started) {
        let ms = t0.elapsed().as_secs_f64() * 1e3 + clock.request_ms;
        clock.frames_ms.push(ms);
        let request = clock.request_ms;
        clock.request_frames_ms.push(request);
    }
    clock.request_ms = 0.0;
}

fn start_request_clock(mut clock: ResMut<SolverClock>) {
    clock.request_started = Some(Instant::now());
}

fn stop_request_clock(mut clock: ResMut<SolverClock>) {
    if let Some(t0) = clock.request_started.take() {
        clock.request_ms = t0.elapsed().as_secs_f64() * 1e3;
    }
}

/// Every animation player plays `clip` on repeat, each from its own phase (as the crowd
/// example does), at its own speed (0.8–1.2) or, with
/// `same_speed` (walkers moved at one speed), at the clip's.
fn play_clip_on_every_player(app: &mut App, clip: Handle<AnimationClip>, same_speed: bool) {
    let (graph, node) = AnimationGraph::from_clip(clip);
    let graph = app
        .world_mut()
        .resource_mut::<Assets<AnimationGraph>>()
        .add(graph);
    let world = app.world_mut();
    let players: Vec<Entity> = world
        .query_filtered::<Entity, With<AnimationPlayer>>()
        .iter(world)
        .collect();
    for (k, player) in players.into_iter().enumerate() {
        let k = k as f32;
        let mut entity = world.entity_mut(player);
        entity.insert(AnimationGraphHandle(graph.clone()));
        entity
            .get_mut::<AnimationPlayer>()
            .expect("queried")
            .play(node)
            .repeat()
            .seek_to((k * 0.731).fract() * 3.0)
            .set_speed(if same_speed {
                1.0
            } else {
                0.8 + 0.4 * (k * 0.377).fract()
            });
    }
}

/// Moves every foot target up and down (a few per cent of the character's size) each frame.
fn bob_targets(time: Res<Time>, mut targets: Query<(&Bob, &mut Transform)>) {
    let t = time.elapsed_secs();
    for (bob, mut transform) in &mut targets {
        transform.translation = bob.rest + Vec3::Y * bob.amplitude * (2.0 * t + bob.phase).sin();
    }
}

/// A position effector on every joint within 4 % of a character's size above its lowest
/// joint (a quadruped's feet and paws), at where it is now; returns how many.
fn plant_feet(app: &mut App, roots: &[Entity]) -> usize {
    let mut count = 0;
    for (k, &root) in roots.iter().enumerate() {
        let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
        let size = posed.model.topology().bounding_diagonal() as f32;
        for joint in posed.lowest_joints(0.04) {
            let p = app
                .world()
                .get::<GlobalTransform>(joint)
                .unwrap()
                .translation();
            app.world_mut().spawn((
                PoseEffector::position(root, joint),
                Transform::from_translation(p),
                Bob {
                    rest: p,
                    phase: k as f32 * 0.7 + count as f32,
                    amplitude: 0.03 * size,
                },
            ));
            count += 1;
        }
    }
    count
}
