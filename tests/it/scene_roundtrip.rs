//! A scene saved from the world and loaded back (`DynamicWorld`) keeps every entity reference
//! of the crate's components pointing at the right (new) entities.

use bevy::ecs::entity::EntityHashMap;
use bevy::prelude::*;
use bevy::world_serialization::DynamicWorld;
use bevy_wii_deform::ecs::{DeformableFrom, DeformableScene, GrabHandle};
use bevy_wii_deform::prelude::*;

use crate::common;

/// An app whose type registry knows every component of the crate (no update is run).
fn registry_app() -> App {
    let mut app = common::app();
    app.add_plugins((
        DeformPlugin::default(),
        PosePlugin,
        GrabPlugin,
        MouseControlPlugin,
        MotionControlPlugin,
    ));
    app
}

#[test]
fn a_scene_round_trip_keeps_handles_pins_and_controls_pointing_at_the_right_entities() {
    let mut source = registry_app();
    let world = source.world_mut();
    let camera = world.spawn(Name::new("camera")).id();
    let remote = world.spawn(Name::new("remote")).id();
    let mesh = world.spawn(Name::new("mesh")).id();
    let root = world
        .spawn((
            Name::new("root"),
            DeformableScene {
                primitives: vec![mesh],
            },
        ))
        .id();
    world.entity_mut(mesh).insert(DeformableFrom(root));
    let hip = world.spawn(Name::new("hip")).id();
    let foot = world.spawn(Name::new("foot")).id();
    let character = world
        .spawn((Name::new("character"), PinnedJoints(vec![hip, foot])))
        .id();
    let handle = world
        .spawn((
            Name::new("handle"),
            DeformHandle {
                target: mesh,
                vertices: vec![1, 2, 3],
                pivot: None,
            },
            MouseHandleControl::default()
                .with_camera(camera)
                .with_space(mesh),
            MotionHandleControl::default()
                .with_remote(remote)
                .with_camera(camera)
                .with_space(mesh),
        ))
        .id();
    world.entity_mut(mesh).insert(GrabHandle(handle));
    world.entity_mut(character).insert(PoseAnchor {
        joints: vec![foot],
        vertices: vec![7],
    });
    let joint_handle = world
        .spawn((
            Name::new("joint handle"),
            PoseJointHandle::new(character, foot),
        ))
        .id();
    let saved = DynamicWorld::from_world(source.world());

    let mut target = registry_app();
    // Other entities first, so the loaded ones get other ids than in the source.
    for _ in 0..17 {
        target.world_mut().spawn_empty();
    }
    let mut map = EntityHashMap::default();
    saved.write_to_world(target.world_mut(), &mut map).unwrap();
    let new = |e: Entity| *map.get(&e).unwrap();
    assert_ne!(new(mesh), mesh, "the test needs new ids");
    let w = target.world();
    let h = w.get::<DeformHandle>(new(handle)).unwrap();
    assert_eq!(h.target, new(mesh));
    assert_eq!(h.vertices, vec![1, 2, 3]);
    let mouse = w.get::<MouseHandleControl>(new(handle)).unwrap();
    assert_eq!(
        (mouse.camera, mouse.space),
        (Some(new(camera)), Some(new(mesh)))
    );
    let wii = w.get::<MotionHandleControl>(new(handle)).unwrap();
    assert_eq!(
        (wii.remote, wii.camera, wii.space),
        (Some(new(remote)), Some(new(camera)), Some(new(mesh)))
    );
    assert_eq!(
        w.get::<PinnedJoints>(new(character)).unwrap().0,
        vec![new(hip), new(foot)]
    );
    let jh = w.get::<PoseJointHandle>(new(joint_handle)).unwrap();
    assert_eq!((jh.target, jh.joint), (new(character), new(foot)));
    assert_eq!(w.get::<DeformableFrom>(new(mesh)).unwrap().0, new(root));
    assert_eq!(
        w.get::<DeformableScene>(new(root)).unwrap().primitives,
        vec![new(mesh)]
    );
    assert_eq!(w.get::<GrabHandle>(new(mesh)).unwrap().0, new(handle));
    assert_eq!(
        w.get::<PoseAnchor>(new(character)).unwrap().joints,
        vec![new(foot)]
    );
}

/// `DeformConfig`'s accelerations and preview region (core types) are reflected: applying
/// another config through reflection changes them, and its reflected fields name them.
#[test]
fn deform_config_reflects_its_accelerations() {
    use bevy::reflect::structs::Struct;
    use bevy_wii_deform::deform::Acceleration;
    let mut app = common::app();
    app.add_plugins(DeformPlugin::default());
    let mut config = app.world().resource::<DeformConfig>().clone();
    let mut other = config.clone();
    other.acceleration = Acceleration::Anderson { depth: 5 };
    other.settle_acceleration = Acceleration::None;
    other.preview = other
        .preview
        .map(|p| bevy_wii_deform::deform::PreviewRegion {
            max_vertices: 1234,
            ..p
        });
    assert_ne!(config.acceleration, other.acceleration);
    config.apply(other.as_partial_reflect());
    assert_eq!(config.acceleration, Acceleration::Anderson { depth: 5 });
    assert_eq!(config.settle_acceleration, Acceleration::None);
    assert_eq!(config.preview.map(|p| p.max_vertices), Some(1234));
    assert!(config.field("acceleration").is_some());
    assert!(config.field("settle_acceleration").is_some());
    assert!(config.field("preview").is_some());
    other.preview = None;
    config.apply(other.as_partial_reflect());
    assert_eq!(config.preview, None);
}

/// A character's last error is shown through reflection (an opaque value an inspector can
/// print) and a scene holding it saves and loads (the error is not written: a loaded scene
/// prepares its characters again).
#[test]
fn a_pose_error_is_reflected_and_scenes_skip_it() {
    use bevy::reflect::structs::Struct;
    use bevy_wii_deform::ecs::PoseableError;
    let mut source = registry_app();
    let status = PoseStatus {
        joints: 3,
        error: Some(PoseableError::NoSkinnedMesh),
        ..default()
    };
    let shown = format!("{:?}", status.field("error").unwrap());
    assert!(shown.contains("NoSkinnedMesh"), "{shown}");
    let character = source.world_mut().spawn(status).id();
    let registry = source.world().resource::<AppTypeRegistry>().read();
    let saved =
        bevy::world_serialization::DynamicWorldBuilder::from_world(source.world(), &registry)
            .extract_entity(character)
            .build();
    let text = saved
        .serialize(&registry)
        .expect("a scene with a pose error serialises");
    assert!(!text.contains("NoSkinnedMesh"), "{text}");
    drop(registry);
    let mut target = registry_app();
    let mut map = EntityHashMap::default();
    saved.write_to_world(target.world_mut(), &mut map).unwrap();
    let loaded = target.world().get::<PoseStatus>(map[&character]).unwrap();
    assert_eq!(loaded.joints, 3);
}

/// A `Poseable` written before `ground_iterations` existed (the field missing from its RON)
/// loads with the default (through `#[reflect(Default)]`), not an error or zero.
#[test]
fn a_poseable_saved_before_ground_iterations_loads_with_the_default() {
    use bevy::reflect::FromReflect;
    use bevy::reflect::serde::TypedReflectDeserializer;
    use serde::de::DeserializeSeed;
    let app = registry_app();
    let registry = app.world().resource::<AppTypeRegistry>().read();
    let registration = registry.get(std::any::TypeId::of::<Poseable>()).unwrap();
    let old = "(max_iterations: 6, tolerance: 0.001, clusters: 40, hold_pose: false)";
    let mut ron = ron::Deserializer::from_str(old).unwrap();
    let value = TypedReflectDeserializer::new(registration, &registry)
        .deserialize(&mut ron)
        .expect("an old Poseable loads");
    let loaded = Poseable::from_reflect(value.as_partial_reflect()).unwrap();
    assert_eq!(loaded.max_iterations, 6);
    assert_eq!(loaded.clusters, 40);
    assert_eq!(
        loaded.ground_iterations,
        Poseable::default().ground_iterations
    );
    assert!(loaded.ground_iterations > 0);
}
