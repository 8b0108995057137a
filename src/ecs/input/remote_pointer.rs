//! The remote's IR pointer as a bevy_picking pointer: where a [`MotionController`] points
//! ([`MotionController::pointer`], from its camera) moves a pointer of its own on the primary window,
//! and A presses and releases its primary button — so hovering, `Pointer<Press>` observers and
//! [`GrabPlugin`](crate::ecs::GrabPlugin) grabs work with the remote as with the mouse. While A
//! holds a grab, turning the remote turns it 1:1 ([`GrabTurn`]) and pointing elsewhere moves it
//! in the view plane; holding B as well freezes the pointer: turn only.

use bevy::asset::uuid::Uuid;
use bevy::picking::PickingSystems;
use bevy::picking::pointer::{Location, PointerAction, PointerButton, PointerId, PointerInput};
use bevy::prelude::*;
use bevy::window::{PrimaryWindow, WindowRef};

use crate::controllers::session::Buttons;
use crate::ecs::GrabTurn;
use crate::ecs::controllers::{MotionController, MotionControllerSystems};

/// Gives every [`MotionController`] with a pointer ([`MotionControllerPlugin::pointer`](crate::ecs::MotionControllerPlugin::pointer))
/// a bevy_picking pointer ([`ControllerPointer::id`]) on the primary window; A is its primary
/// button. Add it with bevy_picking and the Wii Remote plugin.
#[derive(Debug, Clone, Default)]
pub struct ControllerPointerPlugin;

impl Plugin for ControllerPointerPlugin {
    fn build(&self, app: &mut App) {
        app.add_message::<PointerInput>()
            .add_message::<GrabTurn>()
            .add_systems(
                PreUpdate,
                drive_remote_pointers
                    .in_set(PickingSystems::Input)
                    .after(MotionControllerSystems::Receive),
            );
    }
}

/// On a remote's picking pointer entity (with its [`PointerId`]): which remote drives it.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct ControllerPointer {
    /// The [`MotionController`] entity.
    #[entities]
    pub remote: Entity,
    /// Where it was last put (window coordinates), whether A holds a press, and the remote's
    /// orientation when its turn was last passed on.
    last: Option<Vec2>,
    pressed: bool,
    turned_from: Option<Quat>,
}

impl ControllerPointer {
    /// The picking pointer id of the remote with manager id `id` (stable across reconnects).
    pub fn id(id: u32) -> PointerId {
        PointerId::Custom(Uuid::from_u128(
            0x5769_694D_6F74_6500_0000_0000_0000_0000 | id as u128,
        ))
    }
}

fn drive_remote_pointers(
    mut commands: Commands,
    remotes: Query<(Entity, &MotionController)>,
    mut pointers: Query<(&PointerId, &mut ControllerPointer)>,
    window: Query<(Entity, &Window), With<PrimaryWindow>>,
    mut input: MessageWriter<PointerInput>,
    mut turns: MessageWriter<GrabTurn>,
) {
    let Ok((window_entity, window)) = window.single() else {
        return;
    };
    let Some(target) =
        bevy::camera::RenderTarget::Window(WindowRef::Primary).normalize(Some(window_entity))
    else {
        return;
    };
    let size = Vec2::new(window.width(), window.height());
    for (remote, w) in &remotes {
        let Some((&id, mut pointer)) = pointers.iter_mut().find(|(_, p)| p.remote == remote) else {
            if w.pointer.is_some() {
                commands.spawn((
                    ControllerPointer::id(w.id),
                    ControllerPointer {
                        remote,
                        last: None,
                        pressed: false,
                        turned_from: None,
                    },
                ));
            }
            continue;
        };
        let location = |position: Vec2| Location {
            target: target.clone(),
            position,
        };
        let at = w.pointer.map(|p| p * size).filter(|p| p.is_finite());
        // B is the clutch: while it is held the pointer stays put, so turning the remote turns
        // a grab without moving it.
        let clutch = pointer.pressed && w.pressed(Buttons::B);
        if let Some(at) = at
            && pointer.last != Some(at)
            && !clutch
        {
            let delta = pointer.last.map_or(Vec2::ZERO, |last| at - last);
            input.write(PointerInput::new(
                id,
                location(at),
                PointerAction::Move { delta },
            ));
            pointer.last = Some(at);
        }
        // A presses where the remote points; the press lasts until A is released, even if
        // the bar leaves the camera's view meanwhile.
        let a = w.pressed(Buttons::A);
        let press = a && !pointer.pressed && at.is_some();
        let release = !a && pointer.pressed;
        if let (true, Some(last)) = (press || release, pointer.last) {
            let action = if press {
                PointerAction::Press(PointerButton::Primary)
            } else {
                PointerAction::Release(PointerButton::Primary)
            };
            input.write(PointerInput::new(id, location(last), action));
            pointer.pressed = press;
            pointer.turned_from = press.then_some(w.orientation);
        }
        // While pressed, the remote's turn since the last frame turns the grab 1:1 (in the
        // camera's frame, as `MotionHandleControl` maps it).
        if pointer.pressed
            && let Some(from) = pointer.turned_from
        {
            let turn = (w.orientation * from.inverse()).normalize();
            if turn.is_finite() && turn.angle_between(Quat::IDENTITY) > 1e-6 {
                turns.write(GrabTurn {
                    pointer: id,
                    rotation: turn,
                });
                pointer.turned_from = Some(w.orientation);
            }
        }
    }
}
