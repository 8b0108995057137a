//! S saves the pose (RON pose file + one-keyframe glTF clip) to `poses/`, L loads the RON
//! back, R returns to the pose the character was loaded in.

use std::path::PathBuf;

use bevy::prelude::*;
use bevy_wii_deform::pose::{PoseFile, SkeletonPose, write_gltf_pose_clip};
use bevy_wii_deform::prelude::*;

use crate::scene::Character;

/// Save / load / reset keys.
pub struct PoseFilesPlugin;

impl Plugin for PoseFilesPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<LastMessage>().add_systems(
            Update,
            (remember_initial_pose, keys).before(PoseSystems::Request),
        );
    }
}

/// The last save/load result, shown by the HUD.
#[derive(Resource, Default)]
pub struct LastMessage(pub String);

/// The pose the character was loaded in.
#[derive(Component)]
pub struct InitialPose(pub SkeletonPose);

fn remember_initial_pose(
    mut commands: Commands,
    added: Query<(Entity, &PosedSkeleton), Added<PosedSkeleton>>,
) {
    for (entity, posed) in &added {
        commands
            .entity(entity)
            .insert(InitialPose(posed.pose.clone()));
    }
}

/// Where poses and clips are saved.
pub fn directory() -> PathBuf {
    PathBuf::from("poses")
}

/// Name, parent and animation-root flag of an entity: what `PosedSkeleton::joint_paths` asks.
pub fn node_of(
    names: &Query<(Option<&Name>, Option<&ChildOf>, Has<AnimationPlayer>)>,
    e: Entity,
) -> (Option<String>, Option<Entity>, bool) {
    match names.get(e) {
        Ok((name, parent, root)) => (
            name.map(|n| n.as_str().to_string()),
            parent.map(|p| p.parent()),
            root,
        ),
        Err(_) => (None, None, false),
    }
}

/// Writes `pose.ron` and `pose.glb` for the character.
pub fn save(
    world_names: &Query<(Option<&Name>, Option<&ChildOf>, Has<AnimationPlayer>)>,
    posed: &PosedSkeleton,
) -> Result<String, String> {
    let dir = directory();
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    posed
        .pose_file()
        .save(&dir.join("pose.ron"))
        .map_err(|e| e.to_string())?;
    let tracks = posed.clip_tracks(|e| node_of(world_names, e));
    let glb = write_gltf_pose_clip("pose", &tracks).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("pose.glb"), glb).map_err(|e| e.to_string())?;
    Ok(format!(
        "saved {0}/pose.ron and {0}/pose.glb",
        dir.display()
    ))
}

fn keys(
    keys: Res<ButtonInput<KeyCode>>,
    mut message: ResMut<LastMessage>,
    mut character: Query<(&mut PosedSkeleton, &InitialPose), With<Character>>,
    names: Query<(Option<&Name>, Option<&ChildOf>, Has<AnimationPlayer>)>,
) {
    for (mut posed, initial) in &mut character {
        if keys.just_pressed(KeyCode::KeyS) {
            message.0 = save(&names, &posed).unwrap_or_else(|e| format!("save failed: {e}"));
        }
        if keys.just_pressed(KeyCode::KeyL) {
            let loaded = PoseFile::load(&directory().join("pose.ron"))
                .and_then(|file| file.apply(posed.model.skeleton(), &posed.pose));
            match loaded {
                Ok(pose) => {
                    posed.pose = pose;
                    message.0 = "loaded poses/pose.ron".into();
                }
                Err(e) => message.0 = format!("load failed: {e}"),
            }
        }
        if keys.just_pressed(KeyCode::KeyR) {
            posed.pose = initial.0.clone();
            message.0 = "reset".into();
        }
    }
}
