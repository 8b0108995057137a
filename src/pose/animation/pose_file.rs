//! Saving poses as RON pose files (joint name → local transform). glTF clips are in
//! [`crate::pose::animation::gltf_clip`].

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::pose::rig::skeleton::{JointTransform, Skeleton, SkeletonPose};

/// Why a pose file or clip could not be read or written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseFileError {
    /// Reading or writing the file failed.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// The text is not a valid pose file.
    #[error("not a pose file: {0}")]
    Parse(String),
    /// A joint's transform in the file is NaN/infinite (or its rotation is zero).
    #[error("joint {0:?} has a non-finite transform")]
    NonFinite(String),
    /// No joint of the file is a joint of the skeleton.
    #[error("no joint in the file matches the skeleton")]
    NoMatchingJoint,
    /// A clip track has an empty node path.
    #[error("a clip track has an empty node path")]
    EmptyPath,
    /// The clip could not be serialised.
    #[error("could not write the clip: {0}")]
    Serialize(String),
    /// A pose library name that is not a plain file name.
    #[error("{0:?} is not a pose name (letters, digits, spaces, '-', '_', '.')")]
    BadName(String),
}

/// One joint's local transform in a [`PoseFile`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseFileJoint {
    /// Translation relative to the parent joint.
    pub translation: [f64; 3],
    /// Rotation quaternion `[x, y, z, w]`.
    pub rotation: [f64; 4],
    /// Scale.
    #[serde(default = "unit_scale")]
    pub scale: [f64; 3],
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}

/// A saved pose: joint name → local transform, as RON. Joints are matched by name when the
/// pose is applied, so a pose saved on one instance of a character loads on any other.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PoseFile {
    /// Local transforms by joint name.
    pub joints: BTreeMap<String, PoseFileJoint>,
}

impl PoseFile {
    /// The pose of every joint of `skeleton`.
    pub fn from_pose(skeleton: &Skeleton, pose: &SkeletonPose) -> Self {
        let joints = skeleton
            .joints()
            .iter()
            .zip(&pose.local)
            .map(|(j, t)| {
                let joint = PoseFileJoint {
                    translation: t.translation.to_array(),
                    rotation: t.rotation.to_array(),
                    scale: t.scale.to_array(),
                };
                (j.name.clone(), joint)
            })
            .collect();
        Self { joints }
    }

    /// Applies the file to `base`: joints named in the file take its transform, the others
    /// keep theirs, names the skeleton does not have are ignored. Rotations are normalised.
    /// Errors: a non-finite entry, or no matching joint at all.
    pub fn apply(
        &self,
        skeleton: &Skeleton,
        base: &SkeletonPose,
    ) -> Result<SkeletonPose, PoseFileError> {
        let mut out = base.clone();
        let mut matched = 0;
        for (name, entry) in &self.joints {
            let Some(j) = skeleton.find(name) else {
                continue;
            };
            let t = JointTransform {
                translation: DVec3::from_array(entry.translation),
                rotation: DQuat::from_array(entry.rotation),
                scale: DVec3::from_array(entry.scale),
            };
            let length = t.rotation.length();
            if !(t.translation.is_finite()
                && t.scale.is_finite()
                && length.is_finite()
                && length > 1e-9)
            {
                return Err(PoseFileError::NonFinite(name.clone()));
            }
            if let Some(slot) = out.local.get_mut(j) {
                *slot = JointTransform {
                    rotation: t.rotation / length,
                    ..t
                };
                matched += 1;
            }
        }
        if matched == 0 {
            return Err(PoseFileError::NoMatchingJoint);
        }
        Ok(out)
    }

    /// The file as pretty RON text.
    pub fn to_ron(&self) -> Result<String, PoseFileError> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default())
            .map_err(|e| PoseFileError::Serialize(e.to_string()))
    }

    /// Parses RON text.
    pub fn from_ron(text: &str) -> Result<Self, PoseFileError> {
        ron::from_str(text).map_err(|e| PoseFileError::Parse(e.to_string()))
    }

    /// Writes the file.
    pub fn save(&self, path: &Path) -> Result<(), PoseFileError> {
        std::fs::write(path, self.to_ron()?).map_err(|e| io_error(path, e))
    }

    /// Reads a file.
    pub fn load(path: &Path) -> Result<Self, PoseFileError> {
        let text = std::fs::read_to_string(path).map_err(|e| io_error(path, e))?;
        Self::from_ron(&text)
    }
}

pub(crate) fn io_error(path: &Path, e: std::io::Error) -> PoseFileError {
    PoseFileError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}
