//! Poses over time: clips of keys, glTF animations read and written, blending a pose over a
//! playing clip, and poses saved as files.
//!
//! | question | file |
//! |---|---|
//! | a clip of pose keys (step, linear, cubic) sampled at a time | `clip.rs` ([`PoseClip`]) |
//! | clips read from a glTF file's animations, and written as glTF animations Bevy plays | `gltf_clip.rs` ([`read_gltf_clip`], [`write_gltf_clip`]) |
//! | motion capture read from BVH files (and clips written as BVH) | `bvh.rs` ([`read_bvh`], [`write_bvh`]) |
//! | a pose blended over another, override or additive, per joint | `blend.rs` ([`blend_pose`]) |
//! | a pose as a RON file, keyed by joint name | `pose_file.rs` ([`PoseFile`]) |
//! | named poses in a folder | `library.rs` ([`PoseLibrary`]) |
//!
//! [`PoseClip`]: clip::PoseClip
//! [`read_gltf_clip`]: gltf_clip::read_gltf_clip
//! [`write_gltf_clip`]: gltf_clip::write_gltf_clip
//! [`read_bvh`]: bvh::read_bvh
//! [`write_bvh`]: bvh::write_bvh
//! [`blend_pose`]: blend::blend_pose
//! [`PoseFile`]: pose_file::PoseFile
//! [`PoseLibrary`]: library::PoseLibrary

pub mod blend;
pub mod bvh;
pub mod clip;
pub mod gltf_clip;
pub mod library;
pub mod pose_file;
