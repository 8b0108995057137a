//! Keyframed pose clips: authoring (keys stay sorted and valid), sampling by each glTF
//! interpolation, export of several keys that Bevy's own glTF loader plays back on the Fox,
//! import of the Fox's own "Walk", and typed errors for bad clip files.

use bevy::prelude::*;
use bevy_wii_deform::pose::rig::synth_rig::bar_rig;
use bevy_wii_deform::pose::{
    ClipError, GltfFileError, JointTransform, KeyInterpolation, PoseClip, PoseKey, SkeletonPose,
    read_gltf_clip, write_gltf_clip,
};
use bevy_wii_deform::prelude::*;
use glam::{DQuat, DVec3, DVec4};

use crate::common;
use crate::common::scratch::ScratchDir;
use common::{angle_between, animation_player, node_of, play_clip, show_clip_at};

/// `pose` with joint `j` turned by `angle` about `axis` (in its parent's frame).
fn turned(pose: &SkeletonPose, j: usize, axis: DVec3, angle: f64) -> SkeletonPose {
    let mut out = pose.clone();
    out.local[j].rotation =
        (DQuat::from_axis_angle(axis, angle) * out.local[j].rotation).normalize();
    out
}

use bevy_wii_deform::pose::rotation_angle as rotation_error;

#[test]
fn clip_keys_stay_sorted_and_refuse_bad_input() {
    let rig = bar_rig(3, 4, 8);
    let rest = rig.rest.clone();
    let mut clip = PoseClip::new();
    let bent = turned(&rest, 1, DVec3::Z, 0.5);
    assert_eq!(
        clip.set_key(1.0, bent.clone(), KeyInterpolation::Linear),
        Ok(0)
    );
    assert_eq!(
        clip.set_key(0.0, rest.clone(), KeyInterpolation::Linear),
        Ok(0)
    );
    assert_eq!(
        clip.set_key(0.5, rest.clone(), KeyInterpolation::Step),
        Ok(1)
    );
    assert_eq!(clip.times(), vec![0.0, 0.5, 1.0]);
    // Same time: replaced, not added.
    assert_eq!(
        clip.set_key(0.5, bent.clone(), KeyInterpolation::Step),
        Ok(1)
    );
    assert_eq!(clip.keys().len(), 3);
    assert_eq!(clip.keys()[1].pose, bent);

    let before = clip.clone();
    let mut nan = rest.clone();
    nan.local[2].translation.x = f64::NAN;
    assert!(matches!(
        clip.set_key(0.7, nan.clone(), KeyInterpolation::Linear),
        Err(ClipError::NonFiniteKey { joint, .. }) if joint == "2"
    ));
    assert!(matches!(
        clip.set_key(f32::INFINITY, rest.clone(), KeyInterpolation::Linear),
        Err(ClipError::NonFiniteTime(_))
    ));
    let short = SkeletonPose {
        local: rest.local[..2].to_vec(),
    };
    assert_eq!(
        clip.set_key(0.7, short, KeyInterpolation::Linear),
        Err(ClipError::PoseLength {
            got: 2,
            expected: 3
        })
    );
    assert_eq!(clip.move_key(0, 1.0), Err(ClipError::TimeTaken(1.0)));
    assert!(matches!(
        clip.remove_key(7),
        Err(ClipError::KeyOutOfRange { index: 7, keys: 3 })
    ));
    assert_eq!(clip, before, "a refused edit changed the clip");

    // Moving a key reorders; removing drops it.
    assert_eq!(clip.move_key(0, 2.0), Ok(2));
    assert_eq!(clip.times(), vec![0.5, 1.0, 2.0]);
    assert_eq!(clip.keys()[2].pose, rest);
    assert_eq!(clip.remove_key(0).unwrap().time, 0.5);
    assert_eq!(clip.times(), vec![1.0, 2.0]);

    // Keys out of order are refused.
    let keys = vec![
        PoseKey {
            time: 1.0,
            pose: rest.clone(),
            interpolation: KeyInterpolation::Linear,
        },
        PoseKey {
            time: 0.5,
            pose: rest.clone(),
            interpolation: KeyInterpolation::Linear,
        },
    ];
    assert_eq!(
        PoseClip::from_keys(keys),
        Err(ClipError::TimesOutOfOrder {
            index: 1,
            time: 0.5,
            previous: 1.0
        })
    );
}

#[test]
fn a_nan_key_time_is_refused() {
    let rig = bar_rig(2, 4, 8);
    let mut clip = PoseClip::new();
    let result = clip.set_key(f32::NAN, rig.rest.clone(), KeyInterpolation::Linear);
    assert!(matches!(result, Err(ClipError::NonFiniteTime(t)) if t.is_nan()));
    assert!(clip.is_empty());
}

/// Step holds, linear slerps, the cubic spline passes through its keys with glTF's Hermite
/// basis and Catmull–Rom tangents (checked against a formula written out here).
#[test]
fn sampling_follows_each_interpolation() {
    let rig = bar_rig(3, 4, 8);
    let rest = rig.rest.clone();
    let angles = [0.0, 0.9, 0.3];
    let poses: Vec<SkeletonPose> = angles
        .iter()
        .map(|&a| turned(&rest, 1, DVec3::Z, a))
        .collect();
    let times = [0.0f32, 0.5, 1.5];
    for mode in [
        KeyInterpolation::Step,
        KeyInterpolation::Linear,
        KeyInterpolation::CubicSpline,
    ] {
        let mut clip = PoseClip::new();
        for (t, p) in times.iter().zip(&poses) {
            clip.set_key(*t, p.clone(), mode).unwrap();
        }
        for (t, p) in times.iter().zip(&poses) {
            let at = clip.sample(*t).unwrap();
            assert!(rotation_error(at.local[1].rotation, p.local[1].rotation) < 1e-9);
        }
        // Before the first and after the last key: clamped.
        assert_eq!(clip.sample(-1.0).unwrap(), poses[0]);
        assert_eq!(clip.sample(9.0).unwrap(), poses[2]);
        let t = 0.9f32; // inside the second segment, s = 0.4
        let s = f64::from((t - 0.5) / 1.0);
        let expected_angle = match mode {
            KeyInterpolation::Step => angles[1],
            KeyInterpolation::Linear => angles[1] + (angles[2] - angles[1]) * s,
            KeyInterpolation::CubicSpline => {
                // On the quaternion components: one rotation axis, so the angle follows from
                // the normalised Hermite blend of (cos a/2, sin a/2).
                let q = |a: f64| DVec4::new(0.0, 0.0, (a / 2.0).sin(), (a / 2.0).cos());
                let m1 = (q(angles[2]) - q(angles[0])) / 1.5; // Catmull–Rom at key 1
                let m2 = DVec4::ZERO; // the last key: zero
                let (h00, h10, h01, h11) = (
                    2.0 * s.powi(3) - 3.0 * s * s + 1.0,
                    s.powi(3) - 2.0 * s * s + s,
                    -2.0 * s.powi(3) + 3.0 * s * s,
                    s.powi(3) - s * s,
                );
                let v = q(angles[1]) * h00 + m1 * h10 + q(angles[2]) * h01 + m2 * h11;
                let v = v.normalize();
                2.0 * v.z.atan2(v.w)
            }
        };
        let got = clip.sample(t).unwrap().local[1].rotation;
        let want = DQuat::from_axis_angle(DVec3::Z, expected_angle) * rest.local[1].rotation;
        assert!(
            rotation_error(got, want) < 1e-9,
            "{mode:?}: {} rad off",
            rotation_error(got, want)
        );
        // The cubic spline is not the linear one.
        if mode == KeyInterpolation::CubicSpline {
            let linear = angles[1] + (angles[2] - angles[1]) * s;
            assert!((expected_angle - linear).abs() > 1e-3);
        }
    }
}

/// A clip of three keys on the Fox (0, 0.5, 1 s) exported with the joints' node paths, loaded
/// by Bevy's glTF loader and played on the same Fox: every joint within 1e-4 rad of the
/// clip at the keys and halfway between them, for each interpolation.
#[test]
fn a_three_key_clip_plays_back_through_bevys_loader() {
    let Some(dir) = common::shared::shared_asset("models") else {
        return;
    };
    let (mut app, root) = common::fox_app(&dir, PosePlugin);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let skeleton = posed.model.skeleton();
    let joint = |name: &str| skeleton.find(name).expect(name);
    let k0 = posed.pose.clone();
    let k1 = turned(
        &turned(&k0, joint("b_Neck_04"), DVec3::X, 0.6),
        joint("b_Tail01_012"),
        DVec3::Y,
        0.8,
    );
    let k2 = turned(
        &turned(&k1, joint("b_Neck_04"), DVec3::Y, -0.7),
        joint("b_LeftLeg01_015"),
        DVec3::Z,
        0.5,
    );
    let world = app.world();
    let paths = posed.joint_paths(|e| node_of(world, e));
    // Let the clip drive the joints.
    app.world_mut()
        .entity_mut(root)
        .remove::<(Poseable, PosedSkeleton)>();
    let out = ScratchDir::new("pose_clip");
    let player = animation_player(&mut app);
    for (n, mode) in [
        KeyInterpolation::Linear,
        KeyInterpolation::Step,
        KeyInterpolation::CubicSpline,
    ]
    .into_iter()
    .enumerate()
    {
        let mut clip = PoseClip::new();
        for (t, pose) in [(0.0, &k0), (0.5, &k1), (1.0, &k2)] {
            clip.set_key(t, pose.clone(), mode).unwrap();
        }
        let glb = write_gltf_clip(&clip, "authored", &paths, Some(&k0)).unwrap();
        // One channel per joint and property that changes: only rotations of the three
        // turned joints (translations and scales never leave the rest pose).
        let json = gltf::Gltf::from_slice(&glb).unwrap();
        let animation = json.document.animations().next().unwrap();
        assert_eq!(animation.channels().count(), 3, "{mode:?}");
        let file = out.join(format!("clip{n}.glb"));
        std::fs::write(&file, glb).unwrap();
        let handle: Handle<AnimationClip> = app.world().resource::<AssetServer>().load(
            GltfAssetLabel::Animation(0).from_asset(bevy::asset::AssetPath::from_path_buf(file)),
        );
        let node = play_clip(&mut app, player, handle);
        for t in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
            show_clip_at(&mut app, player, node, t);
            let expected = clip.sample(t).unwrap();
            let mut worst = 0.0f32;
            for (&j, want) in posed.joints.iter().zip(&expected.local) {
                let now = app.world().get::<Transform>(j).unwrap().rotation;
                worst = worst.max(angle_between(now, want.rotation.as_quat()));
            }
            assert!(
                worst < 1e-4,
                "{mode:?} at {t} s: a joint is {worst} rad from the clip"
            );
        }
    }
}

/// The Fox's own "Walk" read from its file, written back and read again: the same samples.
#[test]
fn the_foxs_walk_imports_and_exports_unchanged() {
    let Some(path) = common::shared::shared_asset("models/Fox.glb") else {
        return;
    };
    let bytes = std::fs::read(&path).unwrap();
    let (skeleton, base) = fox_skeleton(&bytes);
    let walk = read_gltf_clip(&bytes, None, Some("Walk"), &skeleton, &base).unwrap();
    assert_eq!(walk.keys().len(), 18, "the Walk's keyframes");
    assert!(
        walk.keys()
            .iter()
            .all(|k| k.interpolation == KeyInterpolation::Linear)
    );
    let paths: Vec<Vec<String>> = skeleton
        .joints()
        .iter()
        .map(|j| vec![j.name.clone()])
        .collect();
    let glb = write_gltf_clip(&walk, "Walk", &paths, Some(&base)).unwrap();
    let again = read_gltf_clip(&glb, None, None, &skeleton, &base).unwrap();
    assert_eq!(again.times(), walk.times());
    let steps = 97;
    let mut worst = 0.0f64;
    for i in 0..=steps {
        let t = walk.duration() * i as f32 / steps as f32;
        let (a, b) = (walk.sample(t).unwrap(), again.sample(t).unwrap());
        for (p, q) in a.local.iter().zip(&b.local) {
            worst = worst
                .max(rotation_error(p.rotation, q.rotation))
                .max(p.translation.distance(q.translation) / 100.0);
        }
    }
    assert!(worst < 1e-5, "the re-exported Walk differs by {worst}");
    // And the Walk moves: a clip of constant poses would pass the above trivially.
    let (first, mid) = (
        walk.sample(0.0).unwrap(),
        walk.sample(walk.duration() / 2.0).unwrap(),
    );
    let moved = first
        .local
        .iter()
        .zip(&mid.local)
        .map(|(a, b)| rotation_error(a.rotation, b.rotation))
        .fold(0.0, f64::max);
    assert!(moved > 0.1, "the Walk barely moves ({moved} rad)");
}

/// Bad clip files give typed errors: channels on joints the character lacks, NaN values,
/// times out of order, no animation, not a glTF at all.
#[test]
fn bad_clip_files_give_typed_errors() {
    let Some(path) = common::shared::shared_asset("models/Fox.glb") else {
        return;
    };
    let bytes = std::fs::read(&path).unwrap();
    let (skeleton, base) = fox_skeleton(&bytes);
    let mut clip = PoseClip::new();
    let k1 = turned(&base, 5, DVec3::X, 0.4);
    clip.set_key(0.0, base.clone(), KeyInterpolation::Linear)
        .unwrap();
    clip.set_key(1.0, k1, KeyInterpolation::Linear).unwrap();
    let paths: Vec<Vec<String>> = skeleton
        .joints()
        .iter()
        .map(|j| vec![j.name.clone()])
        .collect();
    let good = write_gltf_clip(&clip, "c", &paths, Some(&base)).unwrap();
    assert!(read_gltf_clip(&good, None, None, &skeleton, &base).is_ok());

    let mut renamed = paths.clone();
    renamed[5] = vec!["NoSuchBone".into()];
    let foreign = write_gltf_clip(&clip, "c", &renamed, Some(&base)).unwrap();
    assert_eq!(
        read_gltf_clip(&foreign, None, None, &skeleton, &base),
        Err(ClipError::UnknownJoint("NoSuchBone".into()))
    );

    // The binary chunk starts with the key times (two floats), then the rotation values.
    let bin = bin_chunk_start(&good);
    let mut swapped = good.clone();
    swapped[bin..bin + 4].copy_from_slice(&2.0f32.to_le_bytes());
    assert!(matches!(
        read_gltf_clip(&swapped, None, None, &skeleton, &base),
        Err(ClipError::TimesOutOfOrder { index: 1, .. })
    ));
    let mut nan = good.clone();
    nan[bin + 8..bin + 12].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(matches!(
        read_gltf_clip(&nan, None, None, &skeleton, &base),
        Err(ClipError::NonFiniteKey { .. })
    ));
    assert_eq!(
        read_gltf_clip(&good, None, Some("Dance"), &skeleton, &base),
        Err(ClipError::NoAnimation(Some("Dance".into())))
    );
    assert!(matches!(
        read_gltf_clip(b"not a glTF", None, None, &skeleton, &base),
        Err(ClipError::File(GltfFileError::Parse(_)))
    ));
    // An empty clip has nothing to export.
    assert_eq!(
        write_gltf_clip(&PoseClip::new(), "c", &paths, None),
        Err(ClipError::NoKeys)
    );
}

/// Mixed interpolations export as a resampled linear clip that still follows the clip.
#[test]
fn mixed_interpolations_export_as_a_resampled_linear_clip() {
    let rig = bar_rig(3, 4, 8);
    let rest = rig.rest.clone();
    let mut clip = PoseClip::new();
    clip.set_key(0.0, rest.clone(), KeyInterpolation::Step)
        .unwrap();
    clip.set_key(
        1.0,
        turned(&rest, 1, DVec3::Z, 0.8),
        KeyInterpolation::CubicSpline,
    )
    .unwrap();
    clip.set_key(
        2.0,
        turned(&rest, 1, DVec3::Z, -0.4),
        KeyInterpolation::Linear,
    )
    .unwrap();
    clip.set_key(
        3.0,
        turned(&rest, 2, DVec3::X, 0.3),
        KeyInterpolation::Linear,
    )
    .unwrap();
    let paths: Vec<Vec<String>> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| vec![j.name.clone()])
        .collect();
    let glb = write_gltf_clip(&clip, "mixed", &paths, None).unwrap();
    let back = read_gltf_clip(&glb, None, None, &rig.skeleton, &rest).unwrap();
    assert!(back.keys().len() > clip.keys().len());
    let mut worst = 0.0f64;
    for i in 0..=300 {
        let t = 3.0 * i as f32 / 300.0;
        // Skip the 1 ms before a step's end, where the linear file ramps.
        if (0.998..1.0).contains(&t) {
            continue;
        }
        let (a, b) = (clip.sample(t).unwrap(), back.sample(t).unwrap());
        for (p, q) in a.local.iter().zip(&b.local) {
            worst = worst.max(rotation_error(p.rotation, q.rotation));
        }
    }
    // Eight linear samples per cubic segment: within a few hundredths of a radian.
    assert!(worst < 0.02, "resampled clip {worst} rad from the clip");
}

/// The Fox's skeleton as the glTF file gives it (joint names and node transforms), without
/// Bevy: joints in skin order with parents from the node hierarchy.
fn fox_skeleton(bytes: &[u8]) -> (bevy_wii_deform::pose::Skeleton, SkeletonPose) {
    use bevy_wii_deform::pose::{Joint, Skeleton};
    let gltf = gltf::Gltf::from_slice(bytes).unwrap();
    let skin = gltf.document.skins().next().unwrap();
    let nodes: Vec<gltf::Node> = skin.joints().collect();
    let index_of = |n: usize| nodes.iter().position(|m| m.index() == n);
    let mut parent = vec![None; nodes.len()];
    for (k, node) in nodes.iter().enumerate() {
        for child in node.children() {
            if let Some(c) = index_of(child.index()) {
                parent[c] = Some(k);
            }
        }
    }
    let joints: Vec<Joint> = nodes
        .iter()
        .enumerate()
        .map(|(k, n)| Joint {
            name: n.name().unwrap().to_string(),
            parent: parent[k],
            parent_frame: glam::DAffine3::IDENTITY,
            inverse_bind: glam::DAffine3::IDENTITY,
        })
        .collect();
    let base = SkeletonPose {
        local: nodes
            .iter()
            .map(|n| {
                let (t, r, s) = n.transform().decomposed();
                JointTransform {
                    translation: Vec3::from_array(t).as_dvec3(),
                    rotation: Quat::from_array(r).as_dquat().normalize(),
                    scale: Vec3::from_array(s).as_dvec3(),
                }
            })
            .collect(),
    };
    (Skeleton::new(joints).unwrap(), base)
}

/// Where a GLB's binary chunk data starts.
fn bin_chunk_start(glb: &[u8]) -> usize {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    12 + 8 + json_len + 8
}

/// A `PoseTimeline` on a character shows its clip: scrubbed to a time, the joints take the
/// clip's pose there; playing, the time advances with the (manual) clock and the joints
/// follow; a clip file naming joints the character lacks is refused and nothing changes.
#[test]
fn a_timeline_shows_its_clip_on_the_character() {
    use std::time::Duration;
    let mut app = common::app();
    app.add_plugins(PosePlugin);
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
        Duration::from_millis(20),
    ));
    let rig = bar_rig(3, 6, 12);
    let (root, joints) = common::posed_rig(&mut app, &rig, |_: &[Entity]| Poseable::default());
    let rest = app.world().get::<PosedSkeleton>(root).unwrap().pose.clone();
    let mut clip = PoseClip::new();
    clip.set_key(0.0, rest.clone(), KeyInterpolation::Linear)
        .unwrap();
    clip.set_key(
        1.0,
        turned(&rest, 1, DVec3::Z, 1.0),
        KeyInterpolation::Linear,
    )
    .unwrap();
    let timeline = PoseTimeline {
        clip: clip.clone(),
        time: 0.5,
        ..Default::default()
    };
    app.world_mut().entity_mut(root).insert(timeline);
    app.update();
    let joint_error = |app: &App, t: f32| {
        let want = clip.sample(t).unwrap();
        joints
            .iter()
            .zip(&want.local)
            .map(|(&j, w)| {
                let now = app.world().get::<Transform>(j).unwrap().rotation;
                rotation_error(now.as_dquat(), w.rotation)
            })
            .fold(0.0, f64::max)
    };
    assert!(joint_error(&app, 0.5) < 1e-6);
    assert!(
        joint_error(&app, 0.0) > 0.4,
        "the scrubbed pose is not the first key"
    );
    // Play: 10 frames of 20 ms.
    app.world_mut()
        .get_mut::<PoseTimeline>(root)
        .unwrap()
        .playing = true;
    for _ in 0..10 {
        app.update();
    }
    let t = app.world().get::<PoseTimeline>(root).unwrap().time;
    assert!((t - 0.7).abs() < 0.021, "played to {t} s");
    assert!(joint_error(&app, t) < 1e-6);
    // A bad file: refused, the timeline and the pose unchanged.
    app.world_mut()
        .get_mut::<PoseTimeline>(root)
        .unwrap()
        .playing = false;
    app.update();
    let before = app.world().get::<PoseTimeline>(root).unwrap().clone();
    let pose_before = app.world().get::<PosedSkeleton>(root).unwrap().pose.clone();
    let mut paths: Vec<Vec<String>> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| vec![j.name.clone()])
        .collect();
    paths[1] = vec!["Elsewhere".into()]; // the joint the clip turns
    let scratch = ScratchDir::new("bad_clip");
    let file = scratch.join("bad_clip.glb");
    std::fs::write(
        &file,
        write_gltf_clip(&clip, "x", &paths, Some(&rest)).unwrap(),
    )
    .unwrap();
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let mut timeline = app.world_mut().get_mut::<PoseTimeline>(root).unwrap();
    assert_eq!(
        timeline.import_gltf(&file, None, &posed),
        Err(ClipError::UnknownJoint("Elsewhere".into()))
    );
    app.update();
    assert_eq!(*app.world().get::<PoseTimeline>(root).unwrap(), before);
    assert_eq!(
        app.world().get::<PosedSkeleton>(root).unwrap().pose,
        pose_before
    );
}

/// The pose library: saved poses are listed by name, load back exactly, apply mirrored
/// (mirroring twice gives the pose back), and refuse names that are not file names.
#[test]
fn the_pose_library_saves_lists_and_loads_poses() {
    use bevy_wii_deform::pose::rig::synth_rig::mannequin_rig;
    use bevy_wii_deform::pose::{Mirror, PoseFile, PoseFileError, PoseLibrary};
    let folder = ScratchDir::new("pose_library");
    std::fs::remove_dir(&*folder).unwrap(); // the library makes its folder
    let library = PoseLibrary::new(folder.to_path_buf());
    assert_eq!(
        library.names(),
        Ok(vec![]),
        "a missing folder is an empty library"
    );
    let rig = mannequin_rig(10);
    let skeleton = &rig.skeleton;
    let arm = skeleton.find("shoulder_l").expect("the left shoulder");
    let wave = turned(&rig.rest, arm, DVec3::Z, 0.8);
    library
        .save("wave", &PoseFile::from_pose(skeleton, &wave))
        .unwrap();
    library
        .save("rest pose", &PoseFile::from_pose(skeleton, &rig.rest))
        .unwrap();
    assert_eq!(library.names().unwrap(), vec!["rest pose", "wave"]);
    let loaded = library
        .load("wave")
        .unwrap()
        .apply(skeleton, &rig.rest)
        .unwrap();
    for (a, b) in loaded.local.iter().zip(&wave.local) {
        assert!(rotation_error(a.rotation, b.rotation) < 1e-12);
    }
    let mirror = Mirror::new(skeleton, &rig.rest);
    let mirrored = mirror.mirror(&loaded);
    assert!(
        rotation_error(mirrored.local[arm].rotation, loaded.local[arm].rotation) > 0.1,
        "the mirrored pose moved the other arm"
    );
    let back = mirror.mirror(&mirrored);
    for (a, b) in back.local.iter().zip(&loaded.local) {
        assert!(rotation_error(a.rotation, b.rotation) < 1e-9);
    }
    for bad in ["", "../escape", ".hidden", "a/b"] {
        assert_eq!(
            library.save(bad, &PoseFile::default()),
            Err(PoseFileError::BadName(bad.into()))
        );
    }
    assert!(matches!(
        library.load("missing"),
        Err(PoseFileError::Io { .. })
    ));
}
