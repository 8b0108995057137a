#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod deform;
pub mod ecs;
pub mod pose;
pub mod wiimote;

/// Everything most apps need: the plugins, their components, messages and settings, and the
/// core types a game touches. Listed by name, so nothing internal leaks in.
pub mod prelude {
    pub use crate::deform::{
        ArapSolver, Constraints, InitialGuess, RigidTransform, SolveOptions, SolverSettings,
        Topology, TriMesh, WeldPolicy, arap_energy,
    };
    pub use crate::ecs::{
        ConnectionState, DeformConfig, DeformError, DeformFailed, DeformHandle, DeformPhase,
        DeformPlugin, DeformSolved, DeformStatus, DeformSystems, Deformable, DeformableFrom,
        DeformableScene, FixedRegion, GrabEnd, GrabMove, GrabPlugin, GrabStart, GrabTwist,
        Grabbable, MouseControlPlugin, MouseHandleControl, PinnedJoints, PoseFailed,
        PoseJointHandle, PosePlugin, PoseSolved, PoseStatus, PoseSystems, Poseable, PoseableError,
        PosedSkeleton, WiiDeformPlugins, Wiimote, WiimoteButtonChanged, WiimoteCalibration,
        WiimoteConnected, WiimoteControlPlugin, WiimoteDisconnected, WiimoteEmulators,
        WiimoteFilter, WiimoteHandleControl, WiimoteLink, WiimoteOrientationChanged, WiimotePlugin,
        WiimoteProblem, WiimoteProblems, WiimoteSettings, WiimoteSource, WiimoteSystems,
        mesh_from_triangles,
    };
    pub use crate::wiimote::{EmulatorConfig, EmulatorControls, FilterKind, RemoteProblem};
}
