//! `plugin_bench --dynamics`: the dragged mesh solved statically (one iteration per solve, as
//! the plugin runs a drag) and with `DeformDynamics` (stepped in time), in four alternating
//! rounds of one run: the worker's time per step (the step's solve, its velocities, the pose
//! for the mesh) against its time per static one-iteration solve (the solve and the pose).

use std::time::Instant;

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use std::time::Duration;

use crate::{Timing, main_thread_report, measure_frames, object, pace, percentile};

/// Drags the mesh `e` for `seconds` at `fps`, alternating four times between static solves
/// (one iteration each, the plugin's worker time per solve) and `DeformDynamics` (its worker
/// time per step), so that the machine's drift falls on both alike; prints the JSON line.
pub fn run(app: &mut App, e: Entity, iterations: u32, seconds: f64, fps: f64) {
    wait_for_poses(app, e);
    let dynamics = DeformDynamics {
        iterations,
        ..default()
    };
    let (mut static_ms, mut step_ms) = (Vec::new(), Vec::new());
    let (mut poses, mut dynamic_s, mut main_ms) = (0u64, 0.0, Vec::new());
    let phase = seconds / 8.0;
    for _ in 0..4 {
        // Static: the plugin's solves of one iteration, pose for the mesh included.
        app.world_mut().entity_mut(e).remove::<DeformDynamics>();
        let (_, solve_ms) = measure_frames(app, phase, fps);
        static_ms.extend(solve_ms);
        // Dynamic: from the first step that lands (the factorization is kept between
        // rounds), every landed batch's milliseconds per step.
        app.world_mut().entity_mut(e).insert(dynamics);
        let before = solves(app, e);
        let wait = Instant::now();
        while solves(app, e) == before {
            app.update();
            std::thread::sleep(Duration::from_millis(1));
            assert!(
                wait.elapsed().as_secs() < 120,
                "the dynamic factorization did not finish"
            );
        }
        let (start, frame) = (Instant::now(), Duration::from_secs_f64(1.0 / fps.max(1.0)));
        let mut seen = solves(app, e);
        let first = seen;
        let from = app.world().resource::<Timing>().frames_ms.len();
        while start.elapsed().as_secs_f64() < phase {
            let f0 = Instant::now();
            app.update();
            let status = app.world().get::<DeformStatus>(e).unwrap();
            if status.solves != seen {
                seen = status.solves;
                step_ms.push(status.solve_ms);
            }
            pace(frame, f0);
        }
        poses += seen - first;
        dynamic_s += start.elapsed().as_secs_f64();
        main_ms.extend_from_slice(&app.world().resource::<Timing>().frames_ms[from..]);
    }
    main_ms.sort_by(f64::total_cmp);
    static_ms.sort_by(f64::total_cmp);
    step_ms.sort_by(f64::total_cmp);
    let (ms_per_iteration, ms_per_step) = (percentile(&static_ms, 0.5), percentile(&step_ms, 0.5));
    // The main thread's time in the plugin's systems, in the dynamic rounds.
    let mut report = main_thread_report(app, e);
    report.extend(object(serde_json::json!({
        "frames": main_ms.len(),
        "main_ms_median": percentile(&main_ms, 0.5),
        "main_ms_p99": percentile(&main_ms, 0.99),
        "poses_per_s": poses as f64 / dynamic_s,
        "iterations_per_step": iterations,
        "ms_per_step": ms_per_step,
        "ms_per_static_iteration": ms_per_iteration,
        "dynamics_step_ratio": ms_per_step / ms_per_iteration,
    })));
    println!("{}", serde_json::Value::Object(report));
}

fn solves(app: &App, e: Entity) -> u64 {
    app.world().get::<DeformStatus>(e).map_or(0, |s| s.solves)
}

/// Updates until the mesh's first pose is written (topology, factorization, first solve).
fn wait_for_poses(app: &mut App, e: Entity) {
    let setup = Instant::now();
    while app
        .world()
        .get::<DeformStatus>(e)
        .is_none_or(|s| s.solves == 0)
    {
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(1));
        assert!(setup.elapsed().as_secs() < 120, "set-up did not finish");
    }
}
