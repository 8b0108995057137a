//! Authoring keyframed clips on a character: a [`PoseTimeline`] holds a
//! [`PoseClip`](crate::pose::PoseClip), the time it is shown at, and playback; the plugin
//! shows the clip's pose at that time on the character (in
//! [`PoseSystems::Timeline`](super::PoseSystems::Timeline)).

use std::path::Path;

use bevy::prelude::*;

use super::PosedSkeleton;
use crate::pose::{
    ClipError, KEY_TIME_EPSILON, KeyInterpolation, PoseClip, SkeletonPose, read_gltf_clip,
    write_gltf_clip,
};

/// A clip being authored on a [`Poseable`](super::Poseable) character. Whenever the timeline
/// changes (scrubbed, a key set or moved, playing), the plugin writes the clip's pose at
/// `time` to [`PosedSkeleton::pose`]; between changes the character is posed as usual (grab
/// it, then [`PoseTimeline::set_key`] to key the result). An empty clip shows nothing.
#[derive(Component, Debug, Clone, PartialEq)]
pub struct PoseTimeline {
    /// The keys.
    pub clip: PoseClip,
    /// The time shown, seconds.
    pub time: f32,
    /// Advancing `time` by `speed` × the frame time.
    pub playing: bool,
    /// At the end, start again (else stop there).
    pub looping: bool,
    /// Playback speed (1 = real time).
    pub speed: f32,
    /// How new keys interpolate to the next.
    pub interpolation: KeyInterpolation,
}

impl Default for PoseTimeline {
    fn default() -> Self {
        Self {
            clip: PoseClip::new(),
            time: 0.0,
            playing: false,
            looping: true,
            speed: 1.0,
            interpolation: KeyInterpolation::Linear,
        }
    }
}

impl PoseTimeline {
    /// Keys the character's current pose at `time` (replacing a key there); returns its index.
    pub fn set_key(&mut self, posed: &PosedSkeleton) -> Result<usize, ClipError> {
        self.clip
            .set_key(self.time, posed.pose.clone(), self.interpolation)
    }

    /// The key at `time` (within [`KEY_TIME_EPSILON`]), if any.
    pub fn key_at_time(&self) -> Option<usize> {
        self.clip
            .keys()
            .iter()
            .position(|k| (k.time - self.time).abs() <= KEY_TIME_EPSILON)
    }

    /// Deletes the key at `time`; false when there is none.
    pub fn delete_key_at_time(&mut self) -> bool {
        self.key_at_time()
            .is_some_and(|i| self.clip.remove_key(i).is_ok())
    }

    /// Advances playback by `seconds` of frame time (looping or stopping at the end).
    pub fn advance(&mut self, seconds: f32) {
        if !self.playing {
            return;
        }
        let duration = self.clip.duration();
        if duration <= 0.0 {
            self.playing = false;
            return;
        }
        self.time += seconds * self.speed;
        if self.time > duration {
            if self.looping {
                self.time %= duration;
            } else {
                self.time = duration;
                self.playing = false;
            }
        }
    }

    /// The clip's pose at `time` for this character (`None` for an empty clip, or a clip keyed
    /// on another skeleton).
    pub fn pose_now(&self, posed: &PosedSkeleton) -> Option<SkeletonPose> {
        self.clip
            .sample(self.time)
            .filter(|p| posed.model.skeleton().check_pose(p).is_ok())
    }

    /// The clip as a glTF (`.glb`) animation called `name` for this character: `node` gives
    /// the joints' node paths (see [`PosedSkeleton::joint_paths`]); properties that never
    /// leave `rest` (e.g. the pose the character was loaded in) are left out.
    pub fn export_glb(
        &self,
        name: &str,
        posed: &PosedSkeleton,
        node: impl Fn(Entity) -> (Option<String>, Option<Entity>, bool),
        rest: Option<&SkeletonPose>,
    ) -> Result<Vec<u8>, ClipError> {
        write_gltf_clip(&self.clip, name, &posed.joint_paths(node), rest)
    }

    /// Replaces the clip by animation `animation` (the first when `None`) of a glTF file, read
    /// for this character (joints without channels at its current pose). On an error the
    /// timeline is unchanged.
    pub fn import_gltf(
        &mut self,
        path: &Path,
        animation: Option<&str>,
        posed: &PosedSkeleton,
    ) -> Result<(), ClipError> {
        let bytes = std::fs::read(path).map_err(|e| {
            ClipError::File(crate::pose::rig::gltf_file::GltfFileError::Io {
                path: path.display().to_string(),
                message: e.to_string(),
            })
        })?;
        let clip = read_gltf_clip(
            &bytes,
            path.parent(),
            animation,
            posed.model.skeleton(),
            &posed.pose,
        )?;
        self.clip = clip;
        self.time = self.time.clamp(0.0, self.clip.duration());
        Ok(())
    }
}
