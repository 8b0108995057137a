//! Joint hierarchies, poses, forward kinematics and CPU linear-blend skinning.

use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::pose::error::PoseError;

/// One joint of a [`Skeleton`].
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// The joint's name (the glTF node name); pose files and clips key joints by it.
    pub name: String,
    /// Index of the parent joint, `None` for a root. Parents come before their children.
    pub parent: Option<usize>,
    /// For a root: the fixed transform of the space its local transform is given in (the
    /// world transform of the root's non-joint parent). Ignored for non-roots.
    pub parent_frame: DAffine3,
    /// The inverse bind matrix: from mesh (bind) space to the joint's space at bind time.
    pub inverse_bind: DAffine3,
}

/// A joint's local transform relative to its parent, as in a Bevy `Transform`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointTransform {
    /// Translation relative to the parent joint.
    pub translation: DVec3,
    /// Rotation relative to the parent joint.
    pub rotation: DQuat,
    /// Scale (the solver keeps it as given; rigged characters use 1).
    pub scale: DVec3,
}

impl Default for JointTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl JointTransform {
    /// No offset, no rotation, unit scale.
    pub const IDENTITY: Self = Self {
        translation: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
        scale: DVec3::ONE,
    };

    /// The affine matrix `T · R · S`.
    pub fn to_affine(&self) -> DAffine3 {
        DAffine3::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// True when every component is finite and the rotation has unit length.
    pub fn is_valid(&self) -> bool {
        self.translation.is_finite()
            && self.scale.is_finite()
            && self.rotation.is_finite()
            && (self.rotation.length() - 1.0).abs() < 1e-6
    }
}

/// A pose: one local transform per joint of a [`Skeleton`], in joint order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SkeletonPose {
    /// Local transforms, indexed like [`Skeleton::joints`].
    pub local: Vec<JointTransform>,
}

/// A joint hierarchy with inverse bind matrices.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    joints: Vec<Joint>,
    children: Vec<Vec<usize>>,
}

impl Skeleton {
    /// Checks and stores a joint list. Parents must precede their children (glTF skins do not
    /// promise this; [`Skeleton::sorted`] reorders). Errors: a parent index out of range or
    /// not before its child ([`PoseError::JointOrder`]), a non-finite matrix
    /// ([`PoseError::NonFiniteJoint`]), an empty list ([`PoseError::NoJoints`]).
    pub fn new(joints: Vec<Joint>) -> Result<Self, PoseError> {
        if joints.is_empty() {
            return Err(PoseError::NoJoints);
        }
        let mut children = vec![Vec::new(); joints.len()];
        for (j, joint) in joints.iter().enumerate() {
            if let Some(p) = joint.parent {
                if p >= j {
                    return Err(PoseError::JointOrder {
                        joint: j,
                        parent: p,
                    });
                }
                children[p].push(j);
            }
            let finite = |a: &DAffine3| a.matrix3.is_finite() && a.translation.is_finite();
            if !finite(&joint.inverse_bind) || !finite(&joint.parent_frame) {
                return Err(PoseError::NonFiniteJoint { joint: j });
            }
        }
        Ok(Self { joints, children })
    }

    /// Reorders joints so parents come first (stable otherwise) and builds the skeleton.
    /// Returns the skeleton and, for each new index, the index the joint had in `joints`.
    /// A cycle or a parent out of range is [`PoseError::JointOrder`].
    pub fn sorted(joints: Vec<Joint>) -> Result<(Self, Vec<usize>), PoseError> {
        let n = joints.len();
        let mut order = Vec::with_capacity(n);
        let mut placed = vec![usize::MAX; n];
        while order.len() < n {
            let before = order.len();
            for (j, joint) in joints.iter().enumerate() {
                if placed[j] != usize::MAX {
                    continue;
                }
                let ready = match joint.parent {
                    None => true,
                    Some(p) if p >= n => {
                        return Err(PoseError::JointOrder {
                            joint: j,
                            parent: p,
                        });
                    }
                    Some(p) => placed[p] != usize::MAX,
                };
                if ready {
                    placed[j] = order.len();
                    order.push(j);
                }
            }
            if order.len() == before {
                let j = (0..n).find(|&j| placed[j] == usize::MAX).unwrap_or(0);
                let parent = joints[j].parent.unwrap_or(j);
                return Err(PoseError::JointOrder { joint: j, parent });
            }
        }
        let reordered = order
            .iter()
            .map(|&old| {
                let mut joint = joints[old].clone();
                joint.parent = joint.parent.map(|p| placed[p]);
                joint
            })
            .collect();
        Ok((Self::new(reordered)?, order))
    }

    /// The joints, parents before children.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Number of joints.
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// Always false (a skeleton has at least one joint); here for API symmetry.
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// Direct children of joint `j`.
    pub fn children(&self, j: usize) -> &[usize] {
        &self.children[j]
    }

    /// Index of the joint called `name`.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Checks that `pose` has one valid transform per joint.
    pub fn check_pose(&self, pose: &SkeletonPose) -> Result<(), PoseError> {
        if pose.local.len() != self.joints.len() {
            return Err(PoseError::PoseLength {
                got: pose.local.len(),
                expected: self.joints.len(),
            });
        }
        match pose.local.iter().position(|t| !t.is_valid()) {
            Some(joint) => Err(PoseError::NonFiniteJoint { joint }),
            None => Ok(()),
        }
    }

    /// The bind pose: local transforms under which every skinning matrix is the identity, so
    /// the mesh skins to its bind-pose positions (the pose the inverse bind matrices were
    /// taken in).
    pub fn bind_pose(&self) -> SkeletonPose {
        let globals: Vec<DAffine3> = self
            .joints
            .iter()
            .map(|j| j.inverse_bind.inverse())
            .collect();
        let local = self
            .joints
            .iter()
            .enumerate()
            .map(|(k, joint)| {
                let parent = joint.parent.map_or(joint.parent_frame, |p| globals[p]);
                let (scale, rotation, translation) =
                    (parent.inverse() * globals[k]).to_scale_rotation_translation();
                JointTransform {
                    translation,
                    rotation: rotation.normalize(),
                    scale,
                }
            })
            .collect();
        SkeletonPose { local }
    }

    /// World (skeleton-space) transform of every joint: forward kinematics.
    pub fn global_transforms(&self, pose: &SkeletonPose) -> Vec<DAffine3> {
        let mut out: Vec<DAffine3> = Vec::with_capacity(self.joints.len());
        self.global_transforms_into(pose, &mut out);
        out
    }

    /// [`Skeleton::global_transforms`] into `out` (its allocation reused).
    pub(crate) fn global_transforms_into(&self, pose: &SkeletonPose, out: &mut Vec<DAffine3>) {
        out.clear();
        for (joint, local) in self.joints.iter().zip(&pose.local) {
            let parent = joint.parent.map_or(joint.parent_frame, |p| out[p]);
            out.push(parent * local.to_affine());
        }
    }

    /// Skinning matrix of every joint, `global · inverse_bind`: maps bind-pose positions to
    /// their place in the pose.
    pub fn skinning_matrices(&self, pose: &SkeletonPose) -> Vec<DAffine3> {
        self.global_transforms(pose)
            .iter()
            .zip(&self.joints)
            .map(|(g, j)| *g * j.inverse_bind)
            .collect()
    }

    /// Rotation part of the transform a joint's local transform is relative to (its parent's
    /// world transform, or the root's parent frame), with scale divided out.
    pub(crate) fn parent_rotation(&self, globals: &[DAffine3], j: usize) -> DQuat {
        let m = self.joints[j]
            .parent
            .map_or(self.joints[j].parent_frame, |p| globals[p]);
        rotation_of(&m.matrix3)
    }

    /// Each joint's position in the bind pose (where its inverse bind matrix takes the origin).
    pub(crate) fn bind_origins(&self) -> Vec<DVec3> {
        self.joints
            .iter()
            .map(|j| j.inverse_bind.inverse().translation)
            .collect()
    }

    /// Whether `joint` is `ancestor` or below it (a rotation of `ancestor` moves it).
    pub(crate) fn descends_from(&self, joint: usize, ancestor: usize) -> bool {
        let mut at = Some(joint);
        while let Some(j) = at {
            if j == ancestor {
                return true;
            }
            at = self.joints.get(j).and_then(|joint| joint.parent);
        }
        false
    }

    /// Linear part of the parent's transform (see [`Skeleton::parent_rotation`]).
    pub(crate) fn parent_linear(&self, globals: &[DAffine3], j: usize) -> DMat3 {
        self.joints[j]
            .parent
            .map_or(self.joints[j].parent_frame, |p| globals[p])
            .matrix3
    }
}

/// The rotation of a rotation-times-scale matrix (columns normalised; a reflection keeps its
/// handedness flip out of the quaternion by negating one axis).
pub(crate) fn rotation_of(m: &DMat3) -> DQuat {
    let (x, y, z) = (
        m.x_axis.normalize_or_zero(),
        m.y_axis.normalize_or_zero(),
        m.z_axis.normalize_or_zero(),
    );
    let z = if x.cross(y).dot(z) < 0.0 { -z } else { z };
    let q = DQuat::from_mat3(&DMat3::from_cols(x, y, z));
    if q.is_finite() {
        q.normalize()
    } else {
        DQuat::IDENTITY
    }
}

/// Per-vertex skin: up to four joints and their weights (glTF `JOINTS_0` / `WEIGHTS_0`).
pub type VertexInfluences = [(u32, f64); 4];

/// Linear-blend skinning on the CPU: `p' = Σ_k w_k · S_k · p` with `S_k` the
/// [`Skeleton::skinning_matrices`] of the pose.
pub fn skin_positions(
    matrices: &[DAffine3],
    positions: &[DVec3],
    influences: &[VertexInfluences],
) -> Vec<DVec3> {
    positions
        .iter()
        .zip(influences)
        .map(|(p, inf)| {
            inf.iter()
                .filter(|(_, w)| *w != 0.0)
                .map(|&(j, w)| matrices[j as usize].transform_point3(*p) * w)
                .sum()
        })
        .collect()
}

/// Largest change of a bone's world length (distance from a joint to its parent) between two
/// poses, in skeleton-space units. 0 for a skeleton posed by rotations only.
pub fn max_bone_length_error(skeleton: &Skeleton, a: &SkeletonPose, b: &SkeletonPose) -> f64 {
    let (ga, gb) = (skeleton.global_transforms(a), skeleton.global_transforms(b));
    let mut worst = 0.0f64;
    for (j, joint) in skeleton.joints().iter().enumerate() {
        if let Some(p) = joint.parent {
            let la = ga[j].translation.distance(ga[p].translation);
            let lb = gb[j].translation.distance(gb[p].translation);
            worst = worst.max((la - lb).abs());
        }
    }
    worst
}

/// The angle (radians, in [0, π]) of the rotation from `a` to `b`: `q` and `-q` are the same
/// rotation. Stable near zero, where `2 acos |a · b|` loses half its digits.
pub fn rotation_angle(a: glam::DQuat, b: glam::DQuat) -> f64 {
    let (a, b) = (a.normalize(), b.normalize());
    let b = if a.dot(b) < 0.0 { -b } else { b };
    4.0 * (a - b).length().atan2((a + b).length())
}
