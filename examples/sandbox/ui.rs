//! The egui side panel. It shows state and writes requests (messages, next states); the other
//! plugins carry them out. One function per section.

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};
use bevy_wii_deform::controllers::manager::RemoteCommand;
use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
use bevy_wii_deform::controllers::wiimote::{DemoMotion, Still};
use bevy_wii_deform::prelude::*;

use crate::challenge::{CLOSE_ENOUGH, Challenge, ChallengeState, Results, TaskList};
use crate::files::{FileCommand, FilePaths};
use crate::history::{History, HistoryCommand};
use crate::loading::{LoadModel, StartTask};
use crate::selection::{RegionsChanged, Selection, SelectionEdit, Tool};
use crate::{EditMode, InputMethod, Model, StatusLine, models, tasks};

/// The side panel.
pub struct PanelPlugin;

impl Plugin for PanelPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(EguiPrimaryContextPass, panel);
    }
}

fn panel(
    mut contexts: EguiContexts,
    mut model: ModelPanel,
    mut edit: EditPanel,
    mut remote: RemotePanel,
    mut config: ResMut<DeformConfig>,
    mut challenge: ChallengePanel,
    mut files: FilesPanel,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    let mut root = egui::Ui::new(
        ctx.clone(),
        "root".into(),
        egui::UiBuilder::new()
            .layer_id(egui::LayerId::background())
            .max_rect(ctx.viewport_rect()),
    );
    egui::Panel::left("panel")
        .default_size(290.0)
        .show(&mut root, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                model_section(ui, &mut model);
                ui.separator();
                edit_section(ui, &mut edit);
                ui.separator();
                input_section(ui, &mut remote);
                ui.separator();
                solver_section(ui, &mut config);
                ui.separator();
                challenge_section(ui, &mut challenge);
                ui.separator();
                files_section(ui, &mut files);
            });
        });
    Ok(())
}

#[derive(SystemParam)]
struct ModelPanel<'w, 's> {
    model: Res<'w, Model>,
    status: Res<'w, StatusLine>,
    statuses: Query<'w, 's, &'static DeformStatus>,
    load: MessageWriter<'w, LoadModel>,
}

fn model_section(ui: &mut egui::Ui, p: &mut ModelPanel) {
    ui.heading("bevy_wii_deform");
    ui.label(&p.status.0);
    ui.separator();
    ui.strong("Model");
    ui.horizontal_wrapped(|ui| {
        for m in models::MODELS {
            if ui.selectable_label(p.model.name == m, m).clicked() {
                p.load.write(LoadModel(m.into()));
            }
        }
    });
    ui.label("Drop a .obj/.off/.gltf/.glb file on the window to load it.");
    if let Some(s) = p.statuses.iter().next() {
        let error = s.error.as_ref().map(|e| format!(" · error: {e}"));
        ui.label(format!(
            "{:?}{} · {} vertices · {:.1} ms · {} it · E {:.5}{}",
            s.phase,
            if s.preview { " (preview)" } else { "" },
            s.vertices,
            s.solve_ms,
            s.iterations,
            s.energy,
            error.unwrap_or_default()
        ));
    }
}

#[derive(SystemParam)]
struct EditPanel<'w> {
    mode: Res<'w, State<EditMode>>,
    next_mode: ResMut<'w, NextState<EditMode>>,
    selection: ResMut<'w, Selection>,
    history: Res<'w, History>,
    history_commands: MessageWriter<'w, HistoryCommand>,
    edits: MessageWriter<'w, SelectionEdit>,
    regions: MessageWriter<'w, RegionsChanged>,
}

fn edit_section(ui: &mut egui::Ui, p: &mut EditPanel) {
    ui.strong("Mode");
    let mut mode = *p.mode.get();
    ui.horizontal(|ui| {
        ui.selectable_value(&mut mode, EditMode::Paint, "Paint regions");
        ui.selectable_value(&mut mode, EditMode::Pose, "Pose");
    });
    if mode != *p.mode.get() {
        p.next_mode.set(mode);
    }
    if mode == EditMode::Paint {
        let selection = &mut *p.selection;
        ui.horizontal(|ui| {
            ui.selectable_value(&mut selection.tool, Tool::Fixed, "Fixed (blue)");
            ui.selectable_value(&mut selection.tool, Tool::Handle, "Handle (red)");
            ui.selectable_value(&mut selection.tool, Tool::Erase, "Erase");
        });
        ui.add(egui::Slider::new(&mut selection.radius, 0.01..=0.5).text("brush radius"));
        ui.horizontal(|ui| {
            if ui.button("Clear").clicked() {
                p.edits.write(SelectionEdit::Clear);
            }
            if ui.button("Invert fixed").clicked() {
                p.edits.write(SelectionEdit::InvertFixed);
            }
        });
    }
    ui.horizontal(|ui| {
        let undo = egui::Button::new("Undo");
        if ui.add_enabled(p.history.can_undo(), undo).clicked() {
            p.history_commands.write(HistoryCommand::Undo);
        }
        let redo = egui::Button::new("Redo");
        if ui.add_enabled(p.history.can_redo(), redo).clicked() {
            p.history_commands.write(HistoryCommand::Redo);
        }
        if ui.button("Reset pose").clicked() {
            p.regions.write(RegionsChanged { pose: None });
        }
    });
}

#[derive(SystemParam)]
struct RemotePanel<'w, 's> {
    input: Res<'w, State<InputMethod>>,
    next_input: ResMut<'w, NextState<InputMethod>>,
    settings: ResMut<'w, ControllerSettings>,
    link: Option<Res<'w, ControllerLink>>,
    emulators: Option<Res<'w, ControllerEmulators>>,
    remotes: Query<'w, 's, &'static MotionController>,
    problems: Option<Res<'w, ControllerProblems>>,
}

fn input_section(ui: &mut egui::Ui, p: &mut RemotePanel) {
    ui.strong("Input");
    let mut input = *p.input.get();
    ui.horizontal(|ui| {
        ui.selectable_value(&mut input, InputMethod::Mouse, "Mouse (arcball)");
        ui.selectable_value(&mut input, InputMethod::Controller, "Wii Remote / pad");
    });
    if input != *p.input.get() {
        p.next_input.set(input);
    }
    if input != InputMethod::Controller {
        return;
    }
    let mut filter = p.settings.filter;
    ui.horizontal(|ui| {
        ui.label("Filter:");
        ui.selectable_value(&mut filter, ControllerFilter::Fusion, "ours");
        ui.selectable_value(&mut filter, ControllerFilter::Vqf, "VQF");
        ui.selectable_value(&mut filter, ControllerFilter::Paper, "paper");
        ui.selectable_value(&mut filter, ControllerFilter::Raw, "raw");
    });
    if filter != p.settings.filter {
        p.settings.filter = filter;
    }
    if p.remotes.is_empty() {
        ui.label("No remote yet (pair with SYNC).");
    }
    // Why a remote is unusable, with the exact fix (selectable, to copy).
    for problem in p.problems.iter().flat_map(|p| p.0.iter()) {
        ui.colored_label(egui::Color32::from_rgb(230, 120, 60), "Wii Remote problem:");
        let mut text = problem.to_string();
        ui.add(egui::TextEdit::multiline(&mut text).desired_rows(3));
    }
    for w in &p.remotes {
        remote_line(ui, w, p.link.as_deref());
    }
    if let Some(emu) = p.emulators.as_ref().and_then(|e| e.0.first()) {
        emulator_controls(ui, emu);
    }
}

fn remote_line(ui: &mut egui::Ui, w: &MotionController, link: Option<&ControllerLink>) {
    ui.label(format!(
        "Remote {}: {:?} · MotionPlus {} · battery {}% · {:?}{}",
        w.id,
        w.connection,
        if w.motion_plus { "on" } else { "off" },
        w.battery as u32 * 100 / 255,
        w.calibration,
        if w.pressed(Buttons::B) {
            " · B held"
        } else {
            ""
        }
    ));
    if ui.button("Recentre").clicked()
        && let Some(link) = link
    {
        link.send(w.id, RemoteCommand::Recenter);
    }
}

fn emulator_controls(ui: &mut egui::Ui, emu: &EmulatorControls) {
    ui.label("Emulated remote:");
    ui.horizontal(|ui| {
        let mut b = emu.buttons().pressed(Buttons::B);
        if ui.checkbox(&mut b, "hold B").changed() {
            emu.set_buttons(Buttons(if b { Buttons::B } else { 0 }));
        }
        if ui.button("play motion").clicked() {
            emu.set_motion(std::sync::Arc::new(DemoMotion));
        }
        if ui.button("hold still").clicked() {
            emu.set_motion(std::sync::Arc::new(Still(glam::DQuat::IDENTITY)));
        }
        let mut on = emu.connected();
        if ui.checkbox(&mut on, "power").changed() {
            emu.set_connected(on);
        }
    });
}

fn solver_section(ui: &mut egui::Ui, config: &mut DeformConfig) {
    ui.strong("Solver");
    ui.add(egui::Slider::new(&mut config.max_iterations, 1..=30).text("iterations / frame"));
    ui.add(
        egui::Slider::new(&mut config.tolerance, 0.0..=0.01)
            .logarithmic(true)
            .text("tolerance"),
    );
}

#[derive(SystemParam)]
struct ChallengePanel<'w> {
    tasks: Res<'w, TaskList>,
    start: MessageWriter<'w, StartTask>,
    challenge: Option<Res<'w, Challenge>>,
    state: Res<'w, State<ChallengeState>>,
    next_state: ResMut<'w, NextState<ChallengeState>>,
    results: ResMut<'w, Results>,
}

fn challenge_section(ui: &mut egui::Ui, p: &mut ChallengePanel) {
    ui.strong("Challenge");
    for (key, task) in &p.tasks.0 {
        if ui.button(format!("Start: {}", task.name)).clicked() {
            p.start.write(StartTask(key.clone()));
        }
    }
    if let Some(ch) = &p.challenge {
        ui.label(match ch.done {
            Some(s) => format!("{} done in {s:.1} s", ch.task.name),
            None => format!(
                "{}: {:.1} s · {:.0}% there (done at {:.0}%)",
                ch.task.name,
                ch.watch.elapsed_secs(),
                ch.progress.max(0.0) * 100.0,
                (1.0 - CLOSE_ENOUGH) * 100.0
            ),
        });
    }
    if *p.state.get() != ChallengeState::Off && ui.button("Leave challenge").clicked() {
        p.next_state.set(ChallengeState::Off);
    }
    ui.checkbox(&mut p.results.show, "Results (Table 1)");
    if p.results.show {
        results_table(ui, &p.results.rows);
    }
}

fn results_table(ui: &mut egui::Ui, rows: &[tasks::ResultRow]) {
    let seconds = |v: Option<f64>| v.map(|v| format!("{v:.1}")).unwrap_or_else(|| "–".into());
    egui::Grid::new("results").striped(true).show(ui, |ui| {
        for heading in ["task", "mouse s", "controller s", "speed-up"] {
            ui.label(heading);
        }
        ui.end_row();
        for (task, m, w, s) in tasks::summary(rows) {
            ui.label(task);
            ui.label(seconds(m));
            ui.label(seconds(w));
            ui.label(s.map(|s| format!("{s:+.0}%")).unwrap_or_else(|| "–".into()));
            ui.end_row();
        }
    });
}

#[derive(SystemParam)]
struct FilesPanel<'w> {
    paths: ResMut<'w, FilePaths>,
    commands: MessageWriter<'w, FileCommand>,
}

fn files_section(ui: &mut egui::Ui, p: &mut FilesPanel) {
    ui.strong("Files");
    ui.horizontal(|ui| {
        ui.text_edit_singleline(&mut p.paths.export);
        if ui.button("Export glTF").clicked() {
            p.commands.write(FileCommand::Export);
        }
    });
    ui.horizontal(|ui| {
        ui.text_edit_singleline(&mut p.paths.setup);
        if ui.button("Save setup").clicked() {
            p.commands.write(FileCommand::SaveSetup);
        }
        if ui.button("Load setup").clicked() {
            p.commands.write(FileCommand::LoadSetup);
        }
    });
}
