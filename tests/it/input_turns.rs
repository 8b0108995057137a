//! Turning handles with the mouse and the pointer on the spaces games have: meshes scaled by
//! 0.01 (centimetre rigs), by 2, non-uniformly, and rotated. A drag turns the handle by the
//! dragged angle about the dragged axis, seen in the world, whatever the mesh's scale.

use std::time::Duration;

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::deform::synth;
use bevy_wii_deform::ecs::{GrabHandle, GrabTwist, arcball_rotation};
use bevy_wii_deform::prelude::*;

use crate::common;
use common::{app, cursor_to, spawn_camera, to_screen};

/// The three spaces of the issue: scale 0.01, 2 and (1, 2, 0.5), each rotated.
fn scaled_spaces() -> [Transform; 3] {
    let rotation = Quat::from_euler(EulerRot::YXZ, 0.5, -0.3, 0.2);
    [
        Vec3::splat(0.01),
        Vec3::splat(2.0),
        Vec3::new(1.0, 2.0, 0.5),
    ]
    .map(|scale| {
        Transform::from_xyz(0.1, 0.0, 0.0)
            .with_rotation(rotation)
            .with_scale(scale)
    })
}

/// The world turn of a handle whose local rotation went `before` → `after` in a space whose
/// rotation is `space_rotation`.
fn world_turn(space_rotation: Quat, before: Quat, after: Quat) -> Quat {
    space_rotation * (after * before.inverse()) * space_rotation.inverse()
}

fn assert_turn(what: &str, got: Quat, want: Quat) {
    let error = got.angle_between(want).to_degrees();
    assert!(
        error < 0.5,
        "{what}: turned {:.2}° about {}, wanted {:.2}° about {} ({error:.2}° off)",
        got.to_axis_angle().1.to_degrees(),
        got.to_axis_angle().0,
        want.to_axis_angle().1.to_degrees(),
        want.to_axis_angle().0,
    );
    // The turn must be a real one, so a control that does nothing cannot pass.
    assert!(
        want.to_axis_angle().1.to_degrees() > 5.0,
        "{what}: too small"
    );
}

fn camera_transform() -> Transform {
    Transform::from_xyz(0.3, 0.6, 4.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y)
}

#[test]
fn arcball_turns_scaled_and_rotated_meshes_by_the_drag() {
    for space_transform in scaled_spaces() {
        let mut app = common::input_app(MouseControlPlugin);
        let camera = spawn_camera(&mut app, camera_transform());
        let space = app.world_mut().spawn(space_transform).id();
        let start = Quat::from_rotation_x(0.4);
        let handle = app
            .world_mut()
            .spawn((
                Transform::from_rotation(start),
                MouseHandleControl::default()
                    .with_camera(camera)
                    .with_space(space),
            ))
            .id();
        app.update();
        let centre = to_screen(&mut app, camera, space_transform.translation);
        let (from, to) = (
            centre + Vec2::new(-40.0, 20.0),
            centre + Vec2::new(70.0, -50.0),
        );
        cursor_to(&mut app, from);
        app.world_mut()
            .resource_mut::<ButtonInput<MouseButton>>()
            .press(MouseButton::Left);
        app.update();
        cursor_to(&mut app, to);
        app.update();
        let after = app.world().get::<Transform>(handle).unwrap().rotation;
        let radius = 720.0 * MouseHandleControl::default().arcball_radius;
        let in_view = arcball_rotation(from, to, centre, radius);
        let camera_rotation = camera_transform().rotation;
        let want = camera_rotation * in_view * camera_rotation.inverse();
        assert_turn(
            &format!("arcball at scale {}", space_transform.scale),
            world_turn(space_transform.rotation, start, after),
            want,
        );
    }
}

/// A grabbable bar one world unit tall in `space_transform` (its local size divides out the
/// scale), grabbed at its tip; returns the app, the camera, the mesh and the grab's handle.
fn grabbed_bar(space_transform: Transform) -> (App, Entity, Entity, Entity) {
    let mut app = app();
    app.add_plugins((DeformPlugin::default(), GrabPlugin));
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(16),
    ));
    let camera = spawn_camera(&mut app, camera_transform());
    let length = 1.0 / space_transform.scale.y as f64;
    let tri = synth::bar(12, 30, 0.1 * length, length);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(mesh),
            space_transform,
            Deformable::default(),
            Grabbable {
                radius: 0.15,
                region_radius: 1.0,
                ..default()
            },
        ))
        .id();
    common::update_until(&mut app, "the prepared mesh", |a| {
        a.world().get::<DeformStatus>(e).unwrap().vertices > 0
    });
    let top = (0..tri.positions.len())
        .max_by(|&a, &b| tri.positions[a].y.total_cmp(&tri.positions[b].y))
        .unwrap();
    let point = space_transform.transform_point(tri.positions[top].as_vec3());
    app.world_mut().write_message(GrabStart {
        pointer: PointerId::Mouse,
        entity: e,
        point,
        camera,
    });
    common::update_until(&mut app, "the grab's handle at its pivot", |a| {
        a.world()
            .get::<GrabHandle>(e)
            .and_then(|h| a.world().get::<DeformHandle>(h.0))
            .is_some_and(|h| h.pivot.is_some())
    });
    let handle = app.world().get::<GrabHandle>(e).unwrap().0;
    (app, camera, e, handle)
}

#[test]
fn grab_shift_turn_and_wheel_twist_turn_scaled_meshes_by_the_drag() {
    let camera_rotation = camera_transform().rotation;
    for space_transform in scaled_spaces() {
        let (mut app, camera, _, handle) = grabbed_bar(space_transform);
        let rotation = |app: &App| app.world().get::<Transform>(handle).unwrap().rotation;
        // Shift-drag: the arcball about the handle's position on screen.
        let before = rotation(&app);
        let at = {
            let local = app.world().get::<Transform>(handle).unwrap().translation;
            space_transform.transform_point(local)
        };
        let centre = to_screen(&mut app, camera, at);
        let (from, to) = (
            centre + Vec2::new(-30.0, 10.0),
            centre + Vec2::new(60.0, -40.0),
        );
        app.world_mut().write_message(GrabMove {
            pointer: PointerId::Mouse,
            from,
            to,
            rotate: true,
        });
        app.update();
        let in_view = arcball_rotation(from, to, centre, 0.35 * 720.0);
        assert_turn(
            &format!("shift-turn at scale {}", space_transform.scale),
            world_turn(space_transform.rotation, before, rotation(&app)),
            camera_rotation * in_view * camera_rotation.inverse(),
        );
        // The wheel: counter-clockwise on screen about the view axis.
        let before = rotation(&app);
        let radians = 30f32.to_radians();
        app.world_mut().write_message(GrabTwist {
            pointer: PointerId::Mouse,
            radians,
        });
        app.update();
        assert_turn(
            &format!("wheel-twist at scale {}", space_transform.scale),
            world_turn(space_transform.rotation, before, rotation(&app)),
            camera_rotation * Quat::from_rotation_z(radians) * camera_rotation.inverse(),
        );
    }
}

/// A remote grab on a mesh scaled by 2 moves the handle at `speed` world units per second
/// (the scale divided out), and turns it 1:1 while it moves.
#[test]
fn the_remote_moves_and_turns_a_handle_in_a_scaled_space_at_world_speed() {
    use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
    let mut app = app();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(10),
    ));
    app.add_plugins(MotionControlPlugin);
    app.world_mut()
        .spawn((Camera3d::default(), Transform::IDENTITY));
    let space_transform =
        Transform::from_rotation(Quat::from_rotation_z(0.7)).with_scale(Vec3::new(2.0, 2.0, 2.0));
    let space = app.world_mut().spawn(space_transform).id();
    let remote = app
        .world_mut()
        .spawn(MotionController {
            connection: ConnectionState::Connected,
            ..default()
        })
        .id();
    let handle = app
        .world_mut()
        .spawn((
            Transform::default(),
            MotionHandleControl::default().with_space(space),
        ))
        .id();
    let set = |app: &mut App, orientation: Quat, buttons: u16| {
        let mut w = app.world_mut().get_mut::<MotionController>(remote).unwrap();
        w.orientation = orientation;
        w.buttons = buttons;
    };
    app.update();
    set(&mut app, Quat::IDENTITY, Buttons::B);
    app.update();
    // Turn 30° about Y and hold D-pad right for 10 frames of 10 ms, at once.
    let turn = Quat::from_rotation_y(30f32.to_radians());
    set(&mut app, turn, Buttons::B | Buttons::RIGHT);
    for _ in 0..10 {
        app.update();
    }
    let t = *app.world().get::<Transform>(handle).unwrap();
    let world_motion = space_transform.transform_point(t.translation) - space_transform.translation;
    let expected = Vec3::X * MotionHandleControl::default().speed * 0.1;
    assert!(
        (world_motion - expected).length() < 0.01 * expected.length(),
        "moved {world_motion} in the world, expected {expected}"
    );
    assert_turn(
        "remote turn in a scaled space",
        world_turn(space_transform.rotation, Quat::IDENTITY, t.rotation),
        turn,
    );
}
