//! Input: everything that moves handles and grabs from a device — the mouse
//! ([`MouseHandleControl`]), the Wii Remote's MotionPlus ([`MotionHandleControl`]) and its IR
//! pointer ([`ControllerPointerPlugin`]), and pointer grabs through bevy_picking
//! ([`GrabPlugin`]) — over one piece of shared view math (`view.rs`: the arcball, turning in the
//! camera's frame, the rotation of a scaled space, motion in the view plane).
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `control/` | Handle controls: input devices that move [`DeformHandle`](crate::ecs::DeformHandle)s (or any entity with a `Transform`). |
//! | `grab/` | Pointer grabs: press on a [`Grabbable`] deformable, drag, release — the surface under the pointer follows it, and the pose stays. |
//! | `remote_pointer.rs` | The remote's IR pointer as a bevy_picking pointer: where a [`MotionController`] points ([`MotionController::pointer`], from its camera) moves a pointer of its own on the primary window, and A presses and releases its primary button — so hovering, `Pointer<Press>` observers and [`GrabPlugin`](crate::ecs::GrabPlugin) grabs work with the remote as with the mouse. |
//! | `view.rs` | The view math every input shares: the arcball, turning a handle by a rotation given in the camera's frame, the rotation of an affine space (scale divided out), and motion in the view plane. |
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
    MotionControlPlugin, MotionHandleControl, MouseControlPlugin, MouseHandleControl,
};
pub use grab::{
    ActiveGrabs, GrabButton, GrabEnd, GrabHandle, GrabMove, GrabPlugin, GrabStart, GrabTurn,
    GrabTwist, Grabbable,
};
pub use remote_pointer::{ControllerPointer, ControllerPointerPlugin};
pub use view::arcball_rotation;

use bevy::prelude::*;

use crate::ecs::{DeformSystems, MotionControllerSystems};

/// Where input moves handles and grabs, in `Update`, in this order.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InputSystems {
    /// Pointer presses become grabs (before [`DeformSystems::Prepare`], so a mesh a grab bakes
    /// starts preparing again in the same frame).
    StartGrabs,
    /// Handles move: grabs in progress, the mouse and the remote's handle controls
    /// ([`MotionControllerSystems::Control`] is part of it). After [`DeformSystems::Prepare`] (a rest
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
            MotionControllerSystems::Control.in_set(InputSystems::MoveHandles),
        ),
    );
}
