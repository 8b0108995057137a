//! The remote's IR pointer as a bevy_picking pointer: where a [`Wiimote`] points
//! ([`Wiimote::pointer`], from its camera) moves a pointer of its own on the primary window,
//! and A presses and releases its primary button — so hovering, `Pointer<Press>` observers and
//! [`GrabPlugin`](crate::ecs::GrabPlugin) grabs work with the remote as with the mouse.

use bevy::asset::uuid::Uuid;
use bevy::picking::PickingSystems;
use bevy::picking::pointer::{Location, PointerAction, PointerButton, PointerId, PointerInput};
use bevy::prelude::*;
use bevy::window::{PrimaryWindow, WindowRef};

use super::{Wiimote, WiimoteSystems};
use crate::wiimote::protocol::Buttons;

/// Gives every [`Wiimote`] with a pointer ([`WiimotePlugin::pointer`](crate::ecs::WiimotePlugin::pointer))
/// a bevy_picking pointer ([`WiimotePointer::id`]) on the primary window; A is its primary
/// button. Add it with bevy_picking and the Wii Remote plugin.
#[derive(Debug, Clone, Default)]
pub struct WiimotePointerPlugin;

impl Plugin for WiimotePointerPlugin {
    fn build(&self, app: &mut App) {
        app.add_message::<PointerInput>().add_systems(
            PreUpdate,
            drive_remote_pointers
                .in_set(PickingSystems::Input)
                .after(WiimoteSystems::Receive),
        );
    }
}

/// On a remote's picking pointer entity (with its [`PointerId`]): which remote drives it.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct WiimotePointer {
    /// The [`Wiimote`] entity.
    #[entities]
    pub remote: Entity,
    /// Where it was last put (window coordinates), and whether A is held.
    last: Option<Vec2>,
    pressed: bool,
}

impl WiimotePointer {
    /// The picking pointer id of the remote with manager id `id` (stable across reconnects).
    pub fn id(id: u32) -> PointerId {
        PointerId::Custom(Uuid::from_u128(
            0x5769_694D_6F74_6500_0000_0000_0000_0000 | id as u128,
        ))
    }
}

fn drive_remote_pointers(
    mut commands: Commands,
    remotes: Query<(Entity, &Wiimote)>,
    mut pointers: Query<(&PointerId, &mut WiimotePointer)>,
    window: Query<(Entity, &Window), With<PrimaryWindow>>,
    mut input: MessageWriter<PointerInput>,
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
                    WiimotePointer::id(w.id),
                    WiimotePointer {
                        remote,
                        last: None,
                        pressed: false,
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
        if let Some(at) = at
            && pointer.last != Some(at)
        {
            let delta = pointer.last.map_or(Vec2::ZERO, |last| at - last);
            input.write(PointerInput::new(
                id,
                location(at),
                PointerAction::Move { delta },
            ));
            pointer.last = Some(at);
        }
        let held = w.pressed(Buttons::A) && w.pointer.is_some();
        if held != pointer.pressed
            && let Some(last) = pointer.last
        {
            let action = if held {
                PointerAction::Press(PointerButton::Primary)
            } else {
                PointerAction::Release(PointerButton::Primary)
            };
            input.write(PointerInput::new(id, location(last), action));
            pointer.pressed = held;
        }
    }
}
