//! Input: everything that moves handles and grabs from a device — the mouse
//! ([`MouseHandleControl`]), the Wii Remote's MotionPlus ([`WiimoteHandleControl`]) and its IR
//! pointer ([`WiimotePointerPlugin`]), and pointer grabs through bevy_picking
//! ([`GrabPlugin`]) — over one piece of shared view math (`view.rs`: the arcball, turning in the
//! camera's frame, the rotation of a scaled space, motion in the view plane).
//!
//! All of it runs in `Update` in the [`InputSystems`] sets, before
//! [`DeformSystems::Request`](crate::ecs::DeformSystems) (and so before the pose plugin's
//! sets), so a handle moved by any input is solved in the same frame; the remote's picking
//! pointer runs in `PreUpdate`, in bevy_picking's input set. Order your own input systems
//! against [`InputSystems`].

pub(crate) mod control;
pub(crate) mod grab;
mod remote_pointer;
pub(crate) mod view;

pub use control::{
    MouseControlPlugin, MouseHandleControl, WiimoteControlPlugin, WiimoteHandleControl,
};
pub use grab::{
    ActiveGrabs, GrabButton, GrabEnd, GrabHandle, GrabMove, GrabPlugin, GrabStart, GrabTurn,
    GrabTwist, Grabbable,
};
pub use remote_pointer::{WiimotePointer, WiimotePointerPlugin};
pub use view::arcball_rotation;

use bevy::prelude::*;

use crate::ecs::{DeformSystems, WiimoteSystems};

/// Where input moves handles and grabs, in `Update`, in this order.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InputSystems {
    /// Pointer presses become grabs (before [`DeformSystems::Prepare`], so a mesh a grab bakes
    /// starts preparing again in the same frame).
    StartGrabs,
    /// Handles move: grabs in progress, the mouse and the remote's handle controls
    /// ([`WiimoteSystems::Control`] is part of it). After [`DeformSystems::Prepare`] (a rest
    /// pose may have become ready this frame) and before [`DeformSystems::Request`].
    MoveHandles,
}

/// Orders the [`InputSystems`] sets (every input plugin calls it; configuring twice is
/// harmless).
pub(crate) fn configure_input_sets(app: &mut App) {
    app.configure_sets(
        Update,
        (
            InputSystems::StartGrabs.before(DeformSystems::Prepare),
            InputSystems::MoveHandles
                .after(DeformSystems::Prepare)
                .before(DeformSystems::Request),
            WiimoteSystems::Control.in_set(InputSystems::MoveHandles),
        ),
    );
}
