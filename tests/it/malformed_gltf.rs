//! Broken glTF files, made here, loaded through Bevy's glTF loader as `Deformable` scenes:
//! each gives a typed error on its entity (or, where the file is still usable, a working mesh
//! with finite data), and the app keeps running.

use std::path::Path;
use std::time::Duration;

use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::prelude::*;

use crate::common;
use crate::common::scratch::ScratchDir;
use crate::fixtures::broken_gltf::write_files;
use bevy_wii_deform::ecs::MESH_WAIT_FRAMES;

fn gltf_app(dir: &Path) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::asset::AssetPlugin {
            file_path: dir.display().to_string(),
            ..default()
        },
        bevy::mesh::MeshPlugin,
        bevy::transform::TransformPlugin,
        bevy::image::ImagePlugin::default(),
        bevy::world_serialization::WorldSerializationPlugin,
        bevy::gltf::GltfPlugin::default(),
        DeformPlugin::default(),
    ));
    app.init_asset::<StandardMaterial>();
    app.finish();
    app.cleanup();
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(16),
    ));
    app
}

#[test]
fn malformed_gltf_never_panics() {
    let dir = ScratchDir::new("malformed_gltf");
    let files = write_files(&dir);
    let mut app = gltf_app(&dir);
    let roots: Vec<(Entity, &str, bool)> = files
        .iter()
        .map(|&(name, usable)| {
            let scene = app
                .world()
                .resource::<AssetServer>()
                .load(GltfAssetLabel::Scene(0).from_asset(name));
            let e = app
                .world_mut()
                .spawn((
                    WorldAssetRoot(scene),
                    Deformable::default(),
                    Name::new(name),
                ))
                .id();
            (e, name, usable)
        })
        .collect();
    // Every root ends up handed to its meshes (usable) or failed with a reason.
    let settled = |app: &mut App, e: Entity| -> bool {
        let world = app.world();
        let status = world.get::<DeformStatus>(e).unwrap();
        if status.phase == DeformPhase::Failed {
            return true;
        }
        world.get::<DeformableScene>(e).is_some_and(|s| {
            s.primitives.iter().all(|&p| {
                world
                    .get::<DeformStatus>(p)
                    .is_some_and(|st| matches!(st.phase, DeformPhase::Idle | DeformPhase::Failed))
            })
        })
    };
    common::update_until(&mut app, "every file loaded or failed", |a| {
        roots.iter().all(|&(e, _, _)| settled(a, e))
    });
    for _ in 0..10 {
        app.update(); // keeps running
    }
    for &(e, name, usable) in &roots {
        let world = app.world();
        let root_error = world.get::<DeformStatus>(e).unwrap().error.clone();
        let primitive_errors: Vec<DeformError> = world
            .get::<DeformableScene>(e)
            .map(|s| {
                s.primitives
                    .iter()
                    .filter_map(|&p| world.get::<DeformStatus>(p).and_then(|st| st.error.clone()))
                    .collect()
            })
            .unwrap_or_default();
        if usable {
            assert_eq!(root_error, None, "{name}");
            assert!(primitive_errors.is_empty(), "{name}: {primitive_errors:?}");
            // Its mesh data is finite (no NaN reached the mesh).
            let scene = world.get::<DeformableScene>(e).unwrap();
            for &p in &scene.primitives {
                let mesh = world.get::<Mesh3d>(p).unwrap();
                let mesh = world.resource::<Assets<Mesh>>().get(&mesh.0).unwrap();
                for attribute in [Mesh::ATTRIBUTE_POSITION, Mesh::ATTRIBUTE_NORMAL] {
                    if let Some(bevy::mesh::VertexAttributeValues::Float32x3(v)) =
                        mesh.attribute(attribute)
                    {
                        assert!(
                            v.iter().flatten().all(|x| x.is_finite()),
                            "{name}: non-finite {attribute:?}"
                        );
                    }
                }
            }
        } else {
            assert!(
                root_error.is_some() || !primitive_errors.is_empty(),
                "{name} gave no error"
            );
            eprintln!("{name}: {root_error:?} {primitive_errors:?}");
        }
    }
}

/// A `Deformable` on a plain ancestor whose mesh children arrive a few frames later is handed
/// to them; one whose children never come fails with `NoMeshBelow` after the bounded wait.
#[test]
fn late_children_are_waited_for_then_fail_with_the_reason() {
    let mut app = common::app();
    app.add_plugins(DeformPlugin::default());
    let late = app
        .world_mut()
        .spawn((Deformable::default(), Transform::default()))
        .id();
    let never = app
        .world_mut()
        .spawn((Deformable::default(), Transform::default()))
        .id();
    for _ in 0..3 {
        app.update();
    }
    let tri = bevy_wii_deform::deform::synth::bar(8, 10, 0.1, 1.0);
    let mesh = mesh_from_triangles(&tri.positions, &tri.triangles);
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let child = app
        .world_mut()
        .spawn((Mesh3d(mesh), Transform::default(), ChildOf(late)))
        .id();
    for _ in 0..(MESH_WAIT_FRAMES + 5) {
        app.update();
    }
    assert_eq!(
        app.world()
            .get::<DeformableScene>(late)
            .map(|s| s.primitives.clone()),
        Some(vec![child])
    );
    assert_eq!(app.world().get::<DeformStatus>(late).unwrap().error, None);
    let status = app.world().get::<DeformStatus>(never).unwrap();
    assert_eq!(status.phase, DeformPhase::Failed);
    assert_eq!(status.error, Some(DeformError::NoMeshBelow));
}
