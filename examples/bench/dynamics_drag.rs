//! `plugin_bench --dynamics`: the dragged mesh with `DeformDynamics` (stepped in time); its
//! time per step (everything the plugin runs for one: the step's solve, its velocities, the
//! pose for the mesh) against a static ARAP iteration of the same mesh and constraints as a
//! drag runs it (a one-iteration warm solve after a small handle move), measured in the same
//! run.

use std::time::Instant;

use bevy::prelude::*;
use bevy_wii_deform::deform::{
    Acceleration, ArapSolver, Constraints, InitialGuess, SolveOptions, SolverSettings, Topology,
    TriMesh, synth,
};
use bevy_wii_deform::prelude::*;

use crate::{main_thread_report, measure_frames, object, percentile};

/// Drags the dynamic mesh `e` for `seconds` at `fps`; prints the JSON line.
pub fn run(app: &mut App, e: Entity, tri: &TriMesh, iterations: u32, seconds: f64, fps: f64) {
    app.world_mut().entity_mut(e).insert(DeformDynamics {
        iterations,
        ..default()
    });
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
    let solves0 = app.world().get::<DeformStatus>(e).unwrap().solves;
    let mut step_ms = Vec::new();
    let start = Instant::now();
    // The frames, with every landed batch's milliseconds per step.
    while start.elapsed().as_secs_f64() < seconds {
        let (_, _) = measure_frames(app, (seconds / 20.0).max(0.05), fps);
        if let Some(s) = app.world().get::<DeformStatus>(e) {
            step_ms.push(s.solve_ms);
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let status = app.world().get::<DeformStatus>(e).unwrap().clone();
    step_ms.sort_by(f64::total_cmp);
    let ms_per_step = percentile(&step_ms, 0.5);
    let ms_per_iteration = static_iteration_ms(tri);
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

/// Milliseconds of one plain static ARAP iteration on `tri`, held and dragged as the bench
/// does: a one-iteration solve warm-started from the last while the handle moves a little
/// every time (a drag's frame, the static plugin's unit of work), median of 30.
fn static_iteration_ms(tri: &TriMesh) -> f64 {
    let topology = std::sync::Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
    let (fixed, handle) = synth::slab_regions(topology.positions(), 1, 0.1, 0.1);
    let mut constraints = Constraints::with_handle(fixed, handle, Default::default());
    let solver =
        ArapSolver::precompute(topology.clone(), &constraints, SolverSettings::default()).unwrap();
    let options = SolveOptions {
        max_iterations: 1,
        tolerance: 0.0,
        acceleration: Acceleration::None,
    };
    let mut last = solver
        .solve(&constraints, &options, InitialGuess::Rest, &|| false)
        .unwrap();
    let diagonal = topology.bounding_diagonal();
    let mut ms: Vec<f64> = (0..30)
        .map(|k| {
            constraints.handles[0].transform.translation.x = 0.002 * diagonal * k as f64;
            let t0 = Instant::now();
            last = solver
                .solve(&constraints, &options, InitialGuess::Warm(&last), &|| false)
                .unwrap();
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    ms[15]
}
