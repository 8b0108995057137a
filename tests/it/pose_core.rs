//! The skinning-space pose solver on generated rigs: skinning, recovery of known poses,
//! monotone energy, rigid bones, degenerate skins, pose files and clips.

use bevy_wii_deform::deform::{Handle, RigidTransform};
use bevy_wii_deform::pose::rig::synth_rig::{SyntheticRig, bar_rig, mannequin_rig};
use bevy_wii_deform::pose::*;
use glam::{DAffine3, DQuat, DVec3};

use crate::common;
use common::model_of;

/// The bar rig posed by forward kinematics: joint 1 bent 35° about z, joint 2 25° about x.
fn known_pose(rig: &SyntheticRig) -> SkeletonPose {
    let mut pose = rig.rest.clone();
    pose.local[1].rotation = DQuat::from_rotation_z(35f64.to_radians());
    pose.local[2].rotation = DQuat::from_rotation_x(25f64.to_radians());
    pose
}

fn motion_of(m: &DAffine3) -> RigidTransform {
    RigidTransform::new(DQuat::from_mat3(&m.matrix3), m.translation, DVec3::ZERO)
}

/// Constraints for the bar: bottom fixed, the rigid middles of bones 1 and 2 as handles.
fn bar_constraints(rig: &SyntheticRig, model: &SkinnedModel) -> PoseConstraints {
    PoseConstraints {
        fixed_vertices: rig.vertices_where(model, |p| p.y < 0.2),
        handles: vec![
            Handle {
                vertices: rig.vertices_where(model, |p| p.y > 0.43 && p.y < 0.57),
                transform: RigidTransform::IDENTITY,
            },
            Handle {
                vertices: rig.vertices_where(model, |p| p.y > 0.8),
                transform: RigidTransform::IDENTITY,
            },
        ],
        ..Default::default()
    }
}

/// The bar rig's model and a solver for its two handles ([`bar_constraints`], at rest).
fn bar_solver(rig: &SyntheticRig) -> (std::sync::Arc<SkinnedModel>, PoseSolver, PoseConstraints) {
    let model = model_of(rig);
    let constraints = bar_constraints(rig, &model);
    let solver = PoseSolver::new(
        model.clone(),
        &constraints,
        &rig.rest,
        PoseSolverSettings::default(),
    )
    .unwrap();
    (model, solver, constraints)
}

/// Moves the bar's two handles to where `pose` carries their joints.
fn reach(constraints: &mut PoseConstraints, rig: &SyntheticRig, pose: &SkeletonPose) {
    let m = rig.skeleton.skinning_matrices(pose);
    constraints.handles[0].transform = motion_of(&m[1]);
    constraints.handles[1].transform = motion_of(&m[2]);
}

fn angle_deg(a: DQuat, b: DQuat) -> f64 {
    a.angle_between(b).to_degrees()
}

#[test]
fn rest_pose_skins_to_the_bind_positions() {
    let rig = bar_rig(3, 12, 30);
    let model = model_of(&rig);
    let skinned = model.skin_render(&rig.rest);
    for (p, q) in skinned.iter().zip(&rig.mesh.positions) {
        assert!(p.distance(q.as_dvec3()) < 1e-12, "{p} vs {q}");
    }
}

#[test]
fn two_bone_skinning_matches_a_hand_computation() {
    // Joint 0 at the origin, joint 1 at (0, 1, 0); bind pose = identity orientations.
    let joints = vec![
        Joint {
            name: "a".into(),
            parent: None,
            parent_frame: DAffine3::IDENTITY,
            inverse_bind: DAffine3::IDENTITY,
        },
        Joint {
            name: "b".into(),
            parent: Some(0),
            parent_frame: DAffine3::IDENTITY,
            inverse_bind: DAffine3::from_translation(-DVec3::Y),
        },
    ];
    let skeleton = Skeleton::new(joints).unwrap();
    let mut pose = SkeletonPose {
        local: vec![
            JointTransform::IDENTITY,
            JointTransform {
                translation: DVec3::Y,
                ..JointTransform::IDENTITY
            },
        ],
    };
    // Bend joint b by 90° about z: a point at (0, 2, 0) bound to b goes to (−1, 1, 0).
    pose.local[1].rotation = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
    let m = skeleton.skinning_matrices(&pose);
    let points = [
        DVec3::new(0.0, 2.0, 0.0),
        DVec3::new(0.5, 1.0, 0.0),
        DVec3::new(0.0, 0.5, 0.0),
    ];
    let influences: Vec<VertexInfluences> = vec![
        [(1, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
        [(0, 0.5), (1, 0.5), (0, 0.0), (0, 0.0)],
        [(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
    ];
    let out = skin_positions(&m, &points, &influences);
    // By hand: b maps (x, y) ↦ (0, 1) + Rz90 (x, y − 1) = (1 − y, 1 + x)… with Rz90 (u, v) = (−v, u).
    let by_b = |p: DVec3| DVec3::new(-(p.y - 1.0), 1.0 + p.x, p.z);
    let expected = [
        by_b(points[0]),
        0.5 * points[1] + 0.5 * by_b(points[1]),
        points[2],
    ];
    for (o, e) in out.iter().zip(expected) {
        assert!(o.distance(e) < 1e-12, "{o} vs {e}");
    }
    assert!(out[0].distance(DVec3::new(-1.0, 1.0, 0.0)) < 1e-12);
}

#[test]
fn a_forward_kinematics_pose_is_recovered_from_its_handle_targets() {
    let rig = bar_rig(3, 16, 60);
    let (model, solver, mut constraints) = bar_solver(&rig);
    let truth = known_pose(&rig);
    reach(&mut constraints, &rig, &truth);
    let options = PoseSolveOptions {
        max_iterations: 60,
        tolerance: 1e-12,
        ground_iterations: 0,
    };
    let solved = solver
        .solve(&constraints, &options, PoseStart::Pose(&rig.rest), &|| {
            false
        })
        .unwrap();
    for j in 0..3 {
        let err = angle_deg(solved.pose.local[j].rotation, truth.local[j].rotation);
        assert!(
            err < 1.0,
            "joint {j} is {err:.3}° off ({} iterations)",
            solved.stats.iterations
        );
    }
    let (e_solved, e_truth) = (
        model.full_arap_energy(&solved.pose),
        model.full_arap_energy(&truth),
    );
    assert!(
        (e_solved - e_truth).abs() <= 0.05 * e_truth + 1e-9,
        "energy {e_solved} vs the true pose's {e_truth}"
    );
    // The energy never rises (up to the roundoff of the reduced objective, ~1e-12 of the
    // starting energy).
    let e = &solved.stats.energies;
    let slack = 1e-11 * solved.stats.initial_energy;
    assert!(e.windows(2).all(|w| w[1] <= w[0] + slack), "{e:?}");
    assert!(e[0] <= solved.stats.initial_energy + slack);
    assert!(
        e.last().unwrap() < &(0.01 * solved.stats.initial_energy),
        "{e:?}"
    );
}

#[test]
fn bones_keep_their_lengths_and_the_pose_stays_finite() {
    let rig = bar_rig(4, 12, 40);
    let model = model_of(&rig);
    let mut constraints = PoseConstraints {
        fixed_vertices: rig.vertices_where(&model, |p| p.y < 0.1),
        handles: vec![Handle {
            vertices: rig.vertices_where(&model, |p| p.y > 0.9),
            transform: RigidTransform::IDENTITY,
        }],
        ..Default::default()
    };
    let solver = PoseSolver::new(
        model.clone(),
        &constraints,
        &rig.rest,
        PoseSolverSettings::default(),
    )
    .unwrap();
    // An unreachable target (pulls the bar 50 % longer): the skeleton cannot stretch.
    constraints.handles[0].transform.translation = DVec3::new(0.4, 0.5, 0.0);
    let solved = solver
        .solve(
            &constraints,
            &PoseSolveOptions::default(),
            PoseStart::Pose(&rig.rest),
            &|| false,
        )
        .unwrap();
    assert!(max_bone_length_error(&rig.skeleton, &rig.rest, &solved.pose) < 1e-12);
    let skinned = model.skin_render(&solved.pose);
    assert!(skinned.iter().all(|p| p.is_finite()));
    // The top moved toward the target, sideways.
    let top = rig.skeleton.global_transforms(&solved.pose)[3].translation;
    assert!(top.x > 0.1, "top joint at {top}");
    // NaN targets are rejected with a typed error.
    constraints.handles[0].transform.translation = DVec3::NAN;
    let err = solver.solve(
        &constraints,
        &PoseSolveOptions::default(),
        PoseStart::Pose(&solved.pose),
        &|| false,
    );
    assert_eq!(err, Err(PoseError::NonFiniteTarget));
}

#[test]
fn pinned_joints_stay_and_a_joint_handle_reaches_its_target() {
    let rig = bar_rig(3, 12, 40);
    let model = model_of(&rig);
    let mut constraints = PoseConstraints {
        fixed_joints: vec![0],
        joint_handles: vec![JointHandle {
            joint: 2,
            transform: RigidTransform::IDENTITY,
        }],
        ..Default::default()
    };
    let solver = PoseSolver::new(
        model.clone(),
        &constraints,
        &rig.rest,
        PoseSolverSettings::default(),
    )
    .unwrap();
    let rest_globals = rig.skeleton.global_transforms(&rig.rest);
    // Move joint 2 (at y = 2/3) to where a 30° bend of joint 1 puts it.
    let truth = {
        let mut p = rig.rest.clone();
        p.local[1].rotation = DQuat::from_rotation_z(30f64.to_radians());
        p
    };
    let target = rig.skeleton.global_transforms(&truth)[2];
    constraints.joint_handles[0].transform = RigidTransform::new(
        DQuat::from_mat3(&target.matrix3),
        target.translation - rest_globals[2].translation,
        rest_globals[2].translation,
    );
    let options = PoseSolveOptions {
        max_iterations: 40,
        tolerance: 1e-12,
        ground_iterations: 0,
    };
    let solved = solver
        .solve(&constraints, &options, PoseStart::Pose(&rig.rest), &|| {
            false
        })
        .unwrap();
    let g = rig.skeleton.global_transforms(&solved.pose);
    assert!(
        g[0].translation.distance(rest_globals[0].translation) < 1e-3,
        "pinned root moved to {}",
        g[0].translation
    );
    assert!(angle_deg(DQuat::from_mat3(&g[0].matrix3), DQuat::IDENTITY) < 0.5);
    assert!(
        g[2].translation.distance(target.translation) < 1e-2,
        "{} vs {}",
        g[2].translation,
        target.translation
    );
    assert!(angle_deg(solved.pose.local[1].rotation, truth.local[1].rotation) < 1.0);
}

#[test]
fn a_warm_start_continues_where_the_last_solve_stopped() {
    let rig = bar_rig(3, 12, 40);
    let (_, solver, mut constraints) = bar_solver(&rig);
    reach(&mut constraints, &rig, &known_pose(&rig));
    let three = PoseSolveOptions {
        max_iterations: 3,
        tolerance: 0.0,
        ground_iterations: 0,
    };
    let first = solver
        .solve(&constraints, &three, PoseStart::Pose(&rig.rest), &|| false)
        .unwrap();
    let second = solver
        .solve(&constraints, &three, PoseStart::Warm(&first), &|| false)
        .unwrap();
    assert!(second.stats.energies[0] <= *first.stats.energies.last().unwrap() * (1.0 + 1e-12));
    assert!(second.stats.energies.last().unwrap() < first.stats.energies.last().unwrap());
    // Cancellation stops before the first iteration and says so.
    let cancelled = solver
        .solve(&constraints, &three, PoseStart::Warm(&first), &|| true)
        .unwrap();
    assert!(cancelled.stats.cancelled && cancelled.stats.iterations == 0);
    assert_eq!(cancelled.pose, first.pose);
}

/// A warm start does not inherit the damping the last solve ended with. A solve
/// whose steps were rejected again and again (a foot planting, the floor's kinks) ends with a
/// large damping; carried into the next frame's solve, it throttled every step (a walking
/// crowd's 3-iteration solves moved about 1 % of the Gauss–Newton step). Here the targets move
/// after such a solve: the next 3 iterations get as far as from a solve that ended calmly.
#[test]
fn a_warm_start_does_not_inherit_a_stalled_damping() {
    let rig = bar_rig(3, 12, 40);
    let (_, solver, mut constraints) = bar_solver(&rig);
    let three = PoseSolveOptions {
        max_iterations: 3,
        tolerance: 0.0,
        ground_iterations: 0,
    };
    let calm = solver
        .solve(&constraints, &three, PoseStart::Pose(&rig.rest), &|| false)
        .unwrap();
    let mut stalled = calm.clone();
    stalled.damping = 1e6;
    reach(&mut constraints, &rig, &known_pose(&rig));
    let after = |last: &PoseSolution| {
        let solved = solver
            .solve(&constraints, &three, PoseStart::Warm(last), &|| false)
            .unwrap();
        (
            solved.stats.energies[0],
            *solved.stats.energies.last().unwrap(),
        )
    };
    let (start, from_calm) = after(&calm);
    let (_, from_stalled) = after(&stalled);
    assert!(
        from_calm < 0.5 * start,
        "the targets moved: {start} → {from_calm}"
    );
    assert!(
        from_stalled <= from_calm * 1.01,
        "after a stalled solve: {from_stalled}, after a calm one: {from_calm}"
    );
}

#[test]
fn degenerate_skins_get_typed_errors_or_the_documented_normalisation() {
    let rig = bar_rig(2, 8, 10);
    let build = |mesh: &SkinnedMesh| {
        SkinnedModel::new(
            rig.skeleton.clone(),
            mesh,
            &rig.rest,
            ModelSettings::default(),
        )
    };
    let mut zero = rig.mesh.clone();
    zero.joint_weights[5] = [0.0; 4];
    assert!(matches!(
        build(&zero),
        Err(PoseError::UnweightedVertex { vertex: 5 })
    ));
    let mut nan = rig.mesh.clone();
    nan.joint_weights[3][0] = f32::NAN;
    assert!(matches!(
        build(&nan),
        Err(PoseError::InvalidWeight { vertex: 3 })
    ));
    let mut out_of_range = rig.mesh.clone();
    out_of_range.joint_indices[7] = [9, 0, 0, 0];
    out_of_range.joint_weights[7] = [1.0, 0.0, 0.0, 0.0];
    assert!(matches!(
        build(&out_of_range),
        Err(PoseError::JointIndexOutOfRange {
            vertex: 7,
            joint: 9,
            ..
        })
    ));
    let mut short = rig.mesh.clone();
    short.joint_weights.pop();
    assert!(matches!(
        build(&short),
        Err(PoseError::AttributeLength { .. })
    ));
    // An out-of-range joint with weight 0 is ignored; weights summing to 3 are normalised.
    let mut scaled = rig.mesh.clone();
    for (w, j) in scaled
        .joint_weights
        .iter_mut()
        .zip(&mut scaled.joint_indices)
    {
        for (k, x) in w.iter_mut().enumerate() {
            if *x == 0.0 {
                j[k] = 500;
            }
            *x *= 3.0;
        }
    }
    let model = build(&scaled).unwrap();
    let mut pose = rig.rest.clone();
    pose.local[1].rotation = DQuat::from_rotation_x(0.7);
    let reference = model_of(&rig).skin_render(&pose);
    for (a, b) in model.skin_render(&pose).iter().zip(&reference) {
        assert!(a.distance(*b) < 1e-6);
    }
    // A NaN pose is refused before it reaches the solver.
    let mut bad = rig.rest.clone();
    bad.local[0].translation.x = f64::NAN;
    assert!(matches!(
        SkinnedModel::new(
            rig.skeleton.clone(),
            &rig.mesh,
            &bad,
            ModelSettings::default()
        ),
        Err(PoseError::NonFiniteJoint { joint: 0 })
    ));
}

#[test]
fn seams_are_welded_like_the_static_solver() {
    // Split every vertex of the bar per face: the welded model has the bar's vertex count.
    let rig = bar_rig(2, 8, 10);
    let mut split = SkinnedMesh::default();
    for &i in &rig.mesh.indices {
        split.positions.push(rig.mesh.positions[i as usize]);
        split.joint_indices.push(rig.mesh.joint_indices[i as usize]);
        split.joint_weights.push(rig.mesh.joint_weights[i as usize]);
        split.indices.push(split.indices.len() as u32);
    }
    let model = SkinnedModel::new(
        rig.skeleton.clone(),
        &split,
        &rig.rest,
        ModelSettings::default(),
    )
    .unwrap();
    assert_eq!(model.topology().vertex_count(), rig.mesh.positions.len());
}

/// Drags `hand` of `rig` by `lift` with the joints `feet` pinned (40 iterations from the bind
/// pose); returns the solution and where the hand went and was asked to go.
fn drag_joint(
    rig: &SyntheticRig,
    model: std::sync::Arc<SkinnedModel>,
    hand: usize,
    feet: Vec<usize>,
    lift: DVec3,
    iterations: u32,
) -> (PoseSolution, DVec3, DVec3) {
    let mut constraints = PoseConstraints {
        fixed_joints: feet,
        joint_handles: vec![JointHandle {
            joint: hand,
            transform: RigidTransform::IDENTITY,
        }],
        ..Default::default()
    };
    let solver = PoseSolver::new(
        model,
        &constraints,
        &rig.rest,
        PoseSolverSettings::default(),
    )
    .unwrap();
    constraints.joint_handles[0].transform.translation = lift;
    let options = PoseSolveOptions {
        max_iterations: iterations,
        tolerance: 1e-9,
        ground_iterations: 0,
    };
    let solved = solver
        .solve(&constraints, &options, PoseStart::Pose(&rig.rest), &|| {
            false
        })
        .unwrap();
    let before = rig.skeleton.global_transforms(&rig.rest)[hand].translation;
    let after = rig.skeleton.global_transforms(&solved.pose)[hand].translation;
    (solved, after, before + lift)
}

#[test]
fn the_mannequin_rig_clusters_and_solves() {
    let rig = mannequin_rig(40);
    let model = model_of(&rig);
    assert!(
        model.cluster_count() > 50 && model.cluster_count() <= 100,
        "{}",
        model.cluster_count()
    );
    let hand = rig.skeleton.find("wrist_l").unwrap();
    let feet = vec![
        rig.skeleton.find("ankle_l").unwrap(),
        rig.skeleton.find("ankle_r").unwrap(),
    ];
    let (solved, after, wanted) =
        drag_joint(&rig, model, hand, feet, DVec3::new(0.1, 0.4, 0.1), 30);
    assert!(
        after.distance(wanted) < 0.02,
        "hand at {after}, wanted {wanted}"
    );
    assert!(max_bone_length_error(&rig.skeleton, &rig.rest, &solved.pose) < 1e-9);
}

#[test]
fn a_pose_file_round_trips_through_ron() {
    let rig = bar_rig(3, 8, 12);
    let pose = known_pose(&rig);
    let text = PoseFile::from_pose(&rig.skeleton, &pose).to_ron().unwrap();
    assert!(text.contains("bone1"));
    let back = PoseFile::from_ron(&text)
        .unwrap()
        .apply(&rig.skeleton, &rig.rest)
        .unwrap();
    for (a, b) in back.local.iter().zip(&pose.local) {
        assert!(a.translation.distance(b.translation) < 1e-12);
        assert!((a.rotation - b.rotation).length() < 1e-12);
    }
    assert!(matches!(
        PoseFile::from_ron("not ron ("),
        Err(PoseFileError::Parse(_))
    ));
    let stranger =
        PoseFile::from_ron("(joints: {\"nobody\": (translation: (0,0,0), rotation: (0,0,0,1))})")
            .unwrap();
    assert_eq!(
        stranger.apply(&rig.skeleton, &rig.rest),
        Err(PoseFileError::NoMatchingJoint)
    );
}

#[test]
fn a_one_keyframe_clip_holds_the_pose_by_node_path() {
    let rig = bar_rig(3, 8, 12);
    let pose = known_pose(&rig);
    let tracks: Vec<(Vec<String>, JointTransform)> = (0..3)
        .map(|j| {
            let path: Vec<String> = std::iter::once("character".to_string())
                .chain((0..=j).map(|k| format!("bone{k}")))
                .collect();
            (path, pose.local[j])
        })
        .collect();
    let glb = write_gltf_pose_clip("pose", &tracks).unwrap();
    let (document, buffers, _) = gltf::import_slice(&glb).unwrap();
    let animation = document.animations().next().expect("one clip");
    assert_eq!(animation.name(), Some("pose"));
    let mut seen = 0;
    for channel in animation.channels() {
        let node = channel.target().node();
        let reader = channel.reader(|b| Some(&buffers[b.index()]));
        let j: usize = node
            .name()
            .unwrap()
            .trim_start_matches("bone")
            .parse()
            .unwrap();
        if let Some(gltf::animation::util::ReadOutputs::Rotations(r)) = reader.read_outputs() {
            let q = r.into_f32().next().unwrap();
            let q = DQuat::from_array(q.map(|v| v as f64)).normalize();
            assert!(
                angle_deg(q, pose.local[j].rotation) < 1e-3,
                "joint {j}: {q} vs {}",
                pose.local[j].rotation
            );
            seen += 1;
        }
    }
    assert_eq!(seen, 3);
    // The node path: character / bone0 / bone1 / bone2.
    let scene = document.default_scene().unwrap();
    let top = scene.nodes().next().unwrap();
    assert_eq!(top.name(), Some("character"));
    let b2 = top
        .children()
        .next()
        .unwrap()
        .children()
        .next()
        .unwrap()
        .children()
        .next()
        .unwrap();
    assert_eq!(b2.name(), Some("bone2"));
    assert_eq!(
        write_gltf_pose_clip("x", &[(vec![], JointTransform::IDENTITY)]),
        Err(PoseFileError::EmptyPath)
    );
}

/// A humanoid of game-character joint count (52 joints, Mixamo names, five three-bone fingers
/// per hand): the model builds, the mirror pairs every Left/Right joint by name, the humanoid
/// preset recognises its limbs, and a hand drag with the feet pinned keeps every bone rigid and
/// reaches the target.
#[test]
fn a_52_joint_humanoid_poses_with_rigid_bones_and_pairs_by_name() {
    use bevy_wii_deform::pose::rig::synth_rig::humanoid_rig;
    let rig = humanoid_rig(24);
    let joints = rig.skeleton.len();
    assert!((50..=70).contains(&joints), "{joints} joints");
    let mirror = Mirror::new(&rig.skeleton, &rig.rest);
    assert_eq!(
        mirror.pair_count(),
        (joints - 6) / 2,
        "every Left joint has its Right"
    );
    let twice = mirror.mirror(&mirror.mirror(&rig.rest));
    for (a, b) in twice.local.iter().zip(&rig.rest.local) {
        assert!(a.translation.distance(b.translation) < 1e-9);
    }
    let (_, found) = JointLimits::humanoid(&rig.skeleton, &rig.rest);
    for name in ["LeftForeArm", "RightLeg", "Neck", "LeftFoot"] {
        assert!(
            found.iter().any(|(n, _)| n == name),
            "{name} not recognised among {found:?}"
        );
    }
    let model = model_of(&rig);
    let hand = rig.skeleton.find("RightHand").unwrap();
    let feet = vec![
        rig.skeleton.find("LeftFoot").unwrap(),
        rig.skeleton.find("RightFoot").unwrap(),
    ];
    let (solved, after, wanted) =
        drag_joint(&rig, model, hand, feet, DVec3::new(-0.1, 0.35, 0.1), 40);
    assert!(
        after.distance(wanted) < 0.02,
        "hand at {after}, wanted {wanted}"
    );
    assert!(max_bone_length_error(&rig.skeleton, &rig.rest, &solved.pose) < 1e-9);
}

/// A model's sums over its mesh come out the same bit for bit however many threads build it
/// (they were added in whatever order rayon's threads finished, and a balance held at the
/// edge of its polygon flipped between runs on the last bits): the same drag on a model built
/// on one thread and on three gives the same pose exactly.
#[test]
fn a_model_built_on_any_number_of_threads_solves_the_same() {
    let rig = mannequin_rig(40);
    let built_on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        std::sync::Arc::new(pool.install(|| rig.model()).unwrap())
    };
    let (one, three) = (built_on(1), built_on(3));
    assert!(
        one.bind_positions().len() > 4096,
        "several chunks of vertices"
    );
    let hand = rig.skeleton.find("wrist_l").unwrap();
    let feet = vec![
        rig.skeleton.find("ankle_l").unwrap(),
        rig.skeleton.find("ankle_r").unwrap(),
    ];
    let lift = DVec3::new(0.1, 0.4, 0.1);
    let (a, ..) = drag_joint(&rig, one, hand, feet.clone(), lift, 5);
    let (b, ..) = drag_joint(&rig, three, hand, feet, lift, 5);
    assert_eq!(a.pose, b.pose);
    assert_eq!(a.stats.energies, b.stats.energies);
}
