//! Balance in the pose core: the centre of mass over the support polygon, solved
//! with the effectors, on the generated humanoid.

use std::sync::Arc;

use bevy_wii_deform::pose::constraints::effectors::joint_positions;
use bevy_wii_deform::pose::rig::synth_rig::{SyntheticRig, mannequin_rig};
use bevy_wii_deform::pose::*;
use glam::DVec3;

use crate::common::{model_of, solve_pose};

const LEFT_WRIST: usize = 6;
const ANKLES: [usize; 2] = [9, 15];
const HIPS: usize = 0;

/// The mannequin's soles: its welded vertices within 2 cm of the lowest, at rest.
fn soles(model: &SkinnedModel) -> Vec<DVec3> {
    let bind = model.bind_positions();
    let lowest = bind.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    bind.iter()
        .copied()
        .filter(|p| p.y < lowest + 0.02)
        .collect()
}

/// The mannequin standing on its soles: its rig and model, the soles and their polygon.
fn stance() -> (SyntheticRig, Arc<SkinnedModel>, Vec<DVec3>, SupportPolygon) {
    let rig = mannequin_rig(30);
    let model = model_of(&rig);
    let support = soles(&model);
    let polygon = SupportPolygon::new(&support, DVec3::NEG_Y);
    (rig, model, support, polygon)
}

fn height(model: &SkinnedModel) -> f64 {
    let bind = model.bind_positions();
    let (lo, hi) = bind
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    hi - lo
}

/// Both feet pinned, the left hand pulled sideways by `reach` of the height (a position
/// effector of weight 1), with or without balance.
fn pull(
    rig: &SyntheticRig,
    model: &SkinnedModel,
    reach: f64,
    balance: Option<Balance>,
) -> PoseConstraints {
    let wrist = joint_positions(&rig.skeleton, &rig.rest)[LEFT_WRIST];
    PoseConstraints {
        fixed_joints: ANKLES.to_vec(),
        effectors: vec![Effector {
            joint: LEFT_WRIST,
            goal: EffectorGoal::Position(wrist + DVec3::X * reach * height(model)),
            weight: 1.0,
        }],
        balance,
        ..Default::default()
    }
}

/// The pose [`pull`] solves to from rest.
fn pulled(
    rig: &SyntheticRig,
    model: &Arc<SkinnedModel>,
    reach: f64,
    balance: Option<Balance>,
) -> SkeletonPose {
    let constraints = pull(rig, model, reach, balance);
    solve_pose(
        model,
        &rig.rest,
        &constraints,
        60,
        PoseStart::Pose(&rig.rest),
    )
    .unwrap()
    .pose
}

/// A humanoid with both feet planted, its hand pulled outward 30 % of its height:
/// with balance the centre of mass stays inside the support polygon and the hips move the other
/// way; without, the same pull puts it outside (so the test can tell them apart).
#[test]
fn a_pulled_hand_is_counterbalanced_by_the_hips() {
    let (rig, model, support, polygon) = stance();
    assert!(polygon.corners().len() >= 3, "two feet make a polygon");
    let margin = 0.01 * height(&model);
    let rest_com = centre_of_mass(&model, &rig.rest, None).unwrap();
    assert!(
        polygon.signed_distance(rest_com) > margin,
        "standing at rest is balanced"
    );

    let free = pulled(&rig, &model, 0.3, None);
    let com = centre_of_mass(&model, &free, None).unwrap();
    let outside = polygon.signed_distance(com);
    assert!(
        outside < 0.0,
        "without balance the pull topples it: {outside}"
    );

    let balance = Balance {
        margin,
        ..Balance::over(support.clone())
    };
    let held = pulled(&rig, &model, 0.3, Some(balance));
    let com = centre_of_mass(&model, &held, None).unwrap();
    let inside = polygon.signed_distance(com);
    assert!(
        inside >= 0.0,
        "with balance the centre of mass stays over the feet: {inside}"
    );
    // The counterbalance: the hips end further from the pull than where the pull alone takes
    // them.
    let hips_free = joint_positions(&rig.skeleton, &free)[HIPS];
    let hips = joint_positions(&rig.skeleton, &held)[HIPS];
    assert!(
        hips.x < hips_free.x - 0.02 * height(&model),
        "the hips move away from the pull: {} (pulled) → {} (balanced)",
        hips_free.x,
        hips.x
    );
    // The hand still goes as far out as balance lets it.
    let wrist_rest = joint_positions(&rig.skeleton, &rig.rest)[LEFT_WRIST];
    let wrist = joint_positions(&rig.skeleton, &held)[LEFT_WRIST];
    assert!(
        wrist.x > wrist_rest.x + 0.05 * height(&model),
        "{} → {}",
        wrist_rest.x,
        wrist.x
    );
    eprintln!(
        "com without balance {outside:.4}, with {inside:.4}; hips x {:.4} → {:.4}; wrist x {:.4}",
        hips_free.x, hips.x, wrist.x
    );
}

/// A walk's two-paw phases: `Balance::lean` lets the centre of mass out of the
/// polygon by as much as asked, and no further. The hand pulled 30 % of the height leaves the
/// centre of mass `d` outside without balance; leaning half of that, balance holds it half-way
/// (out past its margin, so the lean is not ignored, and not as far as the pull alone takes
/// it, so balance still acts).
#[test]
fn a_lean_lets_the_centre_of_mass_out_as_far_as_asked() {
    let (rig, model, support, polygon) = stance();
    let margin = 0.01 * height(&model);
    let free = pulled(&rig, &model, 0.3, None);
    let out = polygon.signed_distance(centre_of_mass(&model, &free, None).unwrap());
    assert!(out < -0.03 * height(&model), "the pull topples it: {out}");
    let allowed = 0.5 * out;
    let leaning = Balance {
        margin,
        lean: margin - allowed,
        ..Balance::over(support.clone())
    };
    assert!((leaning.required_inside() - allowed).abs() < 1e-12);
    let held = pulled(&rig, &model, 0.3, Some(leaning));
    let at = polygon.signed_distance(centre_of_mass(&model, &held, None).unwrap());
    let tolerance = 0.1 * allowed.abs();
    assert!(
        (at - allowed).abs() < tolerance,
        "held at {at:.4}, {allowed:.4} allowed (without balance {out:.4})"
    );
}

/// A penalty gives. A pull strong enough to leave the centre of mass short of its
/// margin after one solve is met over a few warm solves (`PoseSolution::balance_boost`, a
/// multiplier carried from solve to solve); over other support points the boost starts again.
#[test]
fn warm_solves_bring_the_centre_of_mass_to_its_margin() {
    let (rig, model, support, polygon) = stance();
    let h = height(&model);
    let margin = 0.02 * h;
    let constraints = |support: Vec<DVec3>| {
        let balance = Balance {
            margin,
            ..Balance::over(support)
        };
        pull(&rig, &model, 0.6, Some(balance))
    };
    let over_the_feet = constraints(support.clone());
    let inside =
        |s: &PoseSolution| polygon.signed_distance(centre_of_mass(&model, &s.pose, None).unwrap());
    let mut solution = solve_pose(
        &model,
        &rig.rest,
        &over_the_feet,
        30,
        PoseStart::Pose(&rig.rest),
    )
    .unwrap();
    let first = inside(&solution);
    assert!(
        first < margin - 3e-4 * h,
        "one solve falls short of the margin: {first:.4} of {margin:.4}"
    );
    assert!(solution.balance_boost > 0.0);
    // Half a second of frames at 60 Hz.
    for _ in 0..30 {
        solution = solve_pose(
            &model,
            &rig.rest,
            &over_the_feet,
            30,
            PoseStart::Warm(&solution),
        )
        .unwrap();
    }
    let last = inside(&solution);
    assert!(
        (last - margin).abs() < 1e-4 * h,
        "warm solves meet the margin: {first:.4} → {last:.4} of {margin:.4}"
    );
    // A boost carries over to the same support only: a large one pushes the centre of mass
    // further in over the same feet, and is ignored over feet that moved.
    let stale = PoseSolution {
        balance_boost: 0.03 * h,
        ..solution.clone()
    };
    let same = solve_pose(
        &model,
        &rig.rest,
        &over_the_feet,
        30,
        PoseStart::Warm(&stale),
    )
    .unwrap();
    let mut moved = support.clone();
    moved[0].x += 1e-3;
    let other = solve_pose(
        &model,
        &rig.rest,
        &constraints(moved),
        30,
        PoseStart::Warm(&stale),
    )
    .unwrap();
    let (same, other) = (inside(&same), inside(&other));
    assert!(
        same > margin + 0.01 * h && other < margin + 0.005 * h,
        "a boost over the same feet {same:.4}, over others {other:.4} (margin {margin:.4})"
    );
}

/// Bad balance input is a typed error, never a panic or a NaN pose; one support point and
/// points on a line are balanced over that point or segment.
#[test]
fn balance_input_is_checked_and_degenerate_supports_work() {
    let rig = mannequin_rig(24);
    let model = model_of(&rig);
    let solve = |balance: Balance| {
        let constraints = PoseConstraints {
            fixed_joints: vec![ANKLES[0]],
            balance: Some(balance),
            ..Default::default()
        };
        solve_pose(
            &model,
            &rig.rest,
            &constraints,
            30,
            PoseStart::Pose(&rig.rest),
        )
    };
    for bad in [
        Balance::over(vec![]),
        Balance::over(vec![DVec3::new(f64::NAN, 0.0, 0.0)]),
        Balance {
            gravity: DVec3::ZERO,
            ..Balance::over(vec![DVec3::ZERO])
        },
        Balance {
            margin: -1.0,
            ..Balance::over(vec![DVec3::ZERO])
        },
        Balance {
            lean: -0.1,
            ..Balance::over(vec![DVec3::ZERO])
        },
        Balance {
            lean: f64::NAN,
            ..Balance::over(vec![DVec3::ZERO])
        },
        Balance {
            masses: Some(vec![1.0; 3]),
            ..Balance::over(vec![DVec3::ZERO])
        },
    ] {
        assert!(matches!(solve(bad), Err(PoseError::InvalidBalance(_))));
    }
    assert!(matches!(
        solve(Balance {
            weight: 2.0,
            ..Balance::over(vec![DVec3::ZERO])
        }),
        Err(PoseError::InvalidConstraintWeight { .. })
    ));
    // Standing on one foot: the centre of mass goes over it.
    let ankle = joint_positions(&rig.skeleton, &rig.rest)[ANKLES[0]];
    let pose = solve(Balance::over(vec![DVec3::new(ankle.x, 0.0, ankle.z)]))
        .unwrap()
        .pose;
    let com = centre_of_mass(&model, &pose, None).unwrap();
    let rest_com = centre_of_mass(&model, &rig.rest, None).unwrap();
    let off = DVec3::new(com.x - ankle.x, 0.0, com.z - ankle.z).length();
    let rest_off = DVec3::new(rest_com.x - ankle.x, 0.0, rest_com.z - ankle.z).length();
    assert!(
        off < 0.25 * rest_off,
        "over the one foot: {rest_off:.4} → {off:.4}"
    );
    // Supports on a line: over the segment.
    let line: Vec<DVec3> = (0..5)
        .map(|k| DVec3::new(ankle.x, 0.0, ankle.z + 0.02 * k as f64))
        .collect();
    let pose = solve(Balance::over(line)).unwrap().pose;
    assert!(
        pose.local
            .iter()
            .all(|t| t.rotation.is_finite() && t.translation.is_finite())
    );
}
