//! The spring systems: resolve [`SpringBones`] against prepared characters, then step them in
//! `PostUpdate` after the pose is applied and before transforms propagate.

use std::sync::Arc;

use bevy::prelude::*;
use bevy::transform::TransformSystems;

use super::{SpringBones, SpringRuntime, SpringSource, SpringStatus};
use crate::ecs::pose::resolve_limits;
use crate::ecs::{PoseLimits, PoseSystems, PosedSkeleton};
use crate::pose::{
    JointTransform, SkeletonPose, SpringRig, SpringState, read_vrm_springs, step_springs,
};

/// The spring systems' place: `PostUpdate`, after [`PoseSystems::Apply`] (and so after the
/// animation), before `TransformSystems::Propagate`.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SpringSystems {
    /// Step every character's springs and turn its chain joints.
    Simulate,
}

/// Swings the [`SpringBones`] of posed characters (needs `PosePlugin`).
#[derive(Debug, Clone, Copy, Default)]
pub struct SpringPlugin;

impl Plugin for SpringPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<SpringStatus>()
            .configure_sets(
                PostUpdate,
                SpringSystems::Simulate
                    .after(PoseSystems::Apply)
                    .before(TransformSystems::Propagate),
            )
            .add_systems(
                PostUpdate,
                (resolve_springs, simulate_springs)
                    .chain()
                    .in_set(SpringSystems::Simulate),
            );
    }
}

/// A character whose springs are new, changed, or newly posed.
type SpringsToResolve = Or<(Changed<SpringBones>, Added<PosedSkeleton>)>;

/// Builds the rig of a character whose [`SpringBones`] is new or changed, once it is posed.
fn resolve_springs(
    mut commands: Commands,
    mut characters: Query<
        (Entity, Ref<SpringBones>, &PosedSkeleton, &mut SpringStatus),
        SpringsToResolve,
    >,
) {
    for (entity, bones, posed, mut status) in &mut characters {
        let skeleton = posed.model.skeleton();
        let rig = match &bones.source {
            SpringSource::Names { words, joint } => {
                let words: Vec<&str> = words.iter().map(String::as_str).collect();
                Ok(Arc::new(SpringRig::from_names(skeleton, &words, *joint)))
            }
            SpringSource::Vrm(bytes) => read_vrm_springs(bytes, skeleton)
                .map(Arc::new)
                .map_err(|e| e.to_string()),
            SpringSource::Rig(rig) => rig
                .validate(skeleton)
                .map(|()| rig.clone())
                .map_err(|e| e.to_string()),
        };
        match rig {
            Ok(rig) => {
                *status = SpringStatus {
                    chains: rig.chains.len(),
                    joints: rig.joint_count(),
                    error: None,
                };
                commands.entity(entity).try_insert(SpringRuntime {
                    written: vec![None; skeleton.len()],
                    rig,
                    state: SpringState::default(),
                    limits: None,
                });
            }
            Err(error) => {
                warn!("spring bones of {entity}: {error}");
                status.error = Some(error);
                commands.entity(entity).try_remove::<SpringRuntime>();
            }
        }
    }
}

/// Steps every character's springs by the frame's time and writes the swung rotations.
#[allow(clippy::type_complexity)] // a system's query, named by its parameters
fn simulate_springs(
    time: Res<Time>,
    mut characters: Query<(
        &SpringBones,
        &PosedSkeleton,
        &mut SpringRuntime,
        Option<Ref<PoseLimits>>,
    )>,
    mut joints: Query<&mut Transform>,
) {
    let dt = f64::from(time.delta_secs());
    'characters: for (bones, posed, mut runtime, limits) in &mut characters {
        let runtime = &mut *runtime;
        if !bones.enabled {
            runtime.state.reset();
            runtime.written.iter_mut().for_each(|w| *w = None);
            continue;
        }
        // The animated pose as the joints hold it (a joint the springs turned last frame and
        // nobody rewrote since is still animated by the rotation it had before).
        let mut local = Vec::with_capacity(posed.joints.len());
        for (j, &entity) in posed.joints.iter().enumerate() {
            let Ok(t) = joints.get(entity) else {
                continue 'characters; // a joint despawned: this character's springs wait
            };
            let rotation = match runtime.written[j] {
                Some((wrote, animated)) if wrote == t.rotation => animated,
                _ => t.rotation,
            };
            local.push(JointTransform {
                translation: t.translation.as_dvec3(),
                rotation: rotation.as_dquat().normalize(),
                scale: t.scale.as_dvec3(),
            });
        }
        let animated = SkeletonPose { local };
        let mut pose = animated.clone();
        let limits = resolve_limits(posed, limits.as_ref(), &mut runtime.limits)
            .ok()
            .flatten();
        step_springs(
            &runtime.rig,
            posed.model.skeleton(),
            posed.placement,
            &mut pose,
            dt,
            limits.as_deref(),
            &mut runtime.state,
        );
        for j in runtime.rig.driven_joints() {
            let rotation = pose.local[j].rotation.as_quat();
            if !rotation.is_finite() {
                continue;
            }
            if let Ok(mut t) = joints.get_mut(posed.joints[j]) {
                t.rotation = rotation;
                runtime.written[j] = Some((rotation, animated.local[j].rotation.as_quat()));
            }
        }
    }
}
