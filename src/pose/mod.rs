//! Posing rigged characters: As-Rigid-As-Possible deformation in skinning space, with a
//! skeleton pose as the result. Pure math on `glam`; no Bevy.
//!
//! A game character is a skinned mesh (bind-pose positions, up to four joint weights per
//! vertex) and a skeleton. Posing it means finding joint transforms, not moving vertices:
//! following "Fast Automatic Skinning Transformations" (Jacobson et al. 2012), the mesh's
//! ARAP energy is minimised over the poses the skin can express, `p'_i = Σ_j w_ij S_j p_i`.
//! [`SkinnedModel`] welds the mesh as the static solver does, clusters vertices by weight
//! (one rotation per cluster) and reduces every energy matrix to the joints once;
//! [`PoseSolver`] then iterates at a cost independent of the vertex count. Its unknowns are
//! rigid bones (see [`PoseSolver`]), so the result is always a valid skeleton pose.
//!
//! ```
//! use std::sync::Arc;
//! use bevy_wii_deform::pose::*;
//! use bevy_wii_deform::pose::rig::synth_rig;
//! use bevy_wii_deform::deform::{Handle, RigidTransform};
//! use glam::{DQuat, DVec3};
//!
//! // A bar skinned to a chain of three bones along +y.
//! let rig = synth_rig::bar_rig(3, 12, 24);
//! let model = Arc::new(SkinnedModel::new(
//!     rig.skeleton.clone(), &rig.mesh, &rig.rest, ModelSettings::default()).unwrap());
//! // Hold the bottom, grab the top and swing it sideways.
//! let top = rig.vertices_where(&model, |p| p.y > 0.95);
//! let bottom = rig.vertices_where(&model, |p| p.y < 0.05);
//! let mut constraints = PoseConstraints {
//!     handles: vec![Handle { vertices: top, transform: RigidTransform::IDENTITY }],
//!     fixed_vertices: bottom,
//!     ..Default::default()
//! };
//! let solver = PoseSolver::new(model.clone(), &constraints, &rig.rest,
//!     PoseSolverSettings::default()).unwrap();
//! constraints.handles[0].transform.translation = DVec3::new(0.3, -0.05, 0.0);
//! let solved = solver.solve(&constraints, &PoseSolveOptions::default(), PoseStart::Pose(&rig.rest), &|| false)
//!     .unwrap();
//! // Bones keep their lengths: the result is a skeleton pose.
//! assert!(max_bone_length_error(model.skeleton(), &rig.rest, &solved.pose) < 1e-9);
//! ```
//!
//! ## Where things are
//!
//! The folders are layers: each uses only those above it in this table (`animation` and
//! `springs` sit on `rig`; springs also read joint limits; `retarget` uses them all). A test (`tests/it/layering.rs`)
//! fails on an import against that order.
//!
//! | question | folder |
//! |---|---|
//! | what a character is: skeleton, poses, skinning, the skinned model, its skin sums and masses, humanoid roles by name, the mirror, bone capsules, generated test rigs | [`rig`] |
//! | where the ground is and how feet meet it: the `Ground` trait and plane, mesh ground, one contact, the whole-skin floor, balance and the support polygon, which joints are feet, the per-frame contact tracker, gait phases | [`ground`] |
//! | what a solve must respect: `PoseConstraints`, effectors and stiffness, joint limits (and the humanoid preset), changes of frame | [`constraints`] |
//! | how a pose is solved: parameters, the local/global loop, the damped Gauss–Newton step, the energies, the extra terms, the linear algebra | [`solver`] |
//! | poses over time: clips, glTF clips read and written, motion capture (BVH), blending, pose files and the pose library | [`animation`] |
//! | clips made for another skeleton played on this one, feet kept planted | [`retarget`] |
//! | motion after the pose: spring bones, VRM and RON spring files | [`springs`] |
//! | why something was rejected | [`PoseError`] (`error.rs`) |
//!
//! Everything a game uses is re-exported here (`pose::Skeleton`, `pose::PoseSolver`, …).

pub mod animation;
pub mod constraints;
mod error;
pub mod ground;
pub mod retarget;
pub mod rig;
pub mod solver;
pub mod springs;

pub use animation::blend::{BlendMode, additive_layer_for, blend_joint, blend_pose};
pub use animation::bvh::{BvhError, BvhMotion, MAX_BVH_FRAMES, read_bvh, write_bvh};
pub use animation::clip::{
    ClipError, KEY_TIME_EPSILON, KeyInterpolation, MAX_CLIP_TRANSFORMS, PoseClip, PoseKey,
};
pub use animation::gltf_clip::{read_gltf_clip, write_gltf_clip, write_gltf_pose_clip};
pub use animation::library::PoseLibrary;
pub use animation::pose_file::{PoseFile, PoseFileError};
pub use constraints::effectors::{
    CentroidEffector, Effector, EffectorGoal, ReferenceStiffness, StiffnessWeighting,
};
pub use constraints::limits::{JointLimit, JointLimits, LimitError};
pub use constraints::{JointHandle, PoseConstraints};
pub use error::PoseError;
pub use ground::Ground;
pub use ground::GroundPlane;
pub use ground::balance::{AllowedRegion, Balance, SupportPolygon};
pub use ground::contact::{Contact, Rolling};
pub use ground::feet::{lowest_joints, sole_patch};
pub use ground::floor::{Floor, FloorCastStats, FloorMemory, FloorSampling};
pub use ground::gait::GaitPhases;
pub use ground::mesh::TriangleGround;
pub use ground::tracker::{ContactEvent, ContactTracker};
pub use rig::capsules::{BoneCapsule, fit_bone_capsules};
pub use rig::gltf_character::{CharacterReadError, GltfCharacter, MAX_JOINTS, read_gltf_character};
pub use rig::gltf_file::{
    AccessorUse, GltfFile, GltfFileError, MAX_ACCESSOR_ELEMENTS, MAX_FILE_ELEMENTS,
};
pub use rig::humanoid::{HumanoidRole, Side, humanoid_role, humanoid_role_and_side};
pub use rig::mass::{centre_of_mass, vertex_masses};
pub use rig::mirror::{Mirror, mirror_partners};
pub use rig::model::{ModelSettings, SkinnedMesh, SkinnedModel};
pub use rig::skeleton::{
    Joint, JointTransform, Skeleton, SkeletonPose, VertexInfluences, skin_positions,
};
pub use rig::skeleton::{max_bone_length_error, rotation_angle};
pub use solver::{
    CONTACT_SKIN, OFF_THE_HOLD, PoseSolution, PoseSolveOptions, PoseSolveStats, PoseSolver,
    PoseSolverSettings, PoseStart, THROUGH_THE_GROUND,
};
pub use springs::{
    SpringChain, SpringCollider, SpringColliderShape, SpringError, SpringJoint, SpringRig,
    SpringRonError, SpringSettings, SpringState, VrmSpringError, read_vrm_springs, step_springs,
};
