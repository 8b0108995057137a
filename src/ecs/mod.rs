//! The ECS layer: components, messages, systems and plugins. Thin glue over
//! [`crate::deform`], [`crate::pose`] and [`crate::controllers`].
//!
//! | plugin | what it adds | system sets |
//! |---|---|---|
//! | [`DeformPlugin`] | ARAP on [`Deformable`] meshes moved by [`DeformHandle`]s, solved in the `AsyncComputeTaskPool`, written back to the mesh asset | [`DeformSystems`] (`Update`: Prepare → Request → Poll → Writeback) |
//! | [`PosePlugin`] | posing rigged characters ([`Poseable`]): skinning-space ARAP solved for a skeleton pose, written to the joints, blended over clips ([`PoseBlend`]), clips authored on a [`PoseTimeline`] | [`PoseSystems`] (`Update`: Prepare → Request → Poll → Timeline after `DeformSystems::Request`; `PostUpdate`: Apply after `AnimationSystems`, before propagation) |
//! | [`GrabPlugin`] | press, drag, release on [`Grabbable`] meshes and characters through bevy_picking | [`InputSystems`] (`Update`: StartGrabs before `DeformSystems::Prepare`, MoveHandles after it and before `DeformSystems::Request`) |
//! | [`RetargetPlugin`] | [`Retarget`]: a clip made for another skeleton (BVH, another glTF character) baked onto a posed character, feet planted, as an `AnimationClip` ([`RetargetStatus`]) | [`RetargetSystems`] (`Update`, after `PoseSystems::Poll`) |
//! | [`MouseControlPlugin`] | [`MouseHandleControl`]: arcball and view-plane drags of a handle | `Update`, in `InputSystems::MoveHandles` |
//! | [`ControllerPointerPlugin`] | the Wii Remote's IR pointer as a bevy_picking pointer: A grabs, turning turns ([`GrabTurn`]) | `PreUpdate`, in bevy_picking's input set |
//! | [`MotionControllerPlugin`], [`MotionControlPlugin`] | one entity per remote with a [`MotionController`] component, messages; [`MotionHandleControl`] | [`MotionControllerSystems`] (`PreUpdate`: Receive; `Update`: Control, part of `InputSystems::MoveHandles`) |
//!
//! The input plugins (mouse, remote, pointer grabs) live in one folder, `ecs/input`, over one
//! piece of shared view math.
//!
//! [`WiiDeformPlugins`] adds them all except [`ControllerPointerPlugin`] (opt-in: it needs a sensor
//! bar, [`MotionControllerPlugin::pointer`]).
//!
//! | question | where |
//! |---|---|
//! | how a mesh is made deformable, solved in the background and written back | `deform/` |
//! | how a rigged character is posed, stood on the ground, blended over clips | `pose/` |
//! | how motion controllers become entities and messages | `controllers/` |
//! | how the mouse, a controller or a pointer grab moves a handle | `input/` |
//! | which meshes are the ground, and the ground every plugin reads | `ground/` |
//! | how a clip made for another skeleton becomes the character's `AnimationClip` | `retarget/` |
//! | how spring bones swing after the pose | `springs/` |
//! | how scene roots are marked spawned and missing assets reported | `scene/` |
//! | how bent meshes get Avian colliders (feature `avian`) | `physics/` |
//! | the background-solve pattern the deform and pose plugins share | `tasks.rs` |
//! | the space math input controls and pose effectors share | `space.rs` |

mod controllers;
mod deform;
mod ground;
mod input;
#[cfg(feature = "avian")]
pub mod physics;
mod pose;
mod retarget;
mod scene;
mod space;
mod springs;
mod tasks;

use bevy::app::PluginGroupBuilder;
use bevy::prelude::*;

pub use controllers::{
    ConnectionState, ControllerButtonChanged, ControllerCalibration, ControllerConnected,
    ControllerDisconnected, ControllerEmulators, ControllerFilter, ControllerLink,
    ControllerOrientationChanged, ControllerProblem, ControllerProblems, ControllerSettings,
    ControllerSource, MotionController, MotionControllerPlugin, MotionControllerSystems,
    remote_to_bevy, remote_vec_to_bevy,
};
pub use deform::{
    DeformConfig, DeformDynamics, DeformError, DeformFailed, DeformGround, DeformHandle,
    DeformPhase, DeformPlugin, DeformSolved, DeformState, DeformStatus, DeformSystems, Deformable,
    DeformableFrom, DeformableScene, FixedRegion, MESH_WAIT_FRAMES, mesh_from_triangles,
};
pub use ground::{GroundMesh, GroundPlugin, SceneGround};
pub use input::{
    ActiveGrabs, ControllerPointer, ControllerPointerPlugin, GrabButton, GrabEnd, GrabHandle,
    GrabMove, GrabPlugin, GrabStart, GrabTurn, GrabTwist, Grabbable, InputSystems,
    MotionControlPlugin, MotionHandleControl, MouseControlPlugin, MouseHandleControl,
    arcball_rotation,
};
pub use pose::{
    CharacterSkin, GroundContactState, HandlePositionOnly, JointMask, PinnedJoints, PoseAnchor,
    PoseBalance, PoseBlend, PoseBlendMode, PoseEffector, PoseEffectorKind, PoseFailed, PoseGround,
    PoseInFrame, PoseJointHandle, PoseLimits, PoseModels, PosePlugin, PoseSolved, PoseStatus,
    PoseStiffness, PoseSystems, PoseTimeline, Poseable, PoseableError, PosedSkeleton,
    SymmetricEditing,
};
pub use retarget::{
    Retarget, RetargetFailed, RetargetFoot, RetargetLoadError, RetargetPhase, RetargetPlugin,
    RetargetReady, RetargetStatus, RetargetSystems,
};
pub use scene::{MissingSceneAssets, SceneAssetsMissing, SceneRootPlugin};
pub use springs::{SpringBones, SpringPlugin, SpringSource, SpringStatus, SpringSystems};

/// Every plugin: [`DeformPlugin`], [`PosePlugin`], [`GrabPlugin`], [`MotionControllerPlugin`],
/// [`MotionControlPlugin`] and [`MouseControlPlugin`]. Leave one out with Bevy's plugin-group
/// API, e.g. `WiiDeformPlugins::default().build().disable::<GrabPlugin>()` for an app that
/// grabs nothing with the pointer.
#[derive(Debug, Clone, Default)]
pub struct WiiDeformPlugins {
    /// Deformation settings.
    pub deform: DeformPlugin,
    /// MotionController settings.
    pub wiimote: MotionControllerPlugin,
}

impl PluginGroup for WiiDeformPlugins {
    fn build(self) -> PluginGroupBuilder {
        PluginGroupBuilder::start::<Self>()
            .add(self.deform)
            .add(PosePlugin)
            .add(GrabPlugin)
            .add(self.wiimote)
            .add(MotionControlPlugin)
            .add(MouseControlPlugin)
    }
}
