//! Headless tests of `PosePlugin`: a rigged bar built as Bevy entities (joints, a skinned
//! mesh, inverse bind poses), posed by a vertex handle with the root pinned; and the Fox
//! (`../shared/models/Fox.glb`) through Bevy's glTF loader.

use std::time::{Duration, Instant};

use bevy::asset::RenderAssetUsages;
use bevy::mesh::skinning::{SkinnedMesh as BevySkin, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_wii_deform::pose::synth_rig::{SyntheticRig, bar_rig};
use bevy_wii_deform::pose::{JointTransform, SkeletonPose};
use bevy_wii_deform::prelude::*;

fn app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::asset::AssetPlugin::default(),
        bevy::mesh::MeshPlugin,
        bevy::transform::TransformPlugin,
        PosePlugin,
    ));
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        16,
    )));
    app
}

/// Spawns the rig as a character entity (root) with a joint chain and a skinned mesh child,
/// placed at `offset`. Returns (root, joints, mesh entity).
fn spawn_rig(app: &mut App, rig: &SyntheticRig, offset: Vec3) -> (Entity, Vec<Entity>, Entity) {
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    );
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_POSITION,
        rig.mesh
            .positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    );
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(rig.mesh.joint_indices.clone()),
    );
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, rig.mesh.joint_weights.clone());
    mesh.insert_indices(Indices::U32(rig.mesh.indices.clone()));
    let world = app.world_mut();
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let ibp: Vec<Mat4> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| Mat4::from(j.inverse_bind.as_affine3a()))
        .collect();
    let ibp = world
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(SkinnedMeshInverseBindposes::from(ibp));
    let root = world
        .spawn((Transform::from_translation(offset), Name::new("character")))
        .id();
    let mut joints = Vec::new();
    for (k, joint) in rig.skeleton.joints().iter().enumerate() {
        let t = rig.rest.local[k];
        let parent = joint.parent.map_or(root, |p| joints[p]);
        let e = world
            .spawn((
                Transform::from_translation(t.translation.as_vec3()),
                Name::new(joint.name.clone()),
                ChildOf(parent),
            ))
            .id();
        joints.push(e);
    }
    let skinned = world
        .spawn((
            Mesh3d(mesh),
            BevySkin {
                inverse_bindposes: ibp,
                joints: joints.clone(),
            },
            Transform::default(),
            ChildOf(root),
        ))
        .id();
    (root, joints, skinned)
}

fn pose_of(app: &App, joints: &[Entity]) -> SkeletonPose {
    SkeletonPose {
        local: joints
            .iter()
            .map(|&j| {
                let t = app.world().get::<Transform>(j).unwrap();
                JointTransform {
                    translation: t.translation.as_dvec3(),
                    rotation: t.rotation.as_dquat(),
                    scale: t.scale.as_dvec3(),
                }
            })
            .collect(),
    }
}

/// Updates until `done` holds, with a generous deadline for the background tasks.
fn update_until(app: &mut App, what: &str, done: impl Fn(&mut App) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !done(app) {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        app.update();
        std::thread::yield_now();
    }
}

fn solves(app: &App, e: Entity) -> u64 {
    app.world().get::<PoseStatus>(e).map_or(0, |s| s.solves)
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
    let handle = app
        .world_mut()
        .spawn((
            DeformHandle {
                target: root,
                vertices: top.clone(),
                pivot: None,
            },
            Transform::IDENTITY,
        ))
        .id();
    // The plugin rebases the handle: pivot at the world centroid of the top vertices.
    update_until(&mut app, "the pivot", |a| {
        a.world()
            .get::<DeformHandle>(handle)
            .unwrap()
            .pivot
            .is_some()
    });
    let pivot = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .pivot
        .unwrap();
    assert!(
        (pivot - (offset + Vec3::new(0.0, 0.97, 0.0))).length() < 0.05,
        "pivot {pivot}"
    );
    let root_before = *app.world().get::<Transform>(joints[0]).unwrap();
    // Drag the top sideways, upright: reachable by bending joint 1 by 40° and joint 2 back.
    let a = 40f32.to_radians();
    let target_shift = Vec3::new(-a.sin(), a.cos() - 1.0, 0.0) / 3.0;
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation = pivot + target_shift;
    for _ in 0..40 {
        let before = solves(&app, root);
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .set_changed();
        update_until(&mut app, "a solve", |a| solves(a, root) > before);
    }
    app.update(); // PostUpdate writes the pose
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let pose = pose_of(&app, &joints);
    assert_eq!(pose.local.len(), 3);
    // The joints carry the solved pose, and the CPU-skinned handle vertices are on target.
    let skinned = posed.model.skin_render(&pose);
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
    for _ in 0..20 {
        let before = solves(&app, root);
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .set_changed();
        update_until(&mut app, "a solve", |a| solves(a, root) > before);
    }
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
