//! Keyframed pose clips: a [`PoseClip`] is a list of keys (time, skeleton pose, and how to
//! interpolate to the next key), sampled at any time. Authoring keeps it sorted and valid;
//! [`crate::pose::animation::gltf_clip::write_gltf_clip`] exports it as a glTF animation and
//! [`crate::pose::animation::gltf_clip::read_gltf_clip`] imports one.
//!
//! Interpolation follows glTF's three sampler modes, chosen per key for the segment that
//! starts at it:
//! - [`KeyInterpolation::Step`]: the key's pose holds until the next key;
//! - [`KeyInterpolation::Linear`]: translations and scales lerp, rotations slerp (shortest arc);
//! - [`KeyInterpolation::CubicSpline`]: glTF's cubic Hermite spline on every component, the
//!   rotation normalised afterwards. Tangents are automatic: Catmull–Rom (the slope between the
//!   two neighbouring keys) at inner keys and zero at the first and last key (ease in and out).
//!   The exported file carries exactly these tangents, so a player of the file samples the
//!   same curve.
//!
//! Rotations of one joint are sign-aligned along the keys (each key's quaternion on the same
//! side as the previous one's) before they are interpolated, so no segment takes the long way.

use glam::{DQuat, DVec3, DVec4};

use crate::pose::rig::gltf_file::GltfFileError;
use crate::pose::rig::skeleton::{JointTransform, SkeletonPose};

/// The most joint transforms (keys × joints) a clip read from a file may hold: 4 million, e.g.
/// 11 minutes at 60 keys a second of a 100-joint skeleton (320 MB).
pub const MAX_CLIP_TRANSFORMS: usize = 1 << 22;

/// Why a clip, a key or a clip file was refused. The clip it was applied to is unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClipError {
    /// The clip has no keys (nothing to sample or export).
    #[error("the clip has no keys")]
    NoKeys,
    /// A key time is NaN or infinite.
    #[error("key time {0} is not finite")]
    NonFiniteTime(f32),
    /// A key's pose has a NaN/infinite transform or a zero rotation.
    #[error("the key at {time} s has a non-finite transform on joint {joint:?}")]
    NonFiniteKey {
        /// The key's time.
        time: f32,
        /// The joint (its name when known, else its index).
        joint: String,
    },
    /// Key times do not increase.
    #[error("key {index} at {time} s does not come after the previous key at {previous} s")]
    TimesOutOfOrder {
        /// The key's index.
        index: usize,
        /// Its time.
        time: f32,
        /// The previous key's time.
        previous: f32,
    },
    /// A key's pose has another joint count than the clip's.
    #[error("the pose has {got} joints, the clip's poses have {expected}")]
    PoseLength {
        /// Joints in the pose given.
        got: usize,
        /// Joints in the clip's poses.
        expected: usize,
    },
    /// A key index past the end.
    #[error("key {index} does not exist (the clip has {keys})")]
    KeyOutOfRange {
        /// The index given.
        index: usize,
        /// Keys in the clip.
        keys: usize,
    },
    /// Another key is already at that time.
    #[error("another key is already at {0} s")]
    TimeTaken(f32),
    /// The node paths given for export do not match the skeleton's joints.
    #[error("{paths} node paths for {joints} joints")]
    PathCount {
        /// Paths given.
        paths: usize,
        /// Joints in the clip's poses.
        joints: usize,
    },
    /// A joint's node path for export is empty.
    #[error("joint {0} has an empty node path")]
    EmptyPath(usize),
    /// The file is not a glTF document, its buffers cannot be read, or it claims more than
    /// the readers' bounds.
    #[error(transparent)]
    File(#[from] GltfFileError),
    /// A channel has another number of values than its key times ask for.
    #[error("the channel on {joint:?} has {values} values for {times} key times")]
    ChannelLength {
        /// The joint it animates.
        joint: String,
        /// Values in the channel.
        values: usize,
        /// Key times in the channel.
        times: usize,
    },
    /// The clip read would hold more joint transforms (keys × joints) than
    /// [`MAX_CLIP_TRANSFORMS`].
    #[error("{keys} keys of {joints} joints are past the bound of {limit} joint transforms")]
    TooLarge {
        /// Distinct key times in the file's animation.
        keys: usize,
        /// Joints of the skeleton.
        joints: usize,
        /// [`MAX_CLIP_TRANSFORMS`].
        limit: usize,
    },
    /// The file has no animation (of that name).
    #[error("the file has no animation{}", .0.as_ref().map(|n| format!(" named {n:?}")).unwrap_or_default())]
    NoAnimation(Option<String>),
    /// A channel of the file's animation targets a node that is not a joint of the skeleton.
    #[error("the clip animates {0:?}, which is not a joint of this character")]
    UnknownJoint(String),
    /// The clip could not be serialised.
    #[error("could not write the clip: {0}")]
    Serialize(String),
}

/// How a key interpolates towards the next key (glTF's sampler modes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum KeyInterpolation {
    /// Hold this key's pose until the next key.
    Step,
    /// Lerp translations and scales, slerp rotations.
    #[default]
    Linear,
    /// glTF cubic Hermite spline with automatic (Catmull–Rom, clamped at the ends) tangents.
    CubicSpline,
}

/// One key of a [`PoseClip`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseKey {
    /// Seconds from the start of the clip.
    pub time: f32,
    /// Local transforms of every joint at `time`.
    pub pose: SkeletonPose,
    /// How the segment from this key to the next is interpolated.
    pub interpolation: KeyInterpolation,
}

/// Two keys closer than this (seconds) are at the same time.
pub const KEY_TIME_EPSILON: f32 = 1e-5;

/// A keyframed clip of skeleton poses, kept sorted by time with valid poses of one length.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseClip {
    keys: Vec<PoseKey>,
}

impl PoseClip {
    /// An empty clip.
    pub fn new() -> Self {
        Self::default()
    }

    /// A clip of these keys: times strictly increasing and finite, poses valid and of one
    /// joint count.
    pub fn from_keys(mut keys: Vec<PoseKey>) -> Result<Self, ClipError> {
        let joints = keys.first().map(|k| k.pose.local.len());
        for index in 0..keys.len() {
            check_key(&mut keys[index], joints)?;
            let key = &keys[index];
            if index > 0 && key.time <= keys[index - 1].time {
                return Err(ClipError::TimesOutOfOrder {
                    index,
                    time: key.time,
                    previous: keys[index - 1].time,
                });
            }
        }
        Ok(Self { keys })
    }

    /// The keys in time order.
    pub fn keys(&self) -> &[PoseKey] {
        &self.keys
    }

    /// True when the clip has no key.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Time of the last key (0 for an empty clip).
    pub fn duration(&self) -> f32 {
        self.keys.last().map_or(0.0, |k| k.time)
    }

    /// Joints in the clip's poses (`None` while empty).
    pub fn joint_count(&self) -> Option<usize> {
        self.keys.first().map(|k| k.pose.local.len())
    }

    /// Sets a key: replaces the key at `time` (within [`KEY_TIME_EPSILON`]) or inserts one in
    /// order. Returns its index. Refused (the clip unchanged) for a non-finite time or pose,
    /// or a pose of another joint count.
    pub fn set_key(
        &mut self,
        time: f32,
        pose: SkeletonPose,
        interpolation: KeyInterpolation,
    ) -> Result<usize, ClipError> {
        let mut key = PoseKey {
            time,
            pose,
            interpolation,
        };
        check_key(&mut key, self.joint_count())?;
        Ok(match self.index_at(time) {
            Ok(i) => {
                self.keys[i] = key;
                i
            }
            Err(i) => {
                self.keys.insert(i, key);
                i
            }
        })
    }

    /// Removes and returns key `index`.
    pub fn remove_key(&mut self, index: usize) -> Result<PoseKey, ClipError> {
        if index >= self.keys.len() {
            return Err(self.out_of_range(index));
        }
        Ok(self.keys.remove(index))
    }

    /// Moves key `index` to `time`; returns its new index. Refused when another key is at
    /// that time or the time is not finite.
    pub fn move_key(&mut self, index: usize, time: f32) -> Result<usize, ClipError> {
        if index >= self.keys.len() {
            return Err(self.out_of_range(index));
        }
        if !time.is_finite() {
            return Err(ClipError::NonFiniteTime(time));
        }
        if let Ok(other) = self.index_at(time)
            && other != index
        {
            return Err(ClipError::TimeTaken(time));
        }
        let mut key = self.keys.remove(index);
        key.time = time;
        let at = self.index_at(time).unwrap_or_else(|i| i);
        self.keys.insert(at, key);
        Ok(at)
    }

    /// Changes how key `index` interpolates to the next.
    pub fn set_interpolation(
        &mut self,
        index: usize,
        interpolation: KeyInterpolation,
    ) -> Result<(), ClipError> {
        let keys = self.keys.len();
        let key = self
            .keys
            .get_mut(index)
            .ok_or(ClipError::KeyOutOfRange { index, keys })?;
        key.interpolation = interpolation;
        Ok(())
    }

    /// The pose at `time` (clamped to the first and last key); `None` for an empty clip.
    pub fn sample(&self, time: f32) -> Option<SkeletonPose> {
        let first = self.keys.first()?;
        let last = self.keys.last()?;
        if self.keys.len() == 1 || time.is_nan() || time <= first.time {
            return Some(first.pose.clone());
        }
        if time >= last.time {
            return Some(last.pose.clone());
        }
        // Segment k: keys[k].time <= time < keys[k + 1].time.
        let k = self.keys.partition_point(|key| key.time <= time) - 1;
        let (a, b) = (&self.keys[k], &self.keys[k + 1]);
        let s = f64::from((time - a.time) / (b.time - a.time));
        let local = match a.interpolation {
            KeyInterpolation::Step => a.pose.local.clone(),
            KeyInterpolation::Linear => a
                .pose
                .local
                .iter()
                .zip(&b.pose.local)
                .map(|(p, q)| JointTransform {
                    translation: p.translation.lerp(q.translation, s),
                    rotation: p.rotation.slerp(q.rotation, s).normalize(),
                    scale: p.scale.lerp(q.scale, s),
                })
                .collect(),
            KeyInterpolation::CubicSpline => {
                let times = self.times();
                (0..a.pose.local.len())
                    .map(|j| self.cubic_joint(j, k, s, &times))
                    .collect()
            }
        };
        Some(SkeletonPose { local })
    }

    /// The times of the keys.
    pub fn times(&self) -> Vec<f32> {
        self.keys.iter().map(|k| k.time).collect()
    }

    /// The automatic tangent (per second) of a value sequence at key `k`: Catmull–Rom inside,
    /// zero at the first and last key.
    pub fn auto_tangent(times: &[f32], values: &[DVec4], k: usize) -> DVec4 {
        if k == 0 || k + 1 >= values.len() {
            return DVec4::ZERO;
        }
        let span = f64::from(times[k + 1] - times[k - 1]);
        (values[k + 1] - values[k - 1]) / span
    }

    /// Joint `j` on cubic segment `k` at `s`: only keys `k − 1 ..= k + 2` shape the segment
    /// (the tangents at its two ends), so only they are read.
    fn cubic_joint(&self, j: usize, k: usize, s: f64, times: &[f32]) -> JointTransform {
        let (lo, hi) = (k.saturating_sub(1), (k + 2).min(self.keys.len() - 1));
        let window = &self.keys[lo..=hi];
        let times = &times[lo..=hi];
        let k = k - lo;
        let td = f64::from(times[k + 1] - times[k]);
        let hermite = |values: &[DVec4]| {
            let (m0, m1) = (
                Self::auto_tangent(times, values, k),
                Self::auto_tangent(times, values, k + 1),
            );
            hermite(values[k], m0 * td, values[k + 1], m1 * td, s)
        };
        let column = |f: fn(&JointTransform) -> DVec3| -> Vec<DVec4> {
            window
                .iter()
                .map(|key| f(&key.pose.local[j]).extend(0.0))
                .collect()
        };
        let rotations = sign_aligned(window.iter().map(|key| key.pose.local[j].rotation));
        let rotation = DQuat::from_vec4(hermite(&rotations));
        JointTransform {
            translation: hermite(&column(|t| t.translation)).truncate(),
            rotation: if rotation.length_squared() > 1e-18 {
                rotation.normalize()
            } else {
                window[k].pose.local[j].rotation
            },
            scale: hermite(&column(|t| t.scale)).truncate(),
        }
    }

    fn index_at(&self, time: f32) -> Result<usize, usize> {
        let i = self
            .keys
            .partition_point(|k| k.time < time - KEY_TIME_EPSILON);
        match self.keys.get(i) {
            Some(k) if (k.time - time).abs() <= KEY_TIME_EPSILON => Ok(i),
            _ => Err(i),
        }
    }

    fn out_of_range(&self, index: usize) -> ClipError {
        ClipError::KeyOutOfRange {
            index,
            keys: self.keys.len(),
        }
    }
}

/// Unit quaternions as vectors, each on the same side as the previous one (so that
/// interpolating neighbours never takes the long way; `q` and `−q` are one rotation).
pub(crate) fn sign_aligned(rotations: impl IntoIterator<Item = DQuat>) -> Vec<DVec4> {
    let mut out: Vec<DVec4> = Vec::new();
    for q in rotations {
        let v = DVec4::from(q.normalize());
        let v = match out.last() {
            Some(prev) if prev.dot(v) < 0.0 => -v,
            _ => v,
        };
        out.push(v);
    }
    out
}

/// glTF's cubic Hermite segment: `v0`, `v1` the values, `m0`, `m1` the tangents already
/// scaled by the segment's duration, `s` in [0, 1].
pub(crate) fn hermite(v0: DVec4, m0: DVec4, v1: DVec4, m1: DVec4, s: f64) -> DVec4 {
    let (s2, s3) = (s * s, s * s * s);
    v0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + m0 * (s3 - 2.0 * s2 + s)
        + v1 * (-2.0 * s3 + 3.0 * s2)
        + m1 * (s3 - s2)
}

/// Checks a key and normalises its rotations.
fn check_key(key: &mut PoseKey, joints: Option<usize>) -> Result<(), ClipError> {
    if !key.time.is_finite() {
        return Err(ClipError::NonFiniteTime(key.time));
    }
    if let Some(expected) = joints
        && key.pose.local.len() != expected
    {
        return Err(ClipError::PoseLength {
            got: key.pose.local.len(),
            expected,
        });
    }
    for (j, t) in key.pose.local.iter_mut().enumerate() {
        let length = t.rotation.length();
        if !(t.translation.is_finite() && t.scale.is_finite() && length.is_finite())
            || length < 1e-9
        {
            return Err(ClipError::NonFiniteKey {
                time: key.time,
                joint: j.to_string(),
            });
        }
        if (length - 1.0).abs() > 1e-12 {
            t.rotation /= length;
        }
    }
    Ok(())
}
