//! Saving poses: a RON pose file (joint name → local transform) and a one-keyframe glTF
//! animation clip that Bevy's glTF loader plays on the same character.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DQuat, DVec3};
use gltf_json as json;
use json::validation::{Checked, USize64};
use serde::{Deserialize, Serialize};

use super::skeleton::{JointTransform, Skeleton, SkeletonPose};

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

fn io_error(path: &Path, e: std::io::Error) -> PoseFileError {
    PoseFileError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Writes a binary glTF (`.glb`) holding one animation clip called `clip_name` with a single
/// keyframe per track: each track is the path of node names from the animation root (the
/// node whose entity carries the `AnimationPlayer`, its own name first) down to a joint, and
/// the joint's local transform.
///
/// Bevy's glTF loader targets a clip's curves by exactly that name path
/// (`AnimationTargetId::from_names`), so the clip loaded from this file (`Animation0`)
/// plays on the character the paths were read from, and on any other instance of it. The
/// file's nodes carry the same transforms, so it also shows the pose as a plain scene.
pub fn write_gltf_pose_clip(
    clip_name: &str,
    tracks: &[(Vec<String>, JointTransform)],
) -> Result<Vec<u8>, PoseFileError> {
    let mut root = json::Root::default();
    // Node trie over the name paths.
    let mut node_of: BTreeMap<Vec<String>, u32> = BTreeMap::new();
    let mut children: Vec<Vec<u32>> = Vec::new();
    let mut top: Vec<u32> = Vec::new();
    let mut transforms: Vec<Option<JointTransform>> = Vec::new();
    for (path, t) in tracks {
        if path.is_empty() {
            return Err(PoseFileError::EmptyPath);
        }
        let (t_ok, r_ok) = (
            t.translation.is_finite() && t.scale.is_finite(),
            t.rotation.is_finite(),
        );
        if !(t_ok && r_ok) {
            return Err(PoseFileError::NonFinite(path.join("/")));
        }
        for depth in 1..=path.len() {
            let key = path[..depth].to_vec();
            if let std::collections::btree_map::Entry::Vacant(slot) = node_of.entry(key) {
                let index = children.len() as u32;
                slot.insert(index);
                children.push(Vec::new());
                transforms.push(None);
                if depth == 1 {
                    top.push(index);
                } else {
                    children[node_of[&path[..depth - 1]] as usize].push(index);
                }
            }
        }
        transforms[node_of[path] as usize] = Some(*t);
    }
    let mut names = vec![String::new(); children.len()];
    for (path, &i) in &node_of {
        names[i as usize] = path.last().cloned().unwrap_or_default();
    }
    for (i, name) in names.into_iter().enumerate() {
        let t = transforms[i];
        root.nodes.push(json::Node {
            name: Some(name),
            children: (!children[i].is_empty())
                .then(|| children[i].iter().map(|&c| json::Index::new(c)).collect()),
            translation: t.map(|t| t.translation.as_vec3().to_array()),
            rotation: t
                .map(|t| json::scene::UnitQuaternion(t.rotation.normalize().as_quat().to_array())),
            scale: t.map(|t| t.scale.as_vec3().to_array()),
            ..Default::default()
        });
    }
    root.scenes.push(json::Scene {
        name: Some("Pose".into()),
        nodes: top.iter().map(|&i| json::Index::new(i)).collect(),
        extensions: None,
        extras: Default::default(),
    });
    root.scene = Some(json::Index::new(0));

    // Binary data: time 0, then per track translation (3), rotation (4), scale (3) floats.
    let mut bin: Vec<u8> = Vec::new();
    let push = |bin: &mut Vec<u8>, values: &[f32]| {
        let offset = bin.len();
        for v in values {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        offset
    };
    let accessor = |root: &mut json::Root,
                    offset: usize,
                    count: usize,
                    kind: json::accessor::Type,
                    minmax: Option<f32>| {
        let width = match kind {
            json::accessor::Type::Scalar => 1,
            json::accessor::Type::Vec3 => 3,
            _ => 4,
        };
        let view = root.buffer_views.len() as u32;
        root.buffer_views.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64((count * width * 4) as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: None,
            name: None,
            target: None,
            extensions: None,
            extras: Default::default(),
        });
        root.accessors.push(json::Accessor {
            buffer_view: Some(json::Index::new(view)),
            byte_offset: None,
            count: USize64(count as u64),
            component_type: Checked::Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::F32,
            )),
            type_: Checked::Valid(kind),
            min: minmax.map(|v| json::Value::from(vec![v])),
            max: minmax.map(|v| json::Value::from(vec![v])),
            name: None,
            normalized: false,
            sparse: None,
            extensions: None,
            extras: Default::default(),
        });
        json::Index::<json::Accessor>::new(root.accessors.len() as u32 - 1)
    };
    let time_offset = push(&mut bin, &[0.0]);
    let time = accessor(
        &mut root,
        time_offset,
        1,
        json::accessor::Type::Scalar,
        Some(0.0),
    );
    let mut animation = json::Animation {
        name: Some(clip_name.to_string()),
        channels: Vec::new(),
        samplers: Vec::new(),
        extensions: None,
        extras: Default::default(),
    };
    for (path, t) in tracks {
        let node = json::Index::new(node_of[path]);
        let r = t.rotation.normalize().as_quat();
        let outputs = [
            (
                json::animation::Property::Translation,
                t.translation.as_vec3().to_array().to_vec(),
                json::accessor::Type::Vec3,
            ),
            (
                json::animation::Property::Rotation,
                r.to_array().to_vec(),
                json::accessor::Type::Vec4,
            ),
            (
                json::animation::Property::Scale,
                t.scale.as_vec3().to_array().to_vec(),
                json::accessor::Type::Vec3,
            ),
        ];
        for (property, values, kind) in outputs {
            let offset = push(&mut bin, &values);
            let output = accessor(&mut root, offset, 1, kind, None);
            animation.samplers.push(json::animation::Sampler {
                input: time,
                interpolation: Checked::Valid(json::animation::Interpolation::Step),
                output,
                extensions: None,
                extras: Default::default(),
            });
            animation.channels.push(json::animation::Channel {
                sampler: json::Index::new(animation.samplers.len() as u32 - 1),
                target: json::animation::Target {
                    node,
                    path: Checked::Valid(property),
                    extensions: None,
                    extras: Default::default(),
                },
                extensions: None,
                extras: Default::default(),
            });
        }
    }
    root.animations.push(animation);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.buffers.push(json::Buffer {
        byte_length: USize64(bin.len() as u64),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    root.asset.generator = Some("bevy_wii_deform".into());
    let text =
        json::serialize::to_vec(&root).map_err(|e| PoseFileError::Serialize(e.to_string()))?;
    Ok(crate::deform::glb_container(text, bin))
}
