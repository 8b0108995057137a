//! The ECS layer: components, messages, systems and plugins. Thin glue over
//! [`crate::deform`] and [`crate::wiimote`].
//!
//! | plugin | what it adds | system sets |
//! |---|---|---|
//! | [`DeformPlugin`] | ARAP on [`Deformable`] meshes moved by [`DeformHandle`]s, solved in the `AsyncComputeTaskPool`, written back to the mesh asset | [`DeformSystems`] (`Update`: Prepare → Request → Poll → Writeback) |
//! | [`WiimotePlugin`] | one entity per remote with a [`Wiimote`] component, messages, [`WiimoteHandleControl`] | [`WiimoteSystems`] (`PreUpdate`: Receive; `Update`: Control, before `DeformSystems::Request`) |
//!
//! | [`PosePlugin`] | posing rigged characters ([`Poseable`]): skinning-space ARAP solved for a skeleton pose, written to the joints | [`PoseSystems`] (`Update`: Prepare → Request → Poll after `DeformSystems::Request`; `PostUpdate`: Apply after `AnimationSystems`) |
//!
//! [`WiiDeformPlugins`] adds them all.

mod character;
mod control;
mod deform;
mod grab;
mod mouse;
mod scene;
mod wiimote;

use bevy::app::PluginGroupBuilder;
use bevy::prelude::*;

pub use character::{
    PinnedJoints, PoseFailed, PoseJointHandle, PosePlugin, PoseSolved, PoseStatus, PoseSystems,
    Poseable, PoseableError, PosedSkeleton,
};
pub use control::WiimoteHandleControl;
pub use deform::{
    DeformConfig, DeformError, DeformFailed, DeformHandle, DeformPhase, DeformPlugin, DeformSolved,
    DeformStatus, DeformSystems, Deformable, FixedRegion, mesh_from_triangles,
};
pub use grab::{
    ActiveGrabs, GrabEnd, GrabHandle, GrabMove, GrabPlugin, GrabStart, GrabTwist, Grabbable,
};
pub use mouse::{MouseHandleControl, arcball_rotation};
pub use scene::{DeformableFrom, DeformableScene};
pub use wiimote::{
    ConnectionState, Wiimote, WiimoteButtonChanged, WiimoteCalibration, WiimoteConnected,
    WiimoteDisconnected, WiimoteEmulators, WiimoteFilter, WiimoteLink, WiimoteOrientationChanged,
    WiimotePlugin, WiimoteProblem, WiimoteProblems, WiimoteSettings, WiimoteSource, WiimoteSystems,
    remote_to_bevy, remote_vec_to_bevy,
};

/// Adds [`WiimoteHandleControl`] (requires [`WiimotePlugin`]).
#[derive(Debug, Clone, Default)]
pub struct WiimoteControlPlugin;

impl Plugin for WiimoteControlPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<WiimoteHandleControl>();
        app.add_systems(
            Update,
            control::drive_handles
                .in_set(WiimoteSystems::Control)
                .before(DeformSystems::Request),
        );
    }
}

/// Adds [`MouseHandleControl`]: mouse drags turn and move handles (in `Update`, before
/// [`DeformSystems::Request`]).
#[derive(Debug, Clone, Default)]
pub struct MouseControlPlugin;

impl Plugin for MouseControlPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<MouseHandleControl>();
        app.add_systems(
            Update,
            mouse::drive_mouse_handles.before(DeformSystems::Request),
        );
    }
}

/// Every plugin: [`DeformPlugin`], [`PosePlugin`], [`WiimotePlugin`], [`WiimoteControlPlugin`] and
/// [`MouseControlPlugin`].
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
            .add(self.wiimote)
            .add(WiimoteControlPlugin)
            .add(MouseControlPlugin)
    }
}
