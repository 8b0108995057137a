//! The ECS layer: components, messages, systems and plugins. Thin glue over
//! [`crate::deform`] and [`crate::controllers::wiimote`].
//!
//! | plugin | what it adds | system sets |
//! |---|---|---|
//! | [`DeformPlugin`] | ARAP on [`Deformable`] meshes moved by [`DeformHandle`]s, solved in the `AsyncComputeTaskPool`, written back to the mesh asset | [`DeformSystems`] (`Update`: Prepare → Request → Poll → Writeback) |
//! | [`PosePlugin`] | posing rigged characters ([`Poseable`]): skinning-space ARAP solved for a skeleton pose, written to the joints, blended over clips ([`PoseBlend`]), clips authored on a [`PoseTimeline`] | [`PoseSystems`] (`Update`: Prepare → Request → Poll → Timeline after `DeformSystems::Request`; `PostUpdate`: Apply after `AnimationSystems`, before propagation) |
//! | [`GrabPlugin`] | press, drag, release on [`Grabbable`] meshes and characters through bevy_picking | [`InputSystems`] (`Update`: StartGrabs before `DeformSystems::Prepare`, MoveHandles after it and before `DeformSystems::Request`) |
//! | [`MouseControlPlugin`] | [`MouseHandleControl`]: arcball and view-plane drags of a handle | `Update`, in `InputSystems::MoveHandles` |
//! | [`WiimotePointerPlugin`] | the Wii Remote's IR pointer as a bevy_picking pointer: A grabs, turning turns ([`GrabTurn`]) | `PreUpdate`, in bevy_picking's input set |
//! | [`WiimotePlugin`], [`WiimoteControlPlugin`] | one entity per remote with a [`Wiimote`] component, messages; [`WiimoteHandleControl`] | [`WiimoteSystems`] (`PreUpdate`: Receive; `Update`: Control, part of `InputSystems::MoveHandles`) |
//!
//! The input plugins (mouse, remote, pointer grabs) live in one folder, `ecs/input`, over one
//! piece of shared view math.
//!
//! [`WiiDeformPlugins`] adds them all except [`WiimotePointerPlugin`] (opt-in: it needs a sensor
//! bar, [`WiimotePlugin::pointer`]).

mod deform;
mod ground;
mod input;
#[cfg(feature = "avian")]
pub mod physics;
mod pose;
mod scene;
mod space;
mod springs;
mod tasks;
mod wiimote;

use bevy::app::PluginGroupBuilder;
use bevy::prelude::*;

pub use deform::{
    DeformConfig, DeformDynamics, DeformError, DeformFailed, DeformGround, DeformHandle,
    DeformPhase, DeformPlugin, DeformSolved, DeformState, DeformStatus, DeformSystems, Deformable,
    DeformableFrom, DeformableScene, FixedRegion, MESH_WAIT_FRAMES, mesh_from_triangles,
};
pub use ground::{GroundMesh, GroundPlugin, SceneGround};
pub use input::{
    ActiveGrabs, GrabButton, GrabEnd, GrabHandle, GrabMove, GrabPlugin, GrabStart, GrabTurn,
    GrabTwist, Grabbable, InputSystems, MouseControlPlugin, MouseHandleControl,
    WiimoteControlPlugin, WiimoteHandleControl, WiimotePointer, WiimotePointerPlugin,
    arcball_rotation,
};
pub use pose::{
    CharacterSkin, GroundContactState, HandlePositionOnly, JointMask, PinnedJoints, PoseAnchor,
    PoseBalance, PoseBlend, PoseBlendMode, PoseEffector, PoseEffectorKind, PoseFailed, PoseGround,
    PoseInFrame, PoseJointHandle, PoseLimits, PoseModels, PosePlugin, PoseSolved, PoseStatus,
    PoseStiffness, PoseSystems, PoseTimeline, Poseable, PoseableError, PosedSkeleton,
    SymmetricEditing,
};
pub use scene::{MissingSceneAssets, SceneAssetsMissing, SceneRootPlugin};
pub use springs::{SpringBones, SpringPlugin, SpringSource, SpringStatus, SpringSystems};
pub use wiimote::{
    ConnectionState, Wiimote, WiimoteButtonChanged, WiimoteCalibration, WiimoteConnected,
    WiimoteDisconnected, WiimoteEmulators, WiimoteFilter, WiimoteLink, WiimoteOrientationChanged,
    WiimotePlugin, WiimoteProblem, WiimoteProblems, WiimoteSettings, WiimoteSource, WiimoteSystems,
    remote_to_bevy, remote_vec_to_bevy,
};

/// Every plugin: [`DeformPlugin`], [`PosePlugin`], [`GrabPlugin`], [`WiimotePlugin`],
/// [`WiimoteControlPlugin`] and [`MouseControlPlugin`]. Leave one out with Bevy's plugin-group
/// API, e.g. `WiiDeformPlugins::default().build().disable::<GrabPlugin>()` for an app that
/// grabs nothing with the pointer.
#[derive(Debug, Clone, Default)]
pub struct WiiDeformPlugins {
    /// Deformation settings.
    pub deform: DeformPlugin,
    /// Wiimote settings.
    pub wiimote: WiimotePlugin,
}

impl PluginGroup for WiiDeformPlugins {
    fn build(self) -> PluginGroupBuilder {
        PluginGroupBuilder::start::<Self>()
            .add(self.deform)
            .add(PosePlugin)
            .add(GrabPlugin)
            .add(self.wiimote)
            .add(WiimoteControlPlugin)
            .add(MouseControlPlugin)
    }
}
