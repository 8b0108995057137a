//! The pose library panel: named poses in `poses/library/` (RON pose files): apply, apply
//! mirrored, blend two by a weight, save the current pose under a name.

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::egui;
use bevy_wii_deform::pose::{BlendMode, Mirror, PoseFile, PoseLibrary, blend_pose};
use bevy_wii_deform::prelude::*;

use crate::files::{LastMessage, directory};
use crate::scene::Character;

/// What the library panel reads and edits.
#[derive(SystemParam)]
pub struct LibraryPanel<'w, 's> {
    character: Query<'w, 's, &'static mut PosedSkeleton, With<Character>>,
    message: ResMut<'w, LastMessage>,
    state: Local<'s, LibraryState>,
}

/// The panel's own state: the listing, the two poses to blend, the name to save as.
#[derive(Default)]
pub struct LibraryState {
    names: Option<Vec<String>>,
    blend: (Option<String>, Option<String>, f32),
    save_as: String,
}

fn library() -> PoseLibrary {
    PoseLibrary::new(directory().join("library"))
}

/// The library panel's contents.
pub fn library_ui(ui: &mut egui::Ui, p: &mut LibraryPanel) {
    let Some(mut posed) = p.character.iter_mut().next() else {
        return;
    };
    let library = library();
    if p.state.names.is_none() || ui.button("Refresh").clicked() {
        p.state.names = Some(library.names().unwrap_or_default());
    }
    let names = p.state.names.clone().unwrap_or_default();
    if names.is_empty() {
        ui.label(format!("no poses in {}", library.folder().display()));
    }
    for name in &names {
        ui.horizontal(|ui| {
            ui.label(name);
            if ui.button("Apply").clicked() {
                p.message.0 = apply(&library, name, &mut posed, false);
            }
            if ui.button("Mirrored").clicked() {
                p.message.0 = apply(&library, name, &mut posed, true);
            }
        });
    }
    ui.separator();
    ui.label("Blend two poses");
    let (a, b, weight) = &mut p.state.blend;
    for (label, slot) in [("A", a), ("B", b)] {
        egui::ComboBox::from_label(label)
            .selected_text(slot.clone().unwrap_or_default())
            .show_ui(ui, |ui| {
                for name in &names {
                    ui.selectable_value(slot, Some(name.clone()), name);
                }
            });
    }
    ui.add(egui::Slider::new(weight, 0.0..=1.0).text("weight of B"));
    if ui.button("Apply blend").clicked() {
        let (a, b, w) = p.state.blend.clone();
        p.message.0 = match (a, b) {
            (Some(a), Some(b)) => blend_two(&library, &a, &b, w, &mut posed),
            _ => "choose poses A and B".into(),
        };
    }
    ui.separator();
    ui.horizontal(|ui| {
        ui.text_edit_singleline(&mut p.state.save_as);
        if ui.button("Save current").clicked() {
            p.message.0 = match library.save(&p.state.save_as, &posed.pose_file()) {
                Ok(path) => format!("saved {}", path.display()),
                Err(e) => format!("save failed: {e}"),
            };
            p.state.names = None;
        }
    });
}

/// Applies pose `name` (mirrored across the character's symmetry plane when asked).
fn apply(library: &PoseLibrary, name: &str, posed: &mut PosedSkeleton, mirrored: bool) -> String {
    let skeleton = posed.model.skeleton();
    let pose = library
        .load(name)
        .and_then(|file| file.apply(skeleton, &posed.pose));
    match pose {
        Ok(pose) => {
            posed.pose = if mirrored {
                Mirror::new(skeleton, &skeleton.bind_pose()).mirror(&pose)
            } else {
                pose
            };
            format!(
                "applied {name}{}",
                if mirrored { " (mirrored)" } else { "" }
            )
        }
        Err(e) => format!("{name}: {e}"),
    }
}

/// Applies the blend of poses `a` and `b` by `weight` (0 = a, 1 = b).
fn blend_two(
    library: &PoseLibrary,
    a: &str,
    b: &str,
    weight: f32,
    posed: &mut PosedSkeleton,
) -> String {
    let skeleton = posed.model.skeleton();
    let load = |name: &str| {
        library
            .load(name)
            .and_then(|f: PoseFile| f.apply(skeleton, &posed.pose))
    };
    match (load(a), load(b)) {
        (Ok(pa), Ok(pb)) => {
            posed.pose = blend_pose(&pa, &pb, &pb, BlendMode::Override, f64::from(weight), None);
            format!("applied {a} ↔ {b} at {weight:.2}")
        }
        (Err(e), _) | (_, Err(e)) => format!("blend failed: {e}"),
    }
}
