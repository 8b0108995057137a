//! Clips made for another skeleton played on yours — motion capture (BVH), another rig's glTF
//! clips — with the feet kept planted and on the ground in the same step, through the pose
//! solver, instead of a foot-IK pass afterwards.
//!
//! | question | file |
//! |---|---|
//! | which target joints follow which source joints: humanoids by role, anything by chains in RON | `mapping.rs` ([`SkeletonMap`]) |
//! | one source pose carried over: rotations relative to each rest pose, bones re-aimed, the root scaled by the legs | `transfer.rs` ([`PoseTransfer`]) |
//! | where the source's feet are planted, read off the clip (height and speed thresholds) | `contacts.rs` ([`detect_contacts`]) |
//! | reading a source: a BVH file or a glTF character's animation | `source.rs` ([`read_source_motion`]) |
//! | a whole clip baked through the solver (feet held, skin above the ground), and how well it went | `bake.rs` ([`Retargeter`], [`RetargetQuality`]) |
//! | a live source retargeted frame by frame, its contacts read as the frames come | `live.rs` ([`LiveRetarget`]) |
//!
//! The top layer of [`crate::pose`]: it uses the rig, the ground, the constraints, the solver
//! and the animation layers, and none of them uses it.
//!
//! ```no_run
//! # use std::sync::Arc;
//! # use bevy_wii_deform::pose::*;
//! # use bevy_wii_deform::pose::retarget::*;
//! # fn run() -> Result<(), Box<dyn std::error::Error>> {
//! let source = read_bvh(&std::fs::read_to_string("walk.bvh")?)?;
//! let target = GltfCharacter::read(std::path::Path::new("character.glb"))?;
//! let model = Arc::new(target.model(ModelSettings::default())?);
//! let map = SkeletonMap::humanoid((&source.skeleton, &source.rest), (&target.skeleton, &target.rest))?;
//! let retargeter = Retargeter::new((&source.skeleton, &source.rest), model, &target.rest, map, RetargetSettings::default())?;
//! let baked = retargeter.bake(&source.clip, &retargeter.rest_ground())?;
//! let glb = write_gltf_clip(&baked.clip, "walk", &[/* the joints' node paths */], Some(&target.rest))?;
//! # Ok(()) }
//! ```

mod bake;
mod contacts;
mod live;
mod mapping;
mod source;
mod transfer;

pub use bake::{RetargetQuality, RetargetSettings, RetargetedClip, Retargeter};
pub use contacts::{ContactThresholds, SourceContacts, detect_contacts};
pub use live::{LiveFrame, LiveRetarget};
pub use mapping::{ChainFile, ChainMapFile, ChainPair, SkeletonMap, Which};
pub use source::{SourceError, SourceMotion, read_source_motion};
pub use transfer::{PoseTransfer, RootMotion};

use crate::pose::animation::clip::ClipError;
use crate::pose::error::PoseError;

/// Why a retarget could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RetargetError {
    /// A humanoid map needs a joint role the skeleton does not have (by its names).
    #[error("the {which:?} skeleton has no {role} (by its joints' names)")]
    MissingRole {
        /// The role (`left thigh`, `hips`, `head`, …).
        role: &'static str,
        /// Which skeleton.
        which: Which,
    },
    /// A chain map names a joint the skeleton does not have.
    #[error("chain {chain:?}: the {which:?} skeleton has no joint {joint:?}")]
    ChainJoint {
        /// The chain.
        chain: String,
        /// The joint's name.
        joint: String,
        /// Which skeleton.
        which: Which,
    },
    /// A chain lists no joints on one side.
    #[error("chain {0:?} has no joints on one side")]
    EmptyChain(String),
    /// A chain map file does not parse.
    #[error("the chain map does not parse: {0}")]
    MapFile(String),
    /// The clip has no keys.
    #[error("the clip has no keys")]
    EmptyClip,
    /// A frame's solve gave a non-finite pose.
    #[error("a frame's solve gave a non-finite pose")]
    NonFiniteSolve,
    /// A skeleton, pose or model is invalid.
    #[error(transparent)]
    Pose(#[from] PoseError),
    /// The baked clip is invalid.
    #[error(transparent)]
    Clip(#[from] ClipError),
}
