//! `GrabPlugin` headless on meshes: grabs bend meshes under the pointer and keep the pose; two
//! pointers grab two meshes at once. (Grabs of characters: `character_grab.rs`.)

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::ecs::GrabHandle;
use bevy_wii_deform::prelude::*;

use crate::common;
use crate::common::bar::*;
use common::{app, spawn_camera, to_screen};

/// A headless app with deformation and grabs, and a camera at `eye` looking at `target`.
fn grab_app(eye: Vec3, target: Vec3) -> (App, Entity) {
    let mut app = app();
    app.add_plugins((DeformPlugin::default(), GrabPlugin));
    let camera = spawn_camera(
        &mut app,
        Transform::from_translation(eye).looking_at(target, Vec3::Y),
    );
    (app, camera)
}

#[test]
fn grabbing_a_scaled_rotated_mesh_bends_it_under_the_pointer_and_keeps_the_pose() {
    let (mut app, camera) = grab_app(Vec3::new(0.0, 1.0, 7.0), Vec3::new(0.0, 1.0, 0.0));
    let (mesh, tri) = bar_mesh();
    let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(h),
            Transform::from_xyz(0.2, 0.1, 0.0)
                .with_rotation(Quat::from_rotation_z(-0.3))
                .with_scale(Vec3::splat(2.0)),
            Deformable {
                max_iterations: Some(20),
                tolerance: Some(0.0),
                ..default()
            },
            // World units: the patch is the tip's cap, the region the upper half of the bar.
            Grabbable {
                radius: 0.15,
                region_radius: 1.0,
                ..default()
            },
        ))
        .id();
    while app.world().get::<DeformStatus>(e).unwrap().vertices == 0 {
        app.update();
    }
    let world = |app: &App, p: Vec3| {
        app.world()
            .get::<GlobalTransform>(e)
            .unwrap()
            .transform_point(p)
    };
    let top = (0..tri.positions.len())
        .max_by(|&a, &b| tri.positions[a].y.total_cmp(&tri.positions[b].y))
        .unwrap();
    let bottom = (0..tri.positions.len())
        .min_by(|&a, &b| tri.positions[a].y.total_cmp(&tri.positions[b].y))
        .unwrap();
    let grab = |app: &mut App, vertex: usize, pixels: Vec2| -> Vec3 {
        let point = world(app, positions(app, e)[vertex]);
        app.world_mut().write_message(GrabStart {
            pointer: PointerId::Mouse,
            entity: e,
            point,
            camera,
        });
        let from = to_screen(app, camera, point);
        app.world_mut().write_message(GrabMove {
            pointer: PointerId::Mouse,
            from,
            to: from + pixels,
            rotate: false,
        });
        settle(app, e);
        app.world_mut().write_message(GrabEnd {
            pointer: PointerId::Mouse,
        });
        settle(app, e);
        under_cursor(app, camera, point, from + pixels) - point
    };
    let drag = grab(&mut app, top, Vec2::new(70.0, 30.0));
    assert!(drag.length() > 0.2, "{drag}");
    let handle = app.world().get::<GrabHandle>(e).expect("a grab handle").0;
    let patch = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .vertices
        .clone();
    assert!(
        patch.contains(&(top as u32)) && patch.len() < 40,
        "{}",
        patch.len()
    );
    let got = positions(&app, e);
    for &v in &patch {
        let moved = world(&app, got[v as usize]) - world(&app, tri.positions[v as usize].as_vec3());
        assert!(
            (moved - drag).length() < 0.02 * drag.length(),
            "vertex {v}: {moved} vs {drag}"
        );
    }
    // The far end is outside the region: exactly at rest.
    let far = (got[bottom].as_dvec3() - tri.positions[bottom]).length();
    assert!(far < 1e-6, "{far}");
    // Released: the pose stays. A second grab, at the bottom, keeps the first bend.
    let tip_after_first = world(&app, got[top]);
    let second = grab(&mut app, bottom, Vec2::new(-30.0, 0.0));
    assert!(second.length() > 0.05);
    let tip_now = world(&app, positions(&app, e)[top]);
    assert!(
        (tip_now - tip_after_first).length() < 0.02 * drag.length(),
        "the first bend was lost: tip at {tip_now}, was {tip_after_first}"
    );
}

#[test]
fn two_pointers_grab_two_meshes_at_once_one_moving_one_turning() {
    let (mut app, camera) = grab_app(Vec3::new(0.0, 0.6, 5.0), Vec3::new(0.0, 0.6, 0.0));
    let (_, tri) = bar_mesh();
    let mut spawn = |x: f32| {
        let (mesh, _) = bar_mesh();
        let h = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        app.world_mut()
            .spawn((
                Mesh3d(h),
                Transform::from_xyz(x, 0.0, 0.0),
                Deformable::default(),
                // The patch takes in the cap's ring, off the turning axis.
                Grabbable {
                    radius: 0.15,
                    region_radius: 0.6,
                    ..default()
                },
            ))
            .id()
    };
    let (a, b) = (spawn(-0.8), spawn(0.8));
    while [a, b]
        .iter()
        .any(|e| app.world().get::<DeformStatus>(*e).unwrap().vertices == 0)
    {
        app.update();
    }
    let top = (0..tri.positions.len())
        .max_by(|&i, &j| tri.positions[i].y.total_cmp(&tri.positions[j].y))
        .unwrap();
    let tip = |x: f32| tri.positions[top].as_vec3() + Vec3::X * x;
    let (mouse, finger) = (PointerId::Mouse, PointerId::Touch(1));
    for (pointer, entity, x) in [(mouse, a, -0.8), (finger, b, 0.8)] {
        app.world_mut().write_message(GrabStart {
            pointer,
            entity,
            point: tip(x),
            camera,
        });
    }
    // Let both handles be placed, then move A with the mouse and turn B with the finger.
    settle(&mut app, a);
    settle(&mut app, b);
    let (from_a, from_b) = (
        to_screen(&mut app, camera, tip(-0.8)),
        to_screen(&mut app, camera, tip(0.8)),
    );
    app.world_mut().write_message(GrabMove {
        pointer: mouse,
        from: from_a,
        to: from_a + Vec2::new(-40.0, 0.0),
        rotate: false,
    });
    app.world_mut().write_message(GrabMove {
        pointer: finger,
        from: from_b,
        to: from_b + Vec2::new(60.0, 0.0),
        rotate: true,
    });
    settle(&mut app, a);
    settle(&mut app, b);
    let handle_of = |app: &App, e: Entity| {
        let h = app.world().get::<GrabHandle>(e).unwrap().0;
        *app.world().get::<Transform>(h).unwrap()
    };
    let pivot_of = |app: &App, e: Entity| {
        let h = app.world().get::<GrabHandle>(e).unwrap().0;
        app.world().get::<DeformHandle>(h).unwrap().pivot.unwrap()
    };
    // A: moved left under the mouse, not turned.
    let ta = handle_of(&app, a);
    let moved = ta.translation - pivot_of(&app, a);
    let expected =
        under_cursor(&mut app, camera, tip(-0.8), from_a + Vec2::new(-40.0, 0.0)) - tip(-0.8);
    assert!(
        (moved - expected).length() < 0.02 * expected.length(),
        "{moved} vs {expected}"
    );
    assert!(ta.rotation.angle_between(Quat::IDENTITY) < 1e-6);
    // B: turned about the view's up axis (a horizontal arcball drag), not moved.
    let tb = handle_of(&app, b);
    assert!((tb.translation - pivot_of(&app, b)).length() < 1e-6);
    let (axis, angle) = tb.rotation.to_axis_angle();
    assert!(
        angle > 0.05 && axis.y > 0.95,
        "turned {angle} rad about {axis}"
    );
    // The meshes follow: A's tip by the drag, B's patch turned (off-axis vertices moved).
    let got_a = positions(&app, a);
    let tip_moved = got_a[top].as_dvec3() - tri.positions[top];
    assert!(
        (tip_moved.as_vec3() - expected).length() < 0.02 * expected.length(),
        "{tip_moved}"
    );
    let h = app.world().get::<GrabHandle>(b).unwrap().0;
    let patch = app.world().get::<DeformHandle>(h).unwrap().vertices.clone();
    let got_b = positions(&app, b);
    let turned = patch
        .iter()
        .map(|&v| (got_b[v as usize].as_dvec3() - tri.positions[v as usize]).length())
        .fold(0.0, f64::max);
    assert!(turned > 1e-3, "{turned}");
}
