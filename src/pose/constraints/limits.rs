//! Joint limits: a swing cone (elliptic) with a twist range about the bone axis, or a hinge.
//!
//! Limits are measured from a joint's *rest* local rotation (the rotation it has in the rest
//! pose given to [`JointLimits::new`], usually the bind pose): a joint at rest is at the centre
//! of its range. The solver respects them as constraints of every step (a projected
//! Levenberg–Marquardt step: each trial pose is projected onto the limits before its energy is
//! measured, and a hinge's own rotation is restricted to its axis), so effectors are solved
//! *with* the limits, not clamped afterwards.
//!
//! Limits come from code ([`JointLimits::set`], [`JointLimit::hinge_deg`],
//! [`JointLimit::cone_deg`]), from a RON file keyed by joint name ([`JointLimits::from_ron`]),
//! or from the humanoid preset ([`JointLimits::humanoid`], names in [`crate::pose::rig::humanoid`]).
//!
//! ```ron
//! (
//!     joints: {
//!         "LeftForeArm": Hinge(axis: (1.0, 0.0, 0.0), min_deg: 0.0, max_deg: 150.0),
//!         "Neck": SwingTwist(swing_deg: (40.0, 30.0), twist_deg: (-50.0, 50.0)),
//!     },
//! )
//! ```

use std::collections::BTreeMap;

use glam::{DQuat, DVec3};
use serde::Deserialize;

use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};

/// Why a limit was refused; names the joint.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LimitError {
    /// No joint of that name in the skeleton.
    #[error("no joint named {0:?} in the skeleton")]
    UnknownJoint(String),
    /// A joint index past the skeleton's end.
    #[error("joint index {joint} is out of range ({count} joints)")]
    JointOutOfRange {
        /// The index.
        joint: usize,
        /// Joints in the skeleton.
        count: usize,
    },
    /// A minimum above its maximum.
    #[error("joint {joint:?}: the limit's minimum {min_deg}° is above its maximum {max_deg}°")]
    MinAboveMax {
        /// The joint's name.
        joint: String,
        /// Minimum, degrees.
        min_deg: f64,
        /// Maximum, degrees.
        max_deg: f64,
    },
    /// A NaN or infinite angle or axis, or a negative swing half-angle.
    #[error("joint {joint:?}: the limit has a non-finite or negative value")]
    Invalid {
        /// The joint's name.
        joint: String,
    },
    /// A zero-length axis.
    #[error("joint {joint:?}: the limit's axis has zero length")]
    ZeroAxis {
        /// The joint's name.
        joint: String,
    },
    /// The RON text does not parse.
    #[error("limits file: {0}")]
    Parse(String),
}

/// One joint's limit, in the joint's rest frame (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointLimit {
    /// The bone may swing away from its rest direction within an ellipse of half-angles
    /// `swing` (about the two axes perpendicular to the bone, see [`swing_axes`]) and twist
    /// about its axis within `twist` (min, max).
    SwingTwist {
        /// The bone axis in the joint's frame; `None` = towards its first child (or +Y).
        axis: Option<DVec3>,
        /// Half-angles of the swing ellipse about the first and second perpendicular axis.
        swing: (f64, f64),
        /// Twist range about the bone axis (min, max).
        twist: (f64, f64),
    },
    /// Rotation about one axis only, within (min, max).
    Hinge {
        /// The hinge axis in the joint's frame.
        axis: DVec3,
        /// Smallest angle.
        min: f64,
        /// Largest angle.
        max: f64,
    },
}

impl JointLimit {
    /// A hinge about `axis` from `min_deg` to `max_deg` degrees.
    pub fn hinge_deg(axis: DVec3, min_deg: f64, max_deg: f64) -> Self {
        JointLimit::Hinge {
            axis,
            min: min_deg.to_radians(),
            max: max_deg.to_radians(),
        }
    }

    /// A swing cone of half-angles `swing_deg` and a twist range `twist_deg`, degrees, about
    /// the bone axis towards the first child.
    pub fn cone_deg(swing_deg: (f64, f64), twist_deg: (f64, f64)) -> Self {
        JointLimit::SwingTwist {
            axis: None,
            swing: (swing_deg.0.to_radians(), swing_deg.1.to_radians()),
            twist: (twist_deg.0.to_radians(), twist_deg.1.to_radians()),
        }
    }

    fn validate(&self, joint: &str) -> Result<(), LimitError> {
        let invalid = || LimitError::Invalid {
            joint: joint.to_string(),
        };
        let ordered = |min: f64, max: f64| {
            if min > max {
                Err(LimitError::MinAboveMax {
                    joint: joint.to_string(),
                    min_deg: min.to_degrees(),
                    max_deg: max.to_degrees(),
                })
            } else {
                Ok(())
            }
        };
        let axis_ok = |a: DVec3| {
            if !a.is_finite() {
                Err(invalid())
            } else if a.length_squared() < 1e-18 {
                Err(LimitError::ZeroAxis {
                    joint: joint.to_string(),
                })
            } else {
                Ok(())
            }
        };
        match *self {
            JointLimit::SwingTwist { axis, swing, twist } => {
                if let Some(a) = axis {
                    axis_ok(a)?;
                }
                let values = [swing.0, swing.1, twist.0, twist.1];
                if values.iter().any(|v| !v.is_finite()) || swing.0 < 0.0 || swing.1 < 0.0 {
                    return Err(invalid());
                }
                ordered(twist.0, twist.1)
            }
            JointLimit::Hinge { axis, min, max } => {
                axis_ok(axis)?;
                if !min.is_finite() || !max.is_finite() {
                    return Err(invalid());
                }
                ordered(min, max)
            }
        }
    }
}

/// The two axes perpendicular to a bone axis `b` that the swing half-angles refer to: the
/// first is the joint frame's X (or Z, when the bone lies along X) made perpendicular to `b`,
/// the second `b × first`.
pub fn swing_axes(b: DVec3) -> (DVec3, DVec3) {
    let seed = if b.x.abs() > 0.9 { DVec3::Z } else { DVec3::X };
    let e1 = (seed - b * seed.dot(b)).normalize();
    (e1, b.cross(e1))
}

/// A limit resolved for one joint (axes normalised, the default bone axis found).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Resolved {
    SwingTwist {
        axis: DVec3,
        e1: DVec3,
        e2: DVec3,
        swing: (f64, f64),
        twist: (f64, f64),
    },
    Hinge {
        axis: DVec3,
        min: f64,
        max: f64,
    },
}

/// The limits of a skeleton's joints (a joint without one is free).
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimits {
    names: Vec<String>,
    rest: Vec<DQuat>,
    bone_axis: Vec<DVec3>,
    limits: Vec<Option<Resolved>>,
}

/// Splits `q` (unit) into `swing · twist` with the twist about `axis`: returns the twist angle
/// (−π, π] and the swing rotation.
fn swing_twist(q: DQuat, axis: DVec3) -> (f64, DQuat) {
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let p = axis * v.dot(axis);
    let twist = DQuat::from_xyzw(p.x, p.y, p.z, q.w);
    let (twist, angle) = if twist.length_squared() < 1e-24 {
        (DQuat::IDENTITY, 0.0)
    } else {
        let t = twist.normalize();
        (t, 2.0 * v.dot(axis).atan2(q.w))
    };
    let angle = if angle > std::f64::consts::PI {
        angle - std::f64::consts::TAU
    } else {
        angle
    };
    (angle, (q * twist.inverse()).normalize())
}

/// The swing's rotation vector components on `(e1, e2)`.
fn swing_components(swing: DQuat, e1: DVec3, e2: DVec3) -> (f64, f64) {
    let s = if swing.w < 0.0 { -swing } else { swing };
    let v = s.to_scaled_axis();
    (v.dot(e1), v.dot(e2))
}

/// `(c1/a1)² + (c2/a2)²`, with a zero half-angle meaning "none allowed".
fn ellipse_value(c: (f64, f64), a: (f64, f64)) -> f64 {
    let term = |c: f64, a: f64| {
        if a > 1e-12 {
            (c / a) * (c / a)
        } else if c.abs() > 1e-12 {
            f64::INFINITY
        } else {
            0.0
        }
    };
    term(c.0, a.0) + term(c.1, a.1)
}

impl Resolved {
    /// The nearest allowed rotation to `delta` (from the rest rotation) by swing–twist: twist
    /// clamped, swing scaled back onto its ellipse; a hinge keeps only its own rotation.
    fn project(&self, delta: DQuat) -> DQuat {
        match *self {
            Resolved::Hinge { axis, min, max } => {
                let (angle, _) = swing_twist(delta, axis);
                DQuat::from_axis_angle(axis, angle.clamp(min, max))
            }
            Resolved::SwingTwist {
                axis,
                e1,
                e2,
                swing,
                twist,
            } => {
                let (angle, swing_q) = swing_twist(delta, axis);
                let twist_q = DQuat::from_axis_angle(axis, angle.clamp(twist.0, twist.1));
                let c = swing_components(swing_q, e1, e2);
                if ellipse_value(c, swing) <= 1.0 {
                    return swing_q * twist_q;
                }
                let keep = |c: f64, a: f64| if a > 1e-12 { c } else { 0.0 };
                let c = (keep(c.0, swing.0), keep(c.1, swing.1));
                let v = ellipse_value(c, swing);
                let k = if v > 0.0 { v.sqrt().recip() } else { 0.0 };
                DQuat::from_scaled_axis((e1 * c.0 + e2 * c.1) * k) * twist_q
            }
        }
    }

    /// By how much `delta` exceeds the limit, radians (0 inside).
    fn excess(&self, delta: DQuat) -> f64 {
        match *self {
            Resolved::Hinge { axis, min, max } => {
                let (angle, swing) = swing_twist(delta, axis);
                let off_axis = swing.angle_between(DQuat::IDENTITY);
                off_axis + (angle - max).max(min - angle).max(0.0)
            }
            Resolved::SwingTwist {
                axis,
                e1,
                e2,
                swing,
                twist,
            } => {
                let (angle, swing_q) = swing_twist(delta, axis);
                let c = swing_components(swing_q, e1, e2);
                let value = ellipse_value(c, swing);
                let magnitude = (c.0 * c.0 + c.1 * c.1).sqrt();
                let swing_excess = if value <= 1.0 {
                    0.0
                } else if value.is_finite() {
                    magnitude * (1.0 - value.sqrt().recip())
                } else {
                    magnitude
                };
                swing_excess + (angle - twist.1).max(twist.0 - angle).max(0.0)
            }
        }
    }
}

impl JointLimits {
    /// No limits yet, measured from `rest` (usually the skeleton's bind pose).
    pub fn new(skeleton: &Skeleton, rest: &SkeletonPose) -> Self {
        let n = skeleton.len();
        let bone_axis = (0..n)
            .map(|j| {
                skeleton
                    .children(j)
                    .first()
                    .map(|&c| rest.local[c].translation)
                    .filter(|t| t.length_squared() > 1e-18)
                    .map_or(DVec3::Y, DVec3::normalize)
            })
            .collect();
        Self {
            names: skeleton.joints().iter().map(|j| j.name.clone()).collect(),
            rest: rest.local.iter().map(|t| t.rotation.normalize()).collect(),
            bone_axis,
            limits: vec![None; n],
        }
    }

    /// Limits `joint` (index). Errors name the joint.
    pub fn set(&mut self, joint: usize, limit: JointLimit) -> Result<&mut Self, LimitError> {
        let Some(name) = self.names.get(joint) else {
            return Err(LimitError::JointOutOfRange {
                joint,
                count: self.names.len(),
            });
        };
        limit.validate(name)?;
        self.limits[joint] = Some(match limit {
            JointLimit::SwingTwist { axis, swing, twist } => {
                let axis = axis.map_or(self.bone_axis[joint], DVec3::normalize);
                let (e1, e2) = swing_axes(axis);
                Resolved::SwingTwist {
                    axis,
                    e1,
                    e2,
                    swing,
                    twist,
                }
            }
            JointLimit::Hinge { axis, min, max } => Resolved::Hinge {
                axis: axis.normalize(),
                min,
                max,
            },
        });
        Ok(self)
    }

    /// Limits the joint named `name` (exact match).
    pub fn set_by_name(&mut self, name: &str, limit: JointLimit) -> Result<&mut Self, LimitError> {
        let joint = self
            .names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| LimitError::UnknownJoint(name.to_string()))?;
        self.set(joint, limit)
    }

    /// Frees a joint.
    pub fn clear(&mut self, joint: usize) {
        if let Some(l) = self.limits.get_mut(joint) {
            *l = None;
        }
    }

    /// Number of limited joints.
    pub fn limited_count(&self) -> usize {
        self.limits.iter().filter(|l| l.is_some()).count()
    }

    /// Whether `joint` has a limit.
    pub fn is_limited(&self, joint: usize) -> bool {
        self.limits.get(joint).is_some_and(Option::is_some)
    }

    /// Limits from RON text keyed by joint name (see the module docs for the format; angles in
    /// degrees). Every name must exist in the skeleton.
    pub fn from_ron(
        text: &str,
        skeleton: &Skeleton,
        rest: &SkeletonPose,
    ) -> Result<Self, LimitError> {
        let file: LimitsFile = ron::from_str(text).map_err(|e| LimitError::Parse(e.to_string()))?;
        let mut limits = Self::new(skeleton, rest);
        for (name, spec) in file.joints {
            limits.set_by_name(&name, spec.into_limit())?;
        }
        Ok(limits)
    }

    /// The hinge axis of `joint` in the joint's own frame (the only axis the solver turns a
    /// hinge about), if it is a hinge.
    pub(crate) fn hinge_axis(&self, joint: usize) -> Option<DVec3> {
        match self.limits.get(joint)? {
            Some(Resolved::Hinge { axis, .. }) => Some(*axis),
            _ => None,
        }
    }

    /// The names of the joints, in skeleton order.
    pub fn joint_names(&self) -> &[String] {
        &self.names
    }

    /// Projects every limited joint of `pose` onto its limits (the nearest allowed rotation by
    /// swing–twist: twist clamped, swing scaled back onto its ellipse; a hinge keeps only its
    /// rotation about its axis, clamped).
    pub fn project(&self, pose: &mut SkeletonPose) {
        for (j, limit) in self.limits.iter().enumerate() {
            let (Some(limit), Some(local)) = (limit, pose.local.get_mut(j)) else {
                continue;
            };
            let delta = (self.rest[j].inverse() * local.rotation).normalize();
            let projected = limit.project(delta);
            local.rotation = (self.rest[j] * projected).normalize();
        }
    }

    /// By how much `pose` exceeds the limits: the largest excess over all joints, degrees
    /// (0 when every joint is within its limits).
    pub fn max_violation_deg(&self, pose: &SkeletonPose) -> f64 {
        let mut worst = 0.0f64;
        for (j, limit) in self.limits.iter().enumerate() {
            let (Some(limit), Some(local)) = (limit, pose.local.get(j)) else {
                continue;
            };
            let delta = (self.rest[j].inverse() * local.rotation).normalize();
            let excess = limit.excess(delta);
            worst = worst.max(excess.to_degrees());
        }
        worst
    }
}

/// The RON limits file.
#[derive(Debug, Deserialize)]
struct LimitsFile {
    joints: BTreeMap<String, LimitSpec>,
}

/// One joint's entry in a limits file (degrees).
#[derive(Debug, Deserialize)]
enum LimitSpec {
    SwingTwist {
        #[serde(default)]
        axis: Option<(f64, f64, f64)>,
        swing_deg: (f64, f64),
        twist_deg: (f64, f64),
    },
    Hinge {
        axis: (f64, f64, f64),
        min_deg: f64,
        max_deg: f64,
    },
}

impl LimitSpec {
    fn into_limit(self) -> JointLimit {
        let v = |a: (f64, f64, f64)| DVec3::new(a.0, a.1, a.2);
        match self {
            LimitSpec::SwingTwist {
                axis,
                swing_deg,
                twist_deg,
            } => JointLimit::SwingTwist {
                axis: axis.map(v),
                swing: (swing_deg.0.to_radians(), swing_deg.1.to_radians()),
                twist: (twist_deg.0.to_radians(), twist_deg.1.to_radians()),
            },
            LimitSpec::Hinge {
                axis,
                min_deg,
                max_deg,
            } => JointLimit::hinge_deg(v(axis), min_deg, max_deg),
        }
    }
}
