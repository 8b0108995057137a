//! The timeline panel: keys of the clip being authored (the library's `PoseTimeline` on the
//! character), scrub, play/loop, set/delete/move keys, import one of the model's own clips,
//! export the clip as a glTF animation (`poses/clip.glb`).

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::egui;
use bevy_wii_deform::pose::KeyInterpolation;
use bevy_wii_deform::prelude::*;

use crate::Args;
use crate::files::{InitialPose, LastMessage, directory, node_of};
use crate::scene::{Character, NewCharacter};

/// A `PoseTimeline` on the character, and its panel (drawn by [`crate::ui::UiPlugin`]).
pub struct TimelinePlugin;

impl Plugin for TimelinePlugin {
    fn build(&self, app: &mut App) {
        let clips = app
            .world()
            .get_resource::<Args>()
            .map(|a| model_clips(&a.model))
            .unwrap_or_default();
        app.insert_resource(ModelClips(clips))
            .add_systems(Update, add_timeline.before(PoseSystems::Request));
    }
}

/// Names of the animations in the model's file (offered for import).
#[derive(Resource, Default)]
pub struct ModelClips(pub Vec<String>);

fn model_clips(path: &str) -> Vec<String> {
    gltf::Gltf::open(crate::cli::asset_file(path))
        .map(|g| {
            g.document
                .animations()
                .enumerate()
                .map(|(i, a)| {
                    a.name()
                        .map_or_else(|| format!("Animation{i}"), str::to_string)
                })
                .collect()
        })
        .unwrap_or_default()
}

fn add_timeline(mut commands: Commands, character: Query<Entity, NewCharacter>) {
    for entity in &character {
        commands.entity(entity).insert(PoseTimeline::default());
    }
}

/// What the timeline panel reads and edits.
#[derive(SystemParam)]
pub struct TimelinePanel<'w, 's> {
    character: Query<
        'w,
        's,
        (
            &'static mut PoseTimeline,
            &'static PosedSkeleton,
            &'static InitialPose,
        ),
        With<Character>,
    >,
    names: Query<
        'w,
        's,
        (
            Option<&'static Name>,
            Option<&'static ChildOf>,
            Has<AnimationPlayer>,
        ),
    >,
    clips: Res<'w, ModelClips>,
    args: Res<'w, Args>,
    message: ResMut<'w, LastMessage>,
    /// The key last clicked (moved by "Move key here").
    selected: Local<'s, Option<usize>>,
}

/// The timeline panel's contents.
pub fn timeline_ui(ui: &mut egui::Ui, p: &mut TimelinePanel) {
    let Some((mut timeline, posed, initial)) = p.character.iter_mut().next() else {
        ui.label("loading...");
        return;
    };
    let end = timeline.clip.duration().max(1.0) + 0.5;
    ui.horizontal(|ui| {
        let play = if timeline.playing { "Pause" } else { "Play" };
        if ui.button(play).clicked() {
            timeline.playing = !timeline.playing;
        }
        let mut looping = timeline.looping;
        if ui.checkbox(&mut looping, "loop").changed() {
            timeline.looping = looping;
        }
        let mut time = timeline.time;
        ui.spacing_mut().slider_width = 480.0;
        let slider = egui::Slider::new(&mut time, 0.0..=end)
            .text("s")
            .step_by(0.01);
        if ui.add(slider).changed() {
            timeline.time = time;
            timeline.playing = false;
        }
    });
    ui.horizontal(|ui| {
        ui.label("keys:");
        let keys: Vec<f32> = timeline.clip.times();
        for (i, t) in keys.iter().enumerate() {
            let at = (t - timeline.time).abs() < 1e-4;
            if ui.selectable_label(at, format!("{t:.2}")).clicked() {
                timeline.time = *t;
                timeline.playing = false;
                *p.selected = Some(i);
            }
        }
        if let Some(i) = *p.selected
            && i < keys.len()
            && ui.button(format!("Move key {:.2} here", keys[i])).clicked()
        {
            let to = timeline.time;
            match timeline.clip.move_key(i, to) {
                Ok(at) => *p.selected = Some(at),
                Err(e) => p.message.0 = format!("move refused: {e}"),
            }
        }
        if keys.is_empty() {
            ui.label("(none: pose the character, then Set key)");
        }
    });
    ui.horizontal(|ui| {
        let mut mode = timeline.interpolation;
        egui::ComboBox::from_label("new keys")
            .selected_text(format!("{mode:?}"))
            .show_ui(ui, |ui| {
                for m in [
                    KeyInterpolation::Step,
                    KeyInterpolation::Linear,
                    KeyInterpolation::CubicSpline,
                ] {
                    ui.selectable_value(&mut mode, m, format!("{m:?}"));
                }
            });
        if mode != timeline.interpolation {
            timeline.interpolation = mode;
        }
        if ui.button("Set key").clicked() {
            p.message.0 = match timeline.set_key(posed) {
                Ok(_) => format!("key set at {:.2} s", timeline.time),
                Err(e) => format!("key refused: {e}"),
            };
        }
        if ui.button("Delete key").clicked() && !timeline.delete_key_at_time() {
            p.message.0 = "no key at this time".into();
        }
        if ui.button("Export clip").clicked() {
            p.message.0 = export(&timeline, posed, initial, &p.names);
        }
        for (i, name) in p.clips.0.iter().enumerate() {
            if ui.button(format!("Import {name}")).clicked() {
                let path = crate::cli::asset_file(&p.args.model);
                let name = p.clips.0.get(i).map(String::as_str);
                p.message.0 = match timeline.import_gltf(&path, name, posed) {
                    Ok(()) => format!(
                        "imported {} keys of {}",
                        timeline.clip.keys().len(),
                        name.unwrap_or("")
                    ),
                    Err(e) => format!("import failed: {e}"),
                };
            }
        }
    });
}

/// Writes the clip to `poses/clip.glb`; the message to show.
pub fn export(
    timeline: &PoseTimeline,
    posed: &PosedSkeleton,
    initial: &InitialPose,
    names: &Query<(Option<&Name>, Option<&ChildOf>, Has<AnimationPlayer>)>,
) -> String {
    let dir = directory();
    let written = std::fs::create_dir_all(&dir)
        .map_err(|e| e.to_string())
        .and_then(|()| {
            timeline
                .export_glb("authored", posed, |e| node_of(names, e), Some(&initial.0))
                .map_err(|e| e.to_string())
        })
        .and_then(|glb| std::fs::write(dir.join("clip.glb"), glb).map_err(|e| e.to_string()));
    match written {
        Ok(()) => format!(
            "exported {} keys to {}/clip.glb",
            timeline.clip.keys().len(),
            dir.display()
        ),
        Err(e) => format!("export failed: {e}"),
    }
}
