//! Plugin benchmark: a headless app in which a handle is dragged every frame; measures the
//! main-thread time spent in the plugin's systems and completed solves per second.
//!
//! ```text
//! cargo run --release --example plugin_bench -- [--mesh PATH | --bar VERTICES] [--seconds 5] [--iterations 1] [--fps 120] [--grab] [--plain] --json
//! ```
//! Default mesh: ../shared/meshes/armadillo.off (26k vertices), else a 26k-vertex bar.
//! `--plain`: the plugin with plain local/global iterations and no settling (default: L-BFGS
//! while dragging, Newton settling after).
//! Last stdout line: `{"vertices": N, "frames": F, "main_ms_median": x, "main_ms_p99": y, "solves_per_s": z}`.
//! `--grab`: no fixed region; a new pointer grab (`GrabStart`, patch radius 3 % and region 30 %
//! of the bounding-box diagonal) every second at a pseudo-random vertex, its handle dragged in
//! between; adds `grab_to_first_pose_ms_median` / `_p95` (press → first written pose, which
//! includes re-preparing the rest pose from the current one and factorizing the region).

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_wii_deform::deform::{TriMesh, synth};
use bevy_wii_deform::prelude::*;

#[derive(Resource, Default)]
struct Timing {
    start: Option<Instant>,
    frames_ms: Vec<f64>,
    measuring: bool,
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

/// Bounding-box diagonal of the benchmark mesh.
#[derive(Resource)]
struct Diagonal(f32);

fn drag(time: Res<Time>, timing: Res<Timing>, mut q: Query<&mut Transform, With<Dragged>>) {
    if !timing.measuring {
        return;
    }
    let t = time.elapsed_secs();
    for mut tr in &mut q {
        tr.rotation = Quat::from_rotation_z(0.6 * (t * 0.7).sin())
            * Quat::from_rotation_x(0.3 * (t * 0.5).sin());
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let seconds: f64 = arg("--seconds").and_then(|v| v.parse().ok()).unwrap_or(5.0);
    let iterations: u32 = arg("--iterations")
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    // Frame rate of the simulated game (the handle moves every frame).
    let fps: f64 = arg("--fps").and_then(|v| v.parse().ok()).unwrap_or(120.0);
    let tri = if let Some(path) = arg("--mesh") {
        TriMesh::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    } else if let Some(n) = arg("--bar").and_then(|v| v.parse().ok()) {
        synth::bar_with_vertices(n)
    } else {
        TriMesh::read("../shared/meshes/armadillo.off").unwrap_or_else(|_| {
            eprintln!("../shared/meshes/armadillo.off absent: using a 26k-vertex bar");
            synth::bar_with_vertices(26_002)
        })
    };
    // `--plain`: plain local/global and no settling (the plugin before L-BFGS), for side-by-side
    // comparisons.
    let deform_plugin = match args.iter().any(|a| a == "--plain") {
        true => DeformPlugin {
            acceleration: bevy_wii_deform::deform::Acceleration::None,
            settle_iterations: 0,
            ..default()
        },
        false => DeformPlugin::default(),
    };
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
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
    let grab = args.iter().any(|a| a == "--grab");
    if grab {
        app.add_plugins(GrabPlugin);
    }
    app.finish();
    app.cleanup();
    let diagonal = bevy_wii_deform::deform::Topology::new(&tri.positions, &tri.triangles)
        .map(|t| t.bounding_diagonal() as f32)
        .unwrap_or(1.0);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let (fixed, handle) = synth::slab_regions(&tri.positions, 1, 0.1, 0.1);
    let bundle_src = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
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
        app.world_mut()
            .spawn((Mesh3d(h), deformable, grabbable))
            .id()
    } else {
        let e = app
            .world_mut()
            .spawn((Mesh3d(h), deformable, FixedRegion(fixed)))
            .id();
        let (handle, transform) = DeformHandle::bundle(&bundle_src, e, handle);
        app.world_mut().spawn((handle, transform, Dragged));
        e
    };
    if grab {
        return run_grabs(&mut app, e, &tri, seconds, fps);
    }
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
    app.world_mut().resource_mut::<Timing>().measuring = true;
    let start = Instant::now();
    let frame = Duration::from_secs_f64(1.0 / fps.max(1.0));
    while start.elapsed().as_secs_f64() < seconds {
        let f0 = Instant::now();
        app.update();
        if let Some(rest) = frame.checked_sub(f0.elapsed()) {
            std::thread::sleep(rest);
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let status = app.world().get::<DeformStatus>(e).unwrap().clone();
    let mut ms = app.world().resource::<Timing>().frames_ms.clone();
    ms.sort_by(f64::total_cmp);
    let pct = |p: f64| ms[((ms.len() - 1) as f64 * p).round() as usize];
    eprintln!(
        "last solve: {} iterations, energy {:.5}, {:.2} ms",
        status.iterations, status.energy, status.solve_ms
    );
    println!(
        "{}",
        serde_json::json!({
            "vertices": status.vertices,
            "frames": ms.len(),
            "main_ms_median": pct(0.5),
            "main_ms_p99": pct(0.99),
            "solves_per_s": (status.solves - solves0) as f64 / elapsed,
        })
    );
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
        if let Some(rest) = frame.checked_sub(f0.elapsed()) {
            std::thread::sleep(rest);
        }
    }
    let mut ms = app.world().resource::<Timing>().frames_ms.clone();
    ms.sort_by(f64::total_cmp);
    latencies.sort_by(f64::total_cmp);
    let pct = |v: &[f64], p: f64| {
        v.get(((v.len().max(1) - 1) as f64 * p).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    eprintln!("grab → first pose, ms: {latencies:.1?}");
    eprintln!(
        "of which the first solve on the worker (factorization of the region + iterations), ms: {worker_ms:.1?}"
    );
    println!(
        "{}",
        serde_json::json!({
            "vertices": app.world().get::<DeformStatus>(e).unwrap().vertices,
            "frames": ms.len(),
            "main_ms_median": pct(&ms, 0.5),
            "main_ms_p99": pct(&ms, 0.99),
            "solves_per_s": solves as f64 / start.elapsed().as_secs_f64(),
            "grabs": latencies.len(),
            "grab_to_first_pose_ms_median": pct(&latencies, 0.5),
            "grab_to_first_pose_ms_p95": pct(&latencies, 0.95),
        })
    );
}
