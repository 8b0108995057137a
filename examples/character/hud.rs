//! The help line and the solver's status.

use bevy::prelude::*;
use bevy_wii_deform::prelude::*;

use crate::Args;
use crate::files::LastMessage;
use crate::scene::Character;

/// The model's credits, from its glTF `asset.copyright` (none when the file has none).
#[derive(Resource, Default)]
struct Credits(Option<String>);

/// Reads `asset.copyright` of the glTF at the asset path `path`.
fn credits_of(path: &str) -> Option<String> {
    let gltf = gltf::Gltf::open(crate::cli::asset_file(path)).ok()?;
    gltf.document.as_json().asset.copyright.clone()
}

/// A text overlay: keys, solver status, the last save/load message, the asset's credits.
pub struct HudPlugin;

impl Plugin for HudPlugin {
    fn build(&self, app: &mut App) {
        let credits = Credits(
            app.world()
                .get_resource::<Args>()
                .and_then(|a| credits_of(&a.model)),
        );
        app.insert_resource(credits)
            .add_systems(Startup, spawn_hud)
            .add_systems(Update, update_hud);
    }
}

#[derive(Component)]
struct Hud;

fn spawn_hud(mut commands: Commands) {
    commands.spawn((
        Text::new("loading..."),
        TextFont {
            font_size: FontSize::Px(15.0),
            ..default()
        },
        Node {
            position_type: PositionType::Absolute,
            top: px(10),
            left: px(10),
            // Long lines (a model's credits) wrap before the side panel (~390 px wide).
            right: px(400),
            ..default()
        },
        Hud,
    ));
}

/// What the HUD reads of the character.
type HudReads = (
    &'static PoseStatus,
    Option<&'static PinnedJoints>,
    Option<&'static RetargetStatus>,
    Option<&'static Retarget>,
);

fn update_hud(
    mut text: Single<&mut Text, With<Hud>>,
    character: Query<HudReads, With<Character>>,
    message: Res<LastMessage>,
    credits: Res<Credits>,
    args: Res<Args>,
) {
    let Some((status, pins, retarget, asked)) = character.iter().next() else {
        return;
    };
    let pinned = pins.map_or(0, |p| p.0.len());
    let mut line = format!(
        "drag the character to pose it | F feet pins ({pinned} pinned) | G ground | B balance | T tail springs | S save | L load | R reset\n\
         {} joints, {} vertices | last solve {} iterations, {:.2} ms | {}",
        status.joints, status.vertices, status.iterations, status.solve_ms, message.0
    );
    if let Some(error) = &status.error {
        line.push_str(&format!("\n{}: {error}", args.model));
    }
    if let Some(clip) = super::clip::clip_line(&args, asked, retarget) {
        line.push('\n');
        line.push_str(&clip);
    }
    if let Some(warning) = &status.warning {
        line.push_str(&format!("\nmissing, drawn without it: {warning}"));
    }
    if let Some(credits) = &credits.0 {
        line.push('\n');
        line.push_str(credits);
    }
    if text.0 != line {
        text.0 = line;
    }
}
