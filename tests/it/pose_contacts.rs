//! Ground contacts in the pose core: a planted sole on a slope, no sliding while
//! planted and lifting once released, a floor nothing sinks through, bad input.

use std::sync::Arc;

use bevy_wii_deform::deform::centroid;
use bevy_wii_deform::pose::constraints::effectors::joint_positions;
use bevy_wii_deform::pose::rig::synth_rig::{SyntheticRig, mannequin_rig};
use bevy_wii_deform::pose::*;
use glam::{DQuat, DVec3};

use crate::common::{model_of, solve_pose};

const HIPS: usize = 0;
const LEFT_ANKLE: usize = 9;
const RIGHT_ANKLE: usize = 15;

struct Scene {
    rig: SyntheticRig,
    model: Arc<SkinnedModel>,
    /// The model's height.
    size: f64,
    /// The left sole's welded vertices.
    sole: Vec<u32>,
    /// The lowest point of the model at rest.
    lowest: f64,
}

fn scene() -> Scene {
    let rig = mannequin_rig(30);
    let model = model_of(&rig);
    let bind = model.bind_positions();
    let lowest = bind.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let highest = bind.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    let sole = rig.vertices_where(&model, |p| p.y < lowest + 0.02 && p.x > 0.0);
    assert!(sole.len() >= 4, "the left foot has a sole: {}", sole.len());
    Scene {
        rig,
        model,
        size: highest - lowest,
        sole,
        lowest,
    }
}

impl Scene {
    fn solve(
        &self,
        constraints: &PoseConstraints,
        start: PoseStart<'_>,
        iterations: u32,
    ) -> Result<PoseSolution, PoseError> {
        solve_pose(&self.model, &self.rig.rest, constraints, iterations, start)
    }

    /// A solver of `constraints` for the mannequin, from its rest pose.
    fn solver(&self, constraints: &PoseConstraints) -> PoseSolver {
        PoseSolver::new(
            self.model.clone(),
            constraints,
            &self.rig.rest,
            PoseSolverSettings::default(),
        )
        .unwrap()
    }

    fn skinned(&self, pose: &SkeletonPose) -> Vec<DVec3> {
        self.model.skin_welded(pose)
    }

    fn sole_at(&self, pose: &SkeletonPose) -> Vec<DVec3> {
        let skinned = self.skinned(pose);
        self.sole.iter().map(|&v| skinned[v as usize]).collect()
    }

    /// The left sole planted on a 30° slope (rising along +x) through its rest centroid.
    fn planted_on_a_30_degree_slope(&self) -> (GroundPlane, Contact) {
        let rest_sole = self.sole_at(&self.rig.rest);
        let centre = rest_sole.iter().sum::<DVec3>() / rest_sole.len() as f64;
        let normal = DQuat::from_rotation_z(30f64.to_radians()) * DVec3::Y;
        let slope = GroundPlane::new(centre, normal).unwrap();
        let mut contact = Contact::new(LEFT_ANKLE, self.sole.clone(), slope);
        contact.plant(&rest_sole, Some(DVec3::Y));
        (slope, contact)
    }

    /// The hips pulled down 0.1 a frame for 12 frames (20 iterations each, warm), with the
    /// floor `floor` gives for the pose each frame starts from; the last pose.
    fn drag_hips_down(&self, floor: impl Fn(&SkeletonPose) -> Option<Floor>) -> SkeletonPose {
        self.lower_hips(0.1, 12, floor)
    }

    /// The hips pulled down `step` a frame for `frames` frames (20 iterations each, warm),
    /// with the floor `floor` gives for the pose each frame starts from; the last pose.
    fn lower_hips(
        &self,
        step: f64,
        frames: u32,
        floor: impl Fn(&SkeletonPose) -> Option<Floor>,
    ) -> SkeletonPose {
        let hips = joint_positions(&self.rig.skeleton, &self.rig.rest)[HIPS];
        let mut last: Option<PoseSolution> = None;
        for frame in 1..=frames {
            let now = last.as_ref().map_or(&self.rig.rest, |l| &l.pose);
            let constraints = PoseConstraints {
                effectors: vec![Effector {
                    joint: HIPS,
                    goal: EffectorGoal::Position(hips - DVec3::Y * step * f64::from(frame)),
                    weight: 1.0,
                }],
                floor: floor(now),
                ..Default::default()
            };
            let start = match &last {
                Some(l) => PoseStart::Warm(l),
                None => PoseStart::Pose(&self.rig.rest),
            };
            last = Some(self.solve(&constraints, start, 20).unwrap());
        }
        last.unwrap().pose
    }

    fn flat_ground(&self) -> GroundPlane {
        GroundPlane::new(DVec3::Y * self.lowest, DVec3::Y).unwrap()
    }

    /// One plane under the body at its lowest point, with the band `PoseGround` uses (30 % of
    /// the size).
    fn flat_floor(&self) -> Floor {
        Floor::Plane {
            plane: self.flat_ground(),
            band: 0.3 * self.size,
        }
    }

    /// The lowest skinned vertex's height above the flat ground (negative: under it).
    fn lowest_height(&self, pose: &SkeletonPose) -> f64 {
        self.skinned(pose)
            .iter()
            .map(|p| p.y - self.lowest)
            .fold(f64::INFINITY, f64::min)
    }
}

/// The angle (degrees) between the ankle's bind-pose up, carried by the ankle, and `normal`.
fn sole_tilt_deg(s: &Scene, pose: &SkeletonPose, normal: DVec3) -> f64 {
    let g = s.rig.skeleton.global_transforms(pose)[LEFT_ANKLE];
    let up = (g.matrix3 * DVec3::Y).normalize();
    up.angle_between(normal).to_degrees()
}

/// A foot planted on a 30° slope turns its sole to the slope's normal (within 3°),
/// and no vertex of the sole is below the slope by more than 1e-3 of the model's size.
#[test]
fn a_foot_planted_on_a_slope_lies_on_it() {
    let s = scene();
    let (slope, contact) = s.planted_on_a_30_degree_slope();
    let normal = slope.normal;
    let constraints = PoseConstraints {
        fixed_joints: vec![RIGHT_ANKLE],
        contacts: vec![contact],
        ..Default::default()
    };
    let pose = s
        .solve(&constraints, PoseStart::Pose(&s.rig.rest), 40)
        .unwrap()
        .pose;
    let tilt = sole_tilt_deg(&s, &pose, normal);
    assert!(tilt < 3.0, "the sole is {tilt:.2}° off the slope's normal");
    assert!(
        sole_tilt_deg(&s, &s.rig.rest, normal) > 25.0,
        "it had to turn"
    );
    let deepest = s
        .sole_at(&pose)
        .iter()
        .map(|p| slope.height(*p))
        .fold(f64::INFINITY, f64::min);
    assert!(
        deepest > -1e-3 * s.size,
        "a sole vertex is {deepest} below the slope"
    );
}

/// A planted foot under a pull on the hips slides at most 1e-3 of the model's size
/// per frame; an effector lifting the foot does not move it while planted, and lifts it once
/// the contact is released.
#[test]
fn a_planted_foot_holds_under_a_pull_and_lifts_when_released() {
    let s = scene();
    let ground = s.flat_ground();
    let rest_sole = s.sole_at(&s.rig.rest);
    let mut contact = Contact::new(LEFT_ANKLE, s.sole.clone(), ground);
    contact.plant(&rest_sole, Some(DVec3::Y));
    let hips = joint_positions(&s.rig.skeleton, &s.rig.rest)[HIPS];
    let mut last: Option<PoseSolution> = None;
    let mut previous = rest_sole.clone();
    let mut slide_max: f64 = 0.0;
    for frame in 1..=10 {
        let constraints = PoseConstraints {
            fixed_joints: vec![RIGHT_ANKLE],
            effectors: vec![Effector {
                joint: HIPS,
                goal: EffectorGoal::Position(hips + DVec3::new(0.012, -0.01, 0.01) * frame as f64),
                weight: 1.0,
            }],
            contacts: vec![contact.clone()],
            ..Default::default()
        };
        let start = match &last {
            Some(l) => PoseStart::Warm(l),
            None => PoseStart::Pose(&s.rig.rest),
        };
        let solved = s.solve(&constraints, start, 8).unwrap();
        let sole = s.sole_at(&solved.pose);
        let slide = sole
            .iter()
            .zip(&previous)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        slide_max = slide_max.max(slide);
        previous = sole;
        last = Some(solved);
    }
    let moved = joint_positions(&s.rig.skeleton, &last.as_ref().unwrap().pose)[HIPS];
    assert!(moved.distance(hips) > 0.05, "the hips followed the pull");
    assert!(
        slide_max <= 1e-3 * s.size,
        "the planted sole slid {slide_max} in a frame"
    );

    let ankle = joint_positions(&s.rig.skeleton, &s.rig.rest)[LEFT_ANKLE];
    let lift = |planted: bool| {
        let mut c = contact.clone();
        if !planted {
            c.release();
        }
        let constraints = PoseConstraints {
            fixed_joints: vec![RIGHT_ANKLE],
            effectors: vec![Effector {
                joint: LEFT_ANKLE,
                goal: EffectorGoal::Position(ankle + DVec3::Y * 0.1),
                weight: 1.0,
            }],
            contacts: vec![c],
            ..Default::default()
        };
        let pose = s
            .solve(&constraints, PoseStart::Pose(&s.rig.rest), 30)
            .unwrap()
            .pose;
        s.sole_at(&pose)
            .iter()
            .map(|p| ground.height(*p))
            .fold(f64::INFINITY, f64::min)
    };
    let held = lift(true);
    assert!(
        held.abs() < 2e-3 * s.size,
        "planted, the sole stays down: {held}"
    );
    let lifted = lift(false);
    assert!(lifted > 0.05, "released, the foot lifts: {lifted}");
}

/// The body dragged down into the floor (its hips pulled below it, frame after
/// frame): with a floor no skin vertex goes below it by more than 1e-3 of the size; without,
/// the same drag sinks it.
#[test]
fn a_body_dragged_into_the_floor_stops_at_it() {
    let s = scene();
    let floor = s.flat_floor();
    let deepest = |floor: Option<Floor>| s.lowest_height(&s.drag_hips_down(|_| floor.clone()));
    let sunk = deepest(None);
    assert!(
        sunk < -0.1 * s.size,
        "without a floor the drag sinks the body: {sunk}"
    );
    let held = deepest(Some(floor));
    assert!(held > -1e-3 * s.size, "a vertex is {held} below the floor");
}

/// A solve whose iteration budget runs out with the skin through the ground takes
/// up to `ground_iterations` more, until no vertex is more than `THROUGH_THE_GROUND` of the
/// size below it. The body's hips pulled down into a floor 40 % of its height further each
/// frame (the first frame solved to convergence, then one warm iteration a frame): without
/// them the skin ends frames in the floor (the test says so, so it can fail); with them no
/// frame does, and most frames need none.
#[test]
fn a_solve_does_not_stop_with_the_skin_in_the_ground() {
    let s = scene();
    let floor = s.flat_floor();
    let hips = joint_positions(&s.rig.skeleton, &s.rig.rest)[HIPS];
    let pulled = |frame: usize| PoseConstraints {
        effectors: vec![Effector {
            joint: HIPS,
            goal: EffectorGoal::Position(hips - DVec3::Y * 0.4 * s.size * frame as f64),
            weight: 1.0,
        }],
        floor: Some(floor.clone()),
        ..Default::default()
    };
    let solver = s.solver(&pulled(0));
    // Per frame: how deep the deepest vertex is (/ size) and the iterations taken.
    let drag = |ground_iterations| {
        let options = PoseSolveOptions {
            max_iterations: 1,
            tolerance: 0.0,
            ground_iterations,
        };
        let mut last: Option<PoseSolution> = None;
        let mut frames = Vec::new();
        for frame in 1..=12 {
            let start = match &last {
                Some(l) => PoseStart::Warm(l),
                None => PoseStart::Pose(&s.rig.rest),
            };
            // The first frame stands the body on the floor (to convergence).
            let options = match last {
                Some(_) => options,
                None => PoseSolveOptions {
                    max_iterations: 40,
                    ..options
                },
            };
            let solved = solver
                .solve(&pulled(frame), &options, start, &|| false)
                .unwrap();
            let deepest = -s.lowest_height(&solved.pose) / s.size;
            if frame > 1 {
                frames.push((deepest, solved.stats.iterations));
            }
            last = Some(solved);
        }
        frames
    };
    let budget = drag(0);
    let deepest = budget.iter().map(|f| f.0).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        deepest > THROUGH_THE_GROUND,
        "one iteration a frame leaves skin in the floor: {deepest}"
    );
    let settled = drag(20);
    for (frame, &(deepest, iterations)) in settled.iter().enumerate() {
        assert!(
            deepest <= THROUGH_THE_GROUND,
            "frame {frame}: a vertex is {deepest} of the size in the floor \
             ({iterations} iterations)"
        );
    }
    let extra = settled.iter().filter(|f| f.1 > 1).count();
    assert!(
        extra > 0 && extra < settled.len() && settled.iter().all(|f| f.1 <= 21),
        "some frames took more iterations, within the ground's: {settled:?}"
    );
}

/// The ground's penalty alone settles where it balances what pushes the skin in —
/// under the ground; the iterations past the budget raise each such vertex's plane by its
/// depth (the method of multipliers) until none is more than `THROUGH_THE_GROUND` of the size
/// in. A sole held 4 % of the size under the floor (a hold the ground has to overrule):
/// solved to convergence with no iterations past the budget the sole stays in (the test says
/// so, so it can fail); with them — no more iterations in all — it does not.
#[test]
fn a_vertex_the_penalty_leaves_in_the_ground_is_raised_out_of_it() {
    let s = scene();
    let ground = s.flat_ground();
    let sunk: Vec<DVec3> = s
        .sole_at(&s.rig.rest)
        .iter()
        .map(|p| *p - DVec3::Y * 0.04 * s.size)
        .collect();
    let mut contact = Contact::new(LEFT_ANKLE, s.sole.clone(), ground);
    // (Set, not `plant`ed: planting lays the points on the ground.)
    contact.planted = Some(sunk);
    let constraints = PoseConstraints {
        fixed_joints: vec![RIGHT_ANKLE],
        contacts: vec![contact],
        floor: Some(s.flat_floor()),
        ..Default::default()
    };
    let solver = s.solver(&constraints);
    let deepest = |max_iterations, ground_iterations| {
        let options = PoseSolveOptions {
            max_iterations,
            tolerance: 0.0,
            ground_iterations,
        };
        let solved = solver
            .solve(
                &constraints,
                &options,
                PoseStart::Pose(&s.rig.rest),
                &|| false,
            )
            .unwrap();
        -s.lowest_height(&solved.pose) / s.size
    };
    let penalty = deepest(40, 0);
    assert!(
        penalty > THROUGH_THE_GROUND,
        "the penalty alone leaves the skin {penalty} of the size in the floor"
    );
    let raised = deepest(20, 20);
    assert!(
        raised <= THROUGH_THE_GROUND,
        "raised, the skin is still {raised} of the size in the floor"
    );
}

/// A solve whose budget runs out with a planted sole off its held points takes up
/// to `ground_iterations` more, until no sole vertex is farther than `OFF_THE_HOLD` of the
/// size from its held point. Each frame starts where the last ended but with the left hip
/// turned 6° one way or the other (as a walk clip under a pose layer moves a planted leg from
/// frame to frame), then one iteration (the first frame solved to convergence): without them
/// the sole ends frames off its holds (the test says so, so it can fail) — the slide a
/// walking crowd's paws showed; with them no frame does.
#[test]
fn a_solve_does_not_stop_with_a_planted_sole_off_its_holds() {
    const LEFT_HIP: usize = 7;
    let s = scene();
    let rest_sole = s.sole_at(&s.rig.rest);
    let mut contact = Contact::new(LEFT_ANKLE, s.sole.clone(), s.flat_ground());
    contact.plant(&rest_sole, Some(DVec3::Y));
    let constraints = PoseConstraints {
        fixed_joints: vec![RIGHT_ANKLE],
        contacts: vec![contact],
        ..Default::default()
    };
    let solver = s.solver(&constraints);
    // Per frame: the sole vertex farthest from its held point (/ size), the iterations taken.
    let walk = |ground_iterations| {
        let mut last = solver
            .solve(
                &constraints,
                &PoseSolveOptions {
                    max_iterations: 40,
                    ..Default::default()
                },
                PoseStart::Pose(&s.rig.rest),
                &|| false,
            )
            .unwrap();
        let mut frames = Vec::new();
        for frame in 0..8 {
            let mut moved = last.pose.clone();
            let turn = if frame % 2 == 0 { 6f64 } else { -6.0 }.to_radians();
            let hip = &mut moved.local[LEFT_HIP].rotation;
            *hip = DQuat::from_rotation_x(turn) * *hip;
            let options = PoseSolveOptions {
                max_iterations: 1,
                tolerance: 0.0,
                ground_iterations,
            };
            let start = PoseStart::Near {
                pose: &moved,
                last: &last,
            };
            let solved = solver
                .solve(&constraints, &options, start, &|| false)
                .unwrap();
            // Each sole vertex is held the contact skin above where it touched.
            let lift = DVec3::Y * CONTACT_SKIN * s.size;
            let off = s
                .sole_at(&solved.pose)
                .iter()
                .zip(&rest_sole)
                .map(|(a, b)| a.distance(*b + lift))
                .fold(0.0, f64::max)
                / s.size;
            frames.push((off, solved.stats.iterations));
            last = solved;
        }
        frames
    };
    let budget = walk(0);
    assert!(
        budget.iter().all(|f| f.0 > OFF_THE_HOLD),
        "one iteration a frame leaves the sole off its holds: {budget:?}"
    );
    let settled = walk(20);
    for (frame, &(off, iterations)) in settled.iter().enumerate() {
        assert!(
            off <= OFF_THE_HOLD && iterations <= 21,
            "frame {frame}: a sole vertex is {off} of the size off its hold \
             ({iterations} iterations)"
        );
    }
}

/// A floor sampled from the ground under each vertex (`Floor::cast`) holds a body
/// dragged down onto steps — the left foot over a block 5 % of the height up, starting sunk in
/// it — while one plane under the root (the lower level) leaves the left foot in the block.
#[test]
fn a_floor_cast_on_steps_holds_the_foot_over_the_higher_step() {
    let s = scene();
    let rest = s.skinned(&s.rig.rest);
    let rise = 0.05 * s.size;
    // The lower level at the feet, a block rising `rise` under everything at x > 0 (the left
    // foot's side).
    let (w, y0) = (10.0 * s.size, s.lowest);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let steps = TriangleGround::new(
        vec![
            p(-w, y0, -w),
            p(0.0, y0, -w),
            p(0.0, y0, w),
            p(-w, y0, w),
            p(0.0, y0 + rise, -w),
            p(w, y0 + rise, -w),
            p(w, y0 + rise, w),
            p(0.0, y0 + rise, w),
        ],
        vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]],
        DVec3::NEG_Y,
    );
    let left_x = centroid(&rest, &s.sole).x;
    assert!(left_x > 0.02 * s.size, "the left foot is over the block");
    let sampling = FloorSampling::for_size(s.size, 0.3, DVec3::NEG_Y);
    // The rest pose stands on the lower level (the left foot in the block); drag the hips down.
    let deepest = |cast: bool| {
        let pose = s.drag_hips_down(|now| {
            Some(if cast {
                Floor::cast(&s.skinned(now), &steps, &sampling).0
            } else {
                s.flat_floor()
            })
        });
        s.skinned(&pose)
            .iter()
            .filter_map(|p| {
                let hit = steps.cast_down(*p + DVec3::Y * s.size, DVec3::NEG_Y, 3.0 * s.size)?;
                Some(hit.height(*p))
            })
            .fold(f64::INFINITY, f64::min)
    };
    let one_plane = deepest(false);
    assert!(
        one_plane < -0.02 * s.size,
        "one plane under the root lets the foot into the block: {one_plane}"
    );
    let cast = deepest(true);
    assert!(
        cast > -1e-3 * s.size,
        "a vertex is {cast} below the step under it"
    );
}

/// Bad contacts are typed errors; a contact whose ground is far above does not produce NaN.
#[test]
fn bad_contacts_are_typed_errors() {
    let s = scene();
    let ground = s.flat_ground();
    let solve = |contacts: Vec<Contact>, floor: Option<Floor>| {
        let constraints = PoseConstraints {
            contacts,
            floor,
            fixed_joints: vec![RIGHT_ANKLE],
            ..Default::default()
        };
        s.solve(&constraints, PoseStart::Pose(&s.rig.rest), 10)
    };
    let mut nan = Contact::new(LEFT_ANKLE, s.sole.clone(), ground);
    nan.ground.point.x = f64::NAN;
    let mut short = Contact::new(LEFT_ANKLE, s.sole.clone(), ground);
    short.planted = Some(vec![DVec3::ZERO]);
    let mut zero_up = Contact::new(LEFT_ANKLE, s.sole.clone(), ground);
    zero_up.up = Some(DVec3::ZERO);
    zero_up.plant(&s.sole_at(&s.rig.rest), None);
    for bad in [nan, short, zero_up] {
        assert!(matches!(
            solve(vec![bad], None),
            Err(PoseError::InvalidContact(_))
        ));
    }
    let out_of_range = Contact::new(99, s.sole.clone(), ground);
    assert!(matches!(
        solve(vec![out_of_range], None),
        Err(PoseError::JointOutOfRange { .. })
    ));
    let bad_floor = Floor::Plane {
        plane: ground,
        band: -1.0,
    };
    assert!(matches!(
        solve(vec![], Some(bad_floor)),
        Err(PoseError::InvalidContact(_))
    ));
    let mut bad_plane = ground;
    bad_plane.normal = DVec3::new(f64::NAN, 1.0, 0.0);
    assert!(matches!(
        solve(vec![], Some(Floor::Under(vec![(0, bad_plane)]))),
        Err(PoseError::InvalidContact(_))
    ));
    assert!(matches!(
        solve(vec![], Some(Floor::Under(vec![(u32::MAX, ground)]))),
        Err(PoseError::VertexOutOfRange { .. })
    ));
    // A ground above the hips: the body is pushed up out of it as far as the pinned foot
    // lets it, and the pose stays finite.
    let above = GroundPlane::new(DVec3::Y * 1.2, DVec3::Y).unwrap();
    let pose = solve(vec![Contact::new(LEFT_ANKLE, s.sole.clone(), above)], None)
        .unwrap()
        .pose;
    assert!(
        pose.local
            .iter()
            .all(|t| t.rotation.is_finite() && t.translation.is_finite())
    );
}

/// On a slope steeper than the leg's limits let the foot turn, the limits hold, the
/// sole does not go into the slope and touches it with its edge.
#[test]
fn on_a_slope_too_steep_for_the_ankle_the_limit_holds_and_the_edge_touches() {
    let s = scene();
    let (slope, contact) = s.planted_on_a_30_degree_slope();
    let normal = slope.normal;
    let mut limits = JointLimits::new(&s.rig.skeleton, &s.rig.rest);
    limits
        .set(LEFT_ANKLE, JointLimit::cone_deg((8.0, 8.0), (-5.0, 5.0)))
        .unwrap()
        .set(LEFT_ANKLE - 1, JointLimit::hinge_deg(DVec3::X, 0.0, 150.0))
        .unwrap()
        .set(
            LEFT_ANKLE - 2,
            JointLimit::cone_deg((6.0, 6.0), (-5.0, 5.0)),
        )
        .unwrap()
        // The hip too: a free hip rolls the whole leg until the sole lies on the slope.
        .set(
            LEFT_ANKLE - 3,
            JointLimit::cone_deg((6.0, 6.0), (-5.0, 5.0)),
        )
        .unwrap();
    let limits = Arc::new(limits);
    let constraints = PoseConstraints {
        fixed_joints: vec![RIGHT_ANKLE],
        contacts: vec![contact],
        limits: Some(limits.clone()),
        ..Default::default()
    };
    let pose = s
        .solve(&constraints, PoseStart::Pose(&s.rig.rest), 40)
        .unwrap()
        .pose;
    assert!(
        limits.max_violation_deg(&pose) < 0.5,
        "{}",
        limits.max_violation_deg(&pose)
    );
    let tilt = sole_tilt_deg(&s, &pose, normal);
    assert!(
        tilt > 5.0,
        "the limits keep the sole off the slope's normal: {tilt:.1}°"
    );
    let heights: Vec<f64> = s.sole_at(&pose).iter().map(|p| slope.height(*p)).collect();
    let deepest = heights.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        deepest > -1e-3 * s.size,
        "a sole vertex is {deepest} into the slope"
    );
    assert!(
        deepest < 2e-3 * s.size,
        "the sole's edge touches: {deepest}"
    );
    let highest = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!(
        highest > 0.01,
        "the rest of the sole is off the slope: {highest}"
    );
}

/// Automatic contacts from ground casts — the feet found as the lowest joints, the
/// foot that touches its step planted and the one above its lower step left free; solved with
/// balance over the planted sole, the planted sole holds, the free foot stays above its step
/// and the centre of mass goes over the standing foot. A cast that hits nothing frees the
/// contacts; a non-finite hit is ignored.
#[test]
fn tracked_contacts_stand_the_body_on_steps() {
    let s = scene();
    let down = DVec3::NEG_Y;
    let feet = lowest_joints(&s.model, &s.rig.rest, down, 0.03 * s.size);
    let mut sorted = feet.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, vec![LEFT_ANKLE, RIGHT_ANKLE], "the feet: {feet:?}");
    // Left foot on a step at its sole's height, the right one's step lower than a foot is
    // placed down to (the plant height, 8 % of the size).
    let (top, bottom) = (s.lowest, s.lowest - 0.12 * s.size);
    let p = DVec3::new;
    let positions = vec![
        p(-1.0, bottom, -1.0),
        p(0.0, bottom, -1.0),
        p(0.0, bottom, 1.0),
        p(-1.0, bottom, 1.0),
        p(0.0, top, -1.0),
        p(1.0, top, -1.0),
        p(1.0, top, 1.0),
        p(0.0, top, 1.0),
    ];
    let triangles = vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]];
    let ground = TriangleGround::new(positions, triangles, down);
    let mut tracker = ContactTracker::new(&s.model, &s.rig.rest, &feet, down);
    let events = tracker.update(&s.model, &s.rig.rest, &ground);
    let event_of = |joint: usize, events: &[ContactEvent], tracker: &ContactTracker| {
        events[tracker
            .contacts
            .iter()
            .position(|c| c.joint == joint)
            .unwrap()]
    };
    assert_eq!(
        event_of(LEFT_ANKLE, &events, &tracker),
        ContactEvent::Planted
    );
    assert_eq!(
        event_of(RIGHT_ANKLE, &events, &tracker),
        ContactEvent::Unchanged
    );
    assert_eq!(
        tracker.active().len(),
        2,
        "both feet have ground under them"
    );

    let support = tracker.support();
    let polygon = SupportPolygon::new(&support, down);
    let hips = joint_positions(&s.rig.skeleton, &s.rig.rest)[HIPS];
    let constraints = PoseConstraints {
        contacts: tracker.active(),
        balance: Some(Balance {
            margin: 0.005 * s.size,
            ..Balance::over(support.clone())
        }),
        effectors: vec![Effector {
            joint: HIPS,
            goal: EffectorGoal::Position(hips - DVec3::Y * 0.08),
            weight: 0.5,
        }],
        ..Default::default()
    };
    let pose = s
        .solve(&constraints, PoseStart::Pose(&s.rig.rest), 40)
        .unwrap()
        .pose;
    let skinned = s.skinned(&pose);
    let left = tracker
        .contacts
        .iter()
        .find(|c| c.joint == LEFT_ANKLE)
        .unwrap();
    let held = left
        .patch
        .iter()
        .zip(left.planted.as_ref().unwrap())
        .map(|(&v, at)| skinned[v as usize].distance(*at))
        .fold(0.0, f64::max);
    assert!(held < 2e-3 * s.size, "the planted sole moved {held}");
    let right = tracker
        .contacts
        .iter()
        .find(|c| c.joint == RIGHT_ANKLE)
        .unwrap();
    let right_low = right
        .patch
        .iter()
        .map(|&v| skinned[v as usize].y - bottom)
        .fold(f64::INFINITY, f64::min);
    assert!(
        right_low > -1e-3 * s.size,
        "the free foot went {right_low} into its step"
    );
    let com = centre_of_mass(&s.model, &pose, None).unwrap();
    assert!(
        polygon.signed_distance(com) > 0.0,
        "over the standing foot: {}",
        polygon.signed_distance(com)
    );
    assert!(
        polygon.signed_distance(centre_of_mass(&s.model, &s.rig.rest, None).unwrap()) < 0.0,
        "it was not at rest"
    );

    // Nothing under the feet: the contacts are free and left out.
    let nothing = |_: DVec3, _: DVec3, _: f64| -> Option<GroundPlane> { None };
    let events = tracker.update(&s.model, &pose, &nothing);
    assert!(events.iter().all(|e| *e == ContactEvent::NoGround));
    assert!(tracker.active().is_empty() && tracker.support().is_empty());
    // A non-finite hit is ignored: the contact keeps the ground it had.
    tracker.update(&s.model, &s.rig.rest, &ground);
    let before = tracker.contacts.clone();
    let broken = |_: DVec3, _: DVec3, _: f64| {
        Some(GroundPlane {
            point: DVec3::NAN,
            normal: DVec3::Y,
        })
    };
    let events = tracker.update(&s.model, &s.rig.rest, &broken);
    assert!(events.iter().all(|e| *e == ContactEvent::NonFiniteHit));
    assert_eq!(tracker.contacts, before);
}

/// A sole planted where a terrace meets the slope rising from it (its centre on the
/// flat, its toes over the slope) is held out of the ground as one piece: no held point
/// under the ground, one touching, the sole's shape kept; solved, no sole vertex goes under.
/// (Laid on the plane under its centre, the toes were held inside the slope: the floor
/// pushed them out, the hold pulled them in, and a walking crowd's planted paws stood 1–1.6 %
/// of their size in the terrain.)
#[test]
fn a_sole_planted_at_the_foot_of_a_slope_is_held_out_of_it() {
    let s = scene();
    let down = DVec3::NEG_Y;
    let mut tracker = ContactTracker::new(&s.model, &s.rig.rest, &[LEFT_ANKLE], down);
    let patch = tracker.contacts[0].patch.clone();
    let patch_at = |pose: &SkeletonPose| -> Vec<DVec3> {
        let skinned = s.skinned(pose);
        patch.iter().map(|&v| skinned[v as usize]).collect()
    };
    let rest_sole = patch_at(&s.rig.rest);
    let (lo, hi) = rest_sole
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.z), hi.max(p.z))
        });
    assert!(
        hi - lo > 1e-2 * s.size,
        "the sole has a length: {lo} .. {hi}"
    );
    // Flat up to a quarter of the sole's length ahead of its middle, then 45° up along +z.
    let foot_of_slope = 0.5 * (lo + hi) + 0.25 * (hi - lo);
    let (y, rise) = (s.lowest, 2.0 * s.size);
    let p = DVec3::new;
    let positions = vec![
        p(-2.0, y, -2.0),
        p(2.0, y, -2.0),
        p(2.0, y, foot_of_slope),
        p(-2.0, y, foot_of_slope),
        p(2.0, y + rise, foot_of_slope + rise),
        p(-2.0, y + rise, foot_of_slope + rise),
    ];
    let triangles = vec![[0, 2, 1], [0, 3, 2], [3, 4, 2], [3, 5, 4]];
    let ground = TriangleGround::new(positions, triangles, down);
    let height_above = |q: DVec3| {
        let hit = ground
            .cast_down(q + DVec3::Y * s.size, down, 4.0 * s.size)
            .unwrap();
        q.y - hit.point.y
    };
    let events = tracker.update(&s.model, &s.rig.rest, &ground);
    assert_eq!(events, vec![ContactEvent::Planted]);
    let contact = &tracker.contacts[0];
    let held = contact.planted.as_ref().unwrap();
    let heights: Vec<f64> = held.iter().map(|q| height_above(*q)).collect();
    let lowest = heights.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        lowest > -1e-9 * s.size,
        "a held point is {:.2e} of the size inside the slope",
        -lowest / s.size
    );
    assert!(
        lowest < 1e-9 * s.size,
        "the sole rests on the ground: {lowest}"
    );
    // One piece: the held points are the sole as its joint carries it, moved.
    let mut laid = Contact::new(LEFT_ANKLE, contact.patch.clone(), contact.ground);
    laid.plant(&rest_sole, Some(DVec3::Y));
    let offset = held[0] - laid.planted.as_ref().unwrap()[0];
    for (a, b) in held.iter().zip(laid.planted.as_ref().unwrap()) {
        assert!(
            (*a - *b - offset).length() < 1e-9 * s.size,
            "the sole kept its shape"
        );
    }
    assert!(offset.y > 1e-3 * s.size, "it was raised: {offset}");

    // Solved standing on it, with the floor under the skin: no sole vertex under the ground.
    let skinned = s.skinned(&s.rig.rest);
    let sampling = FloorSampling::for_size(s.size, 0.3, down);
    let constraints = PoseConstraints {
        contacts: tracker.active(),
        floor: Some(Floor::cast(&skinned, &ground, &sampling).0),
        ..Default::default()
    };
    let pose = s
        .solve(&constraints, PoseStart::Pose(&s.rig.rest), 20)
        .unwrap()
        .pose;
    let deepest = patch_at(&pose)
        .iter()
        .map(|q| -height_above(*q))
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        deepest < 1e-3 * s.size,
        "a sole vertex is {:.2e} of the size under the ground",
        deepest / s.size
    );
}

/// A foot released and put down again tilted 50° (toe first) rolls flat over the
/// tracker's updates, 20° each, and a solve then stands it flat on the ground (within 3°),
/// no sole vertex under it. (Laid flat at once, its held points were up to 7 % of the size
/// from where the foot was, and the solve snapped it there.)
#[test]
fn a_foot_put_down_tilted_rolls_flat_over_the_updates() {
    let s = scene();
    let down = DVec3::NEG_Y;
    let ground = s.flat_ground();
    let mut tracker = ContactTracker::new(&s.model, &s.rig.rest, &[LEFT_ANKLE], down);
    assert_eq!(
        tracker.update(&s.model, &s.rig.rest, &ground),
        vec![ContactEvent::Planted]
    );
    assert!(
        tracker.contacts[0].rolling.is_none(),
        "the first stance is laid at once"
    );
    // Released, then down again with the ankle turned 50° toes down (about x).
    tracker.contacts[0].release();
    let mut tilted = s.rig.rest.clone();
    let ankle = &mut tilted.local[LEFT_ANKLE];
    ankle.rotation = DQuat::from_rotation_x(50f64.to_radians()) * ankle.rotation;
    assert_eq!(
        tracker.update(&s.model, &tilted, &ground),
        vec![ContactEvent::Planted]
    );
    let turn_left = |t: &ContactTracker| {
        t.contacts[0]
            .rolling
            .map_or(0.0, |r| DQuat::IDENTITY.angle_between(r.left).to_degrees())
    };
    let mut lefts = vec![turn_left(&tracker)];
    while tracker.contacts[0].rolling.is_some() && lefts.len() < 10 {
        tracker.update(&s.model, &tilted, &ground);
        lefts.push(turn_left(&tracker));
    }
    assert!(
        (lefts[0] - 30.0).abs() < 1.0 && (lefts[1] - 10.0).abs() < 1.0 && lefts[2] == 0.0,
        "20° at planting, 20° an update after: {lefts:?}"
    );
    // Landed: held on the ground, touching it, no point under it.
    while tracker.contacts[0].landing > 0.0 {
        tracker.update(&s.model, &tilted, &ground);
    }
    let held = tracker.contacts[0].planted.clone().unwrap();
    let lowest_held = held
        .iter()
        .map(|p| p.y - s.lowest)
        .fold(f64::INFINITY, f64::min);
    assert!(
        lowest_held.abs() < 1e-9 * s.size,
        "the lowest held point is {:.2e} of the size off the ground",
        lowest_held / s.size
    );
    let constraints = PoseConstraints {
        contacts: tracker.active(),
        floor: Some(s.flat_floor()),
        ..Default::default()
    };
    let pose = s
        .solve(&constraints, PoseStart::Pose(&tilted), 30)
        .unwrap()
        .pose;
    let tilt = sole_tilt_deg(&s, &pose, DVec3::Y);
    assert!(tilt < 3.0, "the sole stands {tilt:.1}° off flat");
    assert!(
        s.lowest_height(&pose) > -1e-3 * s.size,
        "a vertex {:.2e} of the size under the ground",
        -s.lowest_height(&pose) / s.size
    );
}

/// A character that walked on leaves its planted patches behind in its own space;
/// past the stride they are released and planted again under it.
#[test]
fn a_patch_left_behind_by_a_walk_is_stepped_and_planted_again() {
    let s = scene();
    let down = DVec3::NEG_Y;
    let feet = lowest_joints(&s.model, &s.rig.rest, down, 0.03 * s.size);
    let mut tracker = ContactTracker::new(&s.model, &s.rig.rest, &feet, down);
    let ground = s.flat_ground();
    let events = tracker.update(&s.model, &s.rig.rest, &ground);
    assert!(
        events.iter().all(|e| *e == ContactEvent::Planted),
        "{events:?}"
    );
    // Half a stride: the planted patches hold.
    let walk = |tracker: &mut ContactTracker, dx: f64| {
        for c in &mut tracker.contacts {
            for p in c.planted.iter_mut().flatten() {
                p.x -= dx;
            }
        }
    };
    let stride = tracker.stride;
    walk(&mut tracker, 0.5 * stride);
    let events = tracker.update(&s.model, &s.rig.rest, &ground);
    assert!(
        events.iter().all(|e| *e == ContactEvent::Unchanged),
        "{events:?}"
    );
    // Past the stride: stepped, then planted again where the body carries them.
    walk(&mut tracker, 0.6 * stride);
    let events = tracker.update(&s.model, &s.rig.rest, &ground);
    assert!(
        events.iter().all(|e| *e == ContactEvent::Stepped),
        "{events:?}"
    );
    let events = tracker.update(&s.model, &s.rig.rest, &ground);
    assert!(
        events.iter().all(|e| *e == ContactEvent::Planted),
        "{events:?}"
    );
    for (c, home) in tracker.contacts.iter().zip(&tracker.home) {
        let planted = c.planted.as_ref().unwrap();
        let centre = planted.iter().sum::<DVec3>() / planted.len() as f64;
        assert!(
            (centre.x - home.x).abs() < 1e-9,
            "planted under the body again"
        );
    }
}

/// The names of the joints [`lowest_joints`] finds within `tolerance` of the size.
fn feet_named(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    down: DVec3,
    tolerance: f64,
) -> Vec<String> {
    let size = model.topology().bounding_diagonal();
    let mut names: Vec<String> = lowest_joints(model, pose, down, tolerance * size)
        .into_iter()
        .map(|j| model.skeleton().joints()[j].name.clone())
        .collect();
    names.sort();
    names
}

/// The joints a character stands on are its feet, not the legs above them. The
/// Fox's hocks (`b_*Foot01`) stand 3–4 % of its size above the paws under them; counted as
/// feet, they were laid on the ground they do not reach and held there against the paws (a
/// hold 3.8 % of the size off, and a support polygon widened by points in the air). A
/// biped's heel and toes (its `Foot` and `ToeBase` joints), both down, stay two feet each.
#[test]
fn the_feet_found_are_paws_and_soles_not_the_hocks_above_them() {
    let humanoid = bevy_wii_deform::pose::rig::synth_rig::humanoid_rig(30);
    let model = model_of(&humanoid);
    let feet = feet_named(&model, &humanoid.rest, DVec3::NEG_Y, 0.04);
    assert_eq!(
        feet,
        ["LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase"],
        "a biped's heels and toes"
    );
    let Some(dir) = crate::common::shared::shared_asset("models") else {
        return;
    };
    let (app, root) = crate::common::fox_app(&dir, bevy_wii_deform::ecs::PosePlugin);
    let posed = app
        .world()
        .get::<bevy_wii_deform::ecs::PosedSkeleton>(root)
        .expect("the Fox is posed");
    let down = (posed.placement.matrix3.inverse() * DVec3::NEG_Y).normalize();
    let paws = [
        "b_LeftFoot02_018",
        "b_LeftHand_011",
        "b_RightFoot02_022",
        "b_RightHand_08",
    ];
    for tolerance in [0.03, 0.04, 0.05] {
        let feet = feet_named(&posed.model, &posed.pose, down, tolerance);
        assert_eq!(feet, paws, "the Fox's feet within {tolerance} of its size");
    }
}

/// A body pulled down to kneel — hips lowered 45 % of its height, both knee joints pulled to
/// 2 % of its height over the floor, so the knees' and shins' skin reaches it, not only the
/// feet — keeps every skin vertex within 1e-3 of the size of the floor (cast under each
/// vertex, solved with the default ground iterations). Without the floor the knees' skin
/// ends well inside it (the test says so, so it can fail), and with it the shins do touch.
#[test]
fn a_kneeling_body_keeps_its_knees_and_shins_out_of_the_floor() {
    const LEFT_KNEE: usize = 8;
    const RIGHT_KNEE: usize = 14;
    let s = scene();
    let ground = s.flat_ground();
    let joints = joint_positions(&s.rig.skeleton, &s.rig.rest);
    let kneel = |with_floor: bool| {
        let solver = s.solver(&PoseConstraints {
            effectors: vec![
                Effector {
                    joint: HIPS,
                    goal: EffectorGoal::Position(joints[HIPS]),
                    weight: 1.0,
                },
                Effector {
                    joint: LEFT_KNEE,
                    goal: EffectorGoal::Position(joints[LEFT_KNEE]),
                    weight: 1.0,
                },
                Effector {
                    joint: RIGHT_KNEE,
                    goal: EffectorGoal::Position(joints[RIGHT_KNEE]),
                    weight: 1.0,
                },
            ],
            floor: Some(s.flat_floor()),
            ..Default::default()
        });
        let sampling = FloorSampling::for_size(s.size, 0.3, DVec3::NEG_Y);
        let mut last: Option<PoseSolution> = None;
        for frame in 1..=12 {
            let t = frame as f64 / 12.0;
            let now = last.as_ref().map_or(&s.rig.rest, |l| &l.pose);
            let knee_goal = |j: usize| {
                let down = joints[j].y - (s.lowest + 0.02 * s.size);
                joints[j] - DVec3::Y * down * t + DVec3::Z * 0.1 * s.size * t
            };
            let constraints = PoseConstraints {
                effectors: vec![
                    Effector {
                        joint: HIPS,
                        goal: EffectorGoal::Position(joints[HIPS] - DVec3::Y * 0.45 * s.size * t),
                        weight: 1.0,
                    },
                    Effector {
                        joint: LEFT_KNEE,
                        goal: EffectorGoal::Position(knee_goal(LEFT_KNEE)),
                        weight: 1.0,
                    },
                    Effector {
                        joint: RIGHT_KNEE,
                        goal: EffectorGoal::Position(knee_goal(RIGHT_KNEE)),
                        weight: 1.0,
                    },
                ],
                floor: with_floor.then(|| Floor::cast(&s.skinned(now), &ground, &sampling).0),
                ..Default::default()
            };
            let start = match &last {
                Some(l) => PoseStart::Warm(l),
                None => PoseStart::Pose(&s.rig.rest),
            };
            let options = PoseSolveOptions {
                max_iterations: 20,
                ..Default::default()
            };
            last = Some(
                solver
                    .solve(&constraints, &options, start, &|| false)
                    .unwrap(),
            );
        }
        s.skinned(&last.unwrap().pose)
    };
    // The shins' and knees' skin: between the ankles and the thighs in the bind pose.
    let bind = s.model.bind_positions();
    let shin = |p: &DVec3| p.y > s.lowest + 0.1 * s.size && p.y < s.lowest + 0.35 * s.size;
    let lowest_of = |skin: &[DVec3], keep: &dyn Fn(usize) -> bool| {
        skin.iter()
            .enumerate()
            .filter(|(v, _)| keep(*v))
            .map(|(_, p)| (p.y - s.lowest) / s.size)
            .fold(f64::INFINITY, f64::min)
    };
    let free = kneel(false);
    let sunk = lowest_of(&free, &|v| shin(&bind[v]));
    assert!(
        sunk < -5e-3,
        "without the floor the knees' skin goes into it: {sunk}"
    );
    let knelt = kneel(true);
    let deepest = lowest_of(&knelt, &|_| true);
    assert!(
        deepest >= -1e-3,
        "a vertex is {deepest} of the size under the floor"
    );
    let shins = lowest_of(&knelt, &|v| shin(&bind[v]));
    assert!(
        shins < 1e-2,
        "the knees and shins reach the floor: their lowest is {shins} of the size over it"
    );
}

/// The mannequin lowered onto a ridge a hundredth of its height wide — far narrower than the
/// floor's grid of casts (6 % of its size), so no cast of the grid lands on it — that runs
/// under its left foot, 0.02 of its height below the sole, with the rest of the ground 0.12
/// below: its hips pulled 0.06 of its height down over 8 frames, the floor cast under the
/// pose each frame starts from. No skin vertex ends more than 1e-3 of the size under the
/// ground, because the mesh ground says how high it rises over each cell of the grid and the
/// vertices near that get a cast of their own. The same ground seen only through its casts
/// (a closure, which cannot say) lets the foot into the ridge (the test says so, so it can
/// fail).
#[test]
fn a_foot_lowered_onto_a_ridge_between_the_floors_casts_stays_on_it() {
    let s = scene();
    let rest = s.skinned(&s.rig.rest);
    let sole_x = s.sole.iter().map(|&v| rest[v as usize].x).sum::<f64>() / s.sole.len() as f64;
    let (half, width) = (2.0 * s.size, 0.01 * s.size);
    let (base, top) = (s.lowest - 0.12 * s.size, s.lowest - 0.02 * s.size);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let (a, b) = (sole_x - width / 2.0, sole_x + width / 2.0);
    let ground = TriangleGround::new(
        vec![
            p(-half, base, -half),
            p(half, base, -half),
            p(half, base, half),
            p(-half, base, half),
            p(a, top, -half),
            p(b, top, -half),
            p(b, top, half),
            p(a, top, half),
        ],
        vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]],
        DVec3::NEG_Y,
    );
    let casts_only = |from: DVec3, down: DVec3, max: f64| ground.cast_down(from, down, max);
    let sampling = FloorSampling::for_size(s.size, 0.3, DVec3::NEG_Y);
    let lower = |seen_by: &dyn Ground| {
        s.lower_hips(0.06 * s.size / 8.0, 8, |now| {
            Some(Floor::cast(&s.skinned(now), seen_by, &sampling).0)
        })
    };
    // The deepest skin vertex under the ground right under it, over the size.
    let deepest = |pose: &SkeletonPose| {
        s.skinned(pose)
            .iter()
            .filter_map(|q| {
                let hit = ground.cast_down(*q + DVec3::Y * s.size, DVec3::NEG_Y, 4.0 * s.size)?;
                Some((q.y - hit.point.y) / s.size)
            })
            .fold(f64::INFINITY, f64::min)
    };
    let unseen = deepest(&lower(&casts_only));
    assert!(
        unseen < -5e-3,
        "seen by its casts alone, the ridge lets the foot in: {unseen}"
    );
    let seen = lower(&ground);
    let deepest_seen = deepest(&seen);
    assert!(
        deepest_seen >= -1e-3,
        "a vertex is {deepest_seen} of the size under the ridge"
    );
    // The foot does stand on the ridge: the sole's lowest vertex is near its top.
    let sole_lowest = s
        .sole_at(&seen)
        .iter()
        .map(|q| (q.y - top) / s.size)
        .fold(f64::INFINITY, f64::min);
    assert!(
        sole_lowest < 0.01,
        "the sole rests on the ridge: {sole_lowest} of the size over it"
    );
}
