//! Effectors, limits, stiffness and symmetric editing through the pose plugin: goals read
//! from entities (and followed as they move), limits from files (bad ones fail by name).

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;

use bevy_wii_deform::pose::rig::synth_rig::{bar_rig, mannequin_rig};
use bevy_wii_deform::prelude::*;

use crate::common;
use common::{posed_rig, settle_pose, update_until};

fn app() -> App {
    let mut app = common::app();
    app.add_plugins(PosePlugin);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        16,
    )));
    app
}

fn joint_position(app: &App, joint: Entity) -> Vec3 {
    app.world()
        .get::<GlobalTransform>(joint)
        .unwrap()
        .translation()
}

#[test]
fn a_position_effector_entity_moves_its_joint_and_is_followed() {
    let mut app = app();
    let rig = bar_rig(3, 12, 30);
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        (
            Poseable {
                max_iterations: 8,
                // Settle until an iteration gains less than 1e-8: the goal is met, not nearly.
                tolerance: 1e-8,
                ..default()
            },
            PinnedJoints(vec![joints[0]]),
        )
    });
    // A moving platform carries the effector (its child): the goal follows the platform.
    let platform = app
        .world_mut()
        .spawn(Transform::from_xyz(0.1, 0.0, 0.0))
        .id();
    app.world_mut().spawn((
        PoseEffector::position(root, joints[2]),
        Transform::from_xyz(0.05, 0.6, 0.1),
        ChildOf(platform),
    ));
    settle_pose(&mut app, root);
    // (Joint 2 swings on a radius of 1/3 about joint 1 at y = 1/3: these goals are on reach.)
    let target = Vec3::new(0.15, 0.6, 0.1);
    let error = joint_position(&app, joints[2]).distance(target);
    assert!(error < 1e-3, "joint 2 is {error} from its goal");
    // The platform moves: the joint follows without anything else changing.
    app.world_mut()
        .get_mut::<Transform>(platform)
        .unwrap()
        .translation = Vec3::new(-0.1, 0.0, 0.0);
    settle_pose(&mut app, root);
    let target = Vec3::new(-0.05, 0.6, 0.1);
    let error = joint_position(&app, joints[2]).distance(target);
    assert!(error < 1e-3, "joint 2 is {error} from the moved goal");
}

#[test]
fn a_look_at_effector_points_the_top_bone_at_its_entity() {
    let mut app = app();
    let rig = bar_rig(3, 12, 30);
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        (
            Poseable {
                max_iterations: 8,
                ..default()
            },
            PinnedJoints(vec![joints[0], joints[1]]),
        )
    });
    let target = Vec3::new(0.6, 1.2, 0.4);
    app.world_mut().spawn((
        PoseEffector::look_at(root, joints[2], Vec3::Y),
        Transform::from_translation(target),
    ));
    settle_pose(&mut app, root);
    let g = app.world().get::<GlobalTransform>(joints[2]).unwrap();
    let axis = g.affine().matrix3 * Vec3A::Y;
    let to = Vec3A::from(target - g.translation());
    let error = axis.angle_between(to).to_degrees();
    assert!(error < 1.0, "the top bone points {error}° off");
}

#[test]
fn limits_from_a_file_naming_a_missing_joint_fail_with_its_name() {
    let mut app = app();
    let rig = bar_rig(3, 12, 30);
    let file =
        r#"(joints: { "elbow": Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 90.0) })"#;
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        (
            Poseable::default(),
            PinnedJoints(vec![joints[0]]),
            PoseLimits::Ron(file.into()),
        )
    });
    app.world_mut().spawn((
        PoseEffector::position(root, joints[2]),
        Transform::from_xyz(0.3, 0.5, 0.0),
    ));
    update_until(&mut app, "the failure", |a| {
        a.world().get::<PoseStatus>(root).unwrap().error.is_some()
    });
    let error = app.world().get::<PoseStatus>(root).unwrap().error.clone();
    let message = error.as_ref().unwrap().to_string();
    assert!(message.contains("elbow"), "{message}");
    assert!(matches!(error, Some(PoseableError::Limits(_))), "{error:?}");
}

#[test]
fn a_hinge_limit_holds_under_an_effector_pulling_behind() {
    let mut app = app();
    let rig = bar_rig(3, 12, 30);
    let file =
        r#"(joints: { "bone1": Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 150.0) })"#;
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        (
            Poseable {
                max_iterations: 8,
                ..default()
            },
            PinnedJoints(vec![joints[0]]),
            PoseLimits::Ron(file.into()),
        )
    });
    app.world_mut().spawn((
        PoseEffector::position(root, joints[2]),
        Transform::from_xyz(0.0, 0.55, -0.15),
    ));
    settle_pose(&mut app, root);
    let r = app.world().get::<Transform>(joints[1]).unwrap().rotation;
    let r = if r.w < 0.0 { -r } else { r };
    let angle = (2.0 * r.x.atan2(r.w)).to_degrees();
    assert!(angle > -0.5, "the elbow bent backwards to {angle}°");
}

#[test]
fn symmetric_editing_drives_the_mirror_joint_too() {
    let mut app = app();
    let rig = mannequin_rig(10);
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        let find = |n: &str| joints[rig.skeleton.find(n).unwrap()];
        let pins = vec![find("hips"), find("ankle_l"), find("ankle_r")];
        (
            Poseable {
                max_iterations: 8,
                ..default()
            },
            PinnedJoints(pins),
            SymmetricEditing,
            PoseStiffness(0.05),
        )
    });
    let find = |n: &str| joints[rig.skeleton.find(n).unwrap()];
    let goal = Vec3::new(0.45, 1.3, 0.25);
    app.world_mut().spawn((
        PoseEffector {
            kind: PoseEffectorKind::Position,
            ..PoseEffector::position(root, find("wrist_l"))
        },
        Transform::from_translation(goal),
    ));
    settle_pose(&mut app, root);
    let left = joint_position(&app, find("wrist_l"));
    let right = joint_position(&app, find("wrist_r"));
    assert!(left.distance(goal) < 0.02, "left wrist at {left}");
    let mirrored_goal = Vec3::new(-goal.x, goal.y, goal.z);
    assert!(
        right.distance(mirrored_goal) < 0.02,
        "right wrist at {right}, mirror goal {mirrored_goal}"
    );
}

/// The largest distance between a joint's position and its partner's mirrored across x = 0
/// (the mannequin's symmetry plane).
fn mirror_asymmetry(
    app: &App,
    rig: &bevy_wii_deform::pose::rig::synth_rig::SyntheticRig,
    joints: &[Entity],
) -> f32 {
    let partners = bevy_wii_deform::pose::mirror_partners(&rig.skeleton);
    partners
        .iter()
        .enumerate()
        .map(|(j, &p)| {
            let a = joint_position(app, joints[j]);
            let b = joint_position(app, joints[p]);
            a.distance(Vec3::new(-b.x, b.y, b.z))
        })
        .fold(0.0, f32::max)
}

/// Symmetric editing mirrors a grab: the vertices around the left wrist dragged out, up and
/// forward give a mirror-symmetric pose (every joint where its partner's mirror image is,
/// within 2 % of the size: the mesh's own asymmetry; measured 0.7 %) with the right wrist on
/// the mirrored drag; without the switch the same grab leaves the pose lopsided (15 %).
#[test]
fn a_symmetric_grab_gives_a_mirror_symmetric_pose() {
    // Meshed on 24 cells the mannequin is symmetric to ~4 % of its size (marching tetrahedra
    // split the grid's cubes one way): mirrored vertex sets are the nearest vertices.
    let rig = mannequin_rig(24);
    let mut lopsided = 0.0;
    for symmetric in [true, false] {
        let mut app = app();
        let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
            let find = |n: &str| joints[rig.skeleton.find(n).unwrap()];
            (
                Poseable {
                    max_iterations: 8,
                    ..default()
                },
                PinnedJoints(vec![find("hips"), find("ankle_l"), find("ankle_r")]),
                PoseStiffness(0.05),
            )
        });
        if symmetric {
            app.world_mut().entity_mut(root).insert(SymmetricEditing);
        }
        let find = |n: &str| joints[rig.skeleton.find(n).unwrap()];
        let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
        let size = posed.model.topology().bounding_diagonal() as f32;
        assert!(
            mirror_asymmetry(&app, &rig, &joints) < 1e-4 * size,
            "a symmetric rest"
        );
        let wrist = joint_position(&app, find("wrist_l"));
        let drawn = posed.skinned_positions();
        let mut grabbed: Vec<u32> = (0..drawn.len() as u32).collect();
        grabbed.sort_by(|a, b| {
            let d = |i: &u32| drawn[*i as usize].distance(wrist);
            d(a).total_cmp(&d(b))
        });
        grabbed.truncate(12);
        assert!(
            grabbed.iter().all(|&i| drawn[i as usize].x > 0.1),
            "the left hand's"
        );
        let (handle, pivot) = common::spawn_handle(&mut app, root, grabbed, ());
        let drag = Vec3::new(0.15, 0.2, 0.1);
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .translation = pivot + drag;
        common::drive_solves(&mut app, root, handle, 10);
        settle_pose(&mut app, root);
        let asymmetry = mirror_asymmetry(&app, &rig, &joints);
        let right = joint_position(&app, find("wrist_r"));
        let right_rest = Vec3::new(-wrist.x, wrist.y, wrist.z);
        if symmetric {
            assert!(
                asymmetry < 0.02 * size,
                "joints {asymmetry} off their partners' mirror images (size {size})"
            );
            let moved = right - right_rest;
            let mirrored_drag = Vec3::new(-drag.x, drag.y, drag.z);
            assert!(
                moved.distance(mirrored_drag) < 0.25 * drag.length(),
                "the right wrist moved {moved} for the mirrored drag {mirrored_drag}"
            );
        } else {
            lopsided = asymmetry / size;
            assert!(right.distance(right_rest) < 0.5 * drag.length());
        }
    }
    assert!(
        lopsided > 0.02,
        "without the switch the pose is lopsided ({lopsided})"
    );
}

/// What the character's held pose was at the end of `Update` (before `PostUpdate`).
#[derive(Resource, Default)]
struct PoseAtEndOfUpdate(Option<bevy_wii_deform::pose::SkeletonPose>);

/// In-frame mode: a joint handle moved in `Update` is solved in that frame's `PostUpdate`
/// (after animation, before propagation): at the end of `Update` the held pose has not
/// changed (no background solve landed), and when the frame ends the joint is at its target
/// — one `app.update()` after the move, with manual time.
#[test]
fn an_in_frame_solve_is_on_the_joints_in_the_frame_its_target_moved() {
    let rig = bar_rig(3, 12, 30);
    let mut app = app();
    app.init_resource::<PoseAtEndOfUpdate>().add_systems(
        Update,
        (|characters: Query<&PosedSkeleton>, mut seen: ResMut<PoseAtEndOfUpdate>| {
            seen.0 = characters.iter().next().map(|p| p.pose.clone());
        })
        .after(PoseSystems::Timeline),
    );
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        (
            Poseable {
                tolerance: 0.0,
                ..default()
            },
            PinnedJoints(vec![joints[0]]),
            PoseInFrame { iterations: 8 },
        )
    });
    let tip = joints[2];
    let at = joint_position(&app, tip);
    let handle = app
        .world_mut()
        .spawn((
            PoseJointHandle::new(root, tip),
            Transform::from_translation(at),
        ))
        .id();
    // Let the handle be placed and the set start (the first frames rebase it).
    settle_pose(&mut app, root);
    let before = joint_position(&app, tip);
    let held = app.world().get::<PosedSkeleton>(root).unwrap().pose.clone();
    let goal = before + Vec3::new(0.08, -0.02, 0.05);
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation = goal;
    app.update();
    let in_update = app.world().resource::<PoseAtEndOfUpdate>().0.clone();
    assert_eq!(in_update.as_ref(), Some(&held), "a solve landed in Update");
    let after = joint_position(&app, tip);
    let share = (after - before).dot((goal - before).normalize()) / (goal - before).length();
    assert!(
        share > 0.9,
        "the joint went {:.0} % of the way in the frame",
        share * 100.0
    );
}

/// Moves the carrier of an effector in `PostUpdate`, before the pose is solved: as an
/// animation (or any late system) moves the thing a target is attached to.
#[derive(Resource)]
struct Carrier(Entity, Vec3);

/// Moves `carrier` by `step` every frame in `PostUpdate`, before `PoseSystems::Apply`.
fn move_in_post_update(app: &mut App, carrier: Entity, step: Vec3) {
    app.insert_resource(Carrier(carrier, step));
    app.add_systems(
        PostUpdate,
        (|carrier: Res<Carrier>, mut transforms: Query<&mut Transform>| {
            if let Ok(mut t) = transforms.get_mut(carrier.0) {
                t.translation += carrier.1;
            }
        })
        .before(PoseSystems::Apply),
    );
}

/// In-frame mode reads effector targets after animation: an effector parented to a carrier
/// that a `PostUpdate` system moves (before `PoseSystems::Apply`, like the animation does) is
/// met in that same frame — its joint ends the frame where the carrier is now, not where it
/// was when `Update` ran (which is a whole step behind).
#[test]
fn an_in_frame_effector_follows_a_target_moved_after_update() {
    let rig = bar_rig(3, 12, 30);
    let mut app = app();
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        (
            Poseable::default(),
            PinnedJoints(vec![joints[0]]),
            PoseInFrame { iterations: 8 },
        )
    });
    let tip = joints[2];
    let at = joint_position(&app, tip);
    let carrier = app.world_mut().spawn(Transform::from_translation(at)).id();
    let effector = app
        .world_mut()
        .spawn((PoseEffector::position(root, tip), Transform::default()))
        .id();
    app.world_mut().entity_mut(carrier).add_child(effector);
    // Let the effector's set start and the pose settle on the target where it is.
    for _ in 0..30 {
        app.update();
    }
    let step = Vec3::new(0.015, -0.004, 0.01);
    move_in_post_update(&mut app, carrier, step);
    for frame in 0..5 {
        app.update();
        let goal = joint_position(&app, carrier); // (any entity's world position)
        let tip_at = joint_position(&app, tip);
        // A frame late the joint would be a whole step (0.019) short.
        assert!(
            tip_at.distance(goal) < 0.2 * step.length(),
            "frame {frame}: the joint is {} from the target moved this frame",
            tip_at.distance(goal)
        );
    }
}

/// With symmetric editing in-frame, the mirrored effector follows a target moved after
/// `Update` in the same frame too: the right wrist ends each frame nearer the mirror of where
/// the left wrist's target is now than of where it was a step before.
#[test]
fn an_in_frame_mirrored_effector_follows_in_the_same_frame() {
    let rig = mannequin_rig(10);
    let mut app = app();
    let (root, joints) = posed_rig(&mut app, &rig, |joints: &[Entity]| {
        let find = |n: &str| joints[rig.skeleton.find(n).unwrap()];
        (
            Poseable::default(),
            PinnedJoints(vec![find("hips"), find("ankle_l"), find("ankle_r")]),
            SymmetricEditing,
            PoseStiffness(0.05),
            PoseInFrame { iterations: 8 },
        )
    });
    let find = |n: &str| joints[rig.skeleton.find(n).unwrap()];
    let start = Vec3::new(0.45, 1.3, 0.25);
    let carrier = app
        .world_mut()
        .spawn(Transform::from_translation(start))
        .id();
    let effector = app
        .world_mut()
        .spawn((
            PoseEffector::position(root, find("wrist_l")),
            Transform::default(),
        ))
        .id();
    app.world_mut().entity_mut(carrier).add_child(effector);
    for _ in 0..40 {
        app.update();
    }
    let step = Vec3::new(0.0, 0.0, -0.03);
    move_in_post_update(&mut app, carrier, step);
    let mirror = |p: Vec3| Vec3::new(-p.x, p.y, p.z);
    for frame in 0..4 {
        app.update();
        let goal = joint_position(&app, carrier); // (any entity's world position)
        let right = joint_position(&app, find("wrist_r"));
        let now = right.distance(mirror(goal));
        let before = right.distance(mirror(goal - step));
        assert!(
            now < before && now < 0.5 * step.length(),
            "frame {frame}: the right wrist is {now} from the mirrored target now, {before} from where it was"
        );
    }
}
