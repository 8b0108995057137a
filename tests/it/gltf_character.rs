//! Characters read from glTF files without Bevy (`pose::rig::gltf_character`): the same
//! skeleton, rest pose and skin the ECS layer reads from the scene Bevy's loader spawns, for
//! the repository's characters and the shared ones; malformed hierarchies and files that claim
//! more than the readers' bounds refused with typed errors.

use std::path::Path;

use bevy::prelude::*;
use bevy_wii_deform::deform::glb_container;
use bevy_wii_deform::pose::{
    CharacterReadError, ClipError, GltfCharacter, GltfFileError, MAX_ACCESSOR_ELEMENTS,
    ModelSettings, read_gltf_character, read_gltf_clip,
};
use bevy_wii_deform::prelude::{PosePlugin, PosedSkeleton};

use crate::common::scratch::ScratchDir;
use crate::common::{character_app, shared};
use crate::fixtures::broken_gltf::write_files;
use crate::fixtures::textured_rig::write_textured_rig;

/// The character read by the core against the one the plugin read from Bevy's scene: joint
/// names, parents, inverse binds, root frames, the rest pose, and the skinned rest shape.
fn matches_bevys_reading(dir: &Path, file: &str) {
    let core = GltfCharacter::read(&dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
    let (app, root) = character_app(dir, file, PosePlugin);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap();
    let (ours, theirs) = (&core.skeleton, posed.model.skeleton());
    assert_eq!(ours.len(), theirs.len(), "{file}: joint count");
    let near = |a: &glam::DAffine3, b: &glam::DAffine3| {
        a.to_cols_array()
            .iter()
            .zip(b.to_cols_array())
            .all(|(x, y)| (x - y).abs() < 1e-5 * (1.0 + y.abs()))
    };
    for (j, (a, b)) in ours.joints().iter().zip(theirs.joints()).enumerate() {
        assert_eq!(a.name, b.name, "{file}: joint {j}");
        assert_eq!(a.parent, b.parent, "{file}: parent of {}", a.name);
        assert!(
            near(&a.inverse_bind, &b.inverse_bind),
            "{file}: inverse bind of {}",
            a.name
        );
        assert!(
            near(&a.parent_frame, &b.parent_frame),
            "{file}: root frame of {}",
            a.name
        );
        let (r, s) = (core.rest.local[j], posed.pose.local[j]);
        assert!(
            (r.translation - s.translation).length() < 1e-5 * (1.0 + s.translation.length())
                && r.rotation.angle_between(s.rotation) < 1e-5
                && (r.scale - s.scale).length() < 1e-5,
            "{file}: rest pose of {}",
            a.name
        );
    }
    let model = core.model(ModelSettings::default()).unwrap();
    assert_eq!(
        model.bind_positions().len(),
        posed.model.bind_positions().len(),
        "{file}: welded vertices"
    );
    // Bevy's loader splits the vertices of a mesh without normals (flat shading), so the
    // render vertices may differ in number: the welded skins are compared, as sorted lists.
    let sorted = |mut points: Vec<glam::DVec3>| {
        points.sort_by(|p, q| {
            p.to_array()
                .partial_cmp(&q.to_array())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        points
    };
    let a = sorted(model.skin_welded(&core.rest));
    let b = sorted(posed.model.skin_welded(&posed.pose));
    let size = posed.model.topology().bounding_diagonal();
    let worst = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-5 * size,
        "{file}: skinned rest shapes differ by {worst} (size {size})"
    );
}

#[test]
fn the_fox_reads_as_bevy_reads_it_and_the_static_alien_is_refused() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/models");
    matches_bevys_reading(&dir, "Fox.glb");
    assert_eq!(
        GltfCharacter::read(&dir.join("alien.glb")).unwrap_err(),
        CharacterReadError::NoSkinnedMesh
    );
}

/// A converter's layout: a skinned bar under a chain of joint nodes with a material whose
/// texture is missing, read the same by the core and by the plugin.
#[test]
fn a_converted_rig_with_a_missing_texture_reads_as_bevy_reads_it() {
    let dir = ScratchDir::new("gltf_character");
    write_textured_rig(&dir, "bar.glb", 4);
    matches_bevys_reading(&dir, "bar.glb");
}

/// The broken files the loader tests use (indices out of range, NaN positions, recursive
/// nodes, no scene, wrong JSON types, not JSON): a typed error each, never a panic.
#[test]
fn broken_files_give_typed_errors() {
    let dir = ScratchDir::new("gltf_character_broken");
    for (name, _) in write_files(&dir) {
        if name.ends_with(".bin") {
            continue;
        }
        let error = GltfCharacter::read(&dir.join(name));
        assert!(
            error.is_err(),
            "{name} has no skin, yet it read as a character"
        );
    }
}

#[test]
fn the_shared_characters_read_and_a_mesh_without_skin_is_refused() {
    let Some(dir) = shared::shared_asset("models") else {
        return;
    };
    let c = GltfCharacter::read(&dir.join("Fox.glb")).unwrap();
    assert_eq!(c.skeleton.len(), 24, "the Fox's joints");
    c.model(ModelSettings::default()).unwrap();
    // The Fox's clips read onto the skeleton the core found (every channel names a joint).
    let fox = std::fs::read(dir.join("Fox.glb")).unwrap();
    let c = read_gltf_character(&fox, None).unwrap();
    for clip in ["Survey", "Walk", "Run"] {
        let clip = read_gltf_clip(&fox, None, Some(clip), &c.skeleton, &c.rest).unwrap();
        assert!(clip.keys().len() > 10);
    }
    // The seam-split sphere has no skin: a typed error, not a panic.
    assert_eq!(
        GltfCharacter::read(&dir.join("sphere.gltf")).unwrap_err(),
        CharacterReadError::NoSkinnedMesh
    );
}

fn gltf(json: &str) -> Vec<u8> {
    glb_container(json.as_bytes().to_vec(), vec![0; 16])
}

#[test]
fn a_node_cycle_or_a_node_with_two_parents_is_refused() {
    let cycle = gltf(
        r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":16}],
        "nodes":[{"name":"a","children":[1]},{"name":"b","children":[0]}]}"#,
    );
    assert!(matches!(
        read_gltf_character(&cycle, None),
        Err(CharacterReadError::NodeHierarchy { .. })
    ));
    let two_parents = gltf(
        r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":16}],
        "nodes":[{"children":[2]},{"children":[2]},{"name":"c"}]}"#,
    );
    assert_eq!(
        read_gltf_character(&two_parents, None).unwrap_err(),
        CharacterReadError::NodeHierarchy { node: 2 }
    );
}

/// A sparse accessor with no buffer view reads as `count` zeros: sixty bytes of JSON claim four
/// billion key times. The clip reader refuses it before collecting anything, naming the bound.
#[test]
fn a_claimed_four_billion_element_accessor_is_refused_by_its_bound() {
    let json = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":16}],
        "bufferViews":[{"buffer":0,"byteLength":16}],
        "nodes":[{"name":"a"}],
        "accessors":[
          {"componentType":5126,"count":4000000000,"type":"SCALAR","min":[0],"max":[1],
           "sparse":{"count":1,"indices":{"bufferView":0,"componentType":5125},"values":{"bufferView":0}}},
          {"componentType":5126,"count":4000000000,"type":"VEC3",
           "sparse":{"count":1,"indices":{"bufferView":0,"componentType":5125},"values":{"bufferView":0}}}],
        "animations":[{"samplers":[{"input":0,"output":1}],
          "channels":[{"sampler":0,"target":{"node":0,"path":"translation"}}]}]}"#;
    let skeleton = bevy_wii_deform::pose::Skeleton::new(vec![bevy_wii_deform::pose::Joint {
        name: "a".into(),
        parent: None,
        parent_frame: glam::DAffine3::IDENTITY,
        inverse_bind: glam::DAffine3::IDENTITY,
    }])
    .unwrap();
    let base = skeleton.bind_pose();
    let error = read_gltf_clip(&gltf(json), None, None, &skeleton, &base).unwrap_err();
    assert_eq!(
        error,
        ClipError::File(GltfFileError::AccessorTooLarge {
            accessor: 0,
            count: 4_000_000_000,
            limit: MAX_ACCESSOR_ELEMENTS
        })
    );
    assert!(
        error
            .to_string()
            .contains(&MAX_ACCESSOR_ELEMENTS.to_string()),
        "{error}"
    );
}
