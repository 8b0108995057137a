//! `--author-demo OUT.glb`: authoring checked end to end, unattended. Once the character is
//! ready it is posed three times by scripted grabs (the head up, the tail aside, the head
//! down and over), each pose keyed on the timeline at 0, 0.5 and 1 s (linear keys); the clip
//! is exported to OUT.glb — a **clip-only glTF** whose nodes are named and nested as the
//! character's joints from its animation root, so Bevy's loader targets the same joints (the
//! model file is left alone) — then loaded back through Bevy's glTF loader and played on the
//! character. The last stdout line is JSON: the keys, the channels written, and the largest
//! joint-rotation error of the playback at the key times and halfway between keys (against
//! the clip's own linear interpolation).

use bevy::ecs::system::SystemParam;
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

/// The three scripted grabs: a point (fraction of the height from the top, which end along
/// the body) and a drag (fractions of the size).
const GRABS: [(f32, f32, Vec3); 3] = [
    (0.05, 1.0, Vec3::new(0.0, 0.08, 0.03)),
    (0.3, -1.0, Vec3::new(0.10, 0.04, 0.0)),
    (0.05, 1.0, Vec3::new(-0.06, -0.07, 0.0)),
];

/// Where the script is.
#[derive(Default)]
enum Step {
    /// Waiting for the character.
    #[default]
    Waiting,
    /// Dragging grab `k`.
    Posing(Drag),
    /// The clip is exported and loading back.
    Loading(Playback),
    /// Sampling the playback at the check times.
    Checking(Playback),
    Done,
}

/// A scripted drag: grab `k`, its handle, the drag, the frame it started.
struct Drag {
    k: usize,
    handle: Entity,
    shift: Vec3,
    since: u32,
}

/// The exported clip played back: what was authored, the joints, the channels written, the
/// player, and the errors measured so far.
struct Playback {
    clip: Handle<AnimationClip>,
    authored: PoseClip,
    joints: Vec<Entity>,
    channels: usize,
    player: Option<(Entity, AnimationNodeIndex)>,
    next: usize,
    wait: u32,
    errors: Vec<(f32, f32)>,
}

#[derive(Default)]
struct Script {
    frame: u32,
    step: Step,
}

/// What the script reads and drives.
#[derive(SystemParam)]
struct Author<'w, 's> {
    commands: Commands<'w, 's>,
    args: Res<'w, Args>,
    server: Res<'w, AssetServer>,
    clips: Res<'w, Assets<AnimationClip>>,
    graphs: ResMut<'w, Assets<AnimationGraph>>,
    character: Query<
        'w,
        's,
        (
            Entity,
            &'static PosedSkeleton,
            &'static mut PoseTimeline,
            &'static InitialPose,
            &'static PoseStatus,
        ),
        With<Character>,
    >,
    handles: Query<'w, 's, (&'static DeformHandle, &'static mut Transform)>,
    names: Query<
        'w,
        's,
        (
            Option<&'static Name>,
            Option<&'static ChildOf>,
            Has<AnimationPlayer>,
        ),
    >,
    players: Query<'w, 's, (Entity, &'static mut AnimationPlayer)>,
    joints: Query<'w, 's, &'static Transform, Without<DeformHandle>>,
    exit: MessageWriter<'w, AppExit>,
}

fn author(mut script: Local<Script>, mut a: Author) {
    let Some(out) = a.args.author_demo.clone() else {
        return;
    };
    script.frame += 1;
    let frame = script.frame;
    script.step = match std::mem::take(&mut script.step) {
        Step::Waiting => a.waiting(frame),
        Step::Posing(drag) => a.posing(frame, drag, &out),
        Step::Loading(playback) => a.loading(frame, playback),
        Step::Checking(playback) => a.checking(playback),
        Step::Done => Step::Done,
    };
}

impl Author<'_, '_> {
    fn waiting(&mut self, frame: u32) -> Step {
        match self.character.iter().next() {
            Some((entity, posed, ..)) if frame > 10 => {
                let posed = posed.clone();
                Step::Posing(self.start_grab(entity, &posed, 0, frame))
            }
            _ => Step::Waiting,
        }
    }

    /// Drags; once the pose has settled, keys it and starts the next grab or the export.
    fn posing(&mut self, frame: u32, drag: Drag, out: &str) -> Step {
        let Ok((entity, posed, mut timeline, initial, status)) = self.character.single_mut() else {
            return self.fail("the character went away");
        };
        let s = ((frame - drag.since) as f32 / DRAG_FRAMES as f32).min(1.0);
        if let Ok((h, mut t)) = self.handles.get_mut(drag.handle)
            && let Some(pivot) = h.pivot
        {
            // Only a real move is a change (a change starts a solve).
            t.set_if_neq(Transform::from_translation(pivot + drag.shift * s));
        }
        let settled =
            frame > drag.since + DRAG_FRAMES + SETTLE_FRAMES && status.phase == DeformPhase::Idle;
        if !settled {
            return Step::Posing(drag);
        }
        timeline.time = 0.5 * drag.k as f32;
        if let Err(e) = timeline.set_key(posed) {
            return self.fail(&format!("key refused: {e}"));
        }
        let (posed, timeline, initial) = (posed.clone(), timeline.clone(), initial.0.clone());
        self.commands.entity(drag.handle).despawn();
        if drag.k + 1 < GRABS.len() {
            return Step::Posing(self.start_grab(entity, &posed, drag.k + 1, frame));
        }
        match self.export(out, &timeline, &posed, &initial) {
            Ok((clip, channels)) => {
                // The loaded clip drives the joints from now on.
                self.commands
                    .entity(entity)
                    .remove::<(Poseable, PosedSkeleton, PoseTimeline)>();
                Step::Loading(Playback {
                    clip,
                    authored: timeline.clip,
                    joints: posed.joints,
                    channels,
                    player: None,
                    next: 0,
                    wait: 0,
                    errors: Vec::new(),
                })
            }
            Err(e) => self.fail(&e),
        }
    }

    /// Waits for the exported clip, then plays it (paused) on the model's player.
    fn loading(&mut self, frame: u32, mut playback: Playback) -> Step {
        if self.clips.get(&playback.clip).is_none() {
            if frame > 3000 {
                return self.fail("the exported clip never loaded");
            }
            return Step::Loading(playback);
        }
        let Some((player, mut p)) = self.players.iter_mut().next() else {
            return self.fail("the model has no AnimationPlayer");
        };
        let (graph, node) = AnimationGraph::from_clip(playback.clip.clone());
        p.stop_all().play(node).pause();
        self.commands
            .entity(player)
            .insert(AnimationGraphHandle(self.graphs.add(graph)));
        playback.player = Some((player, node));
        Step::Checking(playback)
    }

    /// Seeks each check time, waits for the animation systems, measures the joints.
    fn checking(&mut self, mut playback: Playback) -> Step {
        let times = check_times(&playback.authored);
        let Some((player, node)) = playback.player else {
            return self.fail("no player");
        };
        let Ok((_, mut p)) = self.players.get_mut(player) else {
            return self.fail("the AnimationPlayer went away");
        };
        let t = times[playback.next];
        if let Some(active) = p.animation_mut(node) {
            active.set_seek_time(t).pause();
        }
        if playback.wait < 3 {
            playback.wait += 1;
            return Step::Checking(playback);
        }
        let expected = playback.authored.sample(t).unwrap_or_default();
        let worst = playback
            .joints
            .iter()
            .zip(&expected.local)
            .filter_map(|(&j, want)| {
                let now = self.joints.get(j).ok()?.rotation;
                Some(rotation_angle(now.as_dquat(), want.rotation) as f32)
            })
            .fold(0.0f32, f32::max);
        playback.errors.push((t, worst));
        playback.next += 1;
        playback.wait = 0;
        if playback.next < times.len() {
            return Step::Checking(playback);
        }
        report(&playback.authored, playback.channels, &playback.errors);
        self.exit.write(AppExit::Success);
        Step::Done
    }

    fn start_grab(
        &mut self,
        character: Entity,
        posed: &PosedSkeleton,
        k: usize,
        frame: u32,
    ) -> Drag {
        let (handle, shift) = start_grab(&mut self.commands, character, posed, k);
        Drag {
            k,
            handle,
            shift,
            since: frame,
        }
    }

    /// Exports the timeline to `out`, starts loading it back; the clip handle and the
    /// channels written.
    fn export(
        &self,
        out: &str,
        timeline: &PoseTimeline,
        posed: &PosedSkeleton,
        initial: &bevy_wii_deform::pose::SkeletonPose,
    ) -> Result<(Handle<AnimationClip>, usize), String> {
        let glb = timeline
            .export_glb(
                "authored",
                posed,
                |e| node_of(&self.names, e),
                Some(initial),
            )
            .map_err(|e| e.to_string())?;
        let channels = gltf::Gltf::from_slice(&glb)
            .map_err(|e| e.to_string())?
            .document
            .animations()
            .map(|a| a.channels().count())
            .sum();
        std::fs::write(out, &glb).map_err(|e| format!("{out}: {e}"))?;
        let path = std::fs::canonicalize(out).map_err(|e| format!("{out}: {e}"))?;
        let clip = self.server.load(
            GltfAssetLabel::Animation(0).from_asset(bevy::asset::AssetPath::from_path_buf(path)),
        );
        Ok((clip, channels))
    }

    fn fail(&mut self, why: &str) -> Step {
        eprintln!("author demo failed: {why}");
        self.exit.write(AppExit::error());
        Step::Done
    }
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
