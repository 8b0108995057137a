//! Bends that wobble: a released bar overshoots and rings down to its rest; critically damped
//! it does not overshoot; hitches and frame rates do not change it.

use std::sync::Arc;

use bevy_wii_deform::deform::*;
use glam::DVec3;

const NEVER: &dyn Fn() -> bool = &|| false;

/// A bar (length 1, radius 0.1) held at its bottom tenth, bent by its top tenth pushed 0.3
/// along +X: the topology, the held-only constraints and the bent pose.
fn bent_bar() -> (Arc<Topology>, Constraints, Vec<u32>, Solution) {
    let mesh = synth::bar(12, 30, 0.1, 1.0);
    let topology = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap());
    let (fixed, top) = synth::slab_regions(topology.positions(), 1, 0.1, 0.1);
    let mut bend = Constraints::with_handle(fixed.clone(), top.clone(), RigidTransform::IDENTITY);
    bend.handles[0].transform.translation = DVec3::new(0.3, 0.0, 0.0);
    let solver =
        ArapSolver::precompute(topology.clone(), &bend, SolverSettings::default()).unwrap();
    let options = SolveOptions {
        max_iterations: 200,
        tolerance: 0.0,
        acceleration: Acceleration::Lbfgs { depth: 5 },
    };
    let bent = solver
        .solve(&bend, &options, InitialGuess::Laplacian, NEVER)
        .unwrap();
    let held = Constraints {
        fixed,
        ..Default::default()
    };
    (topology, held, top, bent)
}

/// The dynamic solver of `held` for `settings`: the static factorization's lowest eigenvalue
/// sets the inertia of the dynamic one.
fn dynamic_solver(
    topology: &Arc<Topology>,
    held: &Constraints,
    settings: &DynamicsSettings,
) -> ArapSolver {
    let lambda = ArapSolver::precompute(topology.clone(), held, SolverSettings::default())
        .unwrap()
        .lowest_eigenvalue();
    assert!(lambda > 0.0 && lambda.is_finite(), "{lambda}");
    let inertia = settings.inertia(lambda);
    ArapSolver::precompute(
        topology.clone(),
        held,
        SolverSettings {
            inertia,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The top ring's mean x over `seconds` of frames at `fps` (one sample per frame).
fn tip_path(
    settings: DynamicsSettings,
    fps: f64,
    seconds: f64,
    hitch_at: Option<usize>,
) -> Vec<f64> {
    let (topology, held, top, bent) = bent_bar();
    let solver = dynamic_solver(&topology, &held, &settings);
    let mut motion = MeshMotion::from_solution(bent);
    let mut path = Vec::new();
    for frame in 0..(seconds * fps).round() as usize {
        let dt = if Some(frame) == hitch_at {
            0.1
        } else {
            1.0 / fps
        };
        motion.advance(&solver, &held, &settings, dt, None).unwrap();
        let p = motion.positions();
        path.push(top.iter().map(|&v| p[v as usize].x).sum::<f64>() / top.len() as f64);
    }
    path
}

#[test]
fn a_released_bar_overshoots_rings_down_and_settles_at_rest() {
    let settings = DynamicsSettings::default();
    let (topology, held, top, bent) = bent_bar();
    let solver = dynamic_solver(&topology, &held, &settings);
    let mut motion = MeshMotion::from_solution(bent);
    let mut path = Vec::new();
    for _ in 0..12 * 60 {
        motion
            .advance(&solver, &held, &settings, 1.0 / 60.0, None)
            .unwrap();
        let p = motion.positions();
        path.push(top.iter().map(|&v| p[v as usize].x).sum::<f64>() / top.len() as f64);
    }
    let lowest = path.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(lowest < -0.03, "the tip swings past its rest: {lowest}");
    let peak = |from: usize, to: usize| path[from..to].iter().map(|x| x.abs()).fold(0.0, f64::max);
    let (early, late) = (peak(60, 180), peak(300, 420));
    assert!(
        late < 0.5 * early,
        "the ringing decays: {early} then {late}"
    );
    let off = motion
        .positions()
        .iter()
        .zip(topology.positions())
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    assert!(off < 1e-3, "every vertex within 1e-3 of its rest: {off}");
}

#[test]
fn critical_damping_does_not_overshoot() {
    let settings = DynamicsSettings {
        damping: 1.0,
        ..Default::default()
    };
    let path = tip_path(settings, 60.0, 4.0, None);
    let lowest = path.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(lowest > 0.0, "no overshoot past the rest: {lowest}");
    // It creeps back: never away from the rest, and most of the way in four seconds.
    assert!(path.windows(2).all(|w| w[1] <= w[0] + 1e-9));
    assert!(path[path.len() - 1] < 0.25, "{}", path[path.len() - 1]);
}

#[test]
fn frame_rates_and_a_hitch_step_the_same_motion() {
    let settings = DynamicsSettings::default();
    let at_60 = tip_path(settings, 60.0, 2.0, None);
    let at_30 = tip_path(settings, 30.0, 2.0, None);
    let at_240 = tip_path(settings, 240.0, 2.0, None);
    // Frame k at 30 Hz and frame 8k + 7 at 240 Hz end where frame 2k + 1 at 60 Hz does.
    for k in 0..at_30.len() {
        let (a, b, c) = (at_30[k], at_60[2 * k + 1], at_240[8 * k + 7]);
        assert!(
            (a - b).abs() < 1e-9 && (c - b).abs() < 1e-9,
            "frame {k}: {a} {b} {c}"
        );
    }
    // A 100 ms frame steps on (six steps), stable.
    let hitched = tip_path(settings, 60.0, 4.0, Some(30));
    assert!(hitched.iter().all(|x| x.is_finite() && x.abs() < 0.31));
}

/// The handle's vertices' mean x and the far half's mean x of a bar in a DeformPlugin app.
fn mean_x(app: &bevy::prelude::App, e: bevy::prelude::Entity, vertices: &[u32]) -> f32 {
    let p = crate::common::bar::positions(app, e);
    vertices.iter().map(|&v| p[v as usize].x).sum::<f32>() / vertices.len() as f32
}

#[test]
fn a_dynamic_bar_lags_a_fast_move_overshoots_and_springs_back_when_let_go() {
    use bevy::prelude::*;
    use bevy::time::TimeUpdateStrategy;
    use bevy_wii_deform::prelude::{DeformDynamics, DeformPlugin, DeformStatus};

    let mut app = crate::common::app();
    app.add_plugins(DeformPlugin::default())
        .insert_resource(TimeUpdateStrategy::ManualDuration(
            std::time::Duration::from_secs_f64(1.0 / 60.0),
        ));
    let (e, handle, tri) = crate::common::bar::spawn_bar(&mut app);
    app.world_mut()
        .entity_mut(e)
        .insert(DeformDynamics::default());
    // The middle ring: free, between the held bottom and the handle at the top.
    let middle: Vec<u32> = (0..tri.positions.len() as u32)
        .filter(|&v| (tri.positions[v as usize].y - 0.6).abs() < 0.02)
        .collect();
    crate::common::update_until(&mut app, "the dynamic factorization", |a| {
        a.world()
            .get::<DeformStatus>(e)
            .is_some_and(|s| s.solves > 0)
    });
    // The handle jumps 0.3 sideways and holds there.
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x += 0.3;
    let mut path = Vec::new();
    for _ in 0..600 {
        app.update();
        path.push(mean_x(&app, e, &middle));
    }
    let settled = *path.last().unwrap();
    assert!(settled > 0.05, "the middle follows the handle: {settled}");
    assert!(
        path[2] < 0.5 * settled,
        "it lags the move: {} of {settled}",
        path[2]
    );
    let most = path.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    assert!(
        most > settled * 1.05,
        "it overshoots: {most} past {settled}"
    );
    assert!((path[590] - settled).abs() < 1e-3 * settled.max(1.0));
    // Let go (an elastic mesh's grab does this at release): it rings back to its rest.
    app.world_mut().entity_mut(handle).despawn();
    for _ in 0..900 {
        app.update();
    }
    let back = mean_x(&app, e, &middle);
    assert!(back.abs() < 1e-3, "back at rest: {back}");
}
