//! Poses and clips as glTF animations: export a [`PoseClip`] (or one pose) as a binary glTF
//! that Bevy's glTF loader plays on the character, and import a file's animation as a
//! [`PoseClip`] to edit.
//!
//! **What the exported file holds.** A clip-only glTF: a node per joint, named as the joint
//! and nested along the *node path* from the animation root (the node whose entity carries
//! Bevy's `AnimationPlayer`, its own name first) down to the joint, and one animation. Bevy's
//! loader targets a clip's curves by exactly that name path (`AnimationTargetId::from_names`),
//! so the clip loaded from the file (`Animation0`) plays on the character the paths were read
//! from and on any other instance of it; the model file itself is left alone. The nodes carry
//! the first key's transforms, so the file also shows that pose as a plain scene.
//!
//! **Channels.** One channel per joint and property (translation, rotation, scale) that
//! changes across the keys or differs from the `rest` pose given to [`write_gltf_clip`]
//! (without a rest pose, every property is written). glTF has one interpolation per sampler:
//! when every key of the clip interpolates the same way the file uses that mode (cubic
//! splines with the clip's own tangents); a clip that mixes modes is resampled into a linear
//! one (cubic segments at 8 samples, step segments as a hold ending 1 ms before the next key).
//!
//! **Import.** [`read_gltf_clip`] reads one animation of a `.glb` or `.gltf` (external buffers
//! next to the file; `data:` URIs are not read): each channel must target a node named as a
//! joint of the skeleton ([`ClipError::UnknownJoint`] otherwise); morph-weight channels are
//! skipped. Keys are the union of the channels' times, each channel sampled there with its own
//! interpolation (cubic splines with the file's tangents); joints without channels keep the
//! `base` pose. Keys interpolate as the file's samplers do when they all agree, else linearly.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DQuat, DVec3, DVec4};
use gltf_json as json;
use json::animation::{Interpolation, Property};
use json::validation::{Checked, USize64};

use crate::pose::animation::clip::{
    ClipError, KEY_TIME_EPSILON, KeyInterpolation, MAX_CLIP_TRANSFORMS, PoseClip, PoseKey, hermite,
    sign_aligned,
};
use crate::pose::animation::pose_file::PoseFileError;
use crate::pose::rig::gltf_file::{AccessorUse, GltfFile, GltfFileError};
use crate::pose::rig::skeleton::{JointTransform, Skeleton, SkeletonPose};

/// Writes a binary glTF (`.glb`) holding one animation clip called `clip_name` with a single
/// keyframe per track: each track is a node path (see the [module docs](self)) and the
/// joint's local transform. The one-pose case of [`write_gltf_clip`].
pub fn write_gltf_pose_clip(
    clip_name: &str,
    tracks: &[(Vec<String>, JointTransform)],
) -> Result<Vec<u8>, PoseFileError> {
    let mut channels = Vec::with_capacity(tracks.len() * 3);
    for (track, (path, t)) in tracks.iter().enumerate() {
        if path.is_empty() {
            return Err(PoseFileError::EmptyPath);
        }
        if !(t.translation.is_finite() && t.scale.is_finite() && t.rotation.is_finite()) {
            return Err(PoseFileError::NonFinite(path.join("/")));
        }
        let r = t.rotation.normalize();
        channels.extend([
            Channel::of(track, Property::Translation, [t.translation.extend(0.0)]),
            Channel::of(track, Property::Rotation, [DVec4::from(r)]),
            Channel::of(track, Property::Scale, [t.scale.extend(0.0)]),
        ]);
    }
    let document = ClipDocument {
        name: clip_name,
        paths: tracks.iter().map(|(p, _)| p.as_slice()).collect(),
        nodes: tracks.iter().map(|(_, t)| *t).collect(),
        times: vec![0.0],
        interpolation: Interpolation::Step,
        channels,
    };
    document.encode().map_err(PoseFileError::Serialize)
}

/// Writes `clip` as a binary glTF (`.glb`) animation called `clip_name` (see the
/// [module docs](self) for what the file holds). `paths[j]` is joint `j`'s node path from the
/// animation root; `rest` (the character's rest or bind pose) lets properties that never
/// leave it go unwritten.
pub fn write_gltf_clip(
    clip: &PoseClip,
    clip_name: &str,
    paths: &[Vec<String>],
    rest: Option<&SkeletonPose>,
) -> Result<Vec<u8>, ClipError> {
    let joints = clip.joint_count().ok_or(ClipError::NoKeys)?;
    if paths.len() != joints || rest.is_some_and(|r| r.local.len() != joints) {
        return Err(ClipError::PathCount {
            paths: paths.len(),
            joints,
        });
    }
    if let Some(j) = paths.iter().position(|p| p.is_empty()) {
        return Err(ClipError::EmptyPath(j));
    }
    let samples = export_samples(clip);
    let mut channels = Vec::new();
    for j in 0..joints {
        let properties: [(Property, Vec<DVec4>, Option<DVec4>); 3] = [
            (
                Property::Translation,
                samples.column(j, |t| t.translation.extend(0.0)),
                rest.map(|r| r.local[j].translation.extend(0.0)),
            ),
            (
                Property::Rotation,
                sign_aligned(samples.poses.iter().map(|p| p.local[j].rotation)),
                rest.map(|r| DVec4::from(r.local[j].rotation)),
            ),
            (
                Property::Scale,
                samples.column(j, |t| t.scale.extend(0.0)),
                rest.map(|r| r.local[j].scale.extend(0.0)),
            ),
        ];
        for (property, values, rest) in properties {
            let f32s = |v: DVec4| v.as_vec4();
            let changes = values.windows(2).any(|w| f32s(w[0]) != f32s(w[1]));
            let at_rest = rest.is_some_and(|r| {
                let (v, r) = (f32s(values[0]), f32s(r));
                v == r || (property == Property::Rotation && v == -r)
            });
            if !changes && at_rest {
                continue;
            }
            let channel = if samples.interpolation == Interpolation::CubicSpline {
                let with_tangents = (0..values.len()).flat_map(|k| {
                    let m = PoseClip::auto_tangent(&samples.times, &values, k);
                    [m, values[k], m]
                });
                Channel::of(j, property, with_tangents)
            } else {
                Channel::of(j, property, values)
            };
            channels.push(channel);
        }
    }
    let document = ClipDocument {
        name: clip_name,
        paths: paths.iter().map(Vec::as_slice).collect(),
        nodes: clip.keys()[0].pose.local.clone(),
        times: samples.times,
        interpolation: samples.interpolation,
        channels,
    };
    document.encode().map_err(ClipError::Serialize)
}

/// Reads animation `animation` (by name; the first when `None`) of a glTF file's bytes as a
/// clip of `skeleton`'s poses, joints without channels at `base` (see the
/// [module docs](self)). `folder` is where a `.gltf`'s external buffers are looked for.
pub fn read_gltf_clip(
    bytes: &[u8],
    folder: Option<&Path>,
    animation: Option<&str>,
    skeleton: &Skeleton,
    base: &SkeletonPose,
) -> Result<PoseClip, ClipError> {
    skeleton
        .check_pose(base)
        .map_err(|_| ClipError::PoseLength {
            got: base.local.len(),
            expected: skeleton.len(),
        })?;
    let file = GltfFile::parse(bytes, folder)?;
    let found = file
        .document()
        .animations()
        .find(|a| animation.is_none_or(|name| a.name() == Some(name)));
    let Some(found) = found else {
        return Err(ClipError::NoAnimation(animation.map(str::to_string)));
    };
    let mut channels: Vec<ImportedChannel> = Vec::new();
    for channel in found.channels() {
        let property = match channel.target().property() {
            gltf::animation::Property::Translation => Property::Translation,
            gltf::animation::Property::Rotation => Property::Rotation,
            gltf::animation::Property::Scale => Property::Scale,
            gltf::animation::Property::MorphTargetWeights => continue,
        };
        let node = channel.target().node();
        let name = node
            .name()
            .map_or_else(|| format!("node {}", node.index()), str::to_string);
        let joint = skeleton
            .find(&name)
            .ok_or_else(|| ClipError::UnknownJoint(name.clone()))?;
        channels.push(ImportedChannel::read(
            &channel, &file, joint, &name, property,
        )?);
    }
    let mut times: Vec<f32> = channels.iter().flat_map(|c| c.times.clone()).collect();
    times.sort_by(f32::total_cmp);
    times.dedup_by(|b, a| *b - *a <= KEY_TIME_EPSILON);
    if times.len().saturating_mul(skeleton.len()) > MAX_CLIP_TRANSFORMS {
        return Err(ClipError::TooLarge {
            keys: times.len(),
            joints: skeleton.len(),
            limit: MAX_CLIP_TRANSFORMS,
        });
    }
    let modes: Vec<Interpolation> = channels.iter().map(|c| c.interpolation).collect();
    let interpolation = match modes.first() {
        Some(&m) if modes.iter().all(|&n| n == m) => match m {
            Interpolation::Step => KeyInterpolation::Step,
            Interpolation::CubicSpline => KeyInterpolation::CubicSpline,
            Interpolation::Linear => KeyInterpolation::Linear,
        },
        _ => KeyInterpolation::Linear,
    };
    let keys = times
        .iter()
        .map(|&time| {
            let mut pose = base.clone();
            for c in &channels {
                let v = c.sample(time);
                let t = &mut pose.local[c.joint];
                match c.property {
                    Property::Translation => t.translation = v.truncate(),
                    Property::Rotation => t.rotation = DQuat::from_vec4(v).normalize(),
                    _ => t.scale = v.truncate(),
                }
            }
            PoseKey {
                time,
                pose,
                interpolation,
            }
        })
        .collect();
    PoseClip::from_keys(keys)
}

/// The key times and poses a file is written from, and its one sampler mode.
struct ExportSamples {
    times: Vec<f32>,
    poses: Vec<SkeletonPose>,
    interpolation: Interpolation,
}

impl ExportSamples {
    fn column(&self, j: usize, f: impl Fn(&JointTransform) -> DVec4) -> Vec<DVec4> {
        self.poses.iter().map(|p| f(&p.local[j])).collect()
    }
}

/// The clip's keys when they share one mode; else the clip resampled for linear playback.
fn export_samples(clip: &PoseClip) -> ExportSamples {
    let keys = clip.keys();
    let segments = &keys[..keys.len() - 1];
    let mode = match segments.first() {
        None => Some(KeyInterpolation::Step),
        Some(k) => segments
            .iter()
            .all(|s| s.interpolation == k.interpolation)
            .then_some(k.interpolation),
    };
    if let Some(mode) = mode {
        return ExportSamples {
            times: clip.times(),
            poses: keys.iter().map(|k| k.pose.clone()).collect(),
            interpolation: match mode {
                KeyInterpolation::Step => Interpolation::Step,
                KeyInterpolation::Linear => Interpolation::Linear,
                KeyInterpolation::CubicSpline => Interpolation::CubicSpline,
            },
        };
    }
    let mut times = Vec::new();
    for pair in keys.windows(2) {
        let (a, b) = (pair[0].time, pair[1].time);
        match pair[0].interpolation {
            KeyInterpolation::Linear => times.push(a),
            KeyInterpolation::Step => times.extend([a, b - (1e-3f32).min((b - a) / 10.0)]),
            KeyInterpolation::CubicSpline => {
                times.extend((0..8).map(|i| a + (b - a) * i as f32 / 8.0));
            }
        }
    }
    times.push(clip.duration());
    let poses = times
        .iter()
        .filter_map(|&t| clip.sample(t))
        .collect::<Vec<_>>();
    ExportSamples {
        times,
        poses,
        interpolation: Interpolation::Linear,
    }
}

/// One animation channel to write: a track (node path index), a property, and its values
/// (vec3 in `xyz` or quaternions), with in/out tangents around each value for cubic splines.
struct Channel {
    track: usize,
    property: Property,
    values: Vec<DVec4>,
}

impl Channel {
    fn of(track: usize, property: Property, values: impl IntoIterator<Item = DVec4>) -> Self {
        Self {
            track,
            property,
            values: values.into_iter().collect(),
        }
    }
}

/// A clip-only glTF document: node paths, their node transforms, one time axis and the
/// channels over it.
struct ClipDocument<'a> {
    name: &'a str,
    paths: Vec<&'a [String]>,
    nodes: Vec<JointTransform>,
    times: Vec<f32>,
    interpolation: Interpolation,
    channels: Vec<Channel>,
}

impl ClipDocument<'_> {
    fn encode(&self) -> Result<Vec<u8>, String> {
        let mut root = json::Root::default();
        let node_of = self.write_nodes(&mut root);
        let mut bin: Vec<u8> = Vec::new();
        let times = push_accessor(
            &mut root,
            &mut bin,
            &self.times,
            json::accessor::Type::Scalar,
            true,
        );
        let mut animation = json::Animation {
            name: Some(self.name.to_string()),
            channels: Vec::new(),
            samplers: Vec::new(),
            extensions: None,
            extras: Default::default(),
        };
        for channel in &self.channels {
            let (kind, width) = match channel.property {
                Property::Rotation => (json::accessor::Type::Vec4, 4),
                _ => (json::accessor::Type::Vec3, 3),
            };
            let values: Vec<f32> = channel
                .values
                .iter()
                .flat_map(|v| v.as_vec4().to_array()[..width].to_vec())
                .collect();
            let output = push_accessor(&mut root, &mut bin, &values, kind, false);
            animation.samplers.push(json::animation::Sampler {
                input: times,
                interpolation: Checked::Valid(self.interpolation),
                output,
                extensions: None,
                extras: Default::default(),
            });
            animation.channels.push(json::animation::Channel {
                sampler: json::Index::new(animation.samplers.len() as u32 - 1),
                target: json::animation::Target {
                    node: json::Index::new(node_of[self.paths[channel.track]]),
                    path: Checked::Valid(channel.property),
                    extensions: None,
                    extras: Default::default(),
                },
                extensions: None,
                extras: Default::default(),
            });
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
        let text = json::serialize::to_vec(&root).map_err(|e| e.to_string())?;
        Ok(crate::deform::glb_container(text, bin))
    }

    /// The node trie over the paths (a node per distinct prefix, named by its last name) and
    /// the scene of its tops; returns each path's node index.
    fn write_nodes<'p>(&'p self, root: &mut json::Root) -> BTreeMap<&'p [String], u32> {
        let mut node_of: BTreeMap<&[String], u32> = BTreeMap::new();
        let mut children: Vec<Vec<u32>> = Vec::new();
        let mut names: Vec<String> = Vec::new();
        let mut top: Vec<u32> = Vec::new();
        for path in &self.paths {
            for depth in 1..=path.len() {
                let key = &path[..depth];
                if node_of.contains_key(key) {
                    continue;
                }
                let index = children.len() as u32;
                node_of.insert(key, index);
                children.push(Vec::new());
                names.push(path[depth - 1].clone());
                if depth == 1 {
                    top.push(index);
                } else {
                    children[node_of[&path[..depth - 1]] as usize].push(index);
                }
            }
        }
        let mut transforms: Vec<Option<JointTransform>> = vec![None; names.len()];
        for (path, t) in self.paths.iter().zip(&self.nodes) {
            transforms[node_of[path] as usize] = Some(*t);
        }
        for (i, name) in names.into_iter().enumerate() {
            let t = transforms[i];
            root.nodes.push(json::Node {
                name: Some(name),
                children: (!children[i].is_empty())
                    .then(|| children[i].iter().map(|&c| json::Index::new(c)).collect()),
                translation: t.map(|t| t.translation.as_vec3().to_array()),
                rotation: t.map(|t| {
                    json::scene::UnitQuaternion(t.rotation.normalize().as_quat().to_array())
                }),
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
        node_of
    }
}

/// Appends `values` (f32, little-endian) to the binary chunk with a view and an accessor of
/// `kind`; `bounds` adds the min/max glTF requires of animation inputs.
fn push_accessor(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    values: &[f32],
    kind: json::accessor::Type,
    bounds: bool,
) -> json::Index<json::Accessor> {
    let offset = bin.len();
    for v in values {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    let width = match kind {
        json::accessor::Type::Scalar => 1,
        json::accessor::Type::Vec3 => 3,
        _ => 4,
    };
    let view = root.buffer_views.len() as u32;
    root.buffer_views.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64((values.len() * 4) as u64),
        byte_offset: Some(USize64(offset as u64)),
        byte_stride: None,
        name: None,
        target: None,
        extensions: None,
        extras: Default::default(),
    });
    let bound = |f: fn(f32, f32) -> f32| {
        let v = values.iter().copied().reduce(f).unwrap_or(0.0);
        json::Value::from(vec![v])
    };
    root.accessors.push(json::Accessor {
        buffer_view: Some(json::Index::new(view)),
        byte_offset: None,
        count: USize64((values.len() / width) as u64),
        component_type: Checked::Valid(json::accessor::GenericComponentType(
            json::accessor::ComponentType::F32,
        )),
        type_: Checked::Valid(kind),
        min: bounds.then(|| bound(f32::min)),
        max: bounds.then(|| bound(f32::max)),
        name: None,
        normalized: false,
        sparse: None,
        extensions: None,
        extras: Default::default(),
    });
    json::Index::new(root.accessors.len() as u32 - 1)
}

/// One channel of an imported animation, ready to sample.
struct ImportedChannel {
    joint: usize,
    property: Property,
    interpolation: Interpolation,
    times: Vec<f32>,
    /// One value per key (vec3 in `xyz`, or a quaternion).
    values: Vec<DVec4>,
    /// Cubic splines: the (in, out) tangents of each key, per second.
    tangents: Vec<(DVec4, DVec4)>,
}

impl ImportedChannel {
    fn read(
        channel: &gltf::animation::Channel<'_>,
        file: &GltfFile,
        joint: usize,
        name: &str,
        property: Property,
    ) -> Result<Self, ClipError> {
        file.admit(&channel.sampler().input(), AccessorUse::Times)?;
        let values = match property {
            Property::Rotation => AccessorUse::Rotations,
            _ => AccessorUse::Vectors,
        };
        file.admit(&channel.sampler().output(), values)?;
        let reader = channel.reader(|b| file.buffer(b));
        let missing = || GltfFileError::Unreadable {
            what: format!("the channel on {name:?}"),
        };
        let times: Vec<f32> = reader.read_inputs().ok_or_else(missing)?.collect();
        for (index, &time) in times.iter().enumerate() {
            if !time.is_finite() {
                return Err(ClipError::NonFiniteTime(time));
            }
            if index > 0 && time <= times[index - 1] {
                return Err(ClipError::TimesOutOfOrder {
                    index,
                    time,
                    previous: times[index - 1],
                });
            }
        }
        use gltf::animation::util::ReadOutputs;
        let raw: Vec<DVec4> = match reader.read_outputs().ok_or_else(missing)? {
            ReadOutputs::Translations(v) | ReadOutputs::Scales(v) => v
                .map(|p| DVec3::from_array(p.map(f64::from)).extend(0.0))
                .collect(),
            ReadOutputs::Rotations(r) => r
                .into_f32()
                .map(|q| DVec4::from_array(q.map(f64::from)))
                .collect(),
            ReadOutputs::MorphTargetWeights(_) => Vec::new(),
        };
        let interpolation = match channel.sampler().interpolation() {
            gltf::animation::Interpolation::Step => Interpolation::Step,
            gltf::animation::Interpolation::Linear => Interpolation::Linear,
            gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
        };
        let per_key = if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        if times.is_empty() || raw.len() != times.len() * per_key {
            return Err(ClipError::ChannelLength {
                joint: name.to_string(),
                values: raw.len(),
                times: times.len(),
            });
        }
        if let Some(k) = raw.iter().position(|v| !v.is_finite()) {
            return Err(ClipError::NonFiniteKey {
                time: times[k / per_key],
                joint: name.to_string(),
            });
        }
        if property == Property::Rotation
            && let Some(k) =
                (0..times.len()).find(|&k| raw[k * per_key + per_key / 2].length() < 1e-9)
        {
            return Err(ClipError::NonFiniteKey {
                time: times[k],
                joint: name.to_string(),
            });
        }
        let (values, tangents) = if per_key == 3 {
            let values = raw.chunks(3).map(|c| c[1]).collect();
            let tangents = raw.chunks(3).map(|c| (c[0], c[2])).collect();
            (values, tangents)
        } else {
            (raw, Vec::new())
        };
        Ok(Self {
            joint,
            property,
            interpolation,
            times,
            values,
            tangents,
        })
    }

    /// The channel's value at `time` (clamped to its first and last key).
    fn sample(&self, time: f32) -> DVec4 {
        let n = self.times.len();
        if n == 1 || time <= self.times[0] {
            return self.values[0];
        }
        if time >= self.times[n - 1] {
            return self.values[n - 1];
        }
        let k = self.times.partition_point(|&t| t <= time) - 1;
        let td = f64::from(self.times[k + 1] - self.times[k]);
        let s = f64::from(time - self.times[k]) / td;
        let (a, b) = (self.values[k], self.values[k + 1]);
        match self.interpolation {
            Interpolation::Step => a,
            Interpolation::Linear if self.property == Property::Rotation => {
                let (a, b) = (
                    DQuat::from_vec4(a).normalize(),
                    DQuat::from_vec4(b).normalize(),
                );
                DVec4::from(a.slerp(b, s))
            }
            Interpolation::Linear => a.lerp(b, s),
            Interpolation::CubicSpline => {
                let (out_a, in_b) = (self.tangents[k].1, self.tangents[k + 1].0);
                hermite(a, out_a * td, b, in_b * td, s)
            }
        }
    }
}
