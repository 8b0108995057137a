//! The egui panels: the timeline along the bottom; undo/redo, the body settings (limits,
//! mirror, planted feet), the pose library and a clip from a file on the right. Presses on a panel do not reach the character (bevy_egui's picking).

use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};

use crate::body::{BodyPanel, body_ui};
use crate::clip::{ClipPanel, clip_ui};
use crate::history::HistoryCommand;
use crate::library::{LibraryPanel, library_ui};
use crate::timeline::{TimelinePanel, timeline_ui};

/// The panels.
pub struct UiPlugin;

impl Plugin for UiPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(EguiPlugin::default())
            .add_systems(EguiPrimaryContextPass, panels);
    }
}

fn panels(
    mut contexts: EguiContexts,
    // The timeline reads the character, the library writes its pose: one at a time.
    mut panels: ParamSet<(TimelinePanel, LibraryPanel, BodyPanel, ClipPanel)>,
    mut history: MessageWriter<HistoryCommand>,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    let mut root = egui::Ui::new(
        ctx.clone(),
        "root".into(),
        egui::UiBuilder::new()
            .layer_id(egui::LayerId::background())
            .max_rect(ctx.viewport_rect()),
    );
    egui::Panel::bottom("timeline").show(&mut root, |ui| {
        timeline_ui(ui, &mut panels.p0());
    });
    egui::Panel::right("library")
        .default_size(230.0)
        .show(&mut root, |ui| {
            ui.horizontal(|ui| {
                if ui.button("Undo").clicked() {
                    history.write(HistoryCommand::Undo);
                }
                if ui.button("Redo").clicked() {
                    history.write(HistoryCommand::Redo);
                }
            });
            ui.separator();
            ui.heading("Body");
            body_ui(ui, &mut panels.p2());
            ui.separator();
            ui.heading("Poses");
            library_ui(ui, &mut panels.p1());
            ui.separator();
            ui.heading("Clip from a file");
            clip_ui(ui, &mut panels.p3());
        });
    Ok(())
}
