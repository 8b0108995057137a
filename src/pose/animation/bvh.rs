//! Motion capture in BVH (Biovision Hierarchy), the format public motion-capture libraries ship
//! (CMU, Bandai Namco, Truebones, Rokoko and most mocap tools' exports): a joint hierarchy with
//! rest offsets and per-joint channels, then one line of channel values per frame.
//!
//! * Rotation channels compose in the order they are listed (`Zrotation Xrotation Yrotation`
//!   is `Rz · Rx · Ry`), in degrees.
//! * Position channels give the joint's translation in its parent's frame and replace its
//!   `OFFSET` (Blender's reading: files that put six channels on every joint repeat the offset
//!   there, and a root's offset is usually zero).
//! * `End Site`s become joints of their own (named after their parent with `_end`), never
//!   animated: they give the last bone of a chain its direction.
//!
//! The reader is iterative (no recursion on the hierarchy), checks every count the file claims
//! against what it holds, and bounds the joints ([`MAX_JOINTS`]) and the clip
//! ([`MAX_CLIP_TRANSFORMS`] joint transforms): a malformed or truncated file is a typed
//! [`BvhError`], never a panic or a runaway allocation. [`write_bvh`] writes a clip back.

use glam::{DAffine3, DQuat, DVec3, EulerRot};

use crate::pose::animation::clip::{
    ClipError, KeyInterpolation, MAX_CLIP_TRANSFORMS, PoseClip, PoseKey,
};
use crate::pose::error::PoseError;
use crate::pose::rig::gltf_character::MAX_JOINTS;
use crate::pose::rig::skeleton::{Joint, JointTransform, Skeleton, SkeletonPose};

/// The most frames a BVH file may claim (an hour at 240 frames a second).
pub const MAX_BVH_FRAMES: usize = 864_000;

/// Why a BVH file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BvhError {
    /// The text is not BVH where it says (line numbers from 1).
    #[error("line {line}: {message}")]
    Parse {
        /// The line.
        line: usize,
        /// What was expected or found.
        message: String,
    },
    /// The file claims more joints or frames than the bounds allow.
    #[error("the file has {count} {what}, past the bound of {limit}")]
    TooLarge {
        /// `joints`, `frames` or `joint transforms` (frames × joints).
        what: &'static str,
        /// What it claims.
        count: usize,
        /// The bound ([`MAX_JOINTS`], [`MAX_BVH_FRAMES`], [`MAX_CLIP_TRANSFORMS`]).
        limit: usize,
    },
    /// The file ends before the frames it announces.
    #[error("the file ends in frame {frame} of {frames}")]
    Truncated {
        /// The frame it ends in (from 0).
        frame: usize,
        /// The frames announced.
        frames: usize,
    },
    /// The skeleton is invalid.
    #[error(transparent)]
    Skeleton(#[from] PoseError),
    /// The clip is invalid.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// A motion-capture file read: its skeleton, the rest pose its offsets describe, and its
/// frames as a clip (a key per frame, linear).
#[derive(Debug, Clone)]
pub struct BvhMotion {
    /// The hierarchy, in file order (parents first).
    pub skeleton: Skeleton,
    /// The offsets with no rotation: the pose the file's hierarchy is drawn in.
    pub rest: SkeletonPose,
    /// One key per frame.
    pub clip: PoseClip,
    /// Seconds per frame.
    pub frame_time: f32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    Position(usize),
    Rotation(usize),
}

struct Tokens<'a> {
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    current: std::str::SplitWhitespace<'a>,
    line: usize,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            lines: text.lines().enumerate(),
            current: "".split_whitespace(),
            line: 0,
        }
    }

    fn next(&mut self) -> Option<&'a str> {
        loop {
            if let Some(t) = self.current.next() {
                return Some(t);
            }
            let (n, l) = self.lines.next()?;
            self.line = n + 1;
            self.current = l.split_whitespace();
        }
    }

    fn error(&self, message: impl Into<String>) -> BvhError {
        BvhError::Parse {
            line: self.line.max(1),
            message: message.into(),
        }
    }

    fn expect(&mut self, word: &str) -> Result<(), BvhError> {
        match self.next() {
            Some(t) if t.eq_ignore_ascii_case(word) => Ok(()),
            Some(t) => Err(self.error(format!("expected {word}, found {t:?}"))),
            None => Err(self.error(format!("expected {word}, found the end of the file"))),
        }
    }

    fn number(&mut self) -> Result<f64, BvhError> {
        let t = self
            .next()
            .ok_or_else(|| self.error("expected a number, found the end of the file"))?;
        let v: f64 = t
            .parse()
            .map_err(|_| self.error(format!("expected a number, found {t:?}")))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(format!("{t} is not a finite number")))
        }
    }

    fn count(&mut self, what: &str) -> Result<usize, BvhError> {
        let t = self
            .next()
            .ok_or_else(|| self.error(format!("expected the {what}")))?;
        t.parse()
            .map_err(|_| self.error(format!("expected the {what}, found {t:?}")))
    }
}

/// One joint as the hierarchy gives it.
struct Node {
    name: String,
    parent: Option<usize>,
    offset: DVec3,
    channels: Vec<Channel>,
}

/// Reads a BVH file's text (see the module docs).
pub fn read_bvh(text: &str) -> Result<BvhMotion, BvhError> {
    let mut tokens = Tokens::new(text);
    tokens.expect("HIERARCHY")?;
    let nodes = read_hierarchy(&mut tokens)?;
    tokens.expect("Frames:")?;
    let frames = tokens.count("frame count")?;
    if frames > MAX_BVH_FRAMES {
        return Err(BvhError::TooLarge {
            what: "frames",
            count: frames,
            limit: MAX_BVH_FRAMES,
        });
    }
    if frames.saturating_mul(nodes.len()) > MAX_CLIP_TRANSFORMS {
        return Err(BvhError::TooLarge {
            what: "joint transforms",
            count: frames.saturating_mul(nodes.len()),
            limit: MAX_CLIP_TRANSFORMS,
        });
    }
    tokens.expect("Frame")?;
    tokens.expect("Time:")?;
    let frame_time = tokens.number()? as f32;
    if !(frame_time > 0.0 && frame_time.is_finite()) {
        return Err(tokens.error(format!("frame time {frame_time} is not positive")));
    }
    let rest = SkeletonPose {
        local: nodes
            .iter()
            .map(|n| JointTransform {
                translation: n.offset,
                ..JointTransform::IDENTITY
            })
            .collect(),
    };
    let skeleton = skeleton_of(&nodes, &rest)?;
    let mut keys = Vec::with_capacity(frames);
    for frame in 0..frames {
        let mut pose = rest.clone();
        for (j, node) in nodes.iter().enumerate() {
            let mut rotation = DQuat::IDENTITY;
            for channel in &node.channels {
                let value = match tokens.next() {
                    None => return Err(BvhError::Truncated { frame, frames }),
                    Some(t) => {
                        t.parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite())
                            .ok_or_else(|| {
                                tokens.error(format!("frame {frame}: {t:?} is not a finite number"))
                            })?
                    }
                };
                match *channel {
                    Channel::Position(axis) => pose.local[j].translation[axis] = value,
                    Channel::Rotation(axis) => {
                        let mut unit = DVec3::ZERO;
                        unit[axis] = 1.0;
                        rotation *= DQuat::from_axis_angle(unit, value.to_radians());
                    }
                }
            }
            pose.local[j].rotation = rotation.normalize();
        }
        keys.push(PoseKey {
            time: frame as f32 * frame_time,
            pose,
            interpolation: KeyInterpolation::Linear,
        });
    }
    let clip = PoseClip::from_keys(keys)?;
    Ok(BvhMotion {
        skeleton,
        rest,
        clip,
        frame_time,
    })
}

/// The joints of the hierarchy section (after `HIERARCHY`, up to and with `MOTION`), parents
/// first.
fn read_hierarchy(tokens: &mut Tokens<'_>) -> Result<Vec<Node>, BvhError> {
    let mut nodes: Vec<Node> = Vec::new();
    // The open braces: the joint each belongs to (an End Site's is its parent's index, marked).
    let mut open: Vec<(usize, bool)> = Vec::new();
    let mut expecting_root = true;
    loop {
        let word = tokens
            .next()
            .ok_or_else(|| tokens.error("the hierarchy ends without MOTION"))?;
        match word.to_ascii_uppercase().as_str() {
            "ROOT" | "JOINT" => {
                let is_root = word.eq_ignore_ascii_case("ROOT");
                if is_root != (open.is_empty()) || (is_root && !expecting_root) {
                    return Err(tokens.error(format!("{word} where it cannot be")));
                }
                if open.last().is_some_and(|(_, end)| *end) {
                    return Err(tokens.error("a joint inside an End Site"));
                }
                expecting_root = false;
                let name = tokens
                    .next()
                    .ok_or_else(|| tokens.error("a joint without a name"))?
                    .to_string();
                if nodes.len() == MAX_JOINTS {
                    return Err(BvhError::TooLarge {
                        what: "joints",
                        count: MAX_JOINTS + 1,
                        limit: MAX_JOINTS,
                    });
                }
                tokens.expect("{")?;
                let offset = read_offset(tokens)?;
                tokens.expect("CHANNELS")?;
                let channels = read_channels(tokens)?;
                nodes.push(Node {
                    name,
                    parent: open.last().map(|(p, _)| *p),
                    offset,
                    channels,
                });
                open.push((nodes.len() - 1, false));
            }
            "END" => {
                tokens.expect("Site")?;
                let Some(&(parent, false)) = open.last() else {
                    return Err(tokens.error("an End Site outside a joint"));
                };
                tokens.expect("{")?;
                let offset = read_offset(tokens)?;
                if nodes.len() == MAX_JOINTS {
                    return Err(BvhError::TooLarge {
                        what: "joints",
                        count: MAX_JOINTS + 1,
                        limit: MAX_JOINTS,
                    });
                }
                nodes.push(Node {
                    name: format!("{}_end", nodes[parent].name),
                    parent: Some(parent),
                    offset,
                    channels: Vec::new(),
                });
                open.push((parent, true));
            }
            "}" => {
                if open.pop().is_none() {
                    return Err(tokens.error("a closing brace with nothing open"));
                }
            }
            "MOTION" if open.is_empty() && !nodes.is_empty() => return Ok(nodes),
            _ => return Err(tokens.error(format!("unexpected {word:?} in the hierarchy"))),
        }
    }
}

fn read_offset(tokens: &mut Tokens<'_>) -> Result<DVec3, BvhError> {
    tokens.expect("OFFSET")?;
    Ok(DVec3::new(
        tokens.number()?,
        tokens.number()?,
        tokens.number()?,
    ))
}

fn read_channels(tokens: &mut Tokens<'_>) -> Result<Vec<Channel>, BvhError> {
    let n = tokens.count("channel count")?;
    if n > 6 {
        return Err(tokens.error(format!("{n} channels (at most 6)")));
    }
    let mut channels = Vec::with_capacity(n);
    for _ in 0..n {
        let t = tokens
            .next()
            .ok_or_else(|| tokens.error("expected a channel name"))?;
        let axis = match t.as_bytes().first().map(u8::to_ascii_uppercase) {
            Some(b'X') => 0,
            Some(b'Y') => 1,
            Some(b'Z') => 2,
            _ => return Err(tokens.error(format!("unknown channel {t:?}"))),
        };
        let channel = match t.get(1..).map(str::to_ascii_lowercase).as_deref() {
            Some("position") => Channel::Position(axis),
            Some("rotation") => Channel::Rotation(axis),
            _ => return Err(tokens.error(format!("unknown channel {t:?}"))),
        };
        if channels.contains(&channel) {
            return Err(tokens.error(format!("channel {t} listed twice")));
        }
        channels.push(channel);
    }
    Ok(channels)
}

/// The skeleton of the hierarchy, its inverse binds from the rest pose.
fn skeleton_of(nodes: &[Node], rest: &SkeletonPose) -> Result<Skeleton, BvhError> {
    let mut globals: Vec<DAffine3> = Vec::with_capacity(nodes.len());
    for (j, node) in nodes.iter().enumerate() {
        let local = rest.local[j].to_affine();
        let global = node.parent.map_or(local, |p| globals[p] * local);
        globals.push(global);
    }
    let joints = nodes
        .iter()
        .zip(&globals)
        .map(|(node, global)| Joint {
            name: node.name.clone(),
            parent: node.parent,
            parent_frame: DAffine3::IDENTITY,
            inverse_bind: global.inverse(),
        })
        .collect();
    Ok(Skeleton::new(joints)?)
}

/// Writes `clip` of `skeleton` as BVH: `rest`'s translations as offsets, six channels on the
/// roots (position, then `Zrotation Xrotation Yrotation`), three rotation channels on the
/// others, joints named `…_end` without children as End Sites. Keys are written as they are,
/// one frame each, `frame_time` apart (resample a clip first for other timings).
pub fn write_bvh(
    skeleton: &Skeleton,
    rest: &SkeletonPose,
    clip: &PoseClip,
    frame_time: f32,
) -> Result<String, ClipError> {
    use std::fmt::Write;
    let joints = skeleton.len();
    if rest.local.len() != joints || clip.joint_count().is_some_and(|n| n != joints) {
        return Err(ClipError::PoseLength {
            got: rest.local.len(),
            expected: joints,
        });
    }
    let is_end =
        |j: usize| skeleton.children(j).is_empty() && skeleton.joints()[j].name.ends_with("_end");
    let mut out = String::from("HIERARCHY\n");
    // Depth-first, children in order; an explicit stack of (joint, closing?) entries.
    let mut order = Vec::new();
    for root in (0..joints).filter(|&j| skeleton.joints()[j].parent.is_none()) {
        let mut stack = vec![(root, false)];
        while let Some((j, closing)) = stack.pop() {
            let depth = {
                let mut d = 0;
                let mut up = skeleton.joints()[j].parent;
                while let Some(p) = up {
                    d += 1;
                    up = skeleton.joints()[p].parent;
                }
                d
            };
            let pad = "  ".repeat(depth);
            if closing {
                let _ = writeln!(out, "{pad}}}");
                continue;
            }
            let o = rest.local[j].translation;
            let joint = &skeleton.joints()[j];
            if is_end(j) && joint.parent.is_some() {
                let _ = writeln!(
                    out,
                    "{pad}End Site\n{pad}{{\n{pad}  OFFSET {} {} {}\n{pad}}}",
                    o.x, o.y, o.z
                );
                continue;
            }
            let keyword = if joint.parent.is_none() {
                "ROOT"
            } else {
                "JOINT"
            };
            let channels = if joint.parent.is_none() {
                "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"
            } else {
                "CHANNELS 3 Zrotation Xrotation Yrotation"
            };
            let _ = writeln!(
                out,
                "{pad}{keyword} {}\n{pad}{{\n{pad}  OFFSET {} {} {}\n{pad}  {channels}",
                joint.name, o.x, o.y, o.z
            );
            order.push(j);
            stack.push((j, true));
            for &c in skeleton.children(j).iter().rev() {
                stack.push((c, false));
            }
        }
    }
    let _ = writeln!(
        out,
        "MOTION\nFrames: {}\nFrame Time: {frame_time}",
        clip.keys().len()
    );
    for key in clip.keys() {
        let mut line = String::new();
        for &j in &order {
            let t = &key.pose.local[j];
            if skeleton.joints()[j].parent.is_none() {
                let _ = write!(
                    line,
                    "{} {} {} ",
                    t.translation.x, t.translation.y, t.translation.z
                );
            }
            let (z, x, y) = t.rotation.to_euler(EulerRot::ZXY);
            let _ = write!(
                line,
                "{} {} {} ",
                z.to_degrees(),
                x.to_degrees(),
                y.to_degrees()
            );
        }
        let _ = writeln!(out, "{}", line.trim_end());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::rig::skeleton::rotation_angle;

    /// A two-joint file in the layout of the CMU library's exports (six root channels, three
    /// per joint, an End Site), one frame.
    const SMALL: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0.0 0.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT LeftUpLeg
  {
    OFFSET 3.0 -1.0 0.0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0.0 -17.0 0.0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0083333
1.0 35.0 2.0 0.0 0.0 90.0 10.0 20.0 30.0
1.5 35.0 2.0 0.0 0.0 90.0 0.0 0.0 0.0
";

    #[test]
    fn a_cmu_style_file_reads_with_its_channel_order() {
        let m = read_bvh(SMALL).unwrap();
        assert_eq!(m.skeleton.len(), 3);
        assert_eq!(m.skeleton.joints()[2].name, "LeftUpLeg_end");
        assert_eq!(m.clip.keys().len(), 2);
        assert!((m.frame_time - 0.0083333).abs() < 1e-7);
        let first = &m.clip.keys()[0].pose;
        assert_eq!(first.local[0].translation, DVec3::new(1.0, 35.0, 2.0));
        // The root turns 90° about Y: +Z goes to +X.
        let z = first.local[0].rotation * DVec3::Z;
        assert!((z - DVec3::X).length() < 1e-9, "{z}");
        // Z, then X, then Y, as listed: Rz(10°) · Rx(20°) · Ry(30°).
        let expected = DQuat::from_rotation_z(10f64.to_radians())
            * DQuat::from_rotation_x(20f64.to_radians())
            * DQuat::from_rotation_y(30f64.to_radians());
        assert!(rotation_angle(first.local[1].rotation, expected) < 1e-9);
        assert_eq!(first.local[2].translation, DVec3::new(0.0, -17.0, 0.0));
    }

    #[test]
    fn a_written_clip_reads_back() {
        let m = read_bvh(SMALL).unwrap();
        let text = write_bvh(&m.skeleton, &m.rest, &m.clip, m.frame_time).unwrap();
        let back = read_bvh(&text).unwrap();
        assert_eq!(back.skeleton.len(), m.skeleton.len());
        for (a, b) in m.clip.keys().iter().zip(back.clip.keys()) {
            for (x, y) in a.pose.local.iter().zip(&b.pose.local) {
                assert!(rotation_angle(x.rotation, y.rotation) < 1e-9);
                assert!((x.translation - y.translation).length() < 1e-9);
            }
        }
    }

    #[test]
    fn malformed_files_give_typed_errors() {
        let truncated = SMALL.rsplit_once("1.5").unwrap().0;
        assert_eq!(
            read_bvh(truncated).unwrap_err(),
            BvhError::Truncated {
                frame: 1,
                frames: 2
            }
        );
        let bad_channel = SMALL.replace(
            "Zrotation Xrotation Yrotation\n    End",
            "Wrotation Xrotation Yrotation\n    End",
        );
        assert!(matches!(
            read_bvh(&bad_channel),
            Err(BvhError::Parse { line: 9, .. })
        ));
        let huge = SMALL.replace("Frames: 2", "Frames: 4000000000");
        let error = read_bvh(&huge).unwrap_err();
        assert!(matches!(
            error,
            BvhError::TooLarge {
                what: "frames",
                limit: MAX_BVH_FRAMES,
                ..
            }
        ));
        assert!(error.to_string().contains(&MAX_BVH_FRAMES.to_string()));
        let unclosed = SMALL.replacen("}\n}", "}", 1);
        assert!(read_bvh(&unclosed).is_err());
        let nan = SMALL.replace("10.0 20.0", "NaN 20.0");
        assert!(matches!(read_bvh(&nan), Err(BvhError::Parse { .. })));
        assert!(read_bvh("").is_err());
        assert!(read_bvh("HIERARCHY\nMOTION\nFrames: 0\n").is_err());
    }

    #[test]
    fn a_hierarchy_a_million_deep_fails_fast_on_its_bound() {
        let mut text = String::from("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 0\n");
        for k in 0..(MAX_JOINTS + 5) {
            text.push_str(&format!("JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n"));
        }
        let error = read_bvh(&text).unwrap_err();
        assert!(
            matches!(
                error,
                BvhError::TooLarge {
                    what: "joints",
                    limit: MAX_JOINTS,
                    ..
                }
            ),
            "{error}"
        );
    }
}
