//! Full-body posing constraints in the pose core: joint limits (hinge, swing cone and twist),
//! position / orientation / aim effectors with weights, mirror, limits from files and the
//! humanoid preset.

use std::sync::Arc;

use bevy_wii_deform::deform::{Handle, RigidTransform};
use bevy_wii_deform::pose::rig::synth_rig::{SyntheticRig, bar_rig, mannequin_rig};
use bevy_wii_deform::pose::*;
use glam::{DQuat, DVec3};

use crate::common;
use common::model_of;

fn solve(
    model: &Arc<SkinnedModel>,
    rig: &SyntheticRig,
    constraints: &PoseConstraints,
    iterations: u32,
) -> SkeletonPose {
    let solver = PoseSolver::new(
        model.clone(),
        constraints,
        &rig.rest,
        PoseSolverSettings::default(),
    )
    .unwrap();
    let options = PoseSolveOptions {
        max_iterations: iterations,
        tolerance: 0.0,
        ground_iterations: 0,
    };
    solver
        .solve(constraints, &options, PoseStart::Pose(&rig.rest), &|| false)
        .unwrap()
        .pose
}

fn positions(rig: &SyntheticRig, pose: &SkeletonPose) -> Vec<DVec3> {
    rig.skeleton
        .global_transforms(pose)
        .iter()
        .map(|g| g.translation)
        .collect()
}

/// The angle (degrees) of joint `j`'s rotation about +x, from its rest rotation.
fn hinge_angle_deg(rig: &SyntheticRig, pose: &SkeletonPose, j: usize) -> f64 {
    let d = rig.rest.local[j].rotation.inverse() * pose.local[j].rotation;
    let d = if d.w < 0.0 { -d } else { d };
    (2.0 * d.x.atan2(d.w)).to_degrees()
}

/// The largest turn (degrees) of any joint's local rotation between two poses.
fn largest_turn_deg(a: &SkeletonPose, b: &SkeletonPose) -> f64 {
    a.local
        .iter()
        .zip(&b.local)
        .map(|(x, y)| rotation_angle(x.rotation, y.rotation).to_degrees())
        .fold(0.0, f64::max)
}

/// A three-bone arm along +y: shoulder (joint 0) pinned, a position effector pulling the wrist
/// (joint 2) behind the arm (−z), where only a backward elbow bend goes.
fn arm_pulled_backwards(limits: Option<Arc<JointLimits>>) -> (SyntheticRig, SkeletonPose) {
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let constraints = PoseConstraints {
        fixed_joints: vec![0],
        effectors: vec![Effector {
            joint: 2,
            goal: EffectorGoal::Position(DVec3::new(0.0, 0.55, -0.15)),
            weight: 1.0,
        }],
        limits,
        ..Default::default()
    };
    let pose = solve(&model, &rig, &constraints, 40);
    (rig, pose)
}

#[test]
fn a_hinge_elbow_stays_at_its_limit_for_a_target_behind_the_arm() {
    // Without a limit the elbow bends backwards (negative about +x) well past 0.
    let (rig, free) = arm_pulled_backwards(None);
    let free_angle = hinge_angle_deg(&rig, &free, 1);
    assert!(free_angle < -10.0, "the free elbow bent {free_angle}°");
    // A hinge about +x from 0° to 150°: the elbow stays at 0, within 0.5°.
    let mut limits = JointLimits::new(&rig.skeleton, &rig.rest);
    limits
        .set(1, JointLimit::hinge_deg(DVec3::X, 0.0, 150.0))
        .unwrap();
    let limits = Arc::new(limits);
    let (rig, held) = arm_pulled_backwards(Some(limits.clone()));
    let angle = hinge_angle_deg(&rig, &held, 1);
    assert!(
        angle > -0.5 && angle < 5.0,
        "the limited elbow is at {angle}°, not at its 0° limit"
    );
    assert!(limits.max_violation_deg(&held) <= 0.5);
    // Bones stay rigid.
    assert!(max_bone_length_error(&rig.skeleton, &rig.rest, &held) < 1e-9);
}

#[test]
fn limits_are_solved_with_the_effectors_not_clamped_after() {
    // A reachable target in front (+z) with the elbow limited to 0…40°: the solve reaches the
    // target as far as 40° of elbow allows, using the shoulder's freedom too.
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let mut limits = JointLimits::new(&rig.skeleton, &rig.rest);
    limits
        .set(1, JointLimit::hinge_deg(DVec3::X, 0.0, 40.0))
        .unwrap()
        .set(2, JointLimit::cone_deg((20.0, 20.0), (-10.0, 10.0)))
        .unwrap();
    let limits = Arc::new(limits);
    let target = DVec3::new(0.0, 0.8, 0.45);
    let constraints = PoseConstraints {
        effectors: vec![Effector {
            joint: 2,
            goal: EffectorGoal::Position(target),
            weight: 1.0,
        }],
        limits: Some(limits.clone()),
        ..Default::default()
    };
    let pose = solve(&model, &rig, &constraints, 60);
    assert!(
        limits.max_violation_deg(&pose) <= 0.5,
        "{}",
        limits.max_violation_deg(&pose)
    );
    // The wrist joint is on the target: the root turns to make up what the elbow may not.
    let at = positions(&rig, &pose)[2];
    assert!(
        (at - target).length() < 1e-3,
        "wrist at {at}, target {target}"
    );
}

#[test]
fn a_position_effector_plants_a_foot_while_the_ankle_turns() {
    // Joint 0 of a four-bone bar is the "foot": planted where it is, orientation free; the
    // top ("hips") is pulled sideways by a vertex handle.
    let rig = bar_rig(4, 12, 40);
    let model = model_of(&rig);
    let size = model.topology().bounding_diagonal();
    let top = rig.vertices_where(&model, |p| p.y > 0.95);
    let constraints = PoseConstraints {
        handles: vec![Handle {
            vertices: top,
            transform: RigidTransform::new(
                DQuat::IDENTITY,
                DVec3::new(0.4, -0.1, 0.0),
                DVec3::ZERO,
            ),
        }],
        effectors: vec![Effector {
            joint: 0,
            goal: EffectorGoal::Position(DVec3::ZERO),
            weight: 1.0,
        }],
        ..Default::default()
    };
    let pose = solve(&model, &rig, &constraints, 40);
    let foot = positions(&rig, &pose)[0];
    assert!(foot.length() < 1e-3 * size, "the foot moved {foot}");
    let turned = pose.local[0]
        .rotation
        .angle_between(rig.rest.local[0].rotation)
        .to_degrees();
    assert!(turned > 10.0, "the ankle turned only {turned}°");
}

#[test]
fn an_orientation_effector_sets_the_rotation_and_leaves_the_position_free() {
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let goal = DQuat::from_rotation_z(0.5) * DQuat::from_rotation_x(0.3);
    let constraints = PoseConstraints {
        fixed_joints: vec![0],
        effectors: vec![Effector {
            joint: 2,
            goal: EffectorGoal::Orientation(goal),
            weight: 1.0,
        }],
        ..Default::default()
    };
    let pose = solve(&model, &rig, &constraints, 40);
    let globals = rig.skeleton.global_transforms(&pose);
    let got = DQuat::from_mat3(&globals[2].matrix3);
    assert!(
        got.angle_between(goal).to_degrees() < 0.5,
        "joint 2 at {got}, wanted {goal}"
    );
}

#[test]
fn look_at_points_the_head_at_the_target() {
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let target = DVec3::new(0.5, 1.2, 0.3);
    let constraints = PoseConstraints {
        fixed_joints: vec![0],
        effectors: vec![Effector {
            joint: 2,
            goal: EffectorGoal::Aim {
                axis: DVec3::Y,
                target,
                up: None,
            },
            weight: 1.0,
        }],
        ..Default::default()
    };
    let pose = solve(&model, &rig, &constraints, 40);
    let g = rig.skeleton.global_transforms(&pose)[2];
    let axis = (g.matrix3 * DVec3::Y).normalize();
    let to = (target - g.translation).normalize();
    let error = axis.angle_between(to).to_degrees();
    assert!(error < 1.0, "the head points {error}° off the target");
}

#[test]
fn weight_zero_is_no_constraint_and_a_half_lies_between() {
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let top = rig.vertices_where(&model, |p| p.y > 0.95);
    let base = PoseConstraints {
        fixed_joints: vec![0],
        handles: vec![Handle {
            vertices: top,
            transform: RigidTransform::new(DQuat::IDENTITY, DVec3::new(0.2, 0.0, 0.0), DVec3::ZERO),
        }],
        ..Default::default()
    };
    let target = DVec3::new(-0.25, 0.6, 0.2);
    let with = |weight: f64| PoseConstraints {
        effectors: vec![Effector {
            joint: 2,
            goal: EffectorGoal::Position(target),
            weight,
        }],
        ..base.clone()
    };
    let without = solve(&model, &rig, &base, 30);
    let zero = solve(&model, &rig, &with(0.0), 30);
    assert_eq!(zero, without, "weight 0 changed the pose");
    let half = solve(&model, &rig, &with(0.5), 30);
    let full = solve(&model, &rig, &with(1.0), 30);
    let distance = |p: &SkeletonPose| (positions(&rig, p)[2] - target).length();
    let (d0, d5, d1) = (distance(&without), distance(&half), distance(&full));
    assert!(
        d1 < d5 && d5 < d0,
        "distances to the target: 0 → {d0}, ½ → {d5}, 1 → {d1}"
    );
    // Roughly halfway, not all or nothing.
    assert!(d5 > 0.2 * d0 && d5 < 0.8 * d0, "{d5} of {d0}");
}

#[test]
fn invalid_weights_and_targets_are_typed_errors() {
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let base = PoseConstraints {
        fixed_joints: vec![0],
        ..Default::default()
    };
    let solver = PoseSolver::new(model, &base, &rig.rest, PoseSolverSettings::default()).unwrap();
    let bad = |goal, weight, joint| PoseConstraints {
        effectors: vec![Effector {
            joint,
            goal,
            weight,
        }],
        ..base.clone()
    };
    let run = |c: &PoseConstraints| {
        solver.solve(
            c,
            &PoseSolveOptions::default(),
            PoseStart::Pose(&rig.rest),
            &|| false,
        )
    };
    let p = EffectorGoal::Position(DVec3::ONE);
    assert!(matches!(
        run(&bad(p, 1.5, 1)),
        Err(PoseError::InvalidConstraintWeight { .. })
    ));
    assert!(matches!(
        run(&bad(p, f64::NAN, 1)),
        Err(PoseError::InvalidConstraintWeight { .. })
    ));
    assert!(matches!(
        run(&bad(EffectorGoal::Position(DVec3::NAN), 1.0, 1)),
        Err(PoseError::NonFiniteTarget)
    ));
    assert!(matches!(
        run(&bad(p, 1.0, 9)),
        Err(PoseError::JointOutOfRange { joint: 9, .. })
    ));
}

#[test]
fn bad_limits_are_typed_errors_naming_the_joint() {
    let rig = bar_rig(3, 12, 30);
    let mut limits = JointLimits::new(&rig.skeleton, &rig.rest);
    let error = limits
        .set(1, JointLimit::hinge_deg(DVec3::X, 30.0, 10.0))
        .unwrap_err();
    assert!(
        matches!(&error, LimitError::MinAboveMax { joint, min_deg, max_deg }
            if joint == "bone1" && (min_deg - 30.0).abs() < 1e-9 && (max_deg - 10.0).abs() < 1e-9),
        "{error:?}"
    );
    assert!(error.to_string().contains("bone1"));
    assert_eq!(
        limits
            .set(2, JointLimit::cone_deg((f64::NAN, 10.0), (0.0, 1.0)))
            .unwrap_err(),
        LimitError::Invalid {
            joint: "bone2".into()
        }
    );
    assert_eq!(
        limits
            .set(2, JointLimit::hinge_deg(DVec3::ZERO, 0.0, 1.0))
            .unwrap_err(),
        LimitError::ZeroAxis {
            joint: "bone2".into()
        }
    );
    let file = r#"(joints: { "bone1": Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 90.0),
                             "elbow": Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 90.0) })"#;
    assert_eq!(
        JointLimits::from_ron(file, &rig.skeleton, &rig.rest).unwrap_err(),
        LimitError::UnknownJoint("elbow".into())
    );
    assert!(matches!(
        JointLimits::from_ron("(joints: 3)", &rig.skeleton, &rig.rest),
        Err(LimitError::Parse(_))
    ));
    let good = r#"(joints: {
        "bone1": Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 90.0),
        "bone2": SwingTwist(swing_deg: (30.0, 20.0), twist_deg: (-15.0, 15.0)),
    })"#;
    let limits = JointLimits::from_ron(good, &rig.skeleton, &rig.rest).unwrap();
    assert_eq!(limits.limited_count(), 2);
    assert!(limits.is_limited(1) && limits.is_limited(2) && !limits.is_limited(0));
}

#[test]
fn projection_keeps_swing_and_twist_inside_an_elliptic_cone() {
    let rig = bar_rig(3, 12, 30);
    let mut limits = JointLimits::new(&rig.skeleton, &rig.rest);
    limits
        .set(1, JointLimit::cone_deg((30.0, 10.0), (-20.0, 20.0)))
        .unwrap();
    for (axis, angle, twist) in [
        (DVec3::X, 50.0, 0.0),
        (DVec3::Z, 50.0, 0.0),
        (DVec3::new(1.0, 0.0, 1.0), 80.0, 45.0),
        (DVec3::X, 20.0, -60.0),
    ] {
        let mut pose = rig.rest.clone();
        pose.local[1].rotation = DQuat::from_axis_angle(axis.normalize(), f64::to_radians(angle))
            * DQuat::from_rotation_y(f64::to_radians(twist));
        assert!(
            limits.max_violation_deg(&pose) > 1.0,
            "{axis} {angle} {twist}"
        );
        limits.project(&mut pose);
        assert!(
            limits.max_violation_deg(&pose) < 1e-6,
            "{axis} {angle} {twist}: {}",
            limits.max_violation_deg(&pose)
        );
    }
    // Inside stays put.
    let mut pose = rig.rest.clone();
    pose.local[1].rotation = DQuat::from_rotation_x(0.2) * DQuat::from_rotation_y(0.1);
    let before = pose.clone();
    limits.project(&mut pose);
    assert!(
        pose.local[1]
            .rotation
            .angle_between(before.local[1].rotation)
            < 1e-9
    );
}

/// A grab's mirror image: mirroring a motion twice gives it back, the mirrored motion moves
/// reflected points to the reflected targets (in a character frame turned and moved in the
/// world), and a vertex set maps onto the vertices nearest to its reflection, except for a
/// set that meets its own mirror image.
#[test]
fn a_grab_mirrors_onto_the_vertices_and_motion_of_the_other_side() {
    use glam::DAffine3;
    let rig = mannequin_rig(10);
    let mirror = Mirror::new(&rig.skeleton, &rig.rest);
    let frame = DAffine3::from_rotation_translation(
        DQuat::from_rotation_y(0.8),
        DVec3::new(2.0, 0.0, -1.0),
    );
    let motion = RigidTransform::new(
        DQuat::from_axis_angle(DVec3::new(0.3, 1.0, -0.2).normalize(), 0.9),
        DVec3::new(0.2, 0.1, -0.3),
        frame.transform_point3(DVec3::new(0.5, 1.0, 0.1)),
    );
    let mirrored = mirror.mirror_motion(&motion, &frame);
    let twice = mirror.mirror_motion(&mirrored, &frame);
    assert!(twice.rotation.angle_between(motion.rotation) < 1e-9);
    assert!((twice.translation - motion.translation).length() < 1e-9);
    assert!((twice.pivot - motion.pivot).length() < 1e-9);
    for p in [DVec3::new(0.4, 1.2, 0.0), DVec3::new(0.7, 0.9, -0.2)] {
        let p = frame.transform_point3(p);
        let reflected_then_moved = mirrored.apply(mirror.reflect_point(p, &frame));
        let moved_then_reflected = mirror.reflect_point(motion.apply(p), &frame);
        assert!((reflected_then_moved - moved_then_reflected).length() < 1e-9);
    }
    // Vertices: a symmetric cloud, the left ones map onto the right ones.
    let local = [
        DVec3::new(0.3, 1.0, 0.0),
        DVec3::new(-0.3, 1.0, 0.0),
        DVec3::new(0.5, 0.2, 0.1),
        DVec3::new(-0.5, 0.2, 0.1),
        DVec3::new(0.0, 1.6, 0.0),
    ];
    let world: Vec<DVec3> = local.iter().map(|p| frame.transform_point3(*p)).collect();
    assert_eq!(
        mirror.mirror_vertices(&world, &[0, 2], &frame),
        Some(vec![1, 3])
    );
    assert_eq!(mirror.mirror_vertices(&world, &[4], &frame), None);
    assert_eq!(mirror.mirror_vertices(&world, &[0, 1], &frame), None);
    assert_eq!(mirror.mirror_vertices(&world, &[9], &frame), None);
}

#[test]
fn mirroring_twice_gives_the_pose_back_and_pairs_sides_by_name() {
    let rig = mannequin_rig(10);
    let mirror = Mirror::new(&rig.skeleton, &rig.rest);
    let names: Vec<&str> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| j.name.as_str())
        .collect();
    let find = |n: &str| names.iter().position(|x| *x == n).unwrap();
    for (l, r) in [
        ("elbow_l", "elbow_r"),
        ("knee_l", "knee_r"),
        ("shoulder_l", "shoulder_r"),
    ] {
        assert_eq!(mirror.partners()[find(l)], find(r));
        assert_eq!(mirror.partners()[find(r)], find(l));
    }
    assert_eq!(mirror.partners()[find("head")], find("head"));
    assert_eq!(mirror.pair_count(), 6);
    // A pose with the left arm raised and the body twisted.
    let mut pose = rig.rest.clone();
    pose.local[find("shoulder_l")].rotation = DQuat::from_rotation_z(1.1);
    pose.local[find("elbow_l")].rotation = DQuat::from_rotation_x(0.7);
    pose.local[find("chest")].rotation = DQuat::from_rotation_y(0.4);
    pose.local[0].translation += DVec3::new(0.1, 0.0, 0.05);
    let twice = mirror.mirror(&mirror.mirror(&pose));
    for (a, b) in twice.local.iter().zip(&pose.local) {
        assert!(a.rotation.angle_between(b.rotation) < 1e-9);
        assert!((a.translation - b.translation).length() < 1e-9);
    }
    // The rest pose is symmetric: its mirror is itself.
    let rest = mirror.mirror(&rig.rest);
    for (a, b) in rest.local.iter().zip(&rig.rest.local) {
        assert!(a.rotation.angle_between(b.rotation) < 1e-9);
    }
    // The mirrored pose puts every joint where its partner's reflection was.
    let original = positions(&rig, &pose);
    let mirrored = positions(&rig, &mirror.mirror(&pose));
    let reflect = |p: DVec3| DVec3::new(-p.x, p.y, p.z);
    for (j, &p) in mirror.partners().iter().enumerate() {
        assert!(
            (mirrored[j] - reflect(original[p])).length() < 1e-9,
            "{}: {} vs {}",
            names[j],
            mirrored[j],
            reflect(original[p])
        );
    }
}

#[test]
fn side_names_of_common_exporters_are_recognised() {
    use bevy_wii_deform::pose::rig::humanoid::split_name;
    for (name, base, side) in [
        ("mixamorig:LeftForeArm", "forearm", Some(Side::Left)),
        ("mixamorig:RightUpLeg", "upleg", Some(Side::Right)),
        ("DEF-forearm.L", "forearm", Some(Side::Left)),
        ("thigh.R.001", "thigh", Some(Side::Right)),
        ("J_Bip_L_LowerArm", "lowerarm", Some(Side::Left)),
        ("b_LeftLeg01_015", "leg01", Some(Side::Left)),
        ("b_RightLeg01_019", "leg01", Some(Side::Right)),
        ("L_Hand", "hand", Some(Side::Left)),
        ("hand_r", "hand", Some(Side::Right)),
        ("spine.003", "spine.003", None),
        ("Head", "head", None),
    ] {
        let (b, s) = split_name(name);
        assert_eq!(
            (b.trim_start_matches("b_").to_string(), s),
            (base.to_string(), side),
            "{name}"
        );
    }
    assert_eq!(
        humanoid_role("mixamorig:LeftForeArm"),
        Some(HumanoidRole::Elbow)
    );
    assert_eq!(humanoid_role("DEF-shin.R"), Some(HumanoidRole::Knee));
    assert_eq!(humanoid_role("J_Bip_C_Neck"), Some(HumanoidRole::Neck));
    assert_eq!(humanoid_role("mixamorig:Hips"), None);
}

#[test]
fn the_humanoid_preset_limits_a_generated_humanoid() {
    let rig = mannequin_rig(10);
    let (limits, found) = JointLimits::humanoid(&rig.skeleton, &rig.rest);
    let role = |n: &str| found.iter().find(|(name, _)| name == n).map(|(_, r)| *r);
    assert_eq!(role("elbow_l"), Some(HumanoidRole::Elbow));
    assert_eq!(role("knee_r"), Some(HumanoidRole::Knee));
    assert_eq!(role("shoulder_l"), Some(HumanoidRole::UpperArm));
    assert_eq!(role("neck"), Some(HumanoidRole::Neck));
    assert_eq!(role("hips"), None);
    assert!(found.len() >= 14, "{found:?}");
    // A knee bent forwards (the foot in front) is taken back to straight; bent backwards it
    // stays.
    let knee = rig.skeleton.find("knee_l").unwrap();
    let hip = rig.skeleton.find("hip_l").unwrap();
    let globals = rig.skeleton.global_transforms(&rig.rest);
    let bone = (globals[knee + 1].translation - globals[knee].translation).normalize();
    let ankle_height = |pose: &SkeletonPose| positions(&rig, pose)[knee + 1];
    for (sign, allowed) in [(1.0, false), (-1.0, true)] {
        // Turn the shin about the knee's hinge (forward × bone: flexing takes the foot back):
        // −: foot forward, +: foot back.
        let mut pose = rig.rest.clone();
        let axis = DVec3::Z.cross(bone).normalize();
        let turn = DQuat::from_axis_angle(axis, -sign * 0.8);
        pose.local[knee].rotation = rig.rest.local[knee].rotation * turn;
        let before = ankle_height(&pose);
        let mut projected = pose.clone();
        limits.project(&mut projected);
        let after = ankle_height(&projected);
        let moved = (after - before).length();
        if allowed {
            assert!(moved < 1e-9, "a backward knee bend was changed by {moved}");
        } else {
            assert!(
                moved > 0.05,
                "a forward knee bend was kept ({bone}, hip {hip})"
            );
        }
        assert!(limits.max_violation_deg(&projected) < 1e-6);
    }
}

#[test]
fn a_mirrored_effector_gives_a_mirror_symmetric_pose() {
    // The left wrist pulled to a point, and the same effector mirrored onto the right wrist:
    // the solved pose is its own mirror image.
    let rig = mannequin_rig(10);
    let model = model_of(&rig);
    let mirror = Mirror::new(&rig.skeleton, &rig.rest);
    let wrist = rig.skeleton.find("wrist_l").unwrap();
    let left = Effector {
        joint: wrist,
        goal: EffectorGoal::Position(DVec3::new(0.45, 1.3, 0.25)),
        weight: 1.0,
    };
    let frame = rig.skeleton.joints()[0].parent_frame;
    let right = mirror.mirror_effector(&left, &frame).expect("a partner");
    assert_eq!(right.joint, rig.skeleton.find("wrist_r").unwrap());
    // Feet planted (free legs would swing in the energy's null space, either way).
    let feet = ["ankle_l", "ankle_r"].map(|n| rig.skeleton.find(n).unwrap());
    let constraints = PoseConstraints {
        fixed_joints: vec![0, feet[0], feet[1]],
        effectors: vec![left, right],
        // Joints nothing pulls on (the head) stay where they were, not wherever the
        // (not quite symmetric) weight clusters let them drift.
        stiffness: Some(ReferenceStiffness::uniform(rig.rest.clone(), 0.05)),
        ..Default::default()
    };
    let pose = solve(&model, &rig, &constraints, 40);
    let mirrored = mirror.mirror(&pose);
    let (a, b) = (positions(&rig, &pose), positions(&rig, &mirrored));
    let asymmetry = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f64::max);
    let size = model.topology().bounding_diagonal();
    assert!(
        asymmetry < 0.005 * size,
        "the pose is {asymmetry} from its mirror image"
    );
    // And the wrists reached their targets.
    let reached = (a[wrist] - DVec3::new(0.45, 1.3, 0.25)).length();
    assert!(reached < 0.02, "{reached}");
    // An unpaired joint has no mirrored effector.
    let head = Effector {
        joint: rig.skeleton.find("head").unwrap(),
        ..left
    };
    assert!(mirror.mirror_effector(&head, &frame).is_none());
}

/// A shape at rest other than the bind pose (an additive layer's animation): with nothing
/// pulling, a solve leaves that pose as it is (with the bind shape at rest the same solve
/// bends it back towards the bind pose), and an effector on one wrist bends the body from it
/// while the far leg keeps most of the rest pose's bend (2° off it; 10° with the bind shape).
#[test]
fn a_shape_rest_pose_stays_put_and_effectors_bend_from_it() {
    let rig = mannequin_rig(10);
    let model = model_of(&rig);
    let find = |n: &str| rig.skeleton.find(n).unwrap();
    // The "animation": the left elbow and the right knee bent, the chest leaning.
    let mut animated = rig.rest.clone();
    for (joint, angle) in [("elbow_l", 0.9), ("knee_r", -0.7), ("chest", 0.25)] {
        animated.local[find(joint)].rotation = DQuat::from_rotation_x(angle);
    }
    // 30 iterations from the animated pose, with the effectors given and the shape at rest
    // in `shape_rest` (the bind pose when `None`).
    let solve_from_animated = |effectors: Vec<Effector>, shape_rest: Option<SkeletonPose>| {
        let constraints = PoseConstraints {
            effectors,
            shape_rest,
            ..Default::default()
        };
        let options = PoseSolveOptions {
            max_iterations: 30,
            tolerance: 0.0,
            ground_iterations: 0,
        };
        PoseSolver::new(
            model.clone(),
            &constraints,
            &rig.rest,
            PoseSolverSettings::default(),
        )
        .unwrap()
        .solve(&constraints, &options, PoseStart::Pose(&animated), &|| {
            false
        })
        .unwrap()
        .pose
    };
    let free = |shape_rest: Option<SkeletonPose>| solve_from_animated(Vec::new(), shape_rest);
    let kept = largest_turn_deg(&free(Some(animated.clone())), &animated);
    assert!(kept < 1e-4, "the rest pose moved by {kept}°");
    let relaxed = largest_turn_deg(&free(None), &animated);
    assert!(
        relaxed > 5.0,
        "without it the bind shape should pull the bends back ({relaxed}°)"
    );
    // A wrist pulled up: the right knee (nothing pulls on it directly; the whole body still
    // shares the pull, being one shape) keeps most of its bend.
    let wrist = find("wrist_l");
    let knee = find("knee_r");
    let globals = rig.skeleton.global_transforms(&animated);
    let goal = globals[wrist].translation + DVec3::new(0.0, 0.15, 0.1);
    let pulled = |shape_rest: Option<SkeletonPose>| {
        let effector = Effector {
            joint: wrist,
            goal: EffectorGoal::Position(goal),
            weight: 1.0,
        };
        solve_from_animated(vec![effector], shape_rest)
    };
    let pose = pulled(Some(animated.clone()));
    let reached = rig.skeleton.global_transforms(&pose)[wrist]
        .translation
        .distance(goal);
    assert!(reached < 1e-3, "the wrist is {reached} from its goal");
    let knee_bend =
        rotation_angle(pose.local[knee].rotation, animated.local[knee].rotation).to_degrees();
    let knee_bind = rotation_angle(
        pulled(None).local[knee].rotation,
        animated.local[knee].rotation,
    )
    .to_degrees();
    assert!(
        knee_bend < 0.3 * knee_bind && knee_bind > 5.0,
        "the unpulled knee turned {knee_bend}° from its bend (bind shape at rest: {knee_bind}°)"
    );
}

/// An additive layer's next frame: the clip moved a little (the rest shape with it), the solve
/// starts from the new pose seeded by last frame's solution (`PoseStart::Near`): its tilt's
/// cluster rotations are refined from last frame's, not fitted afresh. With nothing pulling the
/// new rest pose stays put (as with a cold start); with a wrist pulled the seeded solve meets
/// the wrist's goal and ends at least as low as the cold one; and the solution carries the rest
/// shape's rotations, equal to a cold fit's.
#[test]
fn a_solve_seeded_by_last_frames_solution_tilts_the_shape_like_a_cold_one() {
    let rig = mannequin_rig(10);
    let model = model_of(&rig);
    let find = |n: &str| rig.skeleton.find(n).unwrap();
    let animated_at = |t: f64| {
        let mut pose = rig.rest.clone();
        for (joint, angle) in [("elbow_l", 0.9), ("knee_r", -0.7), ("chest", 0.25)] {
            pose.local[find(joint)].rotation = DQuat::from_rotation_x(angle * (1.0 + t));
        }
        pose
    };
    let (frame0, frame1) = (animated_at(0.0), animated_at(0.06));
    let wrist = find("wrist_l");
    let goal =
        rig.skeleton.global_transforms(&frame1)[wrist].translation + DVec3::new(0.0, 0.12, 0.08);
    let constraints_of = |rest: &SkeletonPose, pulled: bool| PoseConstraints {
        effectors: pulled
            .then_some(Effector {
                joint: wrist,
                goal: EffectorGoal::Position(goal),
                weight: 1.0,
            })
            .into_iter()
            .collect(),
        shape_rest: Some(rest.clone()),
        ..Default::default()
    };
    let options = PoseSolveOptions {
        max_iterations: 40,
        tolerance: 0.0,
        ground_iterations: 0,
    };
    for pulled in [false, true] {
        let solver = PoseSolver::new(
            model.clone(),
            &constraints_of(&frame0, pulled),
            &rig.rest,
            PoseSolverSettings::default(),
        )
        .unwrap();
        let last = solver
            .solve(
                &constraints_of(&frame0, pulled),
                &options,
                PoseStart::Pose(&frame0),
                &|| false,
            )
            .unwrap();
        assert_eq!(last.shape_rest_rotations.len(), model.cluster_count());
        let next = constraints_of(&frame1, pulled);
        let seeded = solver
            .solve(
                &next,
                &options,
                PoseStart::Near {
                    pose: &frame1,
                    last: &last,
                },
                &|| false,
            )
            .unwrap();
        let cold = solver
            .solve(&next, &options, PoseStart::Pose(&frame1), &|| false)
            .unwrap();
        let rotations_off = seeded
            .shape_rest_rotations
            .iter()
            .zip(&cold.shape_rest_rotations)
            .map(|(a, b)| rotation_angle(*a, *b))
            .fold(0.0, f64::max);
        assert!(
            rotations_off < 1e-9,
            "pulled {pulled}: the seeded tilt's rotations are {rotations_off} rad off a cold fit"
        );
        // Both descend the same objective; seeded by a nearby solution it gets at least as
        // low within the same iterations (the pulled solve is still descending at 40: lower).
        let energy = |sol: &PoseSolution| *sol.stats.energies.last().unwrap();
        assert!(
            energy(&seeded) <= energy(&cold) * (1.0 + 1e-9),
            "pulled {pulled}: seeded {} vs cold {}",
            energy(&seeded),
            energy(&cold)
        );
        if pulled {
            let reached = rig.skeleton.global_transforms(&seeded.pose)[wrist]
                .translation
                .distance(goal);
            assert!(reached < 1e-3, "the wrist is {reached} from its goal");
        }
        if !pulled {
            let moved = largest_turn_deg(&seeded.pose, &frame1);
            assert!(moved < 1e-4, "the new rest pose moved by {moved}°");
        }
    }
}

/// Stiffness weighted by what each joint carries: the hips carry more than the chest, the
/// chest more than the neck, the neck more than the head; and a look-at to the side under it
/// turns the neck and head while the hips keep (nearly) their rest rotation — with every
/// joint weighed alike the hips take a share of the turn like any other ancestor.
#[test]
fn an_inertia_weighted_stiffness_turns_the_light_joints_first() {
    let rig = mannequin_rig(10);
    let model = model_of(&rig);
    let find = |n: &str| rig.skeleton.find(n).unwrap();
    let inertia = model.relative_inertia();
    let chain = ["hips", "chest", "neck", "head"].map(|n| inertia[find(n)]);
    assert!(
        chain.windows(2).all(|w| w[0] > w[1]) && chain[0] > 4.0 * chain[3],
        "hips, chest, neck, head carry {chain:?}"
    );
    let head = find("head");
    let globals = rig.skeleton.global_transforms(&rig.rest);
    let target = globals[head].translation + DVec3::new(0.8, 0.1, 0.4);
    let hips_turn = |stiffness: ReferenceStiffness| {
        let constraints = PoseConstraints {
            effectors: vec![Effector {
                joint: head,
                goal: EffectorGoal::Aim {
                    axis: DVec3::Y,
                    target,
                    up: None,
                },
                weight: 1.0,
            }],
            stiffness: Some(stiffness),
            ..Default::default()
        };
        let pose = solve(&model, &rig, &constraints, 40);
        let now = rig.skeleton.global_transforms(&pose);
        let aim = (now[head].matrix3 * DVec3::Y).angle_between(target - now[head].translation);
        assert!(
            aim.to_degrees() < 1.0,
            "the head aims {}° off",
            aim.to_degrees()
        );
        rotation_angle(pose.local[0].rotation, rig.rest.local[0].rotation).to_degrees()
    };
    let weighted = hips_turn(ReferenceStiffness::by_inertia(rig.rest.clone(), 0.3));
    let alike = hips_turn(ReferenceStiffness::uniform(rig.rest.clone(), 0.3));
    assert!(
        weighted < 0.3 * alike,
        "the hips turn {weighted}° weighted by inertia, {alike}° weighed alike"
    );
}
