//! Spring bones: gravity and stiffness, frame-rate independence, hitches, teleports,
//! colliders, joint limits, and VRM's `VRMC_springBone` read from a generated VRM-style glTF.

use bevy_wii_deform::pose::rig::synth_rig;
use bevy_wii_deform::pose::*;
use glam::{DAffine3, DQuat, DVec3};

/// A chain of 5 joints along +Y, 0.2 apart (bar_rig's joints), as one spring chain.
fn chain(settings: SpringJoint) -> (SyntheticRigChain, SpringRig) {
    let rig = synth_rig::bar_rig(5, 8, 10);
    let springs = SpringRig::from_names(&rig.skeleton, &["bone"], settings);
    (SyntheticRigChain(rig), springs)
}

struct SyntheticRigChain(synth_rig::SyntheticRig);

/// World positions of the joints of `pose` placed by `placement`.
fn joints_world(
    rig: &synth_rig::SyntheticRig,
    placement: DAffine3,
    pose: &SkeletonPose,
) -> Vec<DVec3> {
    rig.skeleton
        .global_transforms(pose)
        .iter()
        .map(|g| (placement * *g).translation)
        .collect()
}

fn bone_lengths(points: &[DVec3]) -> Vec<f64> {
    points.windows(2).map(|w| w[0].distance(w[1])).collect()
}

/// Runs `seconds` at `fps` frames per second with the root moved by `path(t)`; records the
/// tail's offset from its animated place at each time in `at` (seconds).
fn run(
    springs: &SpringRig,
    rig: &synth_rig::SyntheticRig,
    fps: f64,
    seconds: f64,
    path: impl Fn(f64) -> DVec3,
    at: &[f64],
) -> Vec<DVec3> {
    let frames = (seconds * fps).round() as usize + 1;
    let mut out = Vec::new();
    let place = |t: f64| DAffine3::from_translation(path(t));
    simulate(
        springs,
        rig,
        (frames, fps),
        place,
        None,
        |t, placement, pose| {
            if at.iter().any(|a| (a - t).abs() < 1e-9) {
                let swung = joints_world(rig, placement, pose);
                let animated = joints_world(rig, placement, &rig.rest);
                out.push(swung[4] - animated[4]);
            }
        },
    );
    out
}

/// Steps the rest pose's springs for `frames` frames at `fps` (the first starts them), the
/// character placed by `placement(t)`; `each(t, placement, pose)` sees every frame.
fn simulate(
    springs: &SpringRig,
    rig: &synth_rig::SyntheticRig,
    (frames, fps): (usize, f64),
    placement: impl Fn(f64) -> DAffine3,
    limits: Option<&JointLimits>,
    mut each: impl FnMut(f64, DAffine3, &SkeletonPose),
) -> SkeletonPose {
    let mut state = SpringState::default();
    let mut pose = rig.rest.clone();
    for f in 0..frames {
        let t = f as f64 / fps;
        let at = placement(t);
        pose = rig.rest.clone();
        let dt = if f == 0 { 0.0 } else { 1.0 / fps };
        step_springs(
            springs,
            &rig.skeleton,
            at,
            &mut pose,
            dt,
            limits,
            &mut state,
        );
        each(t, at, &pose);
    }
    pose
}

/// The pose after `frames` 60 Hz frames of the rest pose placed by `placement`.
fn swing(
    springs: &SpringRig,
    rig: &synth_rig::SyntheticRig,
    placement: DAffine3,
    frames: usize,
    limits: Option<&JointLimits>,
) -> SkeletonPose {
    simulate(
        springs,
        rig,
        (frames, 60.0),
        |_| placement,
        limits,
        |_, _, _| {},
    )
}

#[test]
fn a_chain_under_gravity_falls_and_keeps_its_bone_lengths() {
    let (SyntheticRigChain(rig), mut springs) = chain(SpringJoint {
        stiffness: 0.0,
        gravity_power: 2.0,
        ..SpringJoint::new(0)
    });
    assert_eq!(springs.chains.len(), 1);
    assert_eq!(springs.chains[0].joints.len(), 5);
    // Lay the chain sideways: the root turned so the chain points along +X.
    let placement = DAffine3::from_quat(DQuat::from_rotation_z(-std::f64::consts::FRAC_PI_2));
    springs.settings.teleport_distance = 10.0;
    let pose = swing(&springs, &rig, placement, 600, None);
    let rest = joints_world(&rig, placement, &rig.rest);
    let hanging = joints_world(&rig, placement, &pose);
    assert!(rest[4].y.abs() < 1e-12 && rest[4].x > 0.79);
    // With no stiffness, the rule's rest under gravity: the chain straight down from its root.
    assert!(
        hanging[4].distance(DVec3::new(0.0, -0.8, 0.0)) < 1e-3,
        "the free end hangs straight below the root: {:?}",
        hanging[4]
    );
    for (a, b) in bone_lengths(&rest).iter().zip(bone_lengths(&hanging)) {
        assert!((a - b).abs() < 1e-9, "bone length {a} → {b}");
    }
    // The root joint's position never moves (only rotations change).
    assert!(hanging[0].distance(rest[0]) < 1e-12);
}

#[test]
fn the_same_motion_at_30_60_144_and_240_hz() {
    let (SyntheticRigChain(rig), springs) = chain(SpringJoint {
        stiffness: 1.5,
        drag: 0.3,
        ..SpringJoint::new(0)
    });
    // The root swings sideways, 0.3 at 1 Hz: the tail lags and overshoots.
    let path = |t: f64| DVec3::new(0.3 * (std::f64::consts::TAU * t).sin(), 0.0, 0.0);
    // Times every frame rate lands on.
    let at = [0.5, 1.0, 1.5, 2.0];
    let reference = run(&springs, &rig, 60.0, 2.0, path, &at);
    let swing = reference.iter().map(|d| d.length()).fold(0.0, f64::max);
    assert!(swing > 0.05, "the tail lags the motion: {swing}");
    for fps in [30.0, 144.0, 240.0] {
        let other = run(&springs, &rig, fps, 2.0, path, &at);
        let worst = other
            .iter()
            .zip(&reference)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        assert!(
            worst < 0.05 * swing,
            "{fps} Hz differs from 60 Hz by {worst} (the swing is {swing})"
        );
    }
}

#[test]
fn a_hitch_and_a_teleport_do_not_whip_the_chain() {
    let (SyntheticRigChain(rig), springs) = chain(SpringJoint {
        stiffness: 1.0,
        gravity_power: 1.0,
        ..SpringJoint::new(0)
    });
    let mut state = SpringState::default();
    let rest_lengths = bone_lengths(&joints_world(&rig, DAffine3::IDENTITY, &rig.rest));
    let mut x = 0.0;
    for f in 0..200 {
        // A 100 ms frame every 50 frames, moving 0.3 in it.
        let dt = if f % 50 == 49 { 0.1 } else { 1.0 / 60.0 };
        x += if f % 50 == 49 { 0.3 } else { 0.002 };
        let placement = DAffine3::from_translation(DVec3::new(x, 0.0, 0.0));
        let mut pose = rig.rest.clone();
        step_springs(
            &springs,
            &rig.skeleton,
            placement,
            &mut pose,
            dt,
            None,
            &mut state,
        );
        let world = joints_world(&rig, placement, &pose);
        assert!(world.iter().all(|p| p.is_finite()));
        for (a, b) in rest_lengths.iter().zip(bone_lengths(&world)) {
            assert!((a - b).abs() < 1e-9);
        }
    }
    // A jump of 50 units: the chain shows its animated pose, not a whip across the world.
    let placement = DAffine3::from_translation(DVec3::new(x + 50.0, 0.0, 0.0));
    let mut pose = rig.rest.clone();
    step_springs(
        &springs,
        &rig.skeleton,
        placement,
        &mut pose,
        1.0 / 60.0,
        None,
        &mut state,
    );
    let turned = pose
        .local
        .iter()
        .zip(&rig.rest.local)
        .map(|(a, b)| a.rotation.angle_between(b.rotation))
        .fold(0.0, f64::max);
    assert!(
        turned < 1e-6,
        "teleported: every joint at its animated rotation ({turned})"
    );
}

#[test]
fn a_collider_keeps_the_chain_out() {
    let (SyntheticRigChain(rig), mut springs) = chain(SpringJoint {
        stiffness: 0.0,
        gravity_power: 2.0,
        hit_radius: 0.02,
        ..SpringJoint::new(0)
    });
    // The chain points along +X and falls; a ball on the root joint's frame sits in its way.
    let placement = DAffine3::from_quat(DQuat::from_rotation_z(-std::f64::consts::FRAC_PI_2));
    let ball_at = DVec3::new(0.6, -0.25, 0.0); // world
    let ball_radius = 0.15;
    springs.colliders.push(SpringCollider {
        joint: 0,
        shape: SpringColliderShape::Sphere {
            offset: placement.inverse().transform_point3(ball_at),
            radius: ball_radius,
        },
    });
    springs.collider_groups.push(vec![0]);
    let deepest = |springs: &SpringRig| {
        let mut worst = f64::NEG_INFINITY;
        simulate(
            springs,
            &rig,
            (240, 60.0),
            |_| placement,
            None,
            |_, at, pose| {
                for p in &joints_world(&rig, at, pose)[1..] {
                    worst = worst.max(ball_radius + 0.02 - p.distance(ball_at));
                }
            },
        );
        worst
    };
    assert!(
        deepest(&springs) > 0.05,
        "without the group the chain falls through the ball"
    );
    springs.chains[0].collider_groups.push(0);
    springs.validate(&rig.skeleton).unwrap();
    let depth = deepest(&springs);
    assert!(depth < 1e-9, "the tails stay out of the ball: {depth}");
}

#[test]
fn joint_limits_hold_the_swung_joints() {
    let (SyntheticRigChain(rig), springs) = chain(SpringJoint {
        stiffness: 0.0,
        gravity_power: 3.0,
        ..SpringJoint::new(0)
    });
    // The chain's root would hang 90° from its rest; its cone allows 20°.
    let mut limits = JointLimits::new(&rig.skeleton, &rig.rest);
    limits
        .set_by_name("bone0", JointLimit::cone_deg((20.0, 20.0), (-5.0, 5.0)))
        .unwrap();
    let placement = DAffine3::from_quat(DQuat::from_rotation_z(-std::f64::consts::FRAC_PI_2));
    let pose = swing(&springs, &rig, placement, 200, Some(&limits));
    assert!(limits.max_violation_deg(&pose) < 1e-6);
    let bent = pose.local[0]
        .rotation
        .angle_between(rig.rest.local[0].rotation)
        .to_degrees();
    assert!(
        bent > 19.0,
        "the limited joint swings to its limit: {bent}°"
    );
}

/// A VRM-style glTF: a hips joint with a three-joint hair strand (0.1 apart along +Y) and a
/// collider sphere on the hips, in `VRMC_springBone` 1.0 form.
fn vrm_json() -> serde_json::Value {
    serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["VRMC_springBone"],
        "nodes": [
            {"name": "hips", "children": [1]},
            {"name": "hair_1", "translation": [0.0, 0.1, 0.0], "children": [2]},
            {"name": "hair_2", "translation": [0.0, 0.1, 0.0], "children": [3]},
            {"name": "hair_end", "translation": [0.0, 0.1, 0.0]}
        ],
        "extensions": {"VRMC_springBone": {
            "specVersion": "1.0",
            "colliders": [{"node": 0, "shape": {"sphere": {"offset": [0.0, 0.0, 0.1], "radius": 0.05}}},
                          {"node": 0, "shape": {"capsule": {"offset": [0.0, 0.0, 0.0], "tail": [0.0, 0.2, 0.0], "radius": 0.02}}}],
            "colliderGroups": [{"name": "head", "colliders": [0, 1]}],
            "springs": [{
                "name": "hair",
                "joints": [
                    {"node": 1, "hitRadius": 0.01, "stiffness": 0.8, "gravityPower": 0.5,
                     "gravityDir": [0.0, -1.0, 0.0], "dragForce": 0.3},
                    {"node": 2, "hitRadius": 0.01, "stiffness": 0.6, "gravityPower": 0.5,
                     "gravityDir": [0.0, -1.0, 0.0], "dragForce": 0.3},
                    {"node": 3}
                ],
                "colliderGroups": [0],
                "center": 0
            }]
        }}
    })
}

/// The skeleton of [`vrm_json`]'s nodes as the pose layer reads a skin.
fn vrm_skeleton() -> Skeleton {
    let names = ["hips", "hair_1", "hair_2", "hair_end"];
    let joints = names
        .iter()
        .enumerate()
        .map(|(k, name)| Joint {
            name: name.to_string(),
            parent: k.checked_sub(1),
            parent_frame: DAffine3::IDENTITY,
            inverse_bind: DAffine3::from_translation(DVec3::new(0.0, -0.1 * k as f64, 0.0)),
        })
        .collect();
    Skeleton::new(joints).unwrap()
}

#[test]
fn vrm_spring_bones_are_read_from_the_extension() {
    let skeleton = vrm_skeleton();
    let text = serde_json::to_vec(&vrm_json()).unwrap();
    let rig = read_vrm_springs(&text, &skeleton).unwrap();
    assert_eq!(rig.chains.len(), 1);
    let chain = &rig.chains[0];
    assert_eq!(chain.name, "hair");
    assert_eq!(
        chain.joints.iter().map(|j| j.joint).collect::<Vec<_>>(),
        vec![1, 2, 3]
    );
    assert_eq!(chain.joints[0].stiffness, 0.8);
    assert_eq!(chain.joints[1].drag, 0.3);
    assert_eq!(chain.joints[0].hit_radius, 0.01);
    assert_eq!(
        chain.joints[2].drag, 0.5,
        "a joint without settings takes the spec's defaults"
    );
    assert_eq!(chain.center, Some(0));
    assert_eq!(chain.collider_groups, vec![0]);
    assert_eq!(rig.collider_groups, vec![vec![0, 1]]);
    assert!(matches!(
        rig.colliders[1].shape,
        SpringColliderShape::Capsule { radius, .. } if radius == 0.02
    ));
    // The same from a binary glTF.
    let glb = bevy_wii_deform::deform::glb_container(text, Vec::new());
    assert_eq!(read_vrm_springs(&glb, &skeleton).unwrap(), rig);
}

#[test]
fn malformed_vrm_spring_bones_fail_typed() {
    let skeleton = vrm_skeleton();
    let read = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut json = vrm_json();
        edit(&mut json);
        read_vrm_springs(&serde_json::to_vec(&json).unwrap(), &skeleton)
    };
    let ext = "/extensions/VRMC_springBone";
    assert!(matches!(
        read(&|j| j["nodes"][2]["name"] = "elsewhere".into()),
        Err(VrmSpringError::NotAJoint { node: 2, .. })
    ));
    assert!(matches!(
        read(
            &|j| j.pointer_mut(ext).unwrap()["springs"][0]["joints"][0]["stiffness"] =
                "stiff".into()
        ),
        Err(VrmSpringError::Malformed(_))
    ));
    assert!(matches!(
        read(&|j| j.pointer_mut(ext).unwrap()["springs"][0]["joints"][0]["dragForce"] = 3.0.into()),
        Err(VrmSpringError::Rig(SpringError::InvalidSetting { .. }))
    ));
    assert!(matches!(
        read(
            &|j| j.pointer_mut(ext).unwrap()["springs"][0]["colliderGroups"] =
                serde_json::json!([4])
        ),
        Err(VrmSpringError::Rig(SpringError::InvalidCollider {
            collider: 4
        }))
    ));
    assert!(matches!(
        read(&|j| j.pointer_mut(ext).unwrap()["springs"][0]["joints"][1]["stiffness"] = (-1.0).into()),
        Err(VrmSpringError::Rig(SpringError::InvalidSetting { chain })) if chain == "hair"
    ));
    assert!(matches!(
        read(
            &|j| j.pointer_mut(ext).unwrap()["colliders"][0]["shape"]["sphere"]["radius"] =
                0.0.into()
        ),
        Err(VrmSpringError::Rig(SpringError::InvalidCollider {
            collider: 0
        }))
    ));
    assert!(matches!(
        read(&|j| {
            j["extensions"].as_object_mut().unwrap().clear();
        }),
        Err(VrmSpringError::NoExtension)
    ));
    assert!(matches!(
        read_vrm_springs(b"glTF\x02\x00\x00\x00garbage", &skeleton),
        Err(VrmSpringError::NotGltf(_))
    ));
}

#[test]
fn one_step_per_60_hz_frame_is_the_vrm_update_rule() {
    // One bone from hair_1 to hair_2 (0.1 long, along +Y), settings as VRM would give them;
    // the rule written out by hand for 200 frames, with the root still.
    let skeleton = vrm_skeleton();
    let rest = skeleton.bind_pose();
    let (stiffness, drag, gravity) = (0.8, 0.3, 2.0);
    let rig = SpringRig {
        chains: vec![SpringChain {
            name: "hair".into(),
            joints: vec![
                SpringJoint {
                    joint: 1,
                    stiffness,
                    drag,
                    gravity_power: gravity,
                    gravity_dir: DVec3::new(1.0, 0.0, 0.0),
                    hit_radius: 0.0,
                },
                SpringJoint::new(2),
            ],
            collider_groups: vec![],
            center: None,
        }],
        ..Default::default()
    };
    rig.validate(&skeleton).unwrap();
    let h = 1.0 / 60.0;
    let head = DVec3::new(0.0, 0.1, 0.0);
    let (mut tail, mut prev) = (DVec3::new(0.0, 0.2, 0.0), DVec3::new(0.0, 0.2, 0.0));
    let mut state = SpringState::default();
    let mut pose = rest.clone();
    step_springs(
        &rig,
        &skeleton,
        DAffine3::IDENTITY,
        &mut pose,
        0.0,
        None,
        &mut state,
    );
    for frame in 1..=200 {
        let next = tail
            + (tail - prev) * (1.0 - drag)
            + DVec3::Y * (h * stiffness)
            + DVec3::X * (h * gravity);
        let next = head + (next - head).normalize() * 0.1;
        (prev, tail) = (tail, next);
        pose = rest.clone();
        step_springs(
            &rig,
            &skeleton,
            DAffine3::IDENTITY,
            &mut pose,
            h,
            None,
            &mut state,
        );
        let shown = skeleton.global_transforms(&pose)[2].translation;
        assert!(
            shown.distance(tail) < 1e-9,
            "frame {frame}: {shown} against the rule's {tail}"
        );
    }
    assert!(tail.x > 1e-4, "the bone swung toward the pull");
}

#[test]
fn a_spring_rig_in_ron_names_its_joints() {
    let rig = synth_rig::bar_rig(5, 8, 10);
    let text = r#"(
        chains: [(name: "bar", joints: ["bone1", "bone2", "bone3", "bone4"],
                  stiffness: 0.5, drag: 0.2, gravity_power: 1.0, collider_groups: [0])],
        colliders: [(joint: "bone0", offset: (0.0, 0.1, 0.2), radius: 0.05),
                     (joint: "bone0", offset: (0.0, 0.0, 0.0), tail: (0.0, 0.3, 0.0), radius: 0.02)],
        collider_groups: [[0, 1]],
    )"#;
    let springs = SpringRig::from_ron(text, &rig.skeleton).unwrap();
    let chain = &springs.chains[0];
    assert_eq!(
        chain.joints.iter().map(|j| j.joint).collect::<Vec<_>>(),
        vec![1, 2, 3, 4]
    );
    assert!(
        chain
            .joints
            .iter()
            .all(|j| j.stiffness == 0.5 && j.drag == 0.2)
    );
    assert_eq!(chain.joints[0].hit_radius, SpringJoint::new(0).hit_radius);
    assert!(matches!(
        springs.colliders[1].shape,
        SpringColliderShape::Capsule { .. }
    ));
    // A joint the skeleton lacks, a drag out of range, and bad syntax fail typed.
    assert!(matches!(
        SpringRig::from_ron(&text.replace("bone3", "bone9"), &rig.skeleton),
        Err(SpringRonError::UnknownJoint { owner, joint }) if owner == "bar" && joint == "bone9"
    ));
    assert!(matches!(
        SpringRig::from_ron(&text.replace("drag: 0.2", "drag: 2.0"), &rig.skeleton),
        Err(SpringRonError::Rig(SpringError::InvalidSetting { chain })) if chain == "bar"
    ));
    assert!(matches!(
        SpringRig::from_ron("(chains: [", &rig.skeleton),
        Err(SpringRonError::Parse(_))
    ));
}
