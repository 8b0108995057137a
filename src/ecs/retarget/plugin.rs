//! The retarget systems: the character's rest remembered once it is prepared, a bake started
//! on Bevy's compute pool when a [`Retarget`] is added or changed (the latest wins), and a
//! landed bake turned into an `AnimationClip` on the character's joints.

use std::sync::Arc;

use bevy::animation::animated_field;
use bevy::animation::animation_curves::{AnimatableCurve, AnimatableKeyframeCurve};
use bevy::animation::{AnimationClip, AnimationTargetId};
use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, block_on, futures_lite::future};

use super::{
    Retarget, RetargetFailed, RetargetFoot, RetargetLoadError, RetargetPhase, RetargetReady,
    RetargetStatus,
};
use crate::ecs::pose::convert::bevy_transform;
use crate::ecs::{PoseSystems, PosedSkeleton};
use crate::pose::retarget::{Retargeter, SkeletonMap, read_source_motion};
use crate::pose::{PoseClip, SkeletonPose, SkinnedModel};

/// The retarget systems, in `Update` after [`PoseSystems::Poll`].
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RetargetSystems {
    /// Remember rests, start bakes, collect landed ones.
    Bake,
}

/// Plays clips made for other skeletons on posed characters ([`Retarget`]); needs
/// [`PosePlugin`](crate::ecs::PosePlugin) and Bevy's animation plugin for the clips to play.
pub struct RetargetPlugin;

impl Plugin for RetargetPlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<AnimationClip>()
            .register_type::<super::RetargetPhase>()
            .add_message::<RetargetReady>()
            .add_message::<RetargetFailed>()
            .configure_sets(Update, RetargetSystems::Bake.after(PoseSystems::Poll))
            .add_systems(
                Update,
                (remember_rest, start_bakes, finish_bakes)
                    .chain()
                    .in_set(RetargetSystems::Bake),
            );
    }
}

/// The character's pose when it was prepared (its rest): what its retargets are relative to.
#[derive(Component)]
struct RetargetRest(SkeletonPose);

/// A bake running in the background (replacing it drops, and so cancels, the old one).
#[derive(Component)]
struct RetargetTask(Task<Result<Baked, RetargetLoadError>>);

/// What a bake hands back.
struct Baked {
    clip: PoseClip,
    failed_solves: usize,
    unmapped: Vec<String>,
    planted_share: Vec<(String, f32)>,
    /// Per foot: its joint, name and planted time spans.
    feet: Vec<BakedFoot>,
}

/// A foot of a bake: its joint (skeleton index), name, and the clip's spans while the source's
/// foot is planted.
struct BakedFoot {
    joint: usize,
    name: String,
    planted: Vec<(f32, f32)>,
}

/// Characters with a retarget whose rest is not remembered yet.
type WithoutRest = (With<Retarget>, Without<RetargetRest>);

fn remember_rest(mut commands: Commands, characters: Query<(Entity, &PosedSkeleton), WithoutRest>) {
    for (entity, posed) in &characters {
        commands
            .entity(entity)
            .try_insert(RetargetRest(posed.pose.clone()));
    }
}

fn start_bakes(
    mut commands: Commands,
    mut characters: Query<(
        Entity,
        Ref<Retarget>,
        &PosedSkeleton,
        &RetargetRest,
        &mut RetargetStatus,
    )>,
) {
    for (entity, retarget, posed, rest, mut status) in &mut characters {
        if status.phase != RetargetPhase::Waiting && !retarget.is_changed() {
            continue;
        }
        let (retarget, model, rest) = (
            Retarget::clone(&retarget),
            posed.model.clone(),
            rest.0.clone(),
        );
        let task = AsyncComputeTaskPool::get().spawn(async move { bake(&retarget, model, &rest) });
        commands.entity(entity).try_insert(RetargetTask(task));
        *status = RetargetStatus {
            phase: RetargetPhase::Baking,
            ..default()
        };
    }
}

/// Reads the source and the map, and bakes the clip onto `model` at `rest`.
fn bake(
    retarget: &Retarget,
    model: Arc<SkinnedModel>,
    rest: &SkeletonPose,
) -> Result<Baked, RetargetLoadError> {
    let source = read_source_motion(&retarget.source, retarget.animation.as_deref())?;
    let (from, to) = ((&source.skeleton, &source.rest), (model.skeleton(), rest));
    let map = match &retarget.map {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| RetargetLoadError::MapFile {
                path: path.clone(),
                message: e.to_string(),
            })?;
            SkeletonMap::from_ron(&text, from, to)?
        }
        None => SkeletonMap::humanoid(from, to)?,
    };
    let name = |j: usize| model.skeleton().joints()[j].name.clone();
    let unmapped = map.unmapped.iter().map(|&j| name(j)).collect();
    let feet: Vec<usize> = map.feet.iter().map(|&(_, foot)| foot).collect();
    let retargeter = Retargeter::new(from, model.clone(), rest, map, retarget.settings)?;
    let baked = retargeter.bake(&source.clip, &retargeter.rest_ground())?;
    let times: Vec<f32> = baked.clip.keys().iter().map(|k| k.time).collect();
    let (planted_share, feet) = feet
        .iter()
        .zip(&baked.source_contacts.planted)
        .map(|(&joint, frames)| {
            let planted = frames.iter().filter(|&&p| p).count();
            let share = (name(joint), planted as f32 / frames.len().max(1) as f32);
            let foot = BakedFoot {
                joint,
                name: name(joint),
                planted: planted_spans(frames, &times),
            };
            (share, foot)
        })
        .unzip();
    Ok(Baked {
        clip: baked.clip,
        failed_solves: baked.failed_solves,
        unmapped,
        planted_share,
        feet,
    })
}

/// The time spans of the runs of planted frames (`times`: each frame's time).
fn planted_spans(planted: &[bool], times: &[f32]) -> Vec<(f32, f32)> {
    let mut spans = Vec::new();
    let mut start = None;
    for (f, (&down, &time)) in planted.iter().zip(times).enumerate() {
        match (down, start) {
            (true, None) => start = Some(time),
            (false, Some(from)) => {
                spans.push((from, times[f.saturating_sub(1)]));
                start = None;
            }
            _ => {}
        }
    }
    if let (Some(from), Some(&last)) = (start, times.last()) {
        spans.push((from, last));
    }
    spans
}

fn finish_bakes(
    mut commands: Commands,
    mut characters: Query<(
        Entity,
        &mut RetargetTask,
        &mut RetargetStatus,
        &PosedSkeleton,
    )>,
    targets: Query<&AnimationTargetId>,
    mut clips: ResMut<Assets<AnimationClip>>,
    mut ready: MessageWriter<RetargetReady>,
    mut failed: MessageWriter<RetargetFailed>,
) {
    for (entity, mut task, mut status, posed) in &mut characters {
        let Some(result) = block_on(future::poll_once(&mut task.0)) else {
            continue;
        };
        commands.entity(entity).remove::<RetargetTask>();
        let result = result.and_then(|baked| {
            let clip = animation_clip(&baked.clip, &posed.joints, &targets)
                .ok_or(RetargetLoadError::NoAnimationTargets)?;
            Ok((baked, clip))
        });
        match result {
            Ok((baked, clip)) => {
                let clip = clips.add(clip);
                *status = RetargetStatus {
                    phase: RetargetPhase::Ready,
                    clip: Some(clip.clone()),
                    error: None,
                    frames: baked.clip.keys().len(),
                    failed_solves: baked.failed_solves,
                    unmapped: baked.unmapped,
                    planted_share: baked.planted_share,
                    feet: baked
                        .feet
                        .into_iter()
                        .filter_map(|foot| {
                            Some(RetargetFoot {
                                joint: *posed.joints.get(foot.joint)?,
                                name: foot.name,
                                planted: foot.planted,
                            })
                        })
                        .collect(),
                };
                ready.write(RetargetReady { entity, clip });
            }
            Err(error) => {
                warn!("Retarget on {entity}: {error}");
                *status = RetargetStatus {
                    phase: RetargetPhase::Failed,
                    error: Some(error.clone()),
                    ..default()
                };
                failed.write(RetargetFailed { entity, error });
            }
        }
    }
}

/// The clip as Bevy's: per joint that has an `AnimationTargetId`, its translation, rotation
/// and scale keyed at the clip's times and sampled linearly (a clip of one key holds it for
/// an instant). `None` when no joint can be addressed.
fn animation_clip(
    clip: &PoseClip,
    joints: &[Entity],
    targets: &Query<&AnimationTargetId>,
) -> Option<AnimationClip> {
    let keys = clip.keys();
    let mut times: Vec<f32> = keys.iter().map(|k| k.time).collect();
    if times.len() == 1 {
        times.push(times[0] + crate::pose::KEY_TIME_EPSILON * 2.0);
    }
    let at = |i: usize| &keys[i.min(keys.len() - 1)].pose;
    let mut out = AnimationClip::default();
    let mut any = false;
    for (j, &entity) in joints.iter().enumerate() {
        let Ok(&target) = targets.get(entity) else {
            continue;
        };
        let frames: Vec<(f32, Transform)> = (times.iter().enumerate())
            .map(|(i, &t)| (t, bevy_transform(&at(i).local[j])))
            .collect();
        let translations = frames.iter().map(|(t, f)| (*t, f.translation));
        let rotations = frames.iter().map(|(t, f)| (*t, f.rotation));
        let scales = frames.iter().map(|(t, f)| (*t, f.scale));
        let (Ok(translation), Ok(rotation), Ok(scale)) = (
            AnimatableKeyframeCurve::new(translations),
            AnimatableKeyframeCurve::new(rotations),
            AnimatableKeyframeCurve::new(scales),
        ) else {
            continue;
        };
        out.add_curve_to_target(
            target,
            AnimatableCurve::new(animated_field!(Transform::translation), translation),
        );
        out.add_curve_to_target(
            target,
            AnimatableCurve::new(animated_field!(Transform::rotation), rotation),
        );
        out.add_curve_to_target(
            target,
            AnimatableCurve::new(animated_field!(Transform::scale), scale),
        );
        any = true;
    }
    any.then_some(out)
}

#[cfg(test)]
mod tests {
    use super::planted_spans;

    /// Runs of planted frames become spans from their first frame's time to their last's;
    /// a run reaching the clip's end ends at its last time. (Fails with a span ending at the
    /// first unplanted frame.)
    #[test]
    fn planted_runs_become_time_spans() {
        let times = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5];
        let planted = [true, true, false, false, true, true];
        assert_eq!(
            planted_spans(&planted, &times),
            vec![(0.0, 0.1), (0.4, 0.5)]
        );
        assert_eq!(planted_spans(&[false; 6], &times), Vec::new());
        assert_eq!(
            planted_spans(&[false, true, false, false, false, false], &times),
            vec![(0.1, 0.1)]
        );
    }
}
