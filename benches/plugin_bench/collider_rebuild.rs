//! `plugin_bench --collider` (feature `avian`): a plank of about 10k triangles, a static Avian
//! body with `DeformCollider`, bent by its middle for 0.3 s then let settle, again and again;
//! counts the frames from a settled solve to its collider swapped in, and the main thread's
//! time in the deform and collider systems (and the whole frame, Avian's step included): over
//! every frame (`main_ms_*`), and over the frames that start a collider build or swap one in
//! (`collider_main_ms_max`); then, for as long, how late a thread that only sleeps wakes
//! (`idle_wake_late_ms_*`: the machine's floor under `main_ms_max`).

use std::time::{Duration, Instant};

use avian3d::prelude::*;
use bevy::prelude::*;
use bevy_wii_deform::deform::synth;
use bevy_wii_deform::ecs::physics::{
    DeformCollider, DeformColliderStatus, DeformPhysicsPlugin, DeformPhysicsSystems,
};
use bevy_wii_deform::prelude::*;

use crate::{
    Timing, object, pace, percentile, single_threaded_update, start_timer, stop_timer,
    update_executor,
};

/// Runs the collider benchmark for `seconds` at `fps` (with `Update` on the single-threaded
/// executor when asked); prints its JSON line.
pub fn run(seconds: f64, fps: f64, single_threaded: bool) {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::asset::AssetPlugin::default(),
        bevy::mesh::MeshPlugin,
        bevy::transform::TransformPlugin,
        PhysicsPlugins::default(),
        DeformPlugin::default(),
        DeformPhysicsPlugin,
    ))
    .init_resource::<Timing>()
    .add_systems(Update, start_timer.before(DeformSystems::Prepare))
    .add_systems(Update, stop_timer.after(DeformPhysicsSystems::Rebuild));
    if single_threaded {
        single_threaded_update(&mut app);
    }
    let executor = update_executor(&app);
    app.finish();
    app.cleanup();
    // ~10k triangles: a bar of ~5k vertices.
    let tri = synth::bar_with_vertices(5000);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let collider = Collider::trimesh_from_mesh(&mesh).expect("a closed bar");
    let (fixed, _) = synth::slab_regions(&tri.positions, 1, 0.1, 0.1);
    let middle: Vec<u32> = (0..tri.positions.len() as u32)
        .filter(|&v| (tri.positions[v as usize].y - 0.5).abs() < 0.03)
        .collect();
    let bundle = DeformHandle::bundle(&mesh, Entity::PLACEHOLDER, middle);
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let plank = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Deformable::default(),
            FixedRegion(fixed),
            RigidBody::Static,
            collider,
            DeformCollider::default(),
        ))
        .id();
    let (mut handle, rest) = bundle;
    handle.target = plank;
    let handle = app.world_mut().spawn((handle, rest)).id();
    // Set-up (topology, factorization, the first solve and collider) is not measured.
    let setup = Instant::now();
    while app
        .world()
        .get::<DeformColliderStatus>(plank)
        .is_none_or(|s| s.rebuilds == 0)
    {
        app.update();
        std::thread::sleep(Duration::from_millis(1));
        assert!(
            setup.elapsed() < Duration::from_secs(120),
            "set-up did not finish"
        );
    }
    app.world_mut().resource_mut::<Timing>().measuring = true;

    let frame = Duration::from_secs_f64(1.0 / fps.max(1.0));
    let (mut frame_ms, mut to_collider) = (Vec::new(), Vec::new());
    // The main thread's time in the frames that started a build or swapped a collider in.
    let mut collider_main_ms: Vec<f64> = Vec::new();
    let main_ms_now = |app: &App| {
        let timing = app.world().resource::<Timing>();
        timing.frames_ms.last().copied().unwrap_or(f64::NAN)
    };
    let mut settled_at: Option<(u64, u32)> = None;
    let (start, mut n) = (Instant::now(), 0u32);
    let rebuilds0 = rebuilds(&app, plank);
    while start.elapsed().as_secs_f64() < seconds {
        n += 1;
        // Bend for 0.3 s of every second, then let it settle.
        let t = start.elapsed().as_secs_f64();
        if t.fract() < 0.3 {
            let phase = (t.floor() as f32) * 0.7;
            app.world_mut()
                .get_mut::<Transform>(handle)
                .unwrap()
                .translation = rest.translation
                + Vec3::new(0.1 * phase.cos(), 0.0, 0.1 * phase.sin()) * (t.fract() as f32 / 0.3);
        }
        let f0 = Instant::now();
        app.update();
        frame_ms.push(f0.elapsed().as_secs_f64() * 1e3);
        let status = app.world().get::<DeformStatus>(plank).unwrap();
        let built = app.world().get::<DeformColliderStatus>(plank).unwrap();
        if status.phase == DeformPhase::Idle
            && status.solves > built.built_from_solve
            && settled_at.is_none_or(|(s, _)| s != status.solves)
        {
            // The build of this settled solve started in this frame.
            settled_at = Some((status.solves, n));
            collider_main_ms.push(main_ms_now(&app));
        }
        if let Some((solve, at)) = settled_at
            && built.built_from_solve == solve
        {
            to_collider.push(f64::from(n - at));
            collider_main_ms.push(main_ms_now(&app));
            settled_at = None;
        }
        pace(frame, f0);
    }
    let rebuilt = rebuilds(&app, plank) - rebuilds0;
    let timing = app
        .world_mut()
        .remove_resource::<Timing>()
        .unwrap_or_default();
    drop(app);
    let late = idle_wake_lateness(seconds);
    let mut main_ms = timing.frames_ms;
    main_ms.sort_by(f64::total_cmp);
    frame_ms.sort_by(f64::total_cmp);
    to_collider.sort_by(f64::total_cmp);
    let report = object(serde_json::json!({
        "triangles": tri.triangles.len(),
        "frames": n,
        "update_executor": executor,
        "rebuilds": rebuilt,
        "collider_frames_median": percentile(&to_collider, 0.5),
        "collider_frames_max": to_collider.last().copied().unwrap_or(f64::NAN),
        "main_ms_median": percentile(&main_ms, 0.5),
        "main_ms_p99": percentile(&main_ms, 0.99),
        "main_ms_max": main_ms.last().copied().unwrap_or(f64::NAN),
        "collider_main_ms_max": collider_main_ms.iter().copied().fold(f64::NAN, f64::max),
        "frame_ms_median": percentile(&frame_ms, 0.5),
        "frame_ms_max": frame_ms.last().copied().unwrap_or(f64::NAN),
        "idle_wake_late_ms_p99": percentile(&late, 0.99),
        "idle_wake_late_ms_max": late.last().copied().unwrap_or(f64::NAN),
        "idle_wakes_late_over_1ms": late.iter().filter(|l| **l > 1.0).count(),
    }));
    println!("{}", serde_json::Value::Object(report));
}

fn rebuilds(app: &App, plank: Entity) -> u64 {
    app.world()
        .get::<DeformColliderStatus>(plank)
        .map_or(0, |s| s.rebuilds)
}

/// The machine's own scheduling noise, measured after the run for as long with nothing else
/// of the app left: how late (ms, sorted) a thread that only sleeps 1 ms at a time wakes. A
/// core held by the kernel's own threads for a few ms delays any thread woken on it, the
/// frame's systems included: `main_ms_max` cannot be reliably below this.
fn idle_wake_lateness(seconds: f64) -> Vec<f64> {
    let nap = Duration::from_millis(1);
    let start = Instant::now();
    let mut late = Vec::new();
    while start.elapsed().as_secs_f64() < seconds {
        let t = Instant::now();
        std::thread::sleep(nap);
        late.push((t.elapsed().saturating_sub(nap)).as_secs_f64() * 1e3);
    }
    late.sort_by(f64::total_cmp);
    late
}
