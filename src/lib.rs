//! Bevy 0.20 plugins for posing and playfully editing 3D meshes in-engine with
//! As-Rigid-As-Possible deformation, driven by the mouse, a pointer grab, or a Nintendo Wii
//! Remote with the MotionPlus gyroscope.
//!
//! Start with [`prelude`] and the `playground` example; the plugins and their system sets are
//! listed in [`ecs`]. The guide below covers the layers, deforming meshes, posing characters and
//! the core without Bevy.
//!
//! | question | module (folder) |
//! |---|---|
//! | how a mesh is bent As-Rigid-As-Possibly (no Bevy) | [`deform`] (`deform/`) |
//! | how a rigged character is posed, stood on the ground, retargeted (no Bevy) | [`pose`] (`pose/`) |
//! | how a Wii Remote or a gyro pad becomes an orientation (no Bevy) | [`controllers`] (`controllers/`) |
//! | how an editor's undo works (no Bevy) | [`history`] (`history.rs`) |
//! | what the plugins add to a Bevy app | `ecs` (`ecs/`, feature `bevy`) |
//!
#![doc = include_str!("../docs/guide.md")]
#![warn(missing_docs)]

pub mod controllers;
pub mod deform;
#[cfg(feature = "bevy")]
pub mod ecs;
pub mod history;
pub mod pose;

/// Everything most apps need: the plugins, their components, messages and settings, and the
/// core types a game touches. Listed by name, so nothing internal leaks in.
#[cfg(feature = "bevy")]
pub mod prelude {
    pub use crate::controllers::diagnosis::RemoteProblem;
    pub use crate::controllers::emulation::EmulatorControls;
    pub use crate::controllers::fusion::FilterKind;
    pub use crate::controllers::wiimote::EmulatorConfig;
    pub use crate::deform::{
        ArapSolver, Constraints, InitialGuess, RigidTransform, SolveOptions, SolverSettings,
        Topology, TriMesh, WeldPolicy, arap_energy,
    };
    pub use crate::ecs::{
        ConnectionState, ControllerButtonChanged, ControllerCalibration, ControllerConnected,
        ControllerDisconnected, ControllerEmulators, ControllerFilter, ControllerLink,
        ControllerOrientationChanged, ControllerPointer, ControllerPointerPlugin,
        ControllerProblem, ControllerProblems, ControllerSettings, ControllerSource, DeformConfig,
        DeformDynamics, DeformError, DeformFailed, DeformGround, DeformHandle, DeformPhase,
        DeformPlugin, DeformSolved, DeformStatus, DeformSystems, Deformable, DeformableFrom,
        DeformableScene, FixedRegion, GrabButton, GrabEnd, GrabMove, GrabPlugin, GrabStart,
        GrabTurn, GrabTwist, Grabbable, GroundContactState, GroundMesh, InputSystems, JointMask,
        MissingSceneAssets, MotionControlPlugin, MotionController, MotionControllerPlugin,
        MotionControllerSystems, MotionHandleControl, MouseControlPlugin, MouseHandleControl,
        PinnedJoints, PoseAnchor, PoseBalance, PoseBlend, PoseBlendMode, PoseEffector,
        PoseEffectorKind, PoseFailed, PoseGround, PoseInFrame, PoseJointHandle, PoseLimits,
        PoseModels, PosePlugin, PoseSolved, PoseStatus, PoseStiffness, PoseSystems, PoseTimeline,
        Poseable, PoseableError, PosedSkeleton, Retarget, RetargetFailed, RetargetFoot,
        RetargetLoadError, RetargetPhase, RetargetPlugin, RetargetReady, RetargetStatus,
        SceneAssetsMissing, SceneGround, SymmetricEditing, WiiDeformPlugins, mesh_from_triangles,
    };
}
