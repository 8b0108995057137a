//! `MouseControlPlugin` headless: drags move handles with the cursor on scaled and rotated
//! meshes and characters; the arcball turns about the view axes.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use crate::common;
use crate::common::bar::*;
use common::{shift_drag, spawn_camera, to_screen};

/// A headless app with the mouse control and deformation.
fn mouse_app() -> App {
    common::input_app((DeformPlugin::default(), MouseControlPlugin))
}

#[test]
fn a_mouse_drag_moves_a_handle_on_a_scaled_rotated_mesh_with_the_cursor() {
    let mut app = mouse_app();
    let camera = spawn_camera(
        &mut app,
        Transform::from_xyz(0.5, 1.0, 6.0).looking_at(Vec3::new(0.0, 1.0, 0.0), Vec3::Y),
    );
    let (mesh, tri) = bar_mesh();
    let (fixed, handle_vertices) = regions(&tri);
    let bundle_source = mesh.clone();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let mesh_transform = Transform::from_xyz(0.3, 0.2, 0.0)
        .with_rotation(Quat::from_rotation_z(0.6))
        .with_scale(Vec3::splat(2.0));
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            mesh_transform,
            Deformable {
                max_iterations: Some(30),
                tolerance: Some(0.0),
                ..default()
            },
            FixedRegion(fixed),
        ))
        .id();
    let (handle_component, handle_transform) =
        DeformHandle::bundle(&bundle_source, e, handle_vertices.clone());
    let handle = app
        .world_mut()
        .spawn((
            handle_component,
            handle_transform,
            MouseHandleControl::default()
                .with_camera(camera)
                .with_space(e),
        ))
        .id();
    assert_eq!(run_until_messages(&mut app, 1).0.len(), 1);
    app.update();
    // Where the handle is on screen.
    let world_of = |app: &App, local: Vec3| {
        app.world()
            .get::<GlobalTransform>(e)
            .unwrap()
            .transform_point(local)
    };
    let start_world = world_of(&app, handle_transform.translation);
    let start = to_screen(&mut app, camera, start_world);
    let end = start + Vec2::new(60.0, -25.0);
    shift_drag(&mut app, start, end, 3);
    // The handle is under the cursor, at its depth.
    let moved_world = world_of(
        &app,
        app.world().get::<Transform>(handle).unwrap().translation,
    );
    let expected = under_cursor(&mut app, camera, start_world, end);
    let drag = expected - start_world;
    assert!(drag.length() > 0.1, "{drag}");
    assert!(
        (moved_world - expected).length() < 0.02 * drag.length(),
        "handle at {moved_world}, cursor ray at {expected}"
    );
    // The solve moves the handle's vertices by the drag, in world space; the fixed end stays.
    // (Solves of the drag's intermediate frames may land first: wait until the latest did.)
    settle(&mut app, e);
    let got = positions(&app, e);
    let mesh_to_world = app.world().get::<GlobalTransform>(e).unwrap().affine();
    for &v in handle_vertices.iter().take(20) {
        let rest = mesh_to_world.transform_point3(tri.positions[v as usize].as_vec3());
        let now = mesh_to_world.transform_point3(got[v as usize]);
        assert!(
            ((now - rest) - drag).length() < 0.02 * drag.length(),
            "vertex {v}: {}",
            now - rest
        );
    }
    let (fixed, _) = regions(&tri);
    for &v in &fixed {
        assert!((got[v as usize].as_dvec3() - tri.positions[v as usize]).length() < 1e-5);
    }
    assert!(
        !app.world()
            .get::<MouseHandleControl>(handle)
            .unwrap()
            .is_dragging()
    );
}

#[test]
fn the_arcball_turns_about_the_view_axes() {
    let centre = Vec2::new(400.0, 300.0);
    // A horizontal drag through the centre turns about the view's up axis, to the right.
    use bevy_wii_deform::ecs::arcball_rotation;
    let q = arcball_rotation(centre, centre + Vec2::new(50.0, 0.0), centre, 200.0);
    let (axis, angle) = q.to_axis_angle();
    assert!(
        axis.y > 0.99 && (angle - (0.25f32).asin()).abs() < 1e-4,
        "{axis} {angle}"
    );
    // Dragging along the rim rolls about the view direction.
    let q = arcball_rotation(
        centre + Vec2::new(300.0, 0.0),
        centre + Vec2::new(0.0, -300.0),
        centre,
        200.0,
    );
    let (axis, angle) = q.to_axis_angle();
    assert!(
        axis.z > 0.99 && (angle - std::f32::consts::FRAC_PI_2).abs() < 1e-4,
        "{axis} {angle}"
    );
}
