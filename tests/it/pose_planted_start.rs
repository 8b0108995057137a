//! A planted limb's start ([`ContactTracker::carry_planted_limbs`]): where the last solve left
//! it, re-aimed at its holds as the character moved since; nothing else of the start changed.

use bevy_wii_deform::pose::rig::synth_rig::mannequin_rig;
use bevy_wii_deform::pose::*;
use glam::{DQuat, DVec3};

use crate::common::model_of;

const CHEST: usize = 1;
const LEFT_HIP: usize = 7;
const LEFT_KNEE: usize = 8;
const LEFT_ANKLE: usize = 9;
const RIGHT_HIP: usize = 13;

/// The global rotation of every joint of `pose`.
fn global_rotations(skeleton: &Skeleton, pose: &SkeletonPose) -> Vec<DQuat> {
    skeleton
        .global_transforms(pose)
        .iter()
        .map(|g| DQuat::from_mat3(&g.matrix3).normalize())
        .collect()
}

fn turned(pose: &SkeletonPose, turns: &[(usize, DQuat)]) -> SkeletonPose {
    let mut out = pose.clone();
    for &(j, q) in turns {
        out.local[j].rotation = (q * out.local[j].rotation).normalize();
    }
    out
}

/// The mannequin's left sole planted where the last solve (its rest pose with the knee bent a
/// little) put it; the character walked on 2 % of its height since (the holds moved back in
/// its space) and this frame's clip swung the stance leg forward and bent the chest: the
/// carried start holds the chest's turn as given, the leg as last solved but re-aimed, its
/// sole within a fifth of the distance of either the given start's or the merely copied
/// leg's from the holds, its tilt as last solved.
#[test]
fn a_planted_limb_starts_where_the_last_solve_left_it_re_aimed_at_its_holds() {
    let rig = mannequin_rig(30);
    let model = model_of(&rig);
    let skeleton = model.skeleton();
    let height = {
        let ys = model.bind_positions().iter().map(|p| p.y);
        ys.clone().fold(f64::NEG_INFINITY, f64::max) - ys.fold(f64::INFINITY, f64::min)
    };
    let last = turned(
        &rig.rest,
        &[
            (LEFT_HIP, DQuat::from_rotation_x(-0.1)),
            (LEFT_KNEE, DQuat::from_rotation_x(0.2)),
        ],
    );
    let mut tracker = ContactTracker::new(&model, &last, &[LEFT_ANKLE], DVec3::NEG_Y);
    let patch = tracker.contacts[0].patch.clone();
    let at = |pose: &SkeletonPose| model.skinned_centroid(pose, &patch);
    let sole = model.skin_vertices(&last, &patch);
    tracker.contacts[0].plant(&sole, Some(DVec3::Y));
    let walked = DVec3::new(0.0, 0.0, -0.02 * height);
    for held in tracker.contacts[0].planted.iter_mut().flatten() {
        *held += walked;
    }
    let holds = at(&last) + walked;
    let given = turned(
        &rig.rest,
        &[
            (LEFT_HIP, DQuat::from_rotation_x(-0.25)),
            (CHEST, DQuat::from_rotation_x(0.15)),
            (RIGHT_HIP, DQuat::from_rotation_x(0.2)),
        ],
    );
    let mut copied = given.clone();
    for j in [LEFT_HIP, LEFT_KNEE, LEFT_ANKLE] {
        copied.local[j].rotation = last.local[j].rotation;
    }

    let mut start = given.clone();
    assert_eq!(tracker.carry_planted_limbs(&model, &last, &mut start), 1);

    for j in (0..skeleton.len()).filter(|j| ![LEFT_HIP, LEFT_KNEE, LEFT_ANKLE].contains(j)) {
        assert_eq!(
            start.local[j], given.local[j],
            "joint {j} is not the limb's"
        );
    }
    assert_eq!(
        start.local[LEFT_KNEE], last.local[LEFT_KNEE],
        "the knee as solved"
    );
    let off = |pose: &SkeletonPose| at(pose).distance(holds) / height;
    let (given_off, copied_off, carried_off) = (off(&given), off(&copied), off(&start));
    assert!(
        given_off > 0.02 && copied_off > 0.015,
        "neither the clip's leg nor the last one is on the holds: {given_off} {copied_off}"
    );
    assert!(
        carried_off < 0.2 * copied_off && carried_off < 0.2 * given_off,
        "re-aimed at the holds: {carried_off} (given {given_off}, copied {copied_off})"
    );
    let tilt = global_rotations(skeleton, &start)[LEFT_ANKLE]
        .angle_between(global_rotations(skeleton, &copied)[LEFT_ANKLE]);
    assert!(tilt < 1e-9, "the sole keeps its tilt: {tilt} rad");
    let hip_turn = start.local[LEFT_HIP]
        .rotation
        .angle_between(last.local[LEFT_HIP].rotation);
    assert!(hip_turn > 1e-3, "the hip re-aimed: {hip_turn} rad");
}

/// Nothing planted, a `last` of another skeleton or not finite, a patch of another model: the
/// start is left as given.
#[test]
fn a_start_with_nothing_to_carry_is_left_as_given() {
    let rig = mannequin_rig(30);
    let model = model_of(&rig);
    let mut tracker = ContactTracker::new(&model, &rig.rest, &[LEFT_ANKLE], DVec3::NEG_Y);
    let given = turned(&rig.rest, &[(LEFT_HIP, DQuat::from_rotation_x(-0.25))]);
    let last = turned(&rig.rest, &[(LEFT_KNEE, DQuat::from_rotation_x(0.3))]);

    let mut start = given.clone();
    assert_eq!(tracker.carry_planted_limbs(&model, &last, &mut start), 0);
    assert_eq!(start, given, "nothing planted");

    let patch = tracker.contacts[0].patch.clone();
    tracker.contacts[0].plant(&model.skin_vertices(&last, &patch), Some(DVec3::Y));
    let mut short = last.clone();
    short.local.pop();
    let mut broken = last.clone();
    broken.local[LEFT_KNEE].rotation = DQuat::from_xyzw(f64::NAN, 0.0, 0.0, 1.0);
    for bad in [&short, &broken] {
        let mut start = given.clone();
        assert_eq!(tracker.carry_planted_limbs(&model, bad, &mut start), 0);
        assert_eq!(start, given, "a last pose that does not fit");
    }
    let mut start = given.clone();
    assert_eq!(tracker.carry_planted_limbs(&model, &last, &mut start), 1);
    assert!(start.local.iter().all(|t| t.is_valid()));

    let mut foreign = tracker.clone();
    foreign.contacts[0].patch = vec![u32::MAX; patch.len()];
    let mut start = given.clone();
    assert_eq!(foreign.carry_planted_limbs(&model, &last, &mut start), 0);
    assert_eq!(start, given, "a patch that is not the model's");
}
