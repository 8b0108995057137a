//! Clips made for another skeleton played on a character: [`Retarget`] on a [`Poseable`]
//! character names the source (a BVH file, or a glTF/GLB character's animation) and, for
//! skeletons that are not humanoids by their names, a chain map; [`RetargetPlugin`] reads it,
//! bakes it through the pose solver on a background task ([`crate::pose::retarget`]: the
//! feet kept planted and on the ground) and puts the result into `Assets<AnimationClip>`,
//! keyed to the character's own joints — a clip Bevy's `AnimationPlayer` and animation graphs
//! play and blend like any other, and the crate's [`PoseBlend`](crate::ecs::PoseBlend) layers
//! over. [`RetargetStatus`] says how it went; [`RetargetReady`] and [`RetargetFailed`] say when.
//!
//! | question | file |
//! |---|---|
//! | what a retarget asks for, what it reports, its messages and errors | `mod.rs` |
//! | the systems: starting a bake, collecting it, building the `AnimationClip` | `plugin.rs` |
//!
//! [`Poseable`]: crate::ecs::Poseable

mod plugin;

use std::path::PathBuf;

use bevy::animation::AnimationClip;
use bevy::prelude::*;

use crate::pose::retarget::{RetargetError, RetargetSettings, SourceError};

pub use plugin::{RetargetPlugin, RetargetSystems};

/// Plays a clip made for another skeleton on this [`Poseable`](crate::ecs::Poseable) character.
/// Once the character is prepared the plugin reads [`Retarget::source`], maps its skeleton to
/// the character's (humanoids by their joints' names, anything else by [`Retarget::map`]),
/// bakes every frame through the pose solver with the source's planted feet held on a flat
/// ground under the character's rest pose, and stores the clip in [`RetargetStatus::clip`].
/// Changing the component bakes again. The character's pose when it was prepared is its rest
/// (the scene's node transforms, before a clip plays).
#[derive(Component, Debug, Clone, PartialEq)]
#[require(RetargetStatus)]
pub struct Retarget {
    /// The source file: `.bvh` (motion capture), or a glTF/GLB file whose first skinned
    /// character and its animation are the source.
    pub source: PathBuf,
    /// The glTF animation by name (`None`: the first); ignored for BVH.
    pub animation: Option<String>,
    /// A chain map in RON ([`crate::pose::retarget::ChainMapFile`]) for skeletons that are not
    /// humanoids by name; `None`: the humanoid map by joint roles.
    pub map: Option<PathBuf>,
    /// How the clip is retargeted (root motion, contacts, iterations).
    pub settings: RetargetSettings,
}

impl Retarget {
    /// The humanoid retarget of `source`'s first animation with the default settings.
    pub fn new(source: impl Into<PathBuf>) -> Self {
        Self {
            source: source.into(),
            animation: None,
            map: None,
            settings: RetargetSettings::default(),
        }
    }

    /// The source's animation named `name`.
    pub fn animation(mut self, name: impl Into<String>) -> Self {
        self.animation = Some(name.into());
        self
    }

    /// Maps the skeletons by the chain map at `path` instead of by humanoid roles.
    pub fn map(mut self, path: impl Into<PathBuf>) -> Self {
        self.map = Some(path.into());
        self
    }
}

/// Where a [`Retarget`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum RetargetPhase {
    /// Waiting for the character to be prepared.
    #[default]
    Waiting,
    /// Reading and baking in the background.
    Baking,
    /// The clip is in [`RetargetStatus::clip`].
    Ready,
    /// It failed: [`RetargetStatus::error`] says why; the character keeps whatever it played.
    Failed,
}

/// How a character's [`Retarget`] went (inserted with it).
#[derive(Component, Debug, Clone, Default)]
pub struct RetargetStatus {
    /// Where it is.
    pub phase: RetargetPhase,
    /// The baked clip, keyed to the character's joints (their `AnimationTargetId`s).
    pub clip: Option<Handle<AnimationClip>>,
    /// Why it failed.
    pub error: Option<RetargetLoadError>,
    /// Frames baked.
    pub frames: usize,
    /// Frames whose solve failed (their carried-over pose was kept).
    pub failed_solves: usize,
    /// The character's joints the map left at their rest pose, by name.
    pub unmapped: Vec<String>,
    /// Per foot of the map (target joint name), the share of the source's frames it was planted.
    pub planted_share: Vec<(String, f32)>,
    /// Per foot of the map, when the source's foot is planted in the clip (what the bake holds
    /// the character's foot to, with contacts on): to show contacts beside the playing clip.
    pub feet: Vec<RetargetFoot>,
}

/// One foot of a retarget: the character's foot joint and the clip's times the source's foot
/// is planted.
#[derive(Debug, Clone, PartialEq)]
pub struct RetargetFoot {
    /// The character's foot joint entity.
    pub joint: Entity,
    /// Its name.
    pub name: String,
    /// The clip's time spans (seconds, start and end) while the source's foot is planted.
    pub planted: Vec<(f32, f32)>,
}

impl RetargetFoot {
    /// Whether the source's foot is planted at `time` (clip seconds).
    pub fn planted_at(&self, time: f32) -> bool {
        self.planted
            .iter()
            .any(|&(start, end)| (start..=end).contains(&time))
    }
}

/// Why a [`Retarget`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RetargetLoadError {
    /// The source could not be read.
    #[error("the source: {0}")]
    Source(#[from] SourceError),
    /// The chain map could not be read.
    #[error("the chain map {path}: {message}")]
    MapFile {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The skeletons could not be mapped, or the bake failed.
    #[error(transparent)]
    Retarget(#[from] RetargetError),
    /// No joint of the character carries an `AnimationTargetId` (a skeleton not spawned from
    /// a glTF scene, or without names): an `AnimationClip` could not address it.
    #[error("no joint of the character has an AnimationTargetId")]
    NoAnimationTargets,
}

/// A [`Retarget`]'s clip is ready ([`RetargetStatus::clip`]).
#[derive(Message, Debug, Clone)]
pub struct RetargetReady {
    /// The character.
    pub entity: Entity,
    /// The clip.
    pub clip: Handle<AnimationClip>,
}

/// A [`Retarget`] failed ([`RetargetStatus::error`]).
#[derive(Message, Debug, Clone)]
pub struct RetargetFailed {
    /// The character.
    pub entity: Entity,
    /// Why.
    pub error: RetargetLoadError,
}
