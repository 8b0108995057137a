//! [`PosedSkeleton`]: what the plugin keeps of a prepared character — its model, joints and
//! the pose it holds — and what a game reads of it: skinned positions, the pose on screen,
//! the joints it stands on, pose files and clip tracks, and picking on the posed skin.

use std::sync::Arc;

use bevy::prelude::*;
use glam::{DAffine3, DVec3};

use super::convert;
use crate::pose::{JointTransform, PoseFile, SkeletonPose, SkinnedModel};

/// Inserted by the plugin on a prepared [`Poseable`](super::Poseable): the model, its joints and the pose it
/// holds. Read it to save the pose or to pick on what is on screen; write `pose` to load one.
///
/// Not reflected, on purpose: it is state the plugin derives from the [`Poseable`](super::Poseable) and its
/// skin, so it stays out of scenes (a saved one would carry a model for joints that a loaded
/// scene renumbers); the pose itself is in the joints' `Transform`s, which scenes keep, and in
/// [`PosedSkeleton::pose_file`] for a file.
#[derive(Component, Debug, Clone)]
pub struct PosedSkeleton {
    /// The prepared model (skeleton in joint order of [`PosedSkeleton::joints`]), in character
    /// space ([`PosedSkeleton::placement`] maps it into the world), shared by every instance
    /// of the asset.
    pub model: Arc<SkinnedModel>,
    /// Joint entities, indexed like the model's skeleton.
    pub joints: Vec<Entity>,
    /// The skinned primitive entities and the first (combined) render vertex of each.
    pub primitives: Vec<(Entity, u32)>,
    /// The pose written to the joints (local transforms); under an additive
    /// [`PoseBlend`](super::PoseBlend) the layer added to the animation ([`PosedSkeleton::shown_pose`] reads
    /// what is on screen).
    pub pose: SkeletonPose,
    /// Where the character stands: world ← character space, the [`Poseable`](super::Poseable) entity's world
    /// transform as it is now (kept current by the plugin: composed from the local transforms
    /// when a solve is asked and again before an in-frame solve, so a character moved this
    /// frame is not solved where it was). The model is in character space, so
    /// every instance of one asset shares it ([`PoseModels`](super::PoseModels)); a character placed with a
    /// non-uniform scale has its model in world space and this identity.
    pub placement: DAffine3,
}

impl PosedSkeleton {
    /// World positions of every render vertex in the current pose (CPU linear-blend
    /// skinning): ray-cast these to pick the posed character (Bevy's mesh ray cast uses
    /// the bind pose of skinned meshes).
    pub fn skinned_positions(&self) -> Vec<Vec3> {
        self.model
            .skin_render(&self.pose)
            .iter()
            .map(|p| self.placement.transform_point3(*p).as_vec3())
            .collect()
    }

    /// World positions of the model's welded vertices in the current pose.
    pub fn skin_welded_world(&self) -> Vec<DVec3> {
        self.to_world(self.model.skin_welded(&self.pose))
    }

    /// The pose on screen: each joint's local transform as `local` reads it now (the held
    /// pose, whatever a playing clip left on the joints, or a clip plus an additive layer —
    /// [`PosedSkeleton::pose`] then holds the layer), the held one where it has none or an
    /// unusable one.
    pub fn shown_pose(&self, local: impl Fn(Entity) -> Option<Transform>) -> SkeletonPose {
        SkeletonPose {
            local: self
                .joints
                .iter()
                .zip(&self.pose.local)
                .map(|(&j, held)| {
                    let now = local(j).map(|t| convert::joint_transform(&t));
                    now.filter(JointTransform::is_valid).unwrap_or(*held)
                })
                .collect(),
        }
    }

    /// Character-space points of the model moved into the world ([`PosedSkeleton::placement`]).
    pub fn to_world(&self, mut points: Vec<DVec3>) -> Vec<DVec3> {
        for p in &mut points {
            *p = self.placement.transform_point3(*p);
        }
        points
    }

    /// The joints within `within` × the character's size (its bounding diagonal) above its
    /// lowest joint in the held pose: what it stands on (a biped's feet; a quadruped's feet
    /// *and* front paws — the Fox's front paws are "Hand" joints, so names would not do).
    ///
    /// By joint origins, for pins ([`PinnedJoints`](super::PinnedJoints)): a leg joint just above a foot (the
    /// Fox's hocks) is among them. The contacts of [`PoseGround`](super::PoseGround) use
    /// [`crate::pose::lowest_joints`] instead, which reads the skin and leaves such a joint out.
    pub fn lowest_joints(&self, within: f64) -> Vec<Entity> {
        let heights: Vec<f64> = self
            .model
            .skeleton()
            .global_transforms(&self.pose)
            .iter()
            .map(|t| t.translation.y)
            .collect();
        let lowest = heights.iter().copied().fold(f64::MAX, f64::min);
        let size = self.model.topology().bounding_diagonal();
        heights
            .iter()
            .zip(&self.joints)
            .filter(|(h, _)| **h <= lowest + within * size)
            .map(|(_, &e)| e)
            .collect()
    }

    /// The current pose as a [`PoseFile`] (joint name → local transform).
    pub fn pose_file(&self) -> PoseFile {
        PoseFile::from_pose(self.model.skeleton(), &self.pose)
    }

    /// Per joint, the names from the animation root (the entity with the `AnimationPlayer`,
    /// included) down to the joint: the path Bevy's glTF loader keys clips by, and what
    /// [`crate::pose::write_gltf_clip`] needs. `node(e)` gives an entity's name, its parent,
    /// and whether it is the animation root (e.g. from `Name`, `ChildOf` and
    /// `Has<AnimationPlayer>`); without a root the path runs up to the first unnamed ancestor.
    pub fn joint_paths(
        &self,
        node: impl Fn(Entity) -> (Option<String>, Option<Entity>, bool),
    ) -> Vec<Vec<String>> {
        self.joints
            .iter()
            .map(|&joint| {
                let mut path = Vec::new();
                let mut at = Some(joint);
                while let Some(e) = at {
                    let (name, parent, is_root) = node(e);
                    let Some(name) = name else { break };
                    path.push(name);
                    at = if is_root { None } else { parent };
                }
                path.reverse();
                path
            })
            .collect()
    }

    /// The current pose as tracks for [`crate::pose::write_gltf_pose_clip`]: each joint's
    /// path ([`PosedSkeleton::joint_paths`]) and local transform.
    pub fn clip_tracks(
        &self,
        node: impl Fn(Entity) -> (Option<String>, Option<Entity>, bool),
    ) -> Vec<(Vec<String>, crate::pose::JointTransform)> {
        self.joint_paths(node)
            .into_iter()
            .zip(self.pose.local.iter().copied())
            .collect()
    }

    /// The nearest hit of a world-space ray with the posed character (CPU-skinned triangles):
    /// what a click picks, where Bevy's mesh ray cast would test the bind pose of a
    /// skinned mesh. Returns the hit point and its distance along `ray`.
    pub fn ray_cast(&self, ray: Ray3d) -> Option<(Vec3, f32)> {
        self.ray_cast_skinned(&self.skin_welded_world(), ray)
    }

    /// [`PosedSkeleton::ray_cast`] against welded positions already skinned in the current
    /// pose, in the world ([`PosedSkeleton::skin_welded_world`]), so several rays share one
    /// skinning.
    pub fn ray_cast_skinned(&self, skinned: &[glam::DVec3], ray: Ray3d) -> Option<(Vec3, f32)> {
        let (origin, direction) = (ray.origin.as_dvec3(), ray.direction.as_vec3().as_dvec3());
        let mut best: Option<f64> = None;
        for t in self.model.topology().triangles() {
            let [a, b, c] = t.map(|i| skinned[i as usize]);
            let hit = crate::pose::ground::mesh::ray_triangle(origin, direction, a, b, c);
            if let Some(distance) = hit.filter(|&d| d > 0.0 && best.is_none_or(|b| d < b)) {
                best = Some(distance);
            }
        }
        best.map(|d| (ray.get_point(d as f32), d as f32))
    }

    /// Index of a joint entity in the skeleton.
    pub fn joint_index(&self, joint: Entity) -> Option<usize> {
        self.joints.iter().position(|&j| j == joint)
    }
}
