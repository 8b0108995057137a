//! A bend stops at the ground: free vertices projected onto an obstacle, handles lifted onto it.

use std::sync::Arc;

use bevy::prelude::*;
use bevy_wii_deform::deform::*;
use bevy_wii_deform::prelude::{
    DeformGround, DeformPlugin, DeformStatus, GroundMesh, mesh_from_triangles,
};
use glam::DVec3;

use crate::common::bar::{positions, regions, settle, spawn_bar};

const NEVER: &dyn Fn() -> bool = &|| false;

/// A bar of length 1 and radius 0.05 lying along +X at height 0.25, its first tenth fixed and
/// its last tenth a handle.
fn lying_bar() -> (Arc<Topology>, Constraints) {
    let mesh = synth::bar(16, 41, 0.05, 1.0);
    let positions: Vec<DVec3> = mesh
        .positions
        .iter()
        .map(|p| DVec3::new(p.y, 0.25 + p.x, p.z))
        .collect();
    let topology = Arc::new(Topology::new(&positions, &mesh.triangles).unwrap());
    let ps = topology.positions();
    let pick = |f: &dyn Fn(&DVec3) -> bool| -> Vec<u32> {
        (0..ps.len() as u32)
            .filter(|&i| f(&ps[i as usize]))
            .collect()
    };
    let constraints = Constraints::with_handle(
        pick(&|p| p.x < 0.1),
        pick(&|p| p.x > 0.9),
        RigidTransform::new(
            glam::DQuat::IDENTITY,
            DVec3::ZERO,
            DVec3::new(0.95, 0.25, 0.0),
        ),
    );
    (topology, constraints)
}

fn lowest(positions: &[DVec3]) -> f64 {
    positions.iter().map(|p| p.y).fold(f64::INFINITY, f64::min)
}

/// A floor at y = 0 with a ridge 0.15 high across the bar at x = 0.6.
fn ridged_floor() -> HeightField {
    let ridge = |x: f64| 0.15 * (-((x - 0.6) / 0.12).powi(2)).exp();
    HeightField::sample(
        DVec3::new(-1.0, 0.0, -1.0),
        DVec3::Y,
        DVec3::X,
        0.01,
        [301, 301],
        |p| Some(ridge(p.x)),
    )
    .unwrap()
}

/// The deepest any vertex is below `floor` (0 when none is).
fn deepest(floor: &dyn Obstacle, positions: &[DVec3]) -> f64 {
    positions
        .iter()
        .filter_map(|p| floor.surface_at(*p).map(|s| -s.gap(*p)))
        .fold(0.0, f64::max)
}

#[test]
fn a_bar_pushed_into_the_floor_stops_at_it_and_slides_along() {
    let (topology, mut constraints) = lying_bar();
    let solver =
        ArapSolver::precompute(topology.clone(), &constraints, SolverSettings::default()).unwrap();
    // Push the free end 0.6 down (0.35 into the floor) and 0.2 sideways.
    let push = DVec3::new(0.0, -0.6, 0.2);
    constraints.handles[0].transform.translation = push;
    let floor = ridged_floor();
    let options = SolveOptions {
        max_iterations: 300,
        tolerance: 0.0,
        acceleration: Acceleration::None,
    };
    let through = solver
        .solve(&constraints, &options, InitialGuess::Laplacian, NEVER)
        .unwrap();
    assert!(
        lowest(&through.positions) < -0.3,
        "without the floor the push goes through it ({})",
        lowest(&through.positions)
    );

    let lifted = constraints.lifted_above(topology.positions(), &floor);
    let lift = lifted.handles[0].transform.translation - push;
    assert!(
        lift.x.abs() < 1e-12 && lift.z.abs() < 1e-12 && (0.4..0.401).contains(&lift.y),
        "the handle rises straight up onto the floor: {lift}"
    );
    let solution = solver
        .solve_above(&lifted, &options, InitialGuess::Laplacian, &floor, NEVER)
        .unwrap();
    let size = topology.bounding_diagonal();
    assert!(
        deepest(&floor, &through.positions) > 0.05,
        "without the floor the bar goes through the ridge"
    );
    let depth = deepest(&floor, &solution.positions);
    assert!(
        depth < 1e-3 * size,
        "no vertex below the floor by more than 1e-3 of the size: {depth}"
    );
    // The bar rests on the ridge: free vertices are held on it.
    assert!(solution.stats.contacts >= 3, "{}", solution.stats.contacts);
    let on_ridge = solution
        .positions
        .iter()
        .filter(|p| (p.x - 0.6).abs() < 0.15 && p.y < 0.2)
        .count();
    assert!(on_ridge > 0, "the bar lies over the ridge");
    let end: Vec<DVec3> = lifted.handles[0]
        .vertices
        .iter()
        .map(|&v| solution.positions[v as usize])
        .collect();
    let end_z = end.iter().map(|p| p.z).sum::<f64>() / end.len() as f64;
    assert!(
        (end_z - 0.2).abs() < 1e-9,
        "the end slid 0.2 across: {end_z}"
    );
    // The projected global step is the constrained one: once the contacts are found (the
    // surface is curved, so a change of the set may cost a little), the energy never rises.
    let energies = &solution.stats.energies;
    for w in energies[50..].windows(2) {
        assert!(
            w[1] <= w[0] * (1.0 + 1e-9),
            "energy rose: {} → {}",
            w[0],
            w[1]
        );
    }
    let least = energies.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        solution.stats.final_energy() < least * 1.005,
        "{energies:?}"
    );
    // The same lifted drag without the floor bends into the ridge, at a lower energy: the
    // floor is what holds the bar up.
    let free = solver
        .solve(&lifted, &options, InitialGuess::Laplacian, NEVER)
        .unwrap();
    assert!(deepest(&floor, &free.positions) > 0.02);
    assert!(solution.stats.final_energy() > free.stats.final_energy());
}

#[test]
fn an_accelerated_solve_above_the_floor_ends_where_the_plain_one_does() {
    let (topology, mut constraints) = lying_bar();
    let solver =
        ArapSolver::precompute(topology.clone(), &constraints, SolverSettings::default()).unwrap();
    constraints.handles[0].transform.translation = DVec3::new(0.0, -0.6, 0.1);
    let floor = ridged_floor();
    let lifted = constraints.lifted_above(topology.positions(), &floor);
    let solve = |acceleration| {
        let options = SolveOptions {
            max_iterations: 2000,
            tolerance: 1e-13,
            acceleration,
        };
        solver
            .solve_above(&lifted, &options, InitialGuess::Laplacian, &floor, NEVER)
            .unwrap()
    };
    let plain = solve(Acceleration::None);
    let lbfgs = solve(Acceleration::Lbfgs { depth: 5 });
    for s in [&plain, &lbfgs] {
        let depth = deepest(&floor, &s.positions);
        assert!(depth < 1e-3, "{depth} deep, {} contacts", s.stats.contacts);
        assert!(s.stats.contacts > 0);
    }
    let (ep, el) = (plain.stats.final_energy(), lbfgs.stats.final_energy());
    assert!(
        (ep - el).abs() < 2e-3 * ep,
        "plain {ep} ({} iterations, {} contacts), accelerated {el} ({}, {})",
        plain.stats.iterations,
        plain.stats.contacts,
        lbfgs.stats.iterations,
        lbfgs.stats.contacts
    );
}

#[test]
fn a_floor_under_the_bar_changes_nothing() {
    let (topology, mut constraints) = lying_bar();
    let solver =
        ArapSolver::precompute(topology.clone(), &constraints, SolverSettings::default()).unwrap();
    constraints.handles[0].transform.translation = DVec3::new(0.0, 0.1, 0.1);
    let floor = PlaneObstacle::new(DVec3::new(0.0, -1.0, 0.0), DVec3::Y).unwrap();
    let options = SolveOptions::default();
    let free = solver
        .solve(&constraints, &options, InitialGuess::Laplacian, NEVER)
        .unwrap();
    let above = solver
        .solve_above(
            &constraints,
            &options,
            InitialGuess::Laplacian,
            &floor,
            NEVER,
        )
        .unwrap();
    assert_eq!(above.stats.contacts, 0);
    let moved = free
        .positions
        .iter()
        .zip(&above.positions)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    assert!(moved < 1e-12, "{moved}");
}

/// A `DeformPlugin` app at 60 frames a second with a `GroundMesh` quad 6 wide at y = 0.
fn ground_quad_app() -> App {
    let mut app = crate::common::app();
    app.add_plugins(DeformPlugin::default()).insert_resource(
        bevy::time::TimeUpdateStrategy::ManualDuration(std::time::Duration::from_secs_f64(
            1.0 / 60.0,
        )),
    );
    let quad = [
        DVec3::new(-3.0, 0.0, -3.0),
        DVec3::new(3.0, 0.0, -3.0),
        DVec3::new(3.0, 0.0, 3.0),
        DVec3::new(-3.0, 0.0, 3.0),
    ];
    let floor = mesh_from_triangles(&quad, &[[0, 2, 1], [0, 3, 2]]);
    let floor = app.world_mut().resource_mut::<Assets<Mesh>>().add(floor);
    app.world_mut()
        .spawn((Mesh3d(floor), Transform::default(), GroundMesh));
    app
}

/// A bar `Deformable` lying along world +X with its axis 0.4 above a `GroundMesh` quad at y = 0
/// (the mesh turned, raised and scaled ×1.5 by its transform), its handle pushed 1.2 below
/// and 0.3 across in world units; the mesh's world positions once settled.
fn push_a_bar_into_a_ground_quad(on_ground: bool) -> (Vec<Vec3>, Vec<Vec3>, DeformStatus) {
    let mut app = ground_quad_app();
    let (e, handle, tri) = spawn_bar(&mut app);
    let placement = Transform::from_xyz(0.0, 0.4, 0.0)
        .with_rotation(Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2))
        .with_scale(Vec3::splat(1.5));
    app.world_mut().entity_mut(e).insert(placement);
    if on_ground {
        app.world_mut()
            .entity_mut(e)
            .insert(DeformGround::default());
    }
    app.update();
    settle(&mut app, e);
    let to_local = placement.to_matrix().inverse();
    let push = to_local.transform_vector3(Vec3::new(0.0, -1.2, 0.3));
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation += push;
    settle(&mut app, e);
    let world: Vec<Vec3> = positions(&app, e)
        .iter()
        .map(|p| placement.transform_point(*p))
        .collect();
    let (_, hv) = regions(&tri);
    let end = hv.iter().map(|&v| world[v as usize]).collect();
    (
        world,
        end,
        app.world().get::<DeformStatus>(e).unwrap().clone(),
    )
}

#[test]
fn a_bar_grabbed_into_the_scene_ground_stops_at_it_and_slides_along() {
    let lowest = |w: &[Vec3]| w.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let (through, _, status) = push_a_bar_into_a_ground_quad(false);
    assert!(status.error.is_none(), "{status:?}");
    assert!(
        lowest(&through) < -0.5,
        "without DeformGround: {}",
        lowest(&through)
    );

    let (world, end, status) = push_a_bar_into_a_ground_quad(true);
    assert!(status.error.is_none(), "{status:?}");
    let size = 1.5 * (1.0f32 + 0.04 + 0.04).sqrt();
    assert!(
        lowest(&world) > -1e-3 * size,
        "no vertex below the ground by more than 1e-3 of the size: {}",
        lowest(&world)
    );
    // The end rests on the ground, moved across as far as the hand went.
    let bottom = end.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    assert!(bottom.abs() < 1e-3, "the end lies on the ground: {bottom}");
    let across = end.iter().map(|p| p.z).sum::<f32>() / end.len() as f32;
    assert!(
        (across - 0.3).abs() < 1e-3,
        "the end slid 0.3 across: {across}"
    );
}

#[test]
fn a_wobbling_bar_pushed_into_the_ground_never_passes_below_it() {
    use bevy_wii_deform::prelude::DeformDynamics;

    let mut app = ground_quad_app();
    let (e, handle, _) = spawn_bar(&mut app);
    // Lying along +X, its axis 0.3 above the floor.
    let placement = Transform::from_xyz(0.0, 0.3, 0.0)
        .with_rotation(Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2));
    app.world_mut().entity_mut(e).insert((
        placement,
        DeformGround::default(),
        DeformDynamics::default(),
    ));
    crate::common::update_until(&mut app, "the first step", |a| {
        a.world()
            .get::<DeformStatus>(e)
            .is_some_and(|s| s.solves > 0)
    });
    // A fast push of the free end 0.8 down: the bar swings into the floor and rings.
    let push = placement
        .to_matrix()
        .inverse()
        .transform_vector3(Vec3::new(0.0, -0.8, 0.0));
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation += push;
    let mut deepest = 0.0f32;
    let mut touched = 0;
    for _ in 0..240 {
        app.update();
        let lowest = positions(&app, e)
            .iter()
            .map(|p| placement.transform_point(*p).y)
            .fold(f32::INFINITY, f32::min);
        deepest = deepest.min(lowest);
        touched = touched.max(app.world().get::<DeformStatus>(e).unwrap().ground_contacts);
    }
    assert!(touched > 0, "the swing reached the floor");
    assert!(
        deepest > -1e-3,
        "no frame shows a vertex below the floor: {deepest}"
    );
}
