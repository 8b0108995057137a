//! `plugin_bench --dynamics`: the dragged mesh first solved statically (one iteration per
//! solve, as the plugin runs a drag), then with `DeformDynamics` (stepped in time), in one
//! run: the worker's time per step (the step's solve, its velocities, the pose for the mesh)
//! against its time per static one-iteration solve (the solve and the pose for the mesh).

use std::time::Instant;

use bevy::prelude::*;
use bevy_wii_deform::deform::TriMesh;
use bevy_wii_deform::prelude::*;

use std::time::Duration;

use crate::{Timing, main_thread_report, measure_frames, object, pace, percentile};

/// Drags the mesh `e` for `seconds` at `fps`: first half static (one-iteration solves, the
/// plugin's worker time per solve), then with `DeformDynamics` (its worker time per step);
/// prints the JSON line.
pub fn run(app: &mut App, e: Entity, tri: &TriMesh, iterations: u32, seconds: f64, fps: f64) {
    let _ = tri;
    wait_for_poses(app, e);
    // The static drag: the plugin's solves of one iteration, pose for the mesh included.
    let (_, mut solve_ms) = measure_frames(app, seconds / 2.0, fps);
    solve_ms.sort_by(f64::total_cmp);
    let ms_per_iteration = percentile(&solve_ms, 0.5);
    app.world_mut().entity_mut(e).insert(DeformDynamics {
        iterations,
        ..default()
    });
    let solves0 = app.world().get::<DeformStatus>(e).unwrap().solves;
    let setup = Instant::now();
    while app
        .world()
        .get::<DeformStatus>(e)
        .is_none_or(|s| s.solves == solves0)
    {
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(1));
        assert!(
            setup.elapsed().as_secs() < 120,
            "the dynamic factorization did not finish"
        );
    }
    let solves0 = app.world().get::<DeformStatus>(e).unwrap().solves;
    app.world_mut().resource_mut::<Timing>().measuring = true;
    let mut step_ms = Vec::new();
    let (start, frame) = (Instant::now(), Duration::from_secs_f64(1.0 / fps.max(1.0)));
    let mut seen = solves0;
    // Every frame; each batch that landed gives its milliseconds per step.
    while start.elapsed().as_secs_f64() < seconds / 2.0 {
        let f0 = Instant::now();
        app.update();
        let status = app.world().get::<DeformStatus>(e).unwrap();
        if status.solves != seen {
            seen = status.solves;
            step_ms.push(status.solve_ms);
        }
        pace(frame, f0);
    }
    let elapsed = start.elapsed().as_secs_f64();
    let status = app.world().get::<DeformStatus>(e).unwrap().clone();
    step_ms.sort_by(f64::total_cmp);
    let ms_per_step = percentile(&step_ms, 0.5);
    let mut report = main_thread_report(app, e);
    report.extend(object(serde_json::json!({
        "poses_per_s": (status.solves - solves0) as f64 / elapsed,
        "iterations_per_step": iterations,
        "ms_per_step": ms_per_step,
        "ms_per_static_iteration": ms_per_iteration,
        "dynamics_step_ratio": ms_per_step / ms_per_iteration,
    })));
    println!("{}", serde_json::Value::Object(report));
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
