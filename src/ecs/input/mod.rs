//! Input: everything that moves handles and grabs from a device — the mouse
//! ([`MouseHandleControl`]), the Wii Remote's MotionPlus ([`WiimoteHandleControl`]) and its IR
//! pointer ([`WiimotePointerPlugin`]), and pointer grabs through bevy_picking
//! ([`GrabPlugin`]) — over one piece of shared view math (`view.rs`: the arcball, turning in the
//! camera's frame, the rotation of a scaled space, motion in the view plane).
//!
//! All of it runs in `Update` before [`DeformSystems::Request`](crate::ecs::DeformSystems), so
//! a handle moved by any input is solved in the same frame: the handle controls in
//! [`WiimoteSystems::Control`](crate::ecs::WiimoteSystems), the grab systems around
//! [`DeformSystems::Prepare`](crate::ecs::DeformSystems) (new grabs before it, their handles
//! after); the remote's picking pointer in `PreUpdate`, in bevy_picking's input set.

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
