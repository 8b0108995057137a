//! What a retarget reads: a clip made for another skeleton, with that skeleton and its rest
//! pose — from a BVH file (motion capture) or from a glTF/GLB character's animation.

use std::path::{Path, PathBuf};

use crate::pose::animation::bvh::{BvhError, read_bvh};
use crate::pose::animation::clip::{ClipError, PoseClip};
use crate::pose::animation::gltf_clip::read_gltf_clip;
use crate::pose::rig::gltf_character::{CharacterReadError, GltfCharacter};
use crate::pose::rig::gltf_file::GltfFile;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};

/// A clip with the skeleton it was made for.
#[derive(Debug, Clone)]
pub struct SourceMotion {
    /// The source's skeleton.
    pub skeleton: Skeleton,
    /// Its rest pose (the pose its clip's rotations are relative to when carried over).
    pub rest: SkeletonPose,
    /// The clip.
    pub clip: PoseClip,
}

/// Why a retarget's source could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SourceError {
    /// The file could not be read.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        message: String,
    },
    /// A BVH file that does not parse.
    #[error(transparent)]
    Bvh(#[from] BvhError),
    /// A glTF/GLB file without a readable skinned character.
    #[error(transparent)]
    Character(#[from] CharacterReadError),
    /// The glTF file's animation cannot be read (none by that name, bad accessors, …).
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// Reads the source of a retarget from `path`: a `.bvh` file, or any other file as glTF/GLB —
/// its first skinned character and the animation named `animation` (the first when `None`).
/// A malformed file is a typed error, never a panic.
pub fn read_source_motion(
    path: &Path,
    animation: Option<&str>,
) -> Result<SourceMotion, SourceError> {
    let io = |e: std::io::Error| SourceError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bvh"))
    {
        let motion = read_bvh(&std::fs::read_to_string(path).map_err(io)?)?;
        return Ok(SourceMotion {
            skeleton: motion.skeleton,
            rest: motion.rest,
            clip: motion.clip,
        });
    }
    let bytes = std::fs::read(path).map_err(io)?;
    let file = GltfFile::parse(&bytes, path.parent()).map_err(CharacterReadError::from)?;
    let character = GltfCharacter::from_file(&file)?;
    let clip = read_gltf_clip(
        &bytes,
        path.parent(),
        animation,
        &character.skeleton,
        &character.rest,
    )?;
    Ok(SourceMotion {
        skeleton: character.skeleton,
        rest: character.rest,
        clip,
    })
}
