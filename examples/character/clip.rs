//! A clip made for another skeleton — a BVH file, or another glTF character's animation —
//! retargeted onto the character by the library's `RetargetPlugin` (feet kept planted and on
//! the ground) and played by the character's own `AnimationPlayer`, looping: named by
//! `--clip PATH` or in the panel's "Clip from a file" section (a path, the animation's name,
//! a chain map). The HUD says how the retarget went. Each foot shows its contacts while the
//! clip plays: a green ring round the character's foot joint while the source's foot is
//! planted (where the bake holds it), a grey one while it swings; a white cross on the ground
//! under the character's sole while it stands on it, red while it is below. **K** bakes the
//! clip again with contacts off (the joint rotations carried over alone) or back on, to
//! compare.

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy::transform::TransformSystems;
use bevy_egui::egui;
use bevy_wii_deform::pose::sole_patch;
use bevy_wii_deform::prelude::*;
use glam::DVec3;

use super::Args;
use super::scene::Character;

/// Retargets `--clip` (or the panel's file) onto the character and plays it.
pub struct ClipFromFilePlugin;

impl Plugin for ClipFromFilePlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(RetargetPlugin)
            .init_resource::<ClipForm>()
            .add_systems(Update, (ask_for_the_clip, play_the_clip, toggle_contacts))
            // The clip moves the joints in PostUpdate: read them once it has, and they are
            // propagated, or the marks trail the feet by a frame.
            .add_systems(PostUpdate, draw_contacts.after(TransformSystems::Propagate));
    }
}

/// The panel's clip fields, filled from `--clip` when it is given.
#[derive(Resource)]
pub struct ClipForm {
    source: String,
    animation: String,
    map: String,
}

impl FromWorld for ClipForm {
    fn from_world(world: &mut World) -> Self {
        let clip = world.get_resource::<Args>().and_then(|a| a.clip.clone());
        let text =
            |p: Option<&std::path::Path>| p.map_or(String::new(), |p| p.display().to_string());
        Self {
            source: text(clip.as_ref().map(|c| c.source.as_path())),
            animation: clip
                .as_ref()
                .and_then(|c| c.animation.clone())
                .unwrap_or_default(),
            map: text(clip.as_ref().and_then(|c| c.map.as_deref())),
        }
    }
}

/// What the panel's clip section reads and edits.
#[derive(SystemParam)]
pub struct ClipPanel<'w, 's> {
    form: ResMut<'w, ClipForm>,
    character: Query<'w, 's, (Entity, Option<&'static mut Retarget>), ClipTarget>,
    commands: Commands<'w, 's>,
}

/// The character, once poseable.
type ClipTarget = (With<Character>, With<PosedSkeleton>);

/// The panel's clip section: the source file, its animation (a glTF source's; empty: the
/// first), a chain map (empty: humanoids by name), and a button that retargets it onto the
/// character — again, with the fields changed, over a clip already playing.
pub fn clip_ui(ui: &mut egui::Ui, p: &mut ClipPanel) {
    let form = &mut *p.form;
    egui::Grid::new("clip").num_columns(2).show(ui, |ui| {
        ui.label("file");
        ui.text_edit_singleline(&mut form.source)
            .on_hover_text("a .bvh, or a .glb/.gltf character whose animation is the clip");
        ui.end_row();
        ui.label("animation");
        ui.text_edit_singleline(&mut form.animation)
            .on_hover_text("a glTF source's animation by name (empty: the first)");
        ui.end_row();
        ui.label("map");
        ui.text_edit_singleline(&mut form.map)
            .on_hover_text("a chain map (.ron) for skeletons that are not humanoids by name");
        ui.end_row();
    });
    let source = form.source.trim();
    let asked = ui
        .add_enabled(
            !source.is_empty(),
            egui::Button::new("Retarget onto the character"),
        )
        .clicked();
    if !asked {
        return;
    }
    let optional = |s: &str| Some(s.trim()).filter(|s| !s.is_empty()).map(str::to_string);
    let (animation, map) = (optional(&form.animation), optional(&form.map));
    let source = std::path::PathBuf::from(source);
    for (entity, retarget) in &mut p.character {
        match retarget {
            // Changing the asked retarget bakes it again (the plugin watches for changes).
            Some(mut retarget) => {
                retarget.source.clone_from(&source);
                retarget.animation.clone_from(&animation);
                retarget.map = map.clone().map(Into::into);
            }
            None => {
                let mut retarget = Retarget::new(&source);
                retarget.animation.clone_from(&animation);
                retarget.map = map.clone().map(Into::into);
                p.commands.entity(entity).insert(retarget);
            }
        }
    }
}

/// The character, once poseable, before its retarget is asked.
type NotYetAsked = (With<Character>, With<PosedSkeleton>, Without<Retarget>);

/// Puts the `--clip` retarget on the character once it is poseable.
fn ask_for_the_clip(
    mut commands: Commands,
    args: Res<Args>,
    character: Query<Entity, NotYetAsked>,
) {
    let Some(clip) = &args.clip else {
        return;
    };
    for entity in &character {
        let mut retarget = Retarget::new(&clip.source);
        retarget.animation = clip.animation.clone();
        retarget.map = clip.map.clone();
        commands.entity(entity).insert(retarget);
    }
}

/// Plays a landed retarget on the character's `AnimationPlayer`, looping; the pose plugin then
/// stops holding its own pose over the clip (a drag still poses it on top, until released).
fn play_the_clip(
    mut ready: MessageReader<RetargetReady>,
    mut characters: Query<&mut Poseable, With<Character>>,
    children: Query<&Children>,
    mut players: Query<(Entity, &mut AnimationPlayer)>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
    mut commands: Commands,
) {
    for message in ready.read() {
        let Ok(mut poseable) = characters.get_mut(message.entity) else {
            continue;
        };
        let mut below =
            std::iter::once(message.entity).chain(children.iter_descendants(message.entity));
        let Some(player) = below.find(|e| players.contains(*e)) else {
            warn!("--clip: the character has no AnimationPlayer to play the clip");
            continue;
        };
        let (graph, node) = AnimationGraph::from_clip(message.clip.clone());
        commands
            .entity(player)
            .insert(AnimationGraphHandle(graphs.add(graph)));
        if let Ok((_, mut player)) = players.get_mut(player) {
            player.stop_all().play(node).repeat();
        }
        poseable.hold_pose = false;
    }
}

/// **K**: the retarget baked again with its contacts switched off or on.
fn toggle_contacts(keys: Res<ButtonInput<KeyCode>>, mut retargets: Query<&mut Retarget>) {
    if !keys.just_pressed(KeyCode::KeyK) {
        return;
    }
    for mut retarget in &mut retargets {
        retarget.settings.contacts = !retarget.settings.contacts;
    }
}

/// What the contacts display keeps of a character: its size, its ground's height (its lowest
/// skin vertex in the pose it was first seen in, where the bake's ground is) and each foot's
/// sole (welded vertices, by the feet of its retarget status).
struct ContactsView {
    size: f64,
    ground: f64,
    soles: Vec<Vec<u32>>,
}

/// The source's and the target's contacts while the character's retarget plays.
///
/// * The source's: a ring round each foot joint, green while the source's foot is planted at
///   the clip's time (orange with contacts off: the bake does not hold it then), grey while it
///   swings; 4 % of the character's size across.
/// * The target's: a cross on the ground under each foot whose sole is on it (within 0.5 % of
///   the size), red where the sole is below it by more.
fn draw_contacts(
    characters: Query<
        (
            Entity,
            &RetargetStatus,
            &Retarget,
            &PosedSkeleton,
            &GlobalTransform,
        ),
        With<Character>,
    >,
    players: Query<&AnimationPlayer>,
    joints: Query<(&GlobalTransform, &Transform)>,
    mut views: Local<std::collections::HashMap<Entity, ContactsView>>,
    mut gizmos: Gizmos,
) {
    let Some(time) = players
        .iter()
        .find_map(|p| p.playing_animations().next().map(|(_, a)| a.seek_time()))
    else {
        return;
    };
    let flat = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    for (entity, status, retarget, posed, root) in &characters {
        // Sizes, soles and the ground are passes over the vertices: once per character.
        let view = views
            .entry(entity)
            .or_insert_with(|| contacts_view(posed, status));
        let scale = f64::from(root.scale().max_element());
        let size = (view.size * scale) as f32;
        let shown = posed.shown_pose(|j| joints.get(j).ok().map(|(_, local)| *local));
        for (foot, sole) in status.feet.iter().zip(&view.soles) {
            let Ok((at, _)) = joints.get(foot.joint) else {
                continue;
            };
            let planted = foot.planted_at(time);
            let colour = match (planted, retarget.settings.contacts) {
                (true, true) => Color::srgb(0.2, 0.9, 0.3),
                (true, false) => Color::srgb(0.95, 0.6, 0.1),
                (false, _) => Color::srgb(0.6, 0.6, 0.6),
            };
            let radius = if planted { 0.04 } else { 0.025 } * size;
            gizmos.circle(Isometry3d::new(at.translation(), flat), radius, colour);
            // The target's sole against the ground.
            let skin = posed.to_world(posed.model.skin_vertices(&shown, sole));
            let Some(lowest) = skin.iter().copied().min_by(|a, b| a.y.total_cmp(&b.y)) else {
                continue;
            };
            let depth = (view.ground - lowest.y) / (view.size * scale).max(1e-12);
            if depth < -0.005 {
                continue;
            }
            let colour = if depth > 0.005 {
                Color::srgb(0.95, 0.2, 0.2)
            } else {
                Color::WHITE
            };
            let on_ground = Vec3::new(lowest.x as f32, view.ground as f32, lowest.z as f32);
            let arm = 0.015 * size;
            gizmos.line(on_ground - Vec3::X * arm, on_ground + Vec3::X * arm, colour);
            gizmos.line(on_ground - Vec3::Z * arm, on_ground + Vec3::Z * arm, colour);
        }
    }
}

/// A character's [`ContactsView`], from its held pose.
fn contacts_view(posed: &PosedSkeleton, status: &RetargetStatus) -> ContactsView {
    let model = &posed.model;
    let size = model.topology().bounding_diagonal();
    let ground = posed
        .skin_welded_world()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    let soles = status
        .feet
        .iter()
        .map(|foot| {
            let joint = posed.joints.iter().position(|&j| j == foot.joint);
            joint.map_or_else(Vec::new, |j| {
                sole_patch(model, &posed.pose, j, DVec3::NEG_Y, 0.01 * size)
            })
        })
        .collect();
    ContactsView {
        size,
        ground,
        soles,
    }
}

/// The HUD's line about the clip's retarget: `asked` the character's `Retarget`, `status` how
/// it went; while `--clip` waits for the character, says so (`None` without either).
pub fn clip_line(
    args: &Args,
    asked: Option<&Retarget>,
    status: Option<&RetargetStatus>,
) -> Option<String> {
    let Some(asked) = asked else {
        let clip = args.clip.as_ref()?;
        return Some(format!(
            "clip {}: waiting for the character",
            clip.source.display()
        ));
    };
    let name = asked.source.display();
    let contacts = asked.settings.contacts;
    Some(match status {
        None => format!("clip {name}: retargeting…"),
        Some(s) => match s.phase {
            RetargetPhase::Waiting | RetargetPhase::Baking => format!("clip {name}: retargeting…"),
            RetargetPhase::Ready => format!(
                "clip {name}: {} frames, contacts {} (K){}{}",
                s.frames,
                if contacts { "on" } else { "off" },
                if s.unmapped.is_empty() {
                    String::new()
                } else {
                    format!(", {} joints unmapped", s.unmapped.len())
                },
                if s.failed_solves > 0 {
                    format!(", {} frames kept unsolved", s.failed_solves)
                } else {
                    String::new()
                }
            ),
            RetargetPhase::Failed => format!(
                "clip {name}: {}",
                s.error
                    .as_ref()
                    .map_or("failed".into(), ToString::to_string)
            ),
        },
    })
}
