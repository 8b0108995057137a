//! Standing on the ground: G toggles the character's ground contacts (`PoseGround` on the stage,
//! which is `GroundMesh`), B its balance (`PoseBalance`); the planted feet's support polygon and the
//! centre of mass over it are drawn (green inside, red outside).

use bevy::prelude::*;
use bevy_wii_deform::pose::{SupportPolygon, centre_of_mass};
use bevy_wii_deform::prelude::*;

use crate::Args;
use crate::scene::Character;

/// The G and B toggles and the drawing of contacts and balance.
pub struct StandingPlugin;

impl Plugin for StandingPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Update, (toggle_standing, start_standing, draw_balance));
    }
}

/// The character with its standing settings.
type Standing<'w, 's> =
    Query<'w, 's, (Entity, Has<PoseGround>, Option<&'static PoseBalance>), With<Character>>;
/// A standing character's model, pose and status.
type Grounded<'w, 's> = Query<
    'w,
    's,
    (&'static PosedSkeleton, &'static PoseStatus),
    (With<Character>, With<PoseGround>),
>;

/// `--ground`: the character stands and balances from the start.
fn start_standing(
    mut commands: Commands,
    args: Res<Args>,
    character: Query<Entity, (With<Character>, Added<PosedSkeleton>)>,
) {
    if !args.ground {
        return;
    }
    for e in &character {
        commands
            .entity(e)
            .insert((PoseGround::default(), PoseBalance::default()));
    }
}

/// G: ground contacts on or off; B: balance on or off.
fn toggle_standing(mut commands: Commands, keys: Res<ButtonInput<KeyCode>>, character: Standing) {
    for (e, grounded, balance) in &character {
        if keys.just_pressed(KeyCode::KeyG) {
            if grounded {
                commands.entity(e).remove::<PoseGround>();
            } else {
                commands.entity(e).insert(PoseGround::default());
            }
        }
        if keys.just_pressed(KeyCode::KeyB) {
            let enabled = !balance.is_some_and(|b| b.enabled);
            commands.entity(e).insert(PoseBalance {
                enabled,
                ..default()
            });
        }
    }
}

/// The support polygon of the planted feet and the centre of mass seen along gravity.
fn draw_balance(mut gizmos: Gizmos, character: Grounded) {
    for (posed, status) in &character {
        let corners = &status.support_polygon;
        if corners.is_empty() {
            continue;
        }
        let color = Color::srgb(1.0, 0.85, 0.2);
        for (a, b) in corners.iter().zip(corners.iter().cycle().skip(1)) {
            gizmos.line(*a, *b, color);
        }
        let Some(com) = centre_of_mass(&posed.model, &posed.pose, None) else {
            continue;
        };
        let com = posed.placement.transform_point3(com).as_vec3();
        let support: Vec<glam::DVec3> = corners.iter().map(|c| c.as_dvec3()).collect();
        let inside = SupportPolygon::new(&support, glam::DVec3::NEG_Y)
            .signed_distance(com.as_dvec3())
            >= 0.0;
        let mark = if inside {
            Color::srgb(0.2, 0.9, 0.3)
        } else {
            Color::srgb(0.95, 0.2, 0.2)
        };
        let floor = Vec3::new(com.x, corners[0].y, com.z);
        let size = posed.model.topology().bounding_diagonal() as f32;
        gizmos.line(com, floor, mark);
        gizmos.sphere(Isometry3d::from_translation(floor), 0.02 * size, mark);
        gizmos.sphere(Isometry3d::from_translation(com), 0.015 * size, mark);
    }
}
