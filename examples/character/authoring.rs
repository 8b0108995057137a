//! `--author-demo OUT.glb`: authoring checked end to end, unattended. Once the character is
//! ready it is posed three times by scripted grabs (the head up, the tail aside, the head
//! down and over), each pose keyed on the timeline at 0, 0.5 and 1 s (linear keys); the clip
//! is exported to OUT.glb — a **clip-only glTF** whose nodes are named and nested as the
//! character's joints from its animation root, so Bevy's loader targets the same joints (the
//! model file is left alone) — then loaded back through Bevy's glTF loader and played on the
//! character. The last stdout line is JSON: the keys, the channels written, and the largest
//! joint-rotation error of the playback at the key times and halfway between keys (against
//! the clip's own linear interpolation).

use bevy::prelude::*;
use bevy_wii_deform::pose::{PoseClip, rotation_angle};
use bevy_wii_deform::prelude::*;

use crate::Args;
use crate::files::{InitialPose, node_of};
use crate::grab::grab_at;
use crate::scene::Character;

/// The `--author-demo` script.
pub struct AuthorDemoPlugin;

impl Plugin for AuthorDemoPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Update, author.before(PoseSystems::Request));
    }
}

/// Frames a scripted drag takes, and frames a pose is left to settle.
const DRAG_FRAMES: u32 = 20;
const SETTLE_FRAMES: u32 = 40;

/// Where the script is.
#[derive(Default)]
enum Step {
    /// Waiting for the character.
    #[default]
    Waiting,
    /// Dragging grab `k` (its handle, the drag, the frame it started).
    Posing {
        k: usize,
        handle: Entity,
        shift: Vec3,
        since: u32,
    },
    /// The clip is exported and loading back.
    Loading {
        clip: Handle<AnimationClip>,
        authored: PoseClip,
        joints: Vec<Entity>,
        channels: usize,
    },
    /// Sampling the playback at `times[i]`.
    Checking {
        node: AnimationNodeIndex,
        player: Entity,
        authored: PoseClip,
        joints: Vec<Entity>,
        channels: usize,
        i: usize,
        wait: u32,
        errors: Vec<(f32, f32)>,
    },
    Done,
}

/// The three scripted grabs: a point (fraction of the height from the top, which end along
/// the body) and a drag (fractions of the size).
const GRABS: [(f32, f32, Vec3); 3] = [
    (0.05, 1.0, Vec3::new(0.0, 0.08, 0.03)),
    (0.3, -1.0, Vec3::new(0.10, 0.04, 0.0)),
    (0.05, 1.0, Vec3::new(-0.06, -0.07, 0.0)),
];

#[derive(Default)]
struct Script {
    frame: u32,
    step: Step,
}

#[allow(clippy::too_many_arguments)]
fn author(
    mut commands: Commands,
    mut script: Local<Script>,
    args: Res<Args>,
    server: Res<AssetServer>,
    clips: Res<Assets<AnimationClip>>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    mut character: Query<
        (
            Entity,
            &PosedSkeleton,
            &mut PoseTimeline,
            &InitialPose,
            &PoseStatus,
        ),
        With<Character>,
    >,
    mut handles: Query<(&DeformHandle, &mut Transform)>,
    (names, mut players, joints): (
        Query<(Option<&Name>, Option<&ChildOf>, Has<AnimationPlayer>)>,
        Query<(Entity, &mut AnimationPlayer)>,
        Query<&Transform, Without<DeformHandle>>,
    ),
    mut exit: MessageWriter<AppExit>,
) {
    let Some(out) = args.author_demo.clone() else {
        return;
    };
    script.frame += 1;
    let frame = script.frame;
    let step = std::mem::take(&mut script.step);
    script.step = match step {
        Step::Waiting => match character.iter().next() {
            Some((entity, posed, ..)) if frame > 10 => {
                let (handle, shift) = start_grab(&mut commands, entity, posed, 0);
                Step::Posing {
                    k: 0,
                    handle,
                    shift,
                    since: frame,
                }
            }
            _ => Step::Waiting,
        },
        Step::Posing {
            k,
            handle,
            shift,
            since,
        } => {
            let Ok((entity, posed, mut timeline, initial, status)) = character.single_mut() else {
                return fail(&mut exit, "the character went away");
            };
            let s = ((frame - since) as f32 / DRAG_FRAMES as f32).min(1.0);
            if let Ok((h, mut t)) = handles.get_mut(handle)
                && let Some(pivot) = h.pivot
            {
                // Only a real move is a change (a change starts a solve).
                t.set_if_neq(Transform::from_translation(pivot + shift * s));
            }
            let settled =
                frame > since + DRAG_FRAMES + SETTLE_FRAMES && status.phase == DeformPhase::Idle;
            if !settled {
                Step::Posing {
                    k,
                    handle,
                    shift,
                    since,
                }
            } else {
                timeline.time = 0.5 * k as f32;
                if let Err(e) = timeline.set_key(posed) {
                    return fail(&mut exit, &format!("key refused: {e}"));
                }
                commands.entity(handle).despawn();
                if k + 1 < GRABS.len() {
                    let (handle, shift) = start_grab(&mut commands, entity, posed, k + 1);
                    Step::Posing {
                        k: k + 1,
                        handle,
                        shift,
                        since: frame,
                    }
                } else {
                    match export(&out, &timeline, posed, initial, &names, &server) {
                        Ok((clip, channels)) => {
                            // The loaded clip drives the joints from now on.
                            commands
                                .entity(entity)
                                .remove::<(Poseable, PosedSkeleton, PoseTimeline)>();
                            Step::Loading {
                                clip,
                                authored: timeline.clip.clone(),
                                joints: posed.joints.clone(),
                                channels,
                            }
                        }
                        Err(e) => return fail(&mut exit, &e),
                    }
                }
            }
        }
        Step::Loading {
            clip,
            authored,
            joints,
            channels,
        } => {
            if clips.get(&clip).is_none() {
                if frame > 2000 {
                    return fail(&mut exit, "the exported clip never loaded");
                }
                Step::Loading {
                    clip,
                    authored,
                    joints,
                    channels,
                }
            } else {
                let Some((player, mut p)) = players.iter_mut().next() else {
                    return fail(&mut exit, "the model has no AnimationPlayer");
                };
                let (graph, node) = AnimationGraph::from_clip(clip);
                commands
                    .entity(player)
                    .insert(AnimationGraphHandle(graphs.add(graph)));
                p.stop_all().play(node).pause();
                Step::Checking {
                    node,
                    player,
                    authored,
                    joints,
                    channels,
                    i: 0,
                    wait: 0,
                    errors: Vec::new(),
                }
            }
        }
        Step::Checking {
            node,
            player,
            authored,
            joints: joint_entities,
            channels,
            i,
            wait,
            mut errors,
        } => {
            let times = check_times(&authored);
            let Ok((_, mut p)) = players.get_mut(player) else {
                return fail(&mut exit, "the AnimationPlayer went away");
            };
            if let Some(active) = p.animation_mut(node) {
                active.set_seek_time(times[i]).pause();
            }
            if wait < 3 {
                Step::Checking {
                    node,
                    player,
                    authored,
                    joints: joint_entities,
                    channels,
                    i,
                    wait: wait + 1,
                    errors,
                }
            } else {
                let expected = authored.sample(times[i]).unwrap_or_default();
                let worst = joint_entities
                    .iter()
                    .zip(&expected.local)
                    .filter_map(|(&j, want)| {
                        let now = joints.get(j).ok()?.rotation;
                        Some(rotation_angle(now.as_dquat(), want.rotation) as f32)
                    })
                    .fold(0.0f32, f32::max);
                errors.push((times[i], worst));
                if i + 1 < times.len() {
                    Step::Checking {
                        node,
                        player,
                        authored,
                        joints: joint_entities,
                        channels,
                        i: i + 1,
                        wait: 0,
                        errors,
                    }
                } else {
                    report(&authored, channels, &errors);
                    exit.write(AppExit::Success);
                    Step::Done
                }
            }
        }
        Step::Done => Step::Done,
    };
}

/// Starts scripted grab `k` on the posed character; its handle and drag.
fn start_grab(
    commands: &mut Commands,
    character: Entity,
    posed: &PosedSkeleton,
    k: usize,
) -> (Entity, Vec3) {
    let (from_top, end, drag) = GRABS[k];
    let positions = posed.skinned_positions();
    let size = posed.model.topology().bounding_diagonal() as f32;
    let (low, high) = positions
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), p| (l.min(p.y), h.max(p.y)));
    // The point at that height farthest towards `end` along the body's long horizontal axis.
    let height = high - from_top * (high - low);
    let point = positions
        .iter()
        .filter(|p| (p.y - height).abs() < 0.05 * (high - low))
        .max_by(|a, b| (a.z * end).total_cmp(&(b.z * end)))
        .copied()
        .unwrap_or(Vec3::ZERO);
    let handle = grab_at(commands, character, posed, point);
    (handle, drag * size)
}

/// Exports the timeline to `out`, starts loading it back; the clip handle and the channels.
fn export(
    out: &str,
    timeline: &PoseTimeline,
    posed: &PosedSkeleton,
    initial: &InitialPose,
    names: &Query<(Option<&Name>, Option<&ChildOf>, Has<AnimationPlayer>)>,
    server: &AssetServer,
) -> Result<(Handle<AnimationClip>, usize), String> {
    let glb = timeline
        .export_glb("authored", posed, |e| node_of(names, e), Some(&initial.0))
        .map_err(|e| e.to_string())?;
    let channels = gltf::Gltf::from_slice(&glb)
        .map_err(|e| e.to_string())?
        .document
        .animations()
        .map(|a| a.channels().count())
        .sum();
    std::fs::write(out, &glb).map_err(|e| format!("{out}: {e}"))?;
    let path = std::fs::canonicalize(out).map_err(|e| format!("{out}: {e}"))?;
    let clip = server
        .load(GltfAssetLabel::Animation(0).from_asset(bevy::asset::AssetPath::from_path_buf(path)));
    Ok((clip, channels))
}

/// The key times, then the times halfway between keys.
fn check_times(clip: &PoseClip) -> Vec<f32> {
    let keys = clip.times();
    let mids = keys.windows(2).map(|w| (w[0] + w[1]) / 2.0);
    keys.iter().copied().chain(mids).collect()
}

fn report(clip: &PoseClip, channels: usize, errors: &[(f32, f32)]) {
    let keys = clip.times();
    let at_keys = errors
        .iter()
        .filter(|(t, _)| keys.contains(t))
        .map(|e| e.1)
        .fold(0.0f32, f32::max);
    let at_mids = errors
        .iter()
        .filter(|(t, _)| !keys.contains(t))
        .map(|e| e.1)
        .fold(0.0f32, f32::max);
    println!(
        "{{\"keys\": {}, \"channels\": {channels}, \"playback_max_error_rad\": {at_keys:e}, \"playback_mid_error_rad\": {at_mids:e}}}",
        keys.len()
    );
}

fn fail(exit: &mut MessageWriter<AppExit>, why: &str) {
    eprintln!("author demo failed: {why}");
    exit.write(AppExit::error());
}
