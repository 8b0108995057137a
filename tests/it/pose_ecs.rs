//! Headless tests of `PosePlugin`: a rigged bar built as Bevy entities (joints, a skinned
//! mesh, inverse bind poses), posed by a vertex handle with the root pinned; and the Fox
//! (`../shared/models/Fox.glb`) through Bevy's glTF loader.

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_wii_deform::pose::rig::synth_rig::bar_rig;
use bevy_wii_deform::prelude::*;

use crate::common;
use crate::common::scratch::ScratchDir;
use common::{drive_solves, pose_of, spawn_handle, spawn_rig, update_until};

fn app() -> App {
    let mut app = common::app();
    app.add_plugins(PosePlugin);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        16,
    )));
    app
}

#[test]
fn a_vertex_handle_poses_the_skeleton_and_the_pinned_root_stays() {
    let mut app = app();
    let rig = bar_rig(3, 12, 40);
    let offset = Vec3::new(2.0, 0.5, -1.0);
    let (root, joints, _) = spawn_rig(&mut app, &rig, offset);
    app.world_mut().entity_mut(root).insert((
        Poseable {
            max_iterations: 8,
            ..default()
        },
        PinnedJoints(vec![joints[0]]),
    ));
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let top: Vec<u32> = (0..rig.mesh.positions.len() as u32)
        .filter(|&i| rig.mesh.positions[i as usize].y > 0.9)
        .collect();
    // The plugin rebases the handle: pivot at the world centroid of the top vertices.
    let (handle, pivot) = spawn_handle(&mut app, root, top.clone(), ());
    let expected = offset
        + top
            .iter()
            .map(|&i| rig.mesh.positions[i as usize])
            .sum::<Vec3>()
            / top.len() as f32;
    assert!(
        (pivot - expected).length() < 1e-4,
        "pivot {pivot}, the top's centroid {expected}"
    );
    let root_before = *app.world().get::<Transform>(joints[0]).unwrap();
    // Drag the top sideways, upright: reachable by bending joint 1 by 40° and joint 2 back.
    let a = 40f32.to_radians();
    let target_shift = Vec3::new(-a.sin(), a.cos() - 1.0, 0.0) / 3.0;
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation = pivot + target_shift;
    drive_solves(&mut app, root, handle, 40);
    app.update(); // PostUpdate writes the pose
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let pose = pose_of(&app, &joints);
    assert_eq!(pose.local.len(), 3);
    // The joints carry the solved pose, and the CPU-skinned handle vertices are on target.
    // (The model is in character space; `placement` puts it where the character stands.)
    let skinned = posed.to_world(posed.model.skin_render(&pose));
    let size = posed.model.topology().bounding_diagonal() as f32;
    let worst = top
        .iter()
        .map(|&i| {
            let rest = rig.mesh.positions[i as usize] + offset;
            (skinned[i as usize].as_vec3() - (rest + target_shift)).length()
        })
        .fold(0.0f32, f32::max);
    assert!(
        worst < 0.01 * size,
        "handle vertices {worst} from target (size {size})"
    );
    let root_after = *app.world().get::<Transform>(joints[0]).unwrap();
    assert!(root_after.translation.distance(root_before.translation) < 1e-3);
    assert!(root_after.rotation.angle_between(root_before.rotation) < 0.01);
    // The middle joint bent.
    assert!(pose.local[1].rotation.angle_between(glam::DQuat::IDENTITY) > 0.1);
    // Bones keep their lengths.
    for (k, t) in pose.local.iter().enumerate().skip(1) {
        assert!((t.translation - rig.rest.local[k].translation).length() < 1e-6);
    }
}

#[test]
fn a_joint_handle_moves_its_joint_and_nan_never_reaches_a_joint() {
    let mut app = app();
    let rig = bar_rig(3, 12, 40);
    let (root, joints, _) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    app.world_mut().entity_mut(root).insert((
        Poseable {
            max_iterations: 8,
            ..default()
        },
        PinnedJoints(vec![joints[0]]),
    ));
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let handle = app
        .world_mut()
        .spawn((PoseJointHandle::new(root, joints[2]), Transform::IDENTITY))
        .id();
    update_until(&mut app, "the rest", |a| {
        a.world()
            .get::<PoseJointHandle>(handle)
            .unwrap()
            .rest
            .is_some()
    });
    let rest = app
        .world()
        .get::<PoseJointHandle>(handle)
        .unwrap()
        .rest
        .unwrap();
    assert!((rest.translation - Vec3::new(0.0, 2.0 / 3.0, 0.0)).length() < 1e-5);
    // Where a 30° bend of joint 1 about z puts joint 2.
    let bend = Quat::from_rotation_z(30f32.to_radians());
    let target = Vec3::new(0.0, 1.0 / 3.0, 0.0) + bend * Vec3::new(0.0, 1.0 / 3.0, 0.0);
    *app.world_mut().get_mut::<Transform>(handle).unwrap() =
        Transform::from_translation(target).with_rotation(bend);
    drive_solves(&mut app, root, handle, 20);
    app.update();
    let j1 = *app.world().get::<Transform>(joints[1]).unwrap();
    assert!(
        j1.rotation.angle_between(bend).to_degrees() < 1.0,
        "joint 1 at {:?}",
        j1.rotation
    );
    // A NaN target: the solve fails with a typed error and the joints keep the last pose.
    let good = pose_of(&app, &joints);
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation
        .x = f32::NAN;
    update_until(&mut app, "the failure", |a| {
        a.world().get::<PoseStatus>(root).unwrap().error.is_some()
    });
    app.update();
    let after = pose_of(&app, &joints);
    assert!(after.local.iter().all(|t| t.is_valid()));
    for (a, b) in after.local.iter().zip(&good.local) {
        assert!(a.rotation.angle_between(b.rotation) < 1e-6);
    }
    assert!(matches!(
        app.world().get::<PoseStatus>(root).unwrap().error,
        Some(PoseableError::Pose(
            bevy_wii_deform::pose::PoseError::NonFiniteTarget
        ))
    ));
}

#[test]
fn an_entity_without_a_skin_gets_a_typed_error() {
    let mut app = app();
    let child = app.world_mut().spawn(Transform::default()).id();
    let e = app
        .world_mut()
        .spawn((Poseable::default(), Transform::default()))
        .add_child(child)
        .id();
    update_until(&mut app, "the failure", |a| {
        a.world().get::<PoseStatus>(e).unwrap().error.is_some()
    });
    assert_eq!(
        app.world().get::<PoseStatus>(e).unwrap().error,
        Some(PoseableError::NoSkinnedMesh)
    );
}

/// The Fox's pose saved as a RON pose file and as a one-keyframe glTF clip: the clip played
/// back through Bevy's loader on the same Fox gives every joint its posed rotation, and the
/// RON file loads back to the same pose.
fn saved_pose_plays_back_and_loads(
    app: &mut App,
    root: Entity,
    handle: Entity,
    posed: &PosedSkeleton,
) {
    // Save the pose as a RON pose file and as a one-keyframe glTF clip; play the clip back
    // through Bevy's loader on the same Fox, and load the RON file back.
    let world = app.world();
    let tracks = posed.clip_tracks(|e| {
        (
            world.get::<Name>(e).map(|n| n.as_str().to_string()),
            world.get::<ChildOf>(e).map(|c| c.parent()),
            world.get::<AnimationPlayer>(e).is_some(),
        )
    });
    let glb = bevy_wii_deform::pose::write_gltf_pose_clip("pose", &tracks).unwrap();
    let ron = posed.pose_file().to_ron().unwrap();
    let out = ScratchDir::new("pose_ecs");
    std::fs::write(out.join("pose.glb"), glb).unwrap();
    // Let go: no handles, and stop holding the pose so the clip drives the joints.
    app.world_mut().despawn(handle);
    app.world_mut()
        .entity_mut(root)
        .remove::<(Poseable, PosedSkeleton)>();
    let rest = posed.model.skeleton().bind_pose();
    let player = {
        let w = app.world_mut();
        let mut q = w.query_filtered::<Entity, With<AnimationPlayer>>();
        q.iter(w).next().expect("the Fox has an AnimationPlayer")
    };
    // Knock the joints out of the pose, then play the saved clip.
    for &j in &posed.joints {
        app.world_mut().get_mut::<Transform>(j).unwrap().rotation = Quat::IDENTITY;
    }
    let clip: Handle<AnimationClip> = app.world().resource::<AssetServer>().load(
        GltfAssetLabel::Animation(0)
            .from_asset(bevy::asset::AssetPath::from_path_buf(out.join("pose.glb"))),
    );
    let node = common::play_clip(app, player, clip.clone());
    // Every joint of the Fox has a curve in the saved clip (same name paths).
    {
        let w = app.world();
        let c = w.resource::<Assets<AnimationClip>>().get(&clip).unwrap();
        let hits = posed
            .joints
            .iter()
            .filter(|&&j| {
                w.get::<bevy::animation::AnimationTargetId>(j)
                    .is_some_and(|id| c.curves().contains_key(id))
            })
            .count();
        assert_eq!(hits, posed.joints.len());
    }
    common::show_clip_at(app, player, node, 0.0);
    for (&j, t) in posed.joints.iter().zip(&posed.pose.local) {
        let now = app.world().get::<Transform>(j).unwrap();
        let (a, b) = (now.rotation, t.rotation.as_quat());
        let b = if a.dot(b) < 0.0 { -b } else { b };
        assert!(
            (a - b).length() < 1e-5,
            "joint {j}: clip gives {:?}, pose was {:?}",
            now.rotation,
            t.rotation
        );
    }
    let back = bevy_wii_deform::pose::PoseFile::from_ron(&ron)
        .unwrap()
        .apply(posed.model.skeleton(), &rest)
        .unwrap();
    for (a, b) in back.local.iter().zip(&posed.pose.local) {
        assert!(
            (a.rotation - b.rotation).length() < 1e-12,
            "{} vs {}",
            a.rotation,
            b.rotation
        );
        assert!((a.translation - b.translation).length() < 1e-12);
    }
}

/// The Fox through Bevy's own glTF loader: `Poseable` on the scene root finds the skin and
/// 24 joints; a handle on the head's vertices moves them, the feet joints pinned stay.
#[test]
fn the_fox_from_bevys_gltf_loader_is_poseable() {
    let Some(dir) = common::shared::shared_asset("models") else {
        return;
    };
    assert!(dir.join("Fox.glb").exists(), "../shared/models/Fox.glb");
    let (mut app, root) = common::fox_app(&dir, PosePlugin);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    assert_eq!(posed.joints.len(), 24);
    let names: Vec<String> = posed
        .model
        .skeleton()
        .joints()
        .iter()
        .map(|j| j.name.clone())
        .collect();
    let feet: Vec<Entity> = names
        .iter()
        .enumerate()
        .filter(|(_, n)| n.contains("Foot") || n.contains("foot"))
        .map(|(k, _)| posed.joints[k])
        .collect();
    assert!(!feet.is_empty(), "no foot joints among {names:?}");
    app.world_mut()
        .entity_mut(root)
        .insert(PinnedJoints(feet.clone()));
    // The render vertices as drawn now (CPU skinning of the current pose), and the head: the
    // vertices farthest along the body's forward axis (+z of the Fox's bind pose).
    let drawn = posed.skinned_positions();
    let size = posed.model.topology().bounding_diagonal() as f32;
    let mut order: Vec<u32> = (0..drawn.len() as u32).collect();
    order.sort_by(|&a, &b| drawn[b as usize].y.total_cmp(&drawn[a as usize].y));
    let head: Vec<u32> = order[..drawn.len() / 30].to_vec();
    let (handle, pivot) = spawn_handle(&mut app, root, head.clone(), ());
    // Pinned feet hold where they are in the world (their local transforms would not tell:
    // a bone's local translation never changes).
    let feet_before: Vec<Vec3> = feet
        .iter()
        .map(|&f| app.world().get::<GlobalTransform>(f).unwrap().translation())
        .collect();
    let reference = app
        .world()
        .get::<PosedSkeleton>(root)
        .unwrap()
        .skinned_positions();
    let shift = Vec3::new(0.04, 0.03, 0.0) * size;
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation = pivot + shift;
    drive_solves(&mut app, root, handle, 30);
    app.update();
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let now = posed.skinned_positions();
    let mean_error = head
        .iter()
        .map(|&i| (now[i as usize] - (reference[i as usize] + shift)).length())
        .sum::<f32>()
        / head.len() as f32;
    assert!(
        mean_error < 0.01 * size,
        "head vertices {mean_error} from target (size {size})"
    );
    for (f, before) in feet.iter().zip(&feet_before) {
        let after = app
            .world()
            .get::<GlobalTransform>(*f)
            .unwrap()
            .translation();
        assert!(
            after.distance(*before) < 1e-3 * size,
            "a pinned foot moved {} (size {size})",
            after.distance(*before)
        );
    }

    saved_pose_plays_back_and_loads(&mut app, root, handle, &posed);
}

/// The Wii Remote drives a character handle exactly like a static one: holding B and turning
/// the remote 30° about the vertical turns the grabbed top of the bar 1:1 (the top joint
/// follows to within 1°; a gain of 0.9 would be 3° off), the pinned root stays.
#[test]
fn the_wii_remote_turns_a_character_handle_one_to_one() {
    use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
    let mut app = app();
    app.add_plugins(MotionControlPlugin);
    app.world_mut()
        .spawn((Camera3d::default(), Transform::default()));
    let rig = bar_rig(3, 12, 40);
    let (root, joints, _) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    app.world_mut().entity_mut(root).insert((
        Poseable {
            max_iterations: 8,
            ..default()
        },
        PinnedJoints(vec![joints[0]]),
    ));
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    let top: Vec<u32> = (0..rig.mesh.positions.len() as u32)
        .filter(|&i| rig.mesh.positions[i as usize].y > 0.8)
        .collect();
    let (handle, _) = spawn_handle(&mut app, root, top, MotionHandleControl::default());
    let remote = app
        .world_mut()
        .spawn(MotionController {
            connection: ConnectionState::Connected,
            ..default()
        })
        .id();
    let set = |app: &mut App, orientation: Quat, buttons: u16| {
        let mut w = app.world_mut().get_mut::<MotionController>(remote).unwrap();
        w.orientation = orientation;
        w.buttons = buttons;
    };
    set(&mut app, Quat::IDENTITY, Buttons::B);
    app.update();
    let turn = Quat::from_rotation_y(30f32.to_radians());
    set(&mut app, turn, Buttons::B);
    app.update();
    set(&mut app, turn, 0); // release B: the handle keeps its pose
    drive_solves(&mut app, root, handle, 20);
    app.update();
    let handle_rotation = app.world().get::<Transform>(handle).unwrap().rotation;
    assert!(
        (handle_rotation.angle_between(turn)).to_degrees() < 0.5,
        "handle turned to {handle_rotation:?}"
    );
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let globals = posed
        .model
        .skeleton()
        .global_transforms(&pose_of(&app, &joints));
    let (_, top_rotation, _) = globals[2].to_scale_rotation_translation();
    let error = top_rotation.as_quat().angle_between(turn).to_degrees();
    assert!(
        error < 1.0,
        "the top joint is {error:.2}° from the remote's 30° turn"
    );
    let root_rotation = app.world().get::<Transform>(joints[0]).unwrap().rotation;
    assert!(root_rotation.angle_between(Quat::IDENTITY) < 0.01);
}

/// `Poseable` on the skinned mesh entity itself (not an ancestor) works the same way.
#[test]
fn poseable_on_the_skinned_mesh_entity_finds_its_joints() {
    let mut app = app();
    let rig = bar_rig(3, 12, 20);
    let (_, joints, mesh) = spawn_rig(&mut app, &rig, Vec3::ZERO);
    app.world_mut().entity_mut(mesh).insert(Poseable::default());
    update_until(&mut app, "the model", |a| {
        a.world().get::<PosedSkeleton>(mesh).is_some()
    });
    let posed = app.world().get::<PosedSkeleton>(mesh).unwrap();
    assert_eq!(posed.joints, joints);
    assert_eq!(posed.primitives, vec![(mesh, 0)]);
    // At rest the CPU skin is the bind pose.
    let skinned = posed.skinned_positions();
    for (a, b) in skinned.iter().zip(&rig.mesh.positions) {
        assert!(a.distance(*b) < 1e-5);
    }
}
