//! `DeformPlugin` headless (MinimalPlugins + assets + meshes + transforms, no GPU): solves match
//! the core, bursts end on the latest move, bad input fails typed, several meshes, regions of
//! interest, scenes, normals and tangents, settling and previews.

use std::sync::Arc;

use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy_wii_deform::deform::{self, synth};
use bevy_wii_deform::prelude::*;
use glam::{DQuat, DVec3};

use crate::common;
use crate::common::bar::*;
use common::app;

#[test]
fn moved_handle_matches_the_core_solver() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, tri) = spawn_bar(&mut app);
    let (ok, _) = run_until_messages(&mut app, 1); // initial solve at rest
    assert_eq!(ok.len(), 1);
    let rotation = Quat::from_rotation_z(0.5);
    {
        let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
        t.rotation = rotation;
        t.translation += Vec3::new(0.2, 0.0, 0.0);
    }
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(bad.is_empty(), "{bad:?}");
    assert_eq!(ok[0].entity, e);
    let got = positions(&app, e);

    // The same constraints through the core directly (the plugin's first solve, handles at
    // rest, starts from rest; the move is warm-started from it).
    let topology = Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
    let (fixed, hv) = regions(&tri);
    let pivot = hv.iter().map(|&i| tri.positions[i as usize]).sum::<DVec3>() / hv.len() as f64;
    let pivot32 = pivot.as_vec3();
    let mut c = Constraints::with_handle(
        fixed,
        hv,
        RigidTransform::new(DQuat::IDENTITY, DVec3::ZERO, pivot32.as_dvec3()),
    );
    let solver = ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
    let opts = SolveOptions {
        max_iterations: 5,
        tolerance: 0.0,
        acceleration: app.world().resource::<DeformConfig>().acceleration,
    };
    let first = solver
        .solve(&c, &opts, InitialGuess::Rest, &|| false)
        .unwrap();
    c.handles[0].transform = RigidTransform::new(
        rotation.as_dquat(),
        (pivot32 + Vec3::new(0.2, 0.0, 0.0)).as_dvec3() - pivot32.as_dvec3(),
        pivot32.as_dvec3(),
    );
    let second = solver
        .solve(&c, &opts, InitialGuess::Warm(&first), &|| false)
        .unwrap();
    let want = topology.to_render(&second.positions);
    let err = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a.as_dvec3() - *b).length())
        .fold(0.0, f64::max);
    assert!(err < 1e-4, "plugin vs core: {err}");
    assert!(
        got.iter()
            .zip(&tri.positions)
            .any(|(a, b)| (a.as_dvec3() - *b).length() > 0.05)
    );
}

/// The first solve on a rest pose starts from the paper's Laplacian guess only when the
/// handles are far from rest (`DeformConfig::laplacian_start_displacement`), else from rest:
/// one iteration through the plugin matches the core's one iteration from that start, and
/// not the other start's.
#[test]
fn the_first_solve_starts_from_the_laplacian_guess_only_for_a_far_pose() {
    for (offset, laplacian) in [(0.3f32, true), (0.02, false)] {
        let mut app = app();
        app.add_plugins(DeformPlugin::default());
        let (e, handle, tri) = spawn_bar(&mut app);
        app.world_mut()
            .get_mut::<Deformable>(e)
            .unwrap()
            .max_iterations = Some(1);
        let pivot = {
            let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
            let pivot = t.translation;
            t.translation += Vec3::new(offset, 0.0, 0.0);
            pivot
        };
        let (ok, bad) = run_until_messages(&mut app, 1);
        assert!(bad.is_empty() && ok.len() == 1, "{bad:?}");
        let got = positions(&app, e);

        let topology = Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
        let (fixed, hv) = regions(&tri);
        let c = Constraints::with_handle(
            fixed,
            hv,
            RigidTransform::new(
                DQuat::IDENTITY,
                (pivot + Vec3::new(offset, 0.0, 0.0)).as_dvec3() - pivot.as_dvec3(),
                pivot.as_dvec3(),
            ),
        );
        let solver =
            ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
        let opts = SolveOptions {
            max_iterations: 1,
            tolerance: 0.0,
            acceleration: app.world().resource::<DeformConfig>().acceleration,
        };
        let error_from = |start: InitialGuess| {
            let want = solver.solve(&c, &opts, start, &|| false).unwrap();
            let want = topology.to_render(&want.positions);
            got.iter()
                .zip(&want)
                .map(|(a, b)| (a.as_dvec3() - *b).length())
                .fold(0.0, f64::max)
        };
        let (from_laplacian, from_rest) = (
            error_from(InitialGuess::Laplacian),
            error_from(InitialGuess::Rest),
        );
        let (matched, other) = match laplacian {
            true => (from_laplacian, from_rest),
            false => (from_rest, from_laplacian),
        };
        assert!(
            matched < 1e-5 && other > 100.0 * matched.max(1e-6),
            "offset {offset}: from the Laplacian guess {from_laplacian:e}, from rest {from_rest:e}"
        );
    }
}

#[test]
fn a_burst_of_moves_ends_on_the_latest() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, _) = spawn_bar(&mut app);
    run_until_messages(&mut app, 1);
    for k in 1..=20 {
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .rotation = Quat::from_rotation_z(0.03 * k as f32);
        app.update();
    }
    // Let everything land.
    settle(&mut app, e);
    let status = app.world().get::<DeformStatus>(e).unwrap().clone();
    assert!(status.solves >= 2);
    // The final mesh corresponds to the final rotation: the handle centroid turned by 0.6 rad.
    let tip = positions(&app, e);
    let state_rot = Quat::from_rotation_z(0.6);
    let pivot = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .pivot
        .unwrap();
    let verts = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .vertices
        .clone();
    let (_, tri) = bar_mesh();
    for &v in &verts {
        let rest = tri.positions[v as usize].as_vec3();
        let want = pivot + state_rot * (rest - pivot);
        assert!((tip[v as usize] - want).length() < 1e-4, "vertex {v}");
    }
}

#[test]
fn invalid_constraints_fail_and_leave_the_mesh() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, tri) = spawn_bar(&mut app);
    run_until_messages(&mut app, 1);
    let before = positions(&app, e);
    // Overlap: make the fixed region contain a handle vertex.
    let hv = app.world().get::<DeformHandle>(handle).unwrap().vertices[0];
    app.world_mut()
        .get_mut::<FixedRegion>(e)
        .unwrap()
        .0
        .push(hv);
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x += 0.3;
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(ok.is_empty());
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(
        matches!(
            bad[0].error,
            DeformError::Solve(deform::SolveError::Constraint(
                deform::ConstraintError::Overlap { .. }
            ))
        ),
        "{}",
        bad[0].error
    );
    assert_eq!(positions(&app, e), before);
    assert!(app.world().get::<DeformStatus>(e).unwrap().error.is_some());
    let _ = tri;
    // NaN transform: failed, mesh unchanged, nothing non-finite written.
    app.world_mut().get_mut::<FixedRegion>(e).unwrap().0.pop();
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x = f32::NAN;
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(ok.is_empty() && bad.len() == 1);
    assert!(positions(&app, e).iter().all(|p| p.is_finite()));
}

#[test]
fn several_meshes_at_once() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (a, ha, _) = spawn_bar(&mut app);
    let (b, hb, _) = spawn_bar(&mut app);
    run_until_messages(&mut app, 2);
    app.world_mut()
        .get_mut::<Transform>(ha)
        .unwrap()
        .translation
        .x += 0.2;
    app.world_mut()
        .get_mut::<Transform>(hb)
        .unwrap()
        .translation
        .z += 0.2;
    let (ok, _) = run_until_messages(&mut app, 2);
    let entities: Vec<Entity> = ok.iter().map(|m| m.entity).collect();
    assert!(entities.contains(&a) && entities.contains(&b));
    assert_ne!(positions(&app, a), positions(&app, b));
}

#[test]
fn changing_the_region_of_interest_at_run_time_refactorizes() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (e, handle, tri) = spawn_bar(&mut app);
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    {
        let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
        t.rotation = Quat::from_rotation_z(0.5);
        t.translation += Vec3::new(0.2, 0.0, 0.0);
    }
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    // Only the upper part may move now: the lower middle must go back to rest.
    let (lo, hi) = tri
        .positions
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let at = |f: f64| lo + f * (hi - lo);
    let roi: Vec<u32> = (0..tri.positions.len() as u32)
        .filter(|&i| tri.positions[i as usize].y > at(0.5))
        .collect();
    let outside: Vec<usize> = (0..tri.positions.len())
        .filter(|&i| (at(0.15)..at(0.45)).contains(&tri.positions[i].y))
        .collect();
    let moved_before = outside
        .iter()
        .map(|&i| (positions(&app, e)[i].as_dvec3() - tri.positions[i]).length())
        .fold(0.0, f64::max);
    assert!(
        moved_before > 1e-3,
        "the bend moved the lower middle: {moved_before}"
    );
    app.world_mut()
        .get_mut::<Deformable>(e)
        .unwrap()
        .region_of_interest = Some(roi);
    // Solves of the old region may still land (settling); wait until all is done.
    settle(&mut app, e);
    let status = app.world().get::<DeformStatus>(e).unwrap();
    assert!(status.error.is_none(), "{:?}", status.error);
    let got = positions(&app, e);
    let moved_after = outside
        .iter()
        .map(|&i| (got[i].as_dvec3() - tri.positions[i]).length())
        .fold(0.0, f64::max);
    assert!(
        moved_after < 1e-5,
        "outside the region of interest: moved {moved_after}"
    );
}

#[test]
fn a_handle_without_pivot_at_the_identity_transform_does_not_jump() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (mesh, tri) = bar_mesh();
    let (fixed, handle_vertices) = regions(&tri);
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((Mesh3d(h), Deformable::default(), FixedRegion(fixed)))
        .id();
    let centroid = handle_vertices
        .iter()
        .map(|&i| tri.positions[i as usize])
        .sum::<DVec3>()
        / handle_vertices.len() as f64;
    let handle = app
        .world_mut()
        .spawn((
            DeformHandle {
                target: e,
                vertices: handle_vertices,
                pivot: None,
            },
            Transform::IDENTITY,
        ))
        .id();
    let (ok, bad) = run_until_messages(&mut app, 1);
    assert!(bad.is_empty() && ok.len() == 1, "{bad:?}");
    let moved = positions(&app, e)
        .iter()
        .zip(&tri.positions)
        .map(|(a, b)| (a.as_dvec3() - *b).length())
        .fold(0.0, f64::max);
    assert!(moved < 1e-4, "the mesh jumped by {moved}");
    let t = app.world().get::<Transform>(handle).unwrap();
    assert!(
        (t.translation.as_dvec3() - centroid).length() < 1e-5,
        "{t:?}"
    );
    assert_eq!(
        app.world().get::<DeformHandle>(handle).unwrap().pivot,
        Some(t.translation)
    );
}

#[test]
fn a_mesh_that_cannot_be_prepared_fails_with_a_typed_reason() {
    use bevy::mesh::PrimitiveTopology;
    use bevy_wii_deform::deform::MeshError;
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let (mut nan_mesh, _) = bar_mesh();
    if let Some(VertexAttributeValues::Float32x3(p)) =
        nan_mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
    {
        p[5][1] = f32::NAN;
    }
    let lines = Mesh::new(PrimitiveTopology::LineList, Default::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3], [1.0, 0.0, 0.0]]);
    let mut spawn = |mesh: Mesh| {
        let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        app.world_mut()
            .spawn((Mesh3d(h), Deformable::default()))
            .id()
    };
    let (nan, line) = (spawn(nan_mesh), spawn(lines));
    let (ok, bad) = run_until_messages(&mut app, 2);
    assert!(ok.is_empty());
    let error_of = |e: Entity| bad.iter().find(|m| m.entity == e).map(|m| m.error.clone());
    assert_eq!(
        error_of(nan),
        Some(DeformError::Mesh(MeshError::NonFinitePosition {
            vertex: 5
        }))
    );
    assert!(
        matches!(error_of(line), Some(DeformError::NotTriangleList(_))),
        "{bad:?}"
    );
    for e in [nan, line] {
        let status = app.world().get::<DeformStatus>(e).unwrap();
        assert_eq!(status.phase, DeformPhase::Failed);
        assert!(status.error.is_some());
    }
}

#[test]
fn deformable_on_an_ancestor_applies_to_the_meshes_below_it() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    // A glTF-like hierarchy: root → node (its own transform) → primitive with the mesh.
    let (mesh, tri) = bar_mesh();
    let (fixed, handle_vertices) = regions(&tri);
    let bundle_source = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let root = app
        .world_mut()
        .spawn((
            Deformable {
                max_iterations: Some(5),
                ..default()
            },
            Transform::from_scale(Vec3::splat(2.0)),
        ))
        .id();
    let node = app
        .world_mut()
        .spawn((
            Transform::from_rotation(Quat::from_rotation_x(0.7)),
            ChildOf(root),
        ))
        .id();
    let primitive = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Transform::default(),
            FixedRegion(fixed),
            ChildOf(node),
        ))
        .id();
    let lonely = app.world_mut().spawn(Deformable::default()).id();
    let handle = app
        .world_mut()
        .spawn(DeformHandle::bundle(
            &bundle_source,
            primitive,
            handle_vertices,
        ))
        .id();
    let (ok, bad) = run_until_messages(&mut app, 2);
    assert_eq!(ok.len(), 1, "{ok:?} {bad:?}");
    assert_eq!(ok[0].entity, primitive);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert_eq!(
        (bad[0].entity, &bad[0].error),
        (lonely, &DeformError::NoMeshBelow)
    );
    assert_eq!(
        app.world().get::<DeformableScene>(root).unwrap().primitives,
        vec![primitive]
    );
    assert_eq!(
        app.world().get::<DeformableFrom>(primitive),
        Some(&DeformableFrom(root))
    );
    // The handle bends the primitive; settings changed on the root reach it.
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x += 0.2;
    let (ok, _) = run_until_messages(&mut app, 1);
    assert_eq!(ok.len(), 1);
    assert!(
        positions(&app, primitive)
            .iter()
            .zip(&tri.positions)
            .any(|(a, b)| (a.as_dvec3() - *b).length() > 0.05)
    );
    app.world_mut()
        .get_mut::<Deformable>(root)
        .unwrap()
        .max_iterations = Some(2);
    app.update();
    assert_eq!(
        app.world()
            .get::<Deformable>(primitive)
            .unwrap()
            .max_iterations,
        Some(2)
    );
}

/// The lowest and highest y of `positions`.
fn height_range(positions: &[glam::DVec3]) -> (f64, f64) {
    positions.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
        (lo.min(p.y), hi.max(p.y))
    })
}

/// The vertices between heights `a` and `b` (fractions of the height range).
fn height_band(positions: &[glam::DVec3], a: f64, b: f64) -> Vec<u32> {
    let (lo, hi) = height_range(positions);
    (0..positions.len() as u32)
        .filter(|&i| (lo + a * (hi - lo)..=lo + b * (hi - lo)).contains(&positions[i as usize].y))
        .collect()
}

/// The normals and tangents of the turned `top` turned with it (within 3°, handedness kept);
/// the middle's stayed.
fn normals_and_tangents_turned(
    app: &App,
    e: Entity,
    positions: &[glam::DVec3],
    top: &[u32],
    turn: Quat,
    rest_normals: &[[f32; 3]],
) {
    let (lo, hi) = height_range(positions);
    let band = |a: f64, b: f64| height_band(positions, a, b);
    let handle = app.world().get::<Mesh3d>(e).unwrap().0.clone();
    let meshes = app.world().resource::<Assets<Mesh>>();
    let mesh = meshes.get(&handle).unwrap();
    let (
        Some(VertexAttributeValues::Float32x3(normals)),
        Some(VertexAttributeValues::Float32x4(tangents)),
    ) = (
        mesh.attribute(Mesh::ATTRIBUTE_NORMAL),
        mesh.attribute(Mesh::ATTRIBUTE_TANGENT),
    )
    else {
        panic!("normals and tangents kept");
    };
    // (Cells whose whole one-ring is in the handle turn exactly with it: the band's inner ring.)
    let inner = |v: &&u32| {
        let y = positions[**v as usize].y;
        y > lo + 0.95 * (hi - lo) && y < hi - 1e-9
    };
    let checked = top.iter().filter(inner).count();
    assert!(checked >= 12, "{checked}");
    for &v in top.iter().filter(inner) {
        let n = Vec3::from_array(normals[v as usize]);
        let want = turn * Vec3::from_array(rest_normals[v as usize]);
        assert!(
            n.angle_between(want) < 3f32.to_radians(),
            "normal {v}: {n} vs {want}"
        );
        let t = Vec4::from_array(tangents[v as usize]);
        assert!(
            t.truncate().angle_between(turn * Vec3::Y) < 3f32.to_radians(),
            "tangent {v}: {t}"
        );
        assert_eq!(t.w, -1.0);
    }
    for v in band(0.47, 0.53) {
        let n = Vec3::from_array(normals[v as usize]);
        assert!(
            n.angle_between(Vec3::from_array(rest_normals[v as usize])) < 1e-3,
            "middle {v}"
        );
    }
}

#[test]
fn normals_and_tangents_turn_with_the_surface_and_two_handles_move_one_mesh() {
    let mut app = app();
    app.add_plugins(DeformPlugin::default());
    let tri = synth::bar(12, 30, 0.1, 1.0);
    // Rest normals and tangents (tangent along +Y, handedness −1 kept through the solve).
    let mut mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let tangents: Vec<[f32; 4]> = vec![[0.0, 1.0, 0.0, -1.0]; tri.positions.len()];
    mesh.insert_attribute(Mesh::ATTRIBUTE_TANGENT, tangents);
    let rest_normals = match mesh.attribute(Mesh::ATTRIBUTE_NORMAL).unwrap() {
        VertexAttributeValues::Float32x3(n) => n.clone(),
        _ => unreachable!(),
    };
    // Fixed middle, a handle at each end.
    let band = |a: f64, b: f64| height_band(&tri.positions, a, b);
    let (bottom, middle, top) = (band(0.0, 0.08), band(0.4, 0.6), band(0.92, 1.0));
    let bundle_source = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Deformable {
                max_iterations: Some(40),
                tolerance: Some(0.0),
                ..default()
            },
            FixedRegion(middle),
        ))
        .id();
    let top_handle = app
        .world_mut()
        .spawn(DeformHandle::bundle(&bundle_source, e, top.clone()))
        .id();
    let bottom_handle = app
        .world_mut()
        .spawn(DeformHandle::bundle(&bundle_source, e, bottom.clone()))
        .id();
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    let turn = Quat::from_rotation_z(0.5);
    {
        let mut t = app.world_mut().get_mut::<Transform>(top_handle).unwrap();
        t.rotation = turn;
        t.translation.x += 0.1;
    }
    app.world_mut()
        .get_mut::<Transform>(bottom_handle)
        .unwrap()
        .translation
        .x -= 0.15;
    settle(&mut app, e);
    let got = positions(&app, e);
    // Both handles' vertices are on their targets.
    let pivot = |v: &[u32]| {
        v.iter()
            .map(|&i| tri.positions[i as usize].as_vec3())
            .sum::<Vec3>()
            / v.len() as f32
    };
    let pt = pivot(&top);
    for &v in &top {
        let want = pt + Vec3::X * 0.1 + turn * (tri.positions[v as usize].as_vec3() - pt);
        assert!(got[v as usize].distance(want) < 1e-4, "top {v}");
    }
    for &v in &bottom {
        let want = tri.positions[v as usize].as_vec3() - Vec3::X * 0.15;
        assert!(got[v as usize].distance(want) < 1e-4, "bottom {v}");
    }
    normals_and_tangents_turned(&app, e, &tri.positions, &top, turn, &rest_normals);
}

/// The core's converged pose (render order) of the bar of [`spawn_bar`] with its handle
/// entity's `Transform` at `handle_at`, and the bar's bounding diagonal.
fn converged_bar_pose(tri: &deform::TriMesh, handle_at: &Transform) -> (Vec<DVec3>, f64) {
    let topology = Arc::new(Topology::new(&tri.positions, &tri.triangles).unwrap());
    let (fixed, hv) = regions(tri);
    let pivot = deform::centroid(&tri.positions, &hv).as_vec3();
    let c = Constraints::with_handle(
        fixed,
        hv,
        RigidTransform::new(
            handle_at.rotation.as_dquat(),
            (handle_at.translation - pivot).as_dvec3(),
            pivot.as_dvec3(),
        ),
    );
    let solver = ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
    let options = SolveOptions {
        max_iterations: 3000,
        tolerance: 0.0,
        acceleration: deform::Acceleration::Lbfgs { depth: 8 },
    };
    let star = solver
        .solve(&c, &options, InitialGuess::Laplacian, &|| false)
        .unwrap();
    (
        topology.to_render(&star.positions),
        topology.bounding_diagonal(),
    )
}

/// After the handle stops, the plugin keeps iterating (warm, in the background) until the pose
/// has converged: the released pose ends within 5e-4 × the diagonal of the core's converged
/// pose. With settling off, the pose freezes where the last solve of the move left it, farther
/// than that.
#[test]
fn a_released_handle_settles_to_the_converged_pose() {
    let run = |settle_iterations| {
        let mut app = app();
        app.add_plugins(DeformPlugin {
            config: DeformConfig {
                settle_iterations,
                ..default()
            },
        });
        let (e, handle, tri) = spawn_bar(&mut app);
        app.world_mut().get_mut::<Deformable>(e).unwrap().tolerance = Some(1e-7);
        let (ok, _) = run_until_messages(&mut app, 1);
        assert_eq!(ok.len(), 1);
        {
            let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
            t.rotation = Quat::from_rotation_z(1.0);
            t.translation += Vec3::new(0.3, -0.1, 0.0);
        }
        settle(&mut app, e);
        let solves = app.world().get::<DeformStatus>(e).unwrap().solves;
        (
            positions(&app, e),
            tri,
            *app.world().get::<Transform>(handle).unwrap(),
            solves,
        )
    };
    let (settled, tri, handle_at, settled_solves) = run(DeformConfig::default().settle_iterations);
    let (frozen, _, _, frozen_solves) = run(0);

    // The converged pose for the same constraints, from the core.
    let (want, diagonal) = converged_bar_pose(&tri, &handle_at);
    let worst = |got: &[Vec3]| {
        got.iter()
            .zip(&want)
            .map(|(a, b)| (a.as_dvec3() - *b).length())
            .fold(0.0, f64::max)
    };
    let (settled_err, frozen_err) = (worst(&settled), worst(&frozen));
    assert!(
        settled_err <= 5e-4 * diagonal,
        "settled pose {settled_err} from converged ({settled_solves} solves)"
    );
    assert!(
        frozen_err > 5e-4 * diagonal,
        "without settling {frozen_err} ({frozen_solves} solves)"
    );
    assert!(settled_solves > frozen_solves);
}

/// A new constraint set on a mesh larger than the preview region is first shown as a preview:
/// only the vertices near the handle move, the rest stay where they were shown (here, at
/// rest). The whole mesh is then factored in the background and the pose settles to the
/// whole mesh's converged pose. Without a preview the first pose moves the far vertices too.
#[test]
fn a_set_change_on_a_large_mesh_is_previewed_then_solved_whole() {
    let first_and_settled = |preview: Option<deform::PreviewRegion>| {
        let mut app = app();
        app.add_plugins(DeformPlugin {
            config: DeformConfig {
                preview,
                ..default()
            },
        });
        let (e, handle, tri) = spawn_bar(&mut app);
        {
            // Moved before the first solve: the first constraint set is already bent.
            let mut t = app.world_mut().get_mut::<Transform>(handle).unwrap();
            t.rotation = Quat::from_rotation_z(0.6);
            t.translation += Vec3::new(0.25, -0.1, 0.0);
        }
        let (ok, bad) = run_until_messages(&mut app, 1);
        assert!(bad.is_empty(), "{bad:?}");
        assert_eq!(ok.len(), 1);
        let status = app.world().get::<DeformStatus>(e).unwrap().clone();
        let first = positions(&app, e);
        settle(&mut app, e);
        let status_after = app.world().get::<DeformStatus>(e).unwrap().clone();
        assert!(!status_after.preview);
        (
            status.preview,
            first,
            positions(&app, e),
            tri,
            *app.world().get::<Transform>(handle).unwrap(),
        )
    };
    let region = deform::PreviewRegion {
        radius: 0.25,
        max_vertices: 100,
        min_mesh_vertices: 100,
    };
    let (previewed, first, settled, tri, handle_at) = first_and_settled(Some(region));
    let (whole_previewed, whole_first, _, _, _) = first_and_settled(None);
    assert!(previewed);
    assert!(!whole_previewed);

    // The vertices at the bottom half (free, far from the handle at the top) stay at rest in
    // the preview, and move in the whole mesh's first pose.
    let (fixed, hv) = regions(&tri);
    let far: Vec<usize> = (0..tri.positions.len())
        .filter(|&v| tri.positions[v].y < 0.4 && !fixed.contains(&(v as u32)))
        .collect();
    assert!(far.len() > 50);
    let moved = |pose: &[Vec3]| {
        far.iter()
            .map(|&v| (pose[v].as_dvec3() - tri.positions[v]).length())
            .fold(0.0, f64::max)
    };
    assert!(
        moved(&first) < 1e-6,
        "preview moved far vertices {}",
        moved(&first)
    );
    assert!(moved(&whole_first) > 1e-2, "whole {}", moved(&whole_first));
    // Near the handle the preview bends.
    let near =
        (0..tri.positions.len()).filter(|&v| tri.positions[v].y > 0.7 && !hv.contains(&(v as u32)));
    assert!(
        near.clone()
            .any(|v| (first[v].as_dvec3() - tri.positions[v]).length() > 0.02)
    );

    // Settled: the whole mesh's converged pose.
    let (want, diagonal) = converged_bar_pose(&tri, &handle_at);
    let worst = settled
        .iter()
        .zip(&want)
        .map(|(a, b)| (a.as_dvec3() - *b).length())
        .fold(0.0, f64::max);
    assert!(
        worst <= 5e-4 * diagonal,
        "settled {worst} from the whole mesh's converged pose"
    );
}

/// Steps no frame until the deformable's background solve has landed (bounded: the solve of a
/// 360-vertex bar takes milliseconds) or none runs (a solve may land before the poll of the
/// frame that started it, which then shows it at once).
fn wait_for_landing(app: &App, e: Entity) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    loop {
        let state = app
            .world()
            .get::<bevy_wii_deform::ecs::DeformState>(e)
            .unwrap();
        if state.has_landed() || !state.is_solving() {
            return;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the solve never landed: {:?}",
            app.world().get::<DeformStatus>(e)
        );
        std::thread::yield_now();
    }
}

/// The largest distance of the handle's vertices from where its transform puts them.
fn handle_error(app: &App, e: Entity, handle: Entity, rest: &[DVec3]) -> f32 {
    let h = app.world().get::<DeformHandle>(handle).unwrap();
    let t = app.world().get::<Transform>(handle).unwrap();
    let target = h.rigid_transform(t);
    let got = positions(app, e);
    h.vertices
        .iter()
        .map(|&v| (got[v as usize].as_dvec3() - target.apply(rest[v as usize])).length() as f32)
        .fold(0.0, f32::max)
}

/// When a solve lands in a frame whose handle has moved again, the next solve starts
/// in that frame, and its pose is on screen in the next one: at most one frame between a
/// handle's move and its written pose, once the worker is done.
#[test]
fn a_solve_started_in_the_frame_the_last_landed_is_on_screen_the_next_frame() {
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        std::time::Duration::from_secs_f64(1.0 / 120.0),
    ));
    app.add_plugins(DeformPlugin {
        config: DeformConfig {
            settle_iterations: 0,
            ..default()
        },
    });
    let (e, handle, tri) = spawn_bar(&mut app);
    run_until_messages(&mut app, 1);
    common::bar::settle(&mut app, e);
    let move_handle = |app: &mut App, dx: f32| {
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .translation
            .x += dx;
    };
    let landed_unpolled = |app: &App| {
        app.world()
            .get::<bevy_wii_deform::ecs::DeformState>(e)
            .unwrap()
            .has_landed()
    };
    for step in 0..5 {
        // Frame 1: the handle moves, its solve starts (and lands after that frame's poll:
        // when the worker beat the poll, the frame showed it at once; move again).
        for attempt in 0.. {
            assert!(
                attempt < 500,
                "step {step}: every solve landed within its own frame"
            );
            move_handle(&mut app, 0.02);
            app.update();
            wait_for_landing(&app, e);
            if landed_unpolled(&app) {
                break;
            }
        }
        // Frame 2: that pose lands and the handle moves again: the next solve starts now.
        move_handle(&mut app, 0.03);
        app.update();
        let shown_before = handle_error(&app, e, handle, &tri.positions);
        assert!(
            shown_before > 0.02,
            "step {step}: frame 2 still shows frame 1's pose (off by {shown_before})"
        );
        wait_for_landing(&app, e);
        // Frame 3: frame 2's pose is on screen.
        app.update();
        let err = handle_error(&app, e, handle, &tri.positions);
        assert!(
            err < 1e-4,
            "step {step}: frame 2's move is not on screen in frame 3: {err}"
        );
    }
}
