//! Retargeting (`pose::retarget`) on generated figures that differ the way real skeletons do
//! (names, rest poses, proportions, a root above the hips), with a walk whose feet truly stand:
//! a clip comes back unchanged on its own skeleton, arm directions survive a T-pose to A-pose
//! change, planted feet stay put on longer legs only with the contacts (and move with the
//! ground under a walk made in place), the skin stays out of a sloped ground, and what cannot
//! be mapped is a typed error.

use std::sync::Arc;

use bevy_wii_deform::pose::retarget::{
    RetargetError, RetargetQuality, RetargetSettings, Retargeter, SkeletonMap, SourceContacts,
    Which,
};
use bevy_wii_deform::pose::rig::synth_rig::{FigureNames, FigureSpec, SyntheticRig, figure_rig};
use bevy_wii_deform::pose::{
    GroundPlane, PoseClip, PoseKey, SkeletonPose, read_bvh, read_gltf_clip, rotation_angle,
    write_bvh, write_gltf_clip,
};
use glam::{DQuat, DVec3};

use crate::fixtures::walk::{FRAME_TIME, walk};

fn figure(spec: FigureSpec) -> SyntheticRig {
    figure_rig(&FigureSpec { cells: 36, ..spec })
}

fn joint(rig: &SyntheticRig, name: &str) -> usize {
    rig.skeleton
        .find(name)
        .unwrap_or_else(|| panic!("no joint {name}"))
}

/// The Mixamo-named figure's walk: 4 steps of 0.3.
fn mixamo_walk(rig: &SyntheticRig) -> PoseClip {
    let feet = (joint(rig, "LeftFoot"), joint(rig, "RightFoot"));
    walk(rig, joint(rig, "Hips"), feet, 4, 0.3).0
}

fn retargeter(
    source: &SyntheticRig,
    target: &SyntheticRig,
    settings: RetargetSettings,
) -> Retargeter {
    let map = SkeletonMap::humanoid(
        (&source.skeleton, &source.rest),
        (&target.skeleton, &target.rest),
    )
    .unwrap();
    let model = Arc::new(target.model().unwrap());
    Retargeter::new(
        (&source.skeleton, &source.rest),
        model,
        &target.rest,
        map,
        settings,
    )
    .unwrap()
}

/// The Unreal-named figure with legs 30 % longer than the default's (thighs ×1.5, shins
/// ×1.1).
fn longer_legs() -> SyntheticRig {
    let base = FigureSpec::default();
    figure(FigureSpec {
        thigh: base.thigh * 1.5,
        shin: base.shin * 1.1,
        names: FigureNames::Unreal,
        ..base
    })
}

/// How well `clip` carries over from `source` onto `target` on `ground` with the contacts
/// off (the joint rotations carried over alone).
fn quality_without_contacts(
    source: &SyntheticRig,
    target: &SyntheticRig,
    clip: &PoseClip,
    ground: &GroundPlane,
) -> RetargetQuality {
    let without = retargeter(
        source,
        target,
        RetargetSettings {
            contacts: false,
            ..RetargetSettings::default()
        },
    );
    let bare = without.bake(clip, ground).unwrap();
    without.quality(
        &frames(clip),
        &frames(&bare.clip),
        &bare.source_contacts,
        ground,
    )
}

fn size_of(rig: &SyntheticRig) -> f64 {
    rig.model().unwrap().topology().bounding_diagonal()
}

fn frames(clip: &PoseClip) -> Vec<SkeletonPose> {
    clip.keys().iter().map(|k| k.pose.clone()).collect()
}

/// A clip on its own skeleton comes back unchanged — the hips turning about the vertical as a
/// captured body's do (the walk's own hips face ahead), so the root's rotation is carried too.
/// (A lean would move the feet off the rest's ground, and the bake grounds them.)
#[test]
fn a_clip_on_its_own_skeleton_comes_back_unchanged() {
    let rig = figure(FigureSpec::default());
    let hips = joint(&rig, "Hips");
    let keys = mixamo_walk(&rig)
        .keys()
        .iter()
        .map(|k| {
            let mut key = k.clone();
            let t = f64::from(k.time);
            let turn = DQuat::from_rotation_y(0.6 * (2.0 * t).sin());
            let local = &mut key.pose.local[hips].rotation;
            *local = (turn * *local).normalize();
            key
        })
        .collect();
    let clip = PoseClip::from_keys(keys).unwrap();
    let off = RetargetSettings {
        contacts: false,
        ..RetargetSettings::default()
    };
    let r = retargeter(&rig, &rig, off);
    let baked = r.bake(&clip, &r.rest_ground()).unwrap();
    let size = size_of(&rig);
    for (a, b) in clip.keys().iter().zip(baked.clip.keys()) {
        for (j, (x, y)) in a.pose.local.iter().zip(&b.pose.local).enumerate() {
            assert!(
                rotation_angle(x.rotation, y.rotation) < 1e-6,
                "joint {j} at {}",
                a.time
            );
            assert!(
                (x.translation - y.translation).length() < 1e-6 * size,
                "joint {j} at {}",
                a.time
            );
        }
    }
}

#[test]
fn a_horizontal_arm_of_a_t_pose_source_is_horizontal_on_an_a_pose_target() {
    let t_pose = figure(FigureSpec {
        arm_down_deg: 0.0,
        ..FigureSpec::default()
    });
    let a_pose = figure(FigureSpec {
        arm_down_deg: 45.0,
        names: FigureNames::Unreal,
        ..FigureSpec::default()
    });
    // The source holds its rest pose: arms horizontal.
    let clip = PoseClip::from_keys(vec![bevy_wii_deform::pose::PoseKey {
        time: 0.0,
        pose: t_pose.rest.clone(),
        interpolation: Default::default(),
    }])
    .unwrap();
    let off = RetargetSettings {
        contacts: false,
        ..RetargetSettings::default()
    };
    let baked = retargeter(&t_pose, &a_pose, off)
        .bake(
            &clip,
            &GroundPlane {
                point: DVec3::ZERO,
                normal: DVec3::Y,
            },
        )
        .unwrap();
    let pose = &baked.clip.keys()[0].pose;
    let g = a_pose.skeleton.global_transforms(pose);
    for (arm, forearm, hand) in [
        ("upperarm_l", "lowerarm_l", "hand_l"),
        ("upperarm_r", "lowerarm_r", "hand_r"),
    ] {
        for (a, b) in [(arm, forearm), (forearm, hand)] {
            let d = g[joint(&a_pose, b)].translation - g[joint(&a_pose, a)].translation;
            let elevation = d.normalize().y.asin().to_degrees();
            assert!(
                elevation.abs() < 2.0,
                "{a}→{b} is {elevation}° off horizontal (the rest's 45° would be carried)"
            );
        }
    }
}

/// Longer legs (thigh ×1.5, shin ×1.1: 30 % longer) under the same walk: the root motion is
/// scaled, and the planted feet stay put with the contacts — and visibly slide without them.
#[test]
fn planted_feet_stay_put_on_longer_legs_only_with_the_contacts() {
    let source = figure(FigureSpec::default());
    let target = longer_legs();
    let clip = mixamo_walk(&source);
    let with = retargeter(&source, &target, RetargetSettings::default());
    let ground = with.rest_ground();
    let ratio = with.transfer().leg_ratio();
    assert!((ratio - 1.3).abs() < 0.02, "leg ratio {ratio}");
    let baked = with.bake(&clip, &ground).unwrap();
    assert!(
        baked.source_contacts.planted_share() > 0.5,
        "{}",
        baked.source_contacts.planted_share()
    );
    assert_eq!(baked.failed_solves, 0);
    let q = with.quality(
        &frames(&clip),
        &frames(&baked.clip),
        &baked.source_contacts,
        &ground,
    );
    let q0 = quality_without_contacts(&source, &target, &clip, &ground);
    eprintln!("with contacts {q:?}\nwithout {q0:?}");
    assert!(
        q.foot_slide_max <= 2e-3,
        "slide with contacts {}",
        q.foot_slide_max
    );
    assert!(
        q0.foot_slide_max > 2.0 * q.foot_slide_max.max(1e-3),
        "without contacts the feet slide only {}",
        q0.foot_slide_max
    );
    assert!(
        q.penetration_max <= 1e-3,
        "penetration {}",
        q.penetration_max
    );
    assert!(
        q.bone_length_error_max <= 1e-4,
        "bones {}",
        q.bone_length_error_max
    );
    assert!(
        q.limb_direction_error_deg_p95 <= 10.0,
        "limbs {}",
        q.limb_direction_error_deg_p95
    );
    // The root moved 1.3 times as far.
    let hips_s = joint(&source, "Hips");
    let hips_t = joint(&target, "pelvis");
    let travel = |rig: &SyntheticRig, c: &PoseClip, j: usize| {
        let first = rig.skeleton.global_transforms(&c.keys()[0].pose)[j].translation;
        let last = rig
            .skeleton
            .global_transforms(&c.keys()[c.keys().len() - 1].pose)[j]
            .translation;
        (last - first).z
    };
    let (ts, tt) = (
        travel(&source, &clip, hips_s),
        travel(&target, &baked.clip, hips_t),
    );
    assert!(
        (tt / ts - ratio).abs() < 0.05,
        "the root travels {tt} for the source's {ts}"
    );
}

/// Carried over onto longer legs (thighs ×1.5, shins ×1.1), the target's lowest foot is as
/// high over its rest height as the source's, scaled by the legs, in every frame (the walk
/// keeps a foot down throughout, so on the ground): the body is placed by its feet. The hips' height scaled alone is right only for legs that hang
/// straight below the hips joint; the rest of the way down (hips to thigh) is not scaled.
#[test]
fn carried_over_onto_longer_legs_the_lowest_foot_keeps_its_height() {
    let source = figure(FigureSpec::default());
    let target = longer_legs();
    let clip = mixamo_walk(&source);
    let retargeter = retargeter(&source, &target, RetargetSettings::default());
    let transfer = retargeter.transfer();
    let feet = transfer.map().feet.clone();
    // Each foot's joint on one side of the map: the source's (0) or the target's (1).
    let lowest = |rig: &SyntheticRig, pose: &SkeletonPose, side: usize| {
        let g = rig.skeleton.global_transforms(pose);
        feet.iter()
            .map(|f| g[if side == 0 { f.0 } else { f.1 }].translation.y)
            .fold(f64::INFINITY, f64::min)
    };
    let rest_s = lowest(&source, &source.rest, 0);
    let rest_t = lowest(&target, &target.rest, 1);
    let size = size_of(&target);
    let mut worst = 0.0f64;
    for pose in frames(&clip) {
        let carried = transfer.transfer(&pose);
        let want = (lowest(&source, &pose, 0) - rest_s) * transfer.leg_ratio();
        let got = lowest(&target, &carried, 1) - rest_t;
        worst = worst.max((got - want).abs() / size);
    }
    assert!(
        worst < 1e-9,
        "the lowest foot is {worst} of the size off its height"
    );
}

/// The walk streamed frame by frame onto the longer legs (a live source: no clip to read the
/// contacts from): the same feet planted as the bake finds for nearly every frame, planted feet
/// that stay put, no skin below the ground, the limbs following the source's; a malformed frame
/// is a typed error that leaves the stream as it was.
#[test]
fn a_live_source_retargeted_frame_by_frame_keeps_its_feet_planted() {
    let source = figure(FigureSpec::default());
    let target = longer_legs();
    let clip = mixamo_walk(&source);
    let retargeter = retargeter(&source, &target, RetargetSettings::default());
    let ground = retargeter.rest_ground();
    let baked = retargeter.bake(&clip, &ground).unwrap();
    let mut live = retargeter.live();
    let mut poses = Vec::new();
    let mut planted = vec![Vec::new(); retargeter.transfer().map().feet.len()];
    for key in clip.keys() {
        let frame = live.frame(&key.pose, f64::from(key.time), &ground).unwrap();
        for (k, p) in frame.planted.iter().enumerate() {
            planted[k].push(*p);
        }
        poses.push(frame.pose);
    }
    let contacts = SourceContacts {
        planted,
        planted_height: baked.source_contacts.planted_height.clone(),
        treadmill: DVec3::ZERO,
        frame_time: f64::from(FRAME_TIME),
    };
    let pairs = contacts
        .planted
        .iter()
        .flatten()
        .zip(baked.source_contacts.planted.iter().flatten());
    let agree = pairs.filter(|(a, b)| a == b).count() as f64
        / contacts.planted.iter().map(Vec::len).sum::<usize>() as f64;
    assert!(
        agree >= 0.9,
        "live planted {} against the bake's {}: {agree} agree",
        contacts.planted_share(),
        baked.source_contacts.planted_share()
    );
    let q = retargeter.quality(&frames(&clip), &poses, &contacts, &ground);
    eprintln!("live {q:?}");
    assert!(q.foot_slide_max <= 2e-3, "slide {}", q.foot_slide_max);
    assert!(
        q.penetration_max <= 1e-3,
        "penetration {}",
        q.penetration_max
    );
    assert!(
        q.limb_direction_error_deg_p95 <= 10.0,
        "limbs {}",
        q.limb_direction_error_deg_p95
    );

    // A frame with a joint that is not a number, and one of the wrong length, in the middle
    // of the stream: typed errors, and the frames after come out as they would have.
    let mut interrupted = retargeter.live();
    let keys = clip.keys();
    for (f, key) in keys.iter().enumerate().take(12) {
        if f == 6 {
            let mut bad = key.pose.clone();
            bad.local[0].rotation.x = f64::NAN;
            let error = interrupted.frame(&bad, f64::from(key.time), &ground);
            assert!(matches!(error, Err(RetargetError::Pose(_))), "{error:?}");
            let short = SkeletonPose {
                local: key.pose.local[1..].to_vec(),
            };
            let error = interrupted.frame(&short, f64::from(key.time), &ground);
            assert!(matches!(error, Err(RetargetError::Pose(_))), "{error:?}");
        }
        let frame = interrupted
            .frame(&key.pose, f64::from(key.time), &ground)
            .unwrap();
        assert_eq!(frame.pose, poses[f], "frame {f}");
    }
}

/// `clip` made in place, as most game clips are: every frame moved back by the walk's mean
/// velocity (its hips' travel over its length), so the body stays and each stance foot slides
/// back under it at that velocity. Returns the clip and the velocity taken out.
fn made_in_place(rig: &SyntheticRig, clip: &PoseClip) -> (PoseClip, DVec3) {
    let keys = clip.keys();
    let hips = joint(rig, "Hips");
    let at = |k: &PoseKey| rig.skeleton.global_transforms(&k.pose)[hips].translation;
    let (first, last) = (&keys[0], &keys[keys.len() - 1]);
    let travel = at(last) - at(first);
    let velocity = DVec3::new(travel.x, 0.0, travel.z) / f64::from(last.time - first.time);
    let root = (0..rig.skeleton.joints().len())
        .find(|&j| rig.skeleton.joints()[j].parent.is_none())
        .unwrap();
    let frame = rig.skeleton.joints()[root].parent_frame;
    let keys = keys
        .iter()
        .map(|k| {
            let mut key = k.clone();
            let back = -velocity * f64::from(k.time - first.time);
            key.pose.local[root].translation += frame.inverse().transform_vector3(back);
            key
        })
        .collect();
    (PoseClip::from_keys(keys).unwrap(), velocity)
}

/// The walk made in place onto the longer legs: the ground's speed under it is found (the
/// walk's, backwards), the same feet are planted as in the walk that travels, and the target's
/// planted feet move with the ground — they slide on it by no more than 2e-3 of the height a
/// frame with the contacts, and more without; the target stays in place.
#[test]
fn a_walk_made_in_place_keeps_its_feet_moving_with_the_ground() {
    let source = figure(FigureSpec::default());
    let target = longer_legs();
    let travelling = mixamo_walk(&source);
    let (clip, velocity) = made_in_place(&source, &travelling);
    let with = retargeter(&source, &target, RetargetSettings::default());
    let ground = with.rest_ground();
    let reference = with.bake(&travelling, &ground).unwrap();
    let baked = with.bake(&clip, &ground).unwrap();
    let contacts = &baked.source_contacts;
    assert_eq!(reference.source_contacts.treadmill, DVec3::ZERO);
    assert!(
        (contacts.treadmill + velocity).length() <= 0.05 * velocity.length(),
        "the ground moves at {} under a walk of {velocity}",
        contacts.treadmill
    );
    let pairs: Vec<(bool, bool)> = contacts
        .planted
        .iter()
        .flatten()
        .zip(reference.source_contacts.planted.iter().flatten())
        .map(|(a, b)| (*a, *b))
        .collect();
    let agree = pairs.iter().filter(|(a, b)| a == b).count() as f64 / pairs.len() as f64;
    assert!(
        agree >= 0.9 && contacts.planted_share() > 0.5,
        "planted in place {} against {} travelling, {agree} of the pairs agree",
        contacts.planted_share(),
        reference.source_contacts.planted_share()
    );
    assert_eq!(baked.failed_solves, 0);
    let q = with.quality(&frames(&clip), &frames(&baked.clip), contacts, &ground);
    let q0 = quality_without_contacts(&source, &target, &clip, &ground);
    eprintln!("in place, with contacts {q:?}\nwithout {q0:?}");
    assert!(
        q.foot_slide_max <= 2e-3,
        "slide on the ground with contacts {}",
        q.foot_slide_max
    );
    assert!(
        q0.foot_slide_max > 2.0 * q.foot_slide_max.max(1e-3),
        "without contacts the feet slide only {}",
        q0.foot_slide_max
    );
    assert!(
        q.penetration_max <= 1e-3,
        "penetration {}",
        q.penetration_max
    );
    let hips = joint(&target, "pelvis");
    let travel = |c: &PoseClip| {
        let at = |k: &PoseKey| {
            target.skeleton.global_transforms(&k.pose)[hips]
                .translation
                .z
        };
        at(&c.keys()[c.keys().len() - 1]) - at(&c.keys()[0])
    };
    assert!(
        travel(&baked.clip).abs() < 0.05 * travel(&reference.clip).abs(),
        "the target travels {} in place, {} with the walk that travels",
        travel(&baked.clip),
        travel(&reference.clip)
    );
}

#[test]
fn no_skin_goes_below_a_sloped_ground() {
    let rig = figure(FigureSpec::default());
    let clip = mixamo_walk(&rig);
    let r = retargeter(&rig, &rig, RetargetSettings::default());
    // 8° up towards +Z through the rest ground's point: the walk on the flat goes into it.
    let normal = DVec3::new(0.0, 8f64.to_radians().cos(), -8f64.to_radians().sin());
    let slope = GroundPlane {
        point: r.rest_ground().point,
        normal,
    };
    let baked = r.bake(&clip, &slope).unwrap();
    let q = r.quality(
        &frames(&clip),
        &frames(&baked.clip),
        &baked.source_contacts,
        &slope,
    );
    let bare = retargeter(
        &rig,
        &rig,
        RetargetSettings {
            contacts: false,
            ..RetargetSettings::default()
        },
    )
    .bake(&clip, &slope)
    .unwrap();
    let q0 = r.quality(
        &frames(&clip),
        &frames(&bare.clip),
        &bare.source_contacts,
        &slope,
    );
    assert!(
        q0.penetration_max > 1e-2,
        "the flat walk should go into the slope ({})",
        q0.penetration_max
    );
    assert!(
        q.penetration_max <= 1e-3,
        "penetration {}",
        q.penetration_max
    );
}

#[test]
fn what_cannot_be_mapped_is_a_typed_error() {
    let rig = figure(FigureSpec::default());
    let bar = bevy_wii_deform::pose::rig::synth_rig::bar_rig(3, 8, 8);
    assert_eq!(
        SkeletonMap::humanoid((&bar.skeleton, &bar.rest), (&rig.skeleton, &rig.rest)).unwrap_err(),
        RetargetError::MissingRole {
            role: "left thigh",
            which: Which::Source
        }
    );
    let chains = r#"(root: ("Hips", "Hips"), chains: [(name: "tail", source: ["Spine"], target: ["Tail1"])])"#;
    assert_eq!(
        SkeletonMap::from_ron(
            chains,
            (&rig.skeleton, &rig.rest),
            (&rig.skeleton, &rig.rest)
        )
        .unwrap_err(),
        RetargetError::ChainJoint {
            chain: "tail".into(),
            joint: "Tail1".into(),
            which: Which::Target
        }
    );
    let empty =
        r#"(root: ("Hips", "Hips"), chains: [(name: "tail", source: [], target: ["Spine"])])"#;
    assert_eq!(
        SkeletonMap::from_ron(
            empty,
            (&rig.skeleton, &rig.rest),
            (&rig.skeleton, &rig.rest)
        )
        .unwrap_err(),
        RetargetError::EmptyChain("tail".into())
    );
    assert!(matches!(
        SkeletonMap::from_ron(
            "(root: ",
            (&rig.skeleton, &rig.rest),
            (&rig.skeleton, &rig.rest)
        ),
        Err(RetargetError::MapFile(_))
    ));
    // Joints nothing maps to are listed (the Unreal figure's root).
    let unreal = figure(FigureSpec {
        names: FigureNames::Unreal,
        ..FigureSpec::default()
    });
    let map = SkeletonMap::humanoid((&rig.skeleton, &rig.rest), (&unreal.skeleton, &unreal.rest))
        .unwrap();
    assert_eq!(map.unmapped, vec![joint(&unreal, "root")]);
    assert_eq!(map.joints_mapped(), unreal.skeleton.len() - 1);
}

/// A baked clip written to glTF and read back plays the same poses; the source written to BVH
/// and read back retargets the same.
#[test]
fn a_baked_clip_round_trips_through_gltf_and_its_source_through_bvh() {
    let source = figure(FigureSpec::default());
    let target = figure(FigureSpec {
        names: FigureNames::Unreal,
        arm_down_deg: 20.0,
        ..FigureSpec::default()
    });
    let clip = mixamo_walk(&source);
    let r = retargeter(&source, &target, RetargetSettings::default());
    let ground = r.rest_ground();
    let baked = r.bake(&clip, &ground).unwrap();
    let paths: Vec<Vec<String>> = target
        .skeleton
        .joints()
        .iter()
        .map(|j| vec![j.name.clone()])
        .collect();
    let glb = write_gltf_clip(&baked.clip, "walk", &paths, Some(&target.rest)).unwrap();
    let back = read_gltf_clip(&glb, None, Some("walk"), &target.skeleton, &target.rest).unwrap();
    assert_eq!(back.keys().len(), baked.clip.keys().len());
    for (a, b) in baked.clip.keys().iter().zip(back.keys()) {
        for (x, y) in a.pose.local.iter().zip(&b.pose.local) {
            assert!(rotation_angle(x.rotation, y.rotation) < 1e-5);
            assert!((x.translation - y.translation).length() < 1e-5);
        }
    }
    let text = write_bvh(&source.skeleton, &source.rest, &clip, FRAME_TIME).unwrap();
    let motion = read_bvh(&text).unwrap();
    let map = SkeletonMap::humanoid(
        (&motion.skeleton, &motion.rest),
        (&target.skeleton, &target.rest),
    )
    .unwrap();
    let model = Arc::new(target.model().unwrap());
    let from_bvh = Retargeter::new(
        (&motion.skeleton, &motion.rest),
        model,
        &target.rest,
        map,
        RetargetSettings {
            contacts: false,
            ..RetargetSettings::default()
        },
    )
    .unwrap()
    .bake(&motion.clip, &ground)
    .unwrap();
    let direct = retargeter(
        &source,
        &target,
        RetargetSettings {
            contacts: false,
            ..RetargetSettings::default()
        },
    )
    .bake(&clip, &ground)
    .unwrap();
    for (a, b) in direct.clip.keys().iter().zip(from_bvh.clip.keys()) {
        for (x, y) in a.pose.local.iter().zip(&b.pose.local) {
            assert!(rotation_angle(x.rotation, y.rotation) < 1e-5);
            assert!((x.translation - y.translation).length() < 1e-5);
        }
    }
}

/// The Fox's clips through the chain map the repository ships, onto the Fox itself with the
/// contacts off: each comes back as it was — every mapped joint's rotation within 1e-6 rad.
#[test]
fn the_fox_s_clips_through_its_chain_map_come_back_unchanged() {
    use bevy_wii_deform::pose::retarget::read_source_motion;
    use bevy_wii_deform::pose::{GltfCharacter, ModelSettings};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let file = root.join("assets/models/Fox.glb");
    let fox = GltfCharacter::read(&file).unwrap();
    let model = Arc::new(fox.model(ModelSettings::default()).unwrap());
    let ron = std::fs::read_to_string(root.join("assets/retarget/fox.ron")).unwrap();
    for name in ["Survey", "Walk", "Run"] {
        let motion = read_source_motion(&file, Some(name)).unwrap();
        let from = (&motion.skeleton, &motion.rest);
        let map = SkeletonMap::from_ron(&ron, from, (&fox.skeleton, &fox.rest)).unwrap();
        let unmapped = map.unmapped.clone();
        let off = RetargetSettings {
            contacts: false,
            ..RetargetSettings::default()
        };
        let r = Retargeter::new(from, model.clone(), &fox.rest, map, off).unwrap();
        let baked = r.bake(&motion.clip, &r.rest_ground()).unwrap();
        let mut worst = (0.0f64, 0, 0.0f32);
        for (a, b) in motion.clip.keys().iter().zip(baked.clip.keys()) {
            for (j, (x, y)) in a.pose.local.iter().zip(&b.pose.local).enumerate() {
                if unmapped.contains(&j) {
                    continue;
                }
                let angle = rotation_angle(x.rotation, y.rotation);
                if angle > worst.0 {
                    worst = (angle, j, a.time);
                }
            }
        }
        assert!(
            worst.0 < 1e-6,
            "{name}: joint {} ({}) is {} rad off at {} s",
            worst.1,
            fox.skeleton.joints()[worst.1].name,
            worst.0,
            worst.2
        );
    }
}
