//! Grabs start from bevy_picking's hits: only the grab button grabs, and what picking puts in
//! front (another mesh, UI) takes the press from a character behind it.

use std::time::Duration;

use bevy::picking::backend::{HitData, PointerHits};
use bevy::picking::pointer::{PointerAction, PointerButton};
use bevy::prelude::*;
use bevy_wii_deform::deform::synth;
use bevy_wii_deform::ecs::ActiveGrabs;
use bevy_wii_deform::prelude::*;

use crate::common;
use common::{picking_plugins, pointer, spawn_camera, to_screen};

/// A headless app with picking, deformation, posing and grabs, and a camera.
fn picking_app() -> (App, Entity) {
    let mut app = common::input_app((
        picking_plugins(),
        MeshPickingPlugin,
        DeformPlugin::default(),
        PosePlugin,
        GrabPlugin,
    ));
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(16),
    ));
    let camera = spawn_camera(
        &mut app,
        Transform::from_xyz(0.0, 0.5, 4.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y),
    );
    (app, camera)
}

fn grabs(app: &App) -> usize {
    app.world().resource::<ActiveGrabs>().len()
}

/// Presses `button` at `at`, updates twice, releases it and updates until the grab ended.
fn click(app: &mut App, at: Vec2, button: PointerButton) -> usize {
    pointer(app, at, PointerAction::Press(button));
    app.update();
    app.update();
    let grabbed = grabs(app);
    pointer(app, at, PointerAction::Release(button));
    app.update();
    assert_eq!(
        grabs(app),
        0,
        "the release of {button:?} did not end the grab"
    );
    grabbed
}

#[test]
fn only_the_grab_button_starts_a_grab() {
    let (mut app, camera) = picking_app();
    let tri = synth::bar(12, 30, 0.1, 1.0);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = app
        .world_mut()
        .spawn((
            Mesh3d(mesh),
            Transform::default(),
            Deformable::default(),
            Grabbable::default(),
        ))
        .id();
    common::update_until(&mut app, "the prepared mesh", |a| {
        a.world().get::<DeformStatus>(e).unwrap().vertices > 0
    });
    let at = to_screen(&mut app, camera, Vec3::new(0.0, 0.8, 0.1));
    assert_eq!(click(&mut app, at, PointerButton::Secondary), 0, "right");
    assert_eq!(click(&mut app, at, PointerButton::Middle), 0, "middle");
    assert_eq!(click(&mut app, at, PointerButton::Primary), 1, "primary");
    // Another grab button: now the right button grabs and the left does not.
    app.insert_resource(GrabButton(PointerButton::Secondary));
    assert_eq!(
        click(&mut app, at, PointerButton::Primary),
        0,
        "primary after"
    );
    assert_eq!(
        click(&mut app, at, PointerButton::Secondary),
        1,
        "secondary after"
    );
}

/// A grabbable bar character at the origin; returns it once posed.
fn spawn_character(app: &mut App) -> Entity {
    let rig = bevy_wii_deform::pose::rig::synth_rig::bar_rig(3, 12, 30);
    let (root, joints, _) = common::spawn_rig(app, &rig, Vec3::ZERO);
    app.world_mut().entity_mut(root).insert((
        Poseable::default(),
        PinnedJoints(vec![joints[0]]),
        Grabbable {
            radius: 0.12,
            region_radius: 1.0,
            ..default()
        },
    ));
    common::update_until(app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    root
}

#[test]
fn a_mesh_in_front_occludes_a_character() {
    let (mut app, camera) = picking_app();
    let character = spawn_character(&mut app);
    let at = to_screen(&mut app, camera, Vec3::new(0.0, 0.8, 0.1));
    // Nothing in front: the press grabs the character.
    assert_eq!(click(&mut app, at, PointerButton::Primary), 1);
    // A (non-grabbable) box between the camera and the character takes the press.
    let cube = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(0.5, 0.5, 0.1));
    app.world_mut()
        .spawn((Mesh3d(cube), Transform::from_xyz(0.0, 0.8, 1.5)));
    app.update();
    app.update();
    assert_eq!(click(&mut app, at, PointerButton::Primary), 0);
    assert!(app.world().get::<PosedSkeleton>(character).is_some());
}

/// A stand-in for bevy_ui's picking backend: a full-screen panel reported at the camera's
/// order + 0.5, as bevy_ui reports its nodes (above every 3D hit of that camera).
#[derive(Resource)]
struct Panel(Entity);

fn panel_hits(
    panel: Option<Res<Panel>>,
    rays: Res<bevy::picking::backend::ray::RayMap>,
    mut hits: MessageWriter<PointerHits>,
) {
    let Some(panel) = panel else {
        return;
    };
    for (id, _) in rays.iter() {
        let hit = HitData::new(id.camera, 0.0, None, None);
        hits.write(PointerHits::new(id.pointer, vec![(panel.0, hit)], 0.5));
    }
}

#[test]
fn ui_over_a_character_blocks_its_grab() {
    let (mut app, camera) = picking_app();
    app.add_systems(
        PreUpdate,
        panel_hits.in_set(bevy::picking::PickingSystems::Backend),
    );
    spawn_character(&mut app);
    let at = to_screen(&mut app, camera, Vec3::new(0.0, 0.8, 0.1));
    assert_eq!(click(&mut app, at, PointerButton::Primary), 1, "no panel");
    let panel = app.world_mut().spawn(Name::new("panel")).id();
    app.insert_resource(Panel(panel));
    assert_eq!(
        click(&mut app, at, PointerButton::Primary),
        0,
        "under a panel"
    );
}
