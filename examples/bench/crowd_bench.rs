//! Crowd benchmark: N Foxes loaded through Bevy's glTF loader, each solved inside the frame
//! (`PoseInFrame`) with a position effector on each foot and paw whose target bobs every
//! frame — the feet-on-uneven-ground case of a game.
//!
//! ```text
//! cargo run --release --example crowd_bench -- [--characters N] [--frames F] [--iterations I] [--model PATH] [--playing] --json
//! ```
//! Defaults: 100 characters, 120 measured frames (after 20 warm-up frames), 3 iterations per
//! character and frame, `../shared/models/Fox.glb`. Headless (no renderer). Without
//! `--playing` no animation plays; with it every character plays the file's first clip (each
//! at its own phase and speed) and the pose is an additive layer over it (`PoseBlend::additive`,
//! `PoseStiffness(0.3)`: the solve starts from and is held towards the animation of the frame). The solver time of a frame is the wall time of `PoseSystems::Apply` in
//! `PostUpdate` (every in-frame solve of the frame, in parallel on the compute pool, and the
//! write to the joints). The last stdout line is one JSON object: `characters`,
//! `effectors_per_character`, `solver_ms_per_frame_median`, `solver_ms_per_frame_p95`,
//! `ms_per_solve` (median wall time of one character's solve), `frames`, `models_built` (the
//! characters share one model per asset: 1), `playing`.

#[path = "../common/headless_gltf.rs"]
mod headless_gltf;

use std::time::{Duration, Instant};

use bevy::app::AnimationSystems;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::transform::TransformSystems;
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::prelude::*;

/// Command-line settings.
struct Args {
    characters: usize,
    frames: usize,
    iterations: u32,
    model: String,
    playing: bool,
}

fn args() -> Args {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    Args {
        characters: value("--characters")
            .and_then(|v| v.parse().ok())
            .unwrap_or(100),
        frames: value("--frames")
            .and_then(|v| v.parse().ok())
            .unwrap_or(120),
        iterations: value("--iterations")
            .and_then(|v| v.parse().ok())
            .unwrap_or(3),
        model: value("--model").unwrap_or_else(|| "../shared/models/Fox.glb".into()),
        playing: args.iter().any(|a| a == "--playing"),
    }
}

/// When this frame's `PoseSystems::Apply` started, and the measured durations, ms.
#[derive(Resource, Default)]
struct SolverClock {
    started: Option<Instant>,
    frames_ms: Vec<f64>,
    measuring: bool,
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
    let mut app = headless_app(&dir);
    let (scene, clip) = load_scene(&mut app, &file.to_string_lossy());
    if args.playing && clip.is_none() {
        eprintln!("--playing: {} has no animation", path.display());
        std::process::exit(2);
    }
    let clip = clip.filter(|_| args.playing);
    let side = (args.characters as f32).sqrt().ceil() as usize;
    let roots: Vec<Entity> = (0..args.characters)
        .map(|k| {
            let at = Vec3::new((k % side) as f32, 0.0, (k / side) as f32) * 150.0;
            app.world_mut()
                .spawn((
                    WorldAssetRoot(scene.clone()),
                    Transform::from_translation(at),
                    Poseable {
                        max_iterations: args.iterations,
                        ..default()
                    },
                    PoseInFrame {
                        iterations: args.iterations,
                    },
                ))
                .id()
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
    if let Some(clip) = clip {
        play_clip_on_every_player(&mut app, clip);
        for &root in &roots {
            app.world_mut()
                .entity_mut(root)
                .insert((PoseBlend::additive(1.0), PoseStiffness(0.3)));
        }
    }
    let effectors = plant_feet(&mut app, &roots);
    for _ in 0..20 {
        app.update();
    }
    app.world_mut().resource_mut::<SolverClock>().measuring = true;
    let mut solve_ms = Vec::new();
    for _ in 0..args.frames {
        app.update();
        solve_ms.extend(
            roots
                .iter()
                .filter_map(|&r| app.world().get::<PoseStatus>(r))
                .map(|s| s.solve_ms),
        );
    }
    let mut frames = std::mem::take(&mut app.world_mut().resource_mut::<SolverClock>().frames_ms);
    frames.sort_by(f64::total_cmp);
    solve_ms.sort_by(f64::total_cmp);
    let pick = |v: &[f64], p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    println!(
        "{}",
        serde_json::json!({
            "characters": roots.len(),
            "effectors_per_character": effectors as f64 / roots.len() as f64,
            "solver_ms_per_frame_median": pick(&frames, 0.5),
            "solver_ms_per_frame_p95": pick(&frames, 0.95),
            "ms_per_solve": pick(&solve_ms, 0.5),
            "frames": frames.len(),
            "models_built": app.world().resource::<PoseModels>().built(),
            "playing": args.playing,
        })
    );
}

/// Loads the whole file (no materials: nothing is drawn) and returns its first scene and its
/// first clip, if it has one.
fn load_scene(app: &mut App, file: &str) -> (Handle<WorldAsset>, Option<Handle<AnimationClip>>) {
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
            let clip = loaded.animations.first().cloned();
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
fn headless_app(dir: &std::path::Path) -> App {
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
                    .before(TransformSystems::Propagate),
            ),
        )
        .add_systems(Update, bob_targets.before(PoseSystems::Request));
    app.finish();
    app.cleanup();
    app
}

fn start_clock(mut clock: ResMut<SolverClock>) {
    clock.started = Some(Instant::now());
}

fn stop_clock(mut clock: ResMut<SolverClock>) {
    if let (true, Some(t0)) = (clock.measuring, clock.started) {
        clock.frames_ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
}

/// Every animation player plays `clip` on repeat, each from its own phase at its own speed
/// (as the crowd example does).
fn play_clip_on_every_player(app: &mut App, clip: Handle<AnimationClip>) {
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
            .set_speed(0.8 + 0.4 * (k * 0.377).fract());
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
