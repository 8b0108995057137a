//! A glTF whose texture's image file is missing costs only the texture: the geometry, the skin
//! and the scene load, the character poses (down to a rig of one joint), a `Deformable` on it
//! bends, and the statuses name the missing file.

use std::path::Path;
use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::prelude::*;

use crate::common::scratch::ScratchDir;
use crate::common::{drive_solves, headless_gltf, spawn_handle, update_until};
use crate::fixtures::textured_rig::{LENGTH, MISSING_IMAGE, write_textured_rig};

/// A fresh folder for this test's files (removed when the test ends).
fn folder(name: &str) -> ScratchDir {
    ScratchDir::new(name)
}

/// A headless app loading from `dir` with `plugins` and the file's materials as
/// `StandardMaterial`s (as a game's renderer makes them: the scene then depends on the
/// texture); the scene `file` spawned with `root` on its root.
fn app_with_scene<M>(
    dir: &Path,
    file: &str,
    plugins: impl bevy::app::Plugins<M>,
    root: impl Bundle,
) -> (App, Entity) {
    let mut app = App::new();
    app.add_plugins(MinimalPlugins);
    headless_gltf::add_gltf_plugins(&mut app, dir);
    app.add_plugins(plugins);
    app.finish();
    app.cleanup();
    // Materials as a game has them: the scene depends on its textures through them.
    headless_gltf::add_standard_materials(&mut app);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        16,
    )));
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset(file.to_string()));
    let entity = app.world_mut().spawn((WorldAssetRoot(scene), root)).id();
    (app, entity)
}

#[test]
fn a_rig_whose_texture_is_missing_poses_and_names_the_file() {
    for joints in [1, 3] {
        let dir = folder(&format!("missing_texture_{joints}"));
        let file = format!("rig{joints}.glb");
        write_textured_rig(&dir, &file, joints);
        assert!(!dir.join(MISSING_IMAGE).exists());
        let (mut app, character) = app_with_scene(&dir, &file, PosePlugin, Poseable::default());
        update_until(&mut app, "the character's model or an error", |a| {
            a.world().get::<PosedSkeleton>(character).is_some()
                || a.world()
                    .get::<PoseStatus>(character)
                    .is_some_and(|s| s.error.is_some())
        });
        let status = app.world().get::<PoseStatus>(character).unwrap();
        assert_eq!(status.error, None, "{joints} joint(s): {status:?}");
        assert_eq!(status.joints, joints);
        update_until(&mut app, "the missing image's warning", |a| {
            a.world()
                .get::<PoseStatus>(character)
                .is_some_and(|s| s.warning.is_some())
        });
        let warning = app
            .world()
            .get::<PoseStatus>(character)
            .unwrap()
            .warning
            .clone();
        assert!(
            warning
                .as_deref()
                .is_some_and(|w| w.contains(MISSING_IMAGE)),
            "the warning names the missing file: {warning:?}"
        );
        let missing = app.world().get::<MissingSceneAssets>(character).unwrap();
        assert!(missing.message.contains(MISSING_IMAGE));

        // It poses: the top of the bar follows a handle.
        let posed = app.world().get::<PosedSkeleton>(character).unwrap();
        let before = posed.skinned_positions().to_vec();
        let top: Vec<u32> = (0..before.len() as u32)
            .filter(|&v| before[v as usize].y > LENGTH as f32 - 0.06)
            .collect();
        assert!(!top.is_empty());
        let (handle, pivot) = spawn_handle(&mut app, character, top.clone(), ());
        let shift = Vec3::new(0.2, 0.0, 0.0);
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .translation = pivot + shift;
        drive_solves(&mut app, character, handle, 6);
        app.update();
        let after = app
            .world()
            .get::<PosedSkeleton>(character)
            .unwrap()
            .skinned_positions()
            .to_vec();
        let moved: Vec3 = top
            .iter()
            .map(|&v| after[v as usize] - before[v as usize])
            .sum::<Vec3>()
            / top.len() as f32;
        assert!(
            (moved - shift).length() < 0.02,
            "{joints} joint(s): the top moved {moved}, the handle {shift}"
        );
        assert!(after.iter().all(|p| p.is_finite()));
    }
}

#[test]
fn a_scene_whose_texture_is_missing_bends_and_names_the_file() {
    let dir = folder("missing_texture_deform");
    write_textured_rig(&dir, "bar.glb", 2);
    let (mut app, root) = app_with_scene(
        &dir,
        "bar.glb",
        DeformPlugin::default(),
        Deformable::default(),
    );
    update_until(&mut app, "the primitives or a failure", |a| {
        a.world().get::<DeformableScene>(root).is_some()
            || a.world().get::<DeformStatus>(root).unwrap().phase == DeformPhase::Failed
    });
    let status = app.world().get::<DeformStatus>(root).unwrap();
    assert_eq!(status.error, None);
    let primitives = app
        .world()
        .get::<DeformableScene>(root)
        .unwrap()
        .primitives
        .clone();
    assert_eq!(primitives.len(), 1);
    update_until(&mut app, "the primitive prepared", |a| {
        a.world()
            .get::<DeformStatus>(primitives[0])
            .is_some_and(|s| s.vertices > 0)
    });
    update_until(&mut app, "the missing image's warning", |a| {
        a.world()
            .get::<DeformStatus>(root)
            .is_some_and(|s| s.warning.is_some())
    });
    let warning = app
        .world()
        .get::<DeformStatus>(root)
        .unwrap()
        .warning
        .clone();
    assert!(warning.unwrap().contains(MISSING_IMAGE));
}

#[test]
fn a_missing_model_file_still_fails() {
    let dir = folder("missing_model");
    let (mut app, character) = app_with_scene(&dir, "absent.glb", PosePlugin, Poseable::default());
    update_until(&mut app, "the failure", |a| {
        a.world()
            .get::<PoseStatus>(character)
            .is_some_and(|s| s.error.is_some())
    });
    let error = app
        .world()
        .get::<PoseStatus>(character)
        .unwrap()
        .error
        .clone();
    assert!(
        matches!(&error, Some(PoseableError::SceneLoadFailed(m)) if m.contains("absent.glb")),
        "{error:?}"
    );
    assert!(app.world().get::<MissingSceneAssets>(character).is_none());
}
