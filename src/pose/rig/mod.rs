//! What a character is: its skeleton and poses, the skinned mesh prepared for posing, and
//! what is read off them. The lowest layer of [`crate::pose`]: it uses nothing of the others.
//!
//! | question | file |
//! |---|---|
//! | joints, poses, forward kinematics, CPU skinning, bone-length and rotation-angle helpers | `skeleton.rs` ([`Skeleton`], [`SkeletonPose`]) |
//! | a skinned mesh welded, clustered and reduced to the joints for posing | `model.rs` ([`SkinnedModel`]) |
//! | a skinned vertex (or centroid) as per-joint sums; each welded vertex's skin, made once per model | `skin.rs` |
//! | the mass model and the centre of mass | `mass.rs` ([`vertex_masses`], [`centre_of_mass`]) |
//! | how much of the body each joint's rotation carries (stiffness by inertia) | `inertia.rs` |
//! | humanoid joint roles and sides, found by name (Mixamo, Rigify, VRM) | `humanoid.rs` ([`humanoid_role`]) |
//! | left/right joints paired by name, poses mirrored across the symmetry plane | `mirror.rs` ([`Mirror`]) |
//! | capsules fitted to the skin along the bones (physics) | `capsules.rs` ([`fit_bone_capsules`]) |
//! | a glTF file's document and buffers, the bounds on what a file may claim | `gltf_file.rs` ([`GltfFile`]) |
//! | a rigged character (skeleton, skinned mesh, rest pose) read from a glTF file without Bevy | `gltf_character.rs` ([`read_gltf_character`]) |
//! | rigged test characters generated in code (bar, mannequin, 52-joint humanoid) | `synth_rig.rs` |
//!
//! [`Skeleton`]: skeleton::Skeleton
//! [`SkeletonPose`]: skeleton::SkeletonPose
//! [`SkinnedModel`]: model::SkinnedModel
//! [`vertex_masses`]: mass::vertex_masses
//! [`centre_of_mass`]: mass::centre_of_mass
//! [`humanoid_role`]: humanoid::humanoid_role
//! [`Mirror`]: mirror::Mirror
//! [`fit_bone_capsules`]: capsules::fit_bone_capsules
//! [`GltfFile`]: gltf_file::GltfFile
//! [`read_gltf_character`]: gltf_character::read_gltf_character

pub mod capsules;
pub mod gltf_character;
pub mod gltf_file;
pub mod humanoid;
pub(crate) mod inertia;
pub mod mass;
pub mod mirror;
pub mod model;
pub mod skeleton;
pub(crate) mod skin;
pub mod synth_rig;
