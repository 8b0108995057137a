//! A character plays a clip made for another skeleton: `Retarget` bakes it in the background
//! into an `AnimationClip` on the character's own joints, which Bevy's `AnimationPlayer`
//! plays; a source that cannot be read or mapped fails with a typed error in the status.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use bevy::prelude::*;
use bevy_wii_deform::pose::retarget::{
    RetargetError, RetargetSettings, Retargeter, SkeletonMap, SourceError, read_source_motion,
};
use bevy_wii_deform::pose::{GltfCharacter, ModelSettings};
use bevy_wii_deform::prelude::*;

use crate::common;

fn project(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// Updates until the character's retarget has landed or failed (bounded by `update_until`).
fn bake(app: &mut App, root: Entity, retarget: Retarget) -> RetargetStatus {
    // A fresh status: a second retarget on the same character is not taken for the first.
    app.world_mut()
        .entity_mut(root)
        .insert((retarget, RetargetStatus::default()));
    common::update_until(app, "the retarget", |a| {
        a.world()
            .get::<RetargetStatus>(root)
            .is_some_and(|s| matches!(s.phase, RetargetPhase::Ready | RetargetPhase::Failed))
    });
    app.world().get::<RetargetStatus>(root).unwrap().clone()
}

/// The Fox's Walk retargeted onto the Fox (by the chain map the repository ships) through
/// the plugin, played by the Fox's own `AnimationPlayer`: at every time the joints hold the
/// pose the core bakes for the same source, map and rest — the clip is keyed to the right
/// joints, at the right times.
#[test]
fn a_retargeted_clip_plays_through_the_animation_player() {
    let dir = project("assets/models");
    let (mut app, root) = common::fox_app(&dir, (PosePlugin, RetargetPlugin));
    let source = dir.join("Fox.glb");
    let map = project("assets/retarget/fox.ron");
    let status = bake(
        &mut app,
        root,
        Retarget::new(&source).animation("Walk").map(&map),
    );
    assert_eq!(status.error, None);
    assert_eq!(status.phase, RetargetPhase::Ready);
    assert_eq!(status.frames, 18, "a key per source key");
    // The map's four paws are reported.
    assert_eq!(status.planted_share.len(), 4, "{:?}", status.planted_share);
    // Each foot names the character's joint entity, as the shares do.
    let posed_joints = app
        .world()
        .get::<PosedSkeleton>(root)
        .unwrap()
        .joints
        .clone();
    assert_eq!(status.feet.len(), 4);
    for (foot, (name, _)) in status.feet.iter().zip(&status.planted_share) {
        assert_eq!(&foot.name, name);
        assert!(posed_joints.contains(&foot.joint), "{foot:?}");
    }
    let clip = status.clip.expect("a ready retarget has a clip");

    // The same bake by the core.
    let fox = GltfCharacter::read(&source).unwrap();
    let model = Arc::new(fox.model(ModelSettings::default()).unwrap());
    let motion = read_source_motion(&source, Some("Walk")).unwrap();
    let from = (&motion.skeleton, &motion.rest);
    let map = SkeletonMap::from_ron(
        &std::fs::read_to_string(&map).unwrap(),
        from,
        (&fox.skeleton, &fox.rest),
    )
    .unwrap();
    let retargeter =
        Retargeter::new(from, model, &fox.rest, map, RetargetSettings::default()).unwrap();
    let baked = retargeter
        .bake(&motion.clip, &retargeter.rest_ground())
        .unwrap();
    // The Walk is made in place: its paws are planted while they move back with the ground,
    // and each foot's spans say so at every key, as the core's contacts do.
    assert!(baked.source_contacts.treadmill.length() > 0.0);
    for (foot, planted) in status.feet.iter().zip(&baked.source_contacts.planted) {
        assert!(!foot.planted.is_empty(), "{foot:?}");
        for (key, &planted) in motion.clip.keys().iter().zip(planted) {
            assert_eq!(
                foot.planted_at(key.time),
                planted,
                "{foot:?} at {}",
                key.time
            );
        }
    }
    let expected = baked.clip;

    let joints = app
        .world()
        .get::<PosedSkeleton>(root)
        .unwrap()
        .joints
        .clone();
    // The pose plugin holds its pose on the joints after animation unless told not to.
    app.world_mut().get_mut::<Poseable>(root).unwrap().hold_pose = false;
    let player = common::animation_player(&mut app);
    let node = common::play_clip(&mut app, player, clip);
    let mut worst = 0.0f32;
    let mut moved = 0.0f32;
    let first = expected.sample(0.0).unwrap();
    for i in 0..=8 {
        let t = expected.duration() * i as f32 / 8.0;
        common::show_clip_at(&mut app, player, node, t);
        let want = expected.sample(t).unwrap();
        for (j, &joint) in joints.iter().enumerate() {
            let shown = app.world().get::<Transform>(joint).unwrap().rotation;
            let wanted = want.local[j].rotation.as_quat();
            worst = worst.max(common::angle_between(shown, wanted));
            moved = moved.max(common::angle_between(
                wanted,
                first.local[j].rotation.as_quat(),
            ));
        }
    }
    assert!(
        worst < 2e-3,
        "the played clip is {worst} rad off the baked one"
    );
    assert!(moved > 0.1, "the clip barely moves ({moved} rad)");
}

/// A source that is not there, and a humanoid map asked of a skeleton that is not a humanoid
/// by its names (the Fox), fail with typed errors in the status and a message; the character
/// is left as it was.
#[test]
fn a_retarget_that_cannot_be_made_fails_with_a_typed_error() {
    let dir = project("assets/models");
    let (mut app, root) = common::fox_app(&dir, (PosePlugin, RetargetPlugin));
    let status = bake(&mut app, root, Retarget::new(dir.join("no such walk.bvh")));
    assert_eq!(status.phase, RetargetPhase::Failed);
    assert!(
        matches!(
            status.error,
            Some(RetargetLoadError::Source(SourceError::Io { .. }))
        ),
        "{:?}",
        status.error
    );
    assert!(status.clip.is_none());
    let failed = app.world().resource::<Messages<RetargetFailed>>();
    assert!(
        failed.get_cursor().read(failed).any(|m| m.entity == root),
        "a RetargetFailed message was written"
    );

    let status = bake(
        &mut app,
        root,
        Retarget::new(dir.join("Fox.glb")).animation("Walk"),
    );
    assert_eq!(status.phase, RetargetPhase::Failed);
    assert!(
        matches!(
            status.error,
            Some(RetargetLoadError::Retarget(
                RetargetError::MissingRole { .. }
            ))
        ),
        "{:?}",
        status.error
    );
}
