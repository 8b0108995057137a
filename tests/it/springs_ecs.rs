//! `SpringPlugin` headless: a rigged bar's chain lags when the character moves, settles back,
//! stays at the animated pose when disabled, and reports a rig that does not fit.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_wii_deform::ecs::{SpringBones, SpringPlugin, SpringStatus};
use bevy_wii_deform::pose::rig::synth_rig;
use bevy_wii_deform::pose::{SpringChain, SpringJoint, SpringRig};
use bevy_wii_deform::prelude::*;

use crate::common::{spawn_rig, update_until};

/// A five-joint bar standing on a character root, its joints a spring chain, at 60 fps.
fn springy_bar(enabled: bool) -> (App, Entity, Vec<Entity>) {
    let mut app = crate::common::app();
    app.add_plugins((PosePlugin, SpringPlugin)).insert_resource(
        TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)),
    );
    let rig = synth_rig::bar_rig(5, 8, 10);
    let (root, joints, _) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    let mut bones = SpringBones::by_names(
        &["bone"],
        SpringJoint {
            stiffness: 2.0,
            drag: 0.3,
            ..SpringJoint::new(0)
        },
    );
    bones.enabled = enabled;
    app.world_mut()
        .entity_mut(root)
        .insert((Poseable::default(), bones));
    update_until(&mut app, "the springs", |a| {
        a.world()
            .get::<SpringStatus>(root)
            .is_some_and(|s| s.chains == 1)
    });
    (app, root, joints)
}

/// The tip joint's offset from where the bar's rest puts it, in the root's frame.
fn tip_offset(app: &mut App, root: Entity, tip: Entity) -> Vec3 {
    let root_t = *app.world().get::<GlobalTransform>(root).unwrap();
    let tip_t = *app.world().get::<GlobalTransform>(tip).unwrap();
    root_t
        .affine()
        .inverse()
        .transform_point3(tip_t.translation())
        - Vec3::new(0.0, 0.8, 0.0)
}

/// Moves the character 0.02 along +X a frame for 30 frames; the tip's offset after each.
fn walk_sideways(app: &mut App, root: Entity, tip: Entity) -> Vec<Vec3> {
    (0..30)
        .map(|_| {
            app.world_mut()
                .get_mut::<Transform>(root)
                .unwrap()
                .translation
                .x += 0.02;
            app.update();
            tip_offset(app, root, tip)
        })
        .collect()
}

#[test]
fn a_moving_character_swings_its_spring_chain_and_it_settles() {
    let (mut app, root, joints) = springy_bar(true);
    let status = app.world().get::<SpringStatus>(root).unwrap().clone();
    assert_eq!((status.chains, status.joints), (1, 5), "{status:?}");
    // Move the character sideways at 1.2 units/s for half a second.
    let lag = walk_sideways(&mut app, root, joints[4])
        .iter()
        .map(|o| o.x.abs())
        .fold(0.0, f32::max);
    assert!(lag > 0.05, "the tip lags behind the motion: {lag}");
    for _ in 0..240 {
        app.update();
    }
    let rest = tip_offset(&mut app, root, joints[4]).length();
    assert!(
        rest < 1e-3,
        "four seconds after it stopped, the chain is back: {rest}"
    );
}

#[test]
fn disabled_springs_leave_the_pose_as_it_is() {
    let (mut app, root, joints) = springy_bar(false);
    for off in walk_sideways(&mut app, root, joints[4]) {
        assert!(
            off.length() < 1e-5,
            "no spring: the tip stays on the bar ({off})"
        );
    }
}

#[test]
fn a_rig_that_does_not_fit_the_skeleton_is_reported() {
    let mut app = crate::common::app();
    app.add_plugins((PosePlugin, SpringPlugin));
    let rig = synth_rig::bar_rig(3, 8, 10);
    let (root, _, _) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    let springs = SpringRig {
        chains: vec![SpringChain {
            name: "nowhere".into(),
            joints: vec![SpringJoint::new(0), SpringJoint::new(9)],
            collider_groups: vec![],
            center: None,
        }],
        ..Default::default()
    };
    app.world_mut()
        .entity_mut(root)
        .insert((Poseable::default(), SpringBones::rig(springs)));
    update_until(&mut app, "the report", |a| {
        a.world()
            .get::<SpringStatus>(root)
            .is_some_and(|s| s.error.is_some())
    });
    let status = app.world().get::<SpringStatus>(root).unwrap();
    assert!(
        status.error.as_ref().unwrap().contains("joint 9"),
        "{status:?}"
    );
    assert_eq!(status.chains, 0);
}
