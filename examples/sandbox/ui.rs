//! The egui side panel.

use super::*;

#[allow(clippy::too_many_arguments)]
pub(super) fn ui_panel(
    mut contexts: EguiContexts,
    mut commands: Commands,
    mut sb: ResMut<Sandbox>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut config: ResMut<DeformConfig>,
    mut wii_settings: ResMut<WiimoteSettings>,
    link: Option<Res<WiimoteLink>>,
    emulators: Option<Res<WiimoteEmulators>>,
    (remotes, wii_problems): (Query<&Wiimote>, Option<Res<WiimoteProblems>>),
    statuses: Query<&DeformStatus>,
    mesh_q: Query<&Mesh3d>,
    mut transforms: Query<&mut Transform, Without<Camera3d>>,
    mut clear: ResMut<ClearColor>,
    mut history: ResMut<HistoryRequest>,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    let mut root = egui::Ui::new(
        ctx.clone(),
        "root".into(),
        egui::UiBuilder::new()
            .layer_id(egui::LayerId::background())
            .max_rect(ctx.viewport_rect()),
    );
    let mut regions_changed = false;
    // A pose to put the new handle at (Load setup), instead of rest.
    let mut restored_pose: Option<Transform> = None;
    egui::Panel::left("panel")
        .default_size(290.0)
        .show(&mut root, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                ui.heading("bevy_wii_deform");
                ui.label(&sb.message);
                ui.separator();
                ui.strong("Model");
                ui.horizontal_wrapped(|ui| {
                    for m in models::MODELS {
                        if ui.selectable_label(sb.model_name == m, m).clicked() {
                            sb.pending_load = Some(m.into());
                        }
                    }
                });
                ui.label("Drop a .obj/.off/.gltf/.glb file on the window to load it.");
                if let Some(s) = statuses.iter().next() {
                    ui.label(format!(
                        "{:?} · {} vertices · {:.1} ms · {} it · E {:.5}{}",
                        s.phase,
                        s.vertices,
                        s.solve_ms,
                        s.iterations,
                        s.energy,
                        s.error
                            .as_ref()
                            .map(|e| format!(" · error: {e}"))
                            .unwrap_or_default()
                    ));
                }
                ui.separator();
                ui.strong("Mode");
                ui.horizontal(|ui| {
                    ui.selectable_value(&mut sb.mode, Mode::Paint, "Paint regions");
                    ui.selectable_value(&mut sb.mode, Mode::Pose, "Pose");
                });
                if sb.mode == Mode::Paint {
                    ui.horizontal(|ui| {
                        ui.selectable_value(&mut sb.tool, Tool::Fixed, "Fixed (blue)");
                        ui.selectable_value(&mut sb.tool, Tool::Handle, "Handle (red)");
                        ui.selectable_value(&mut sb.tool, Tool::Erase, "Erase");
                    });
                    ui.add(egui::Slider::new(&mut sb.radius, 0.01..=0.5).text("brush radius"));
                    ui.horizontal(|ui| {
                        if ui.button("Clear").clicked() {
                            let snap = snapshot(&sb, &transforms);
                            sb.undo.push(snap);
                            sb.redo.clear();
                            sb.selection.iter_mut().for_each(|s| *s = FREE);
                            regions_changed = true;
                        }
                        if ui.button("Invert fixed").clicked() {
                            let snap = snapshot(&sb, &transforms);
                            sb.undo.push(snap);
                            sb.redo.clear();
                            for s in sb.selection.iter_mut() {
                                *s = match *s {
                                    FIXED => FREE,
                                    FREE => FIXED,
                                    other => other,
                                };
                            }
                            regions_changed = true;
                        }
                    });
                }
                ui.horizontal(|ui| {
                    if ui
                        .add_enabled(!sb.undo.is_empty(), egui::Button::new("Undo"))
                        .clicked()
                    {
                        history.0 = Some(true);
                    }
                    if ui
                        .add_enabled(!sb.redo.is_empty(), egui::Button::new("Redo"))
                        .clicked()
                    {
                        history.0 = Some(false);
                    }
                    if ui.button("Reset pose").clicked() {
                        if let Some(h) = sb.handle_entity
                            && let Ok(mut t) = transforms.get_mut(h)
                        {
                            t.rotation = Quat::IDENTITY;
                        }
                        regions_changed = true;
                    }
                });
                ui.separator();
                ui.strong("Input");
                let before = sb.input;
                ui.horizontal(|ui| {
                    ui.selectable_value(&mut sb.input, InputMethod::Mouse, "Mouse (arcball)");
                    ui.selectable_value(&mut sb.input, InputMethod::Wiimote, "Wii Remote");
                });
                if sb.input != before
                    && let Some(h) = sb.handle_entity
                {
                    // Switch the handle's control in place: the pose stays.
                    if sb.input == InputMethod::Wiimote {
                        commands.entity(h).insert(
                            WiimoteHandleControl::default().with_space(sb.mesh_entity.unwrap_or(h)),
                        );
                    } else {
                        commands.entity(h).remove::<WiimoteHandleControl>();
                    }
                }
                if sb.input == InputMethod::Wiimote {
                    let mut filter = wii_settings.filter;
                    ui.horizontal(|ui| {
                        ui.label("Filter:");
                        ui.selectable_value(&mut filter, WiimoteFilter::Fusion, "ours");
                        ui.selectable_value(&mut filter, WiimoteFilter::Vqf, "VQF");
                        ui.selectable_value(&mut filter, WiimoteFilter::Paper, "paper");
                        ui.selectable_value(&mut filter, WiimoteFilter::Raw, "raw");
                    });
                    if filter != wii_settings.filter {
                        wii_settings.filter = filter;
                    }
                    if remotes.is_empty() {
                        ui.label("No remote yet (pair with SYNC).");
                    }
                    // Why a remote is unusable, with the exact fix (selectable, to copy).
                    for problem in wii_problems.iter().flat_map(|p| p.0.iter()) {
                        ui.colored_label(
                            egui::Color32::from_rgb(230, 120, 60),
                            "Wii Remote problem:",
                        );
                        let mut text = problem.to_string();
                        ui.add(
                            egui::TextEdit::multiline(&mut text)
                                .desired_rows(3)
                                .interactive(true),
                        );
                    }
                    for w in &remotes {
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
                            && let Some(link) = &link
                        {
                            link.send(w.id, RemoteCommand::Recenter);
                        }
                    }
                    if let Some(emu) = emulators.as_ref().and_then(|e| e.0.first()) {
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
                }
                ui.separator();
                ui.strong("Solver");
                ui.add(
                    egui::Slider::new(&mut config.max_iterations, 1..=30)
                        .text("iterations / frame"),
                );
                ui.add(
                    egui::Slider::new(&mut config.tolerance, 0.0..=0.01)
                        .logarithmic(true)
                        .text("tolerance"),
                );
                ui.separator();
                ui.strong("Challenge");
                let keys: Vec<(String, String)> = sb
                    .tasks
                    .iter()
                    .map(|(k, t)| (k.clone(), t.name.clone()))
                    .collect();
                for (key, name) in keys {
                    if ui.button(format!("Start: {name}")).clicked() {
                        sb.pending_task = Some(key);
                    }
                }
                if let Some(ch) = &sb.challenge {
                    match ch.done {
                        Some(s) => ui.label(format!("{} done in {s:.1} s", ch.task.name)),
                        None => ui.label(format!(
                            "{}: {:.1} s · {:.0}% there (done at {:.0}%)",
                            ch.task.name,
                            ch.watch.elapsed_secs(),
                            ch.progress.max(0.0) * 100.0,
                            (1.0 - CLOSE_ENOUGH) * 100.0
                        )),
                    };
                }
                if sb.challenge.is_some() && ui.button("Leave challenge").clicked() {
                    sb.challenge = None;
                    if let Some(c) = sb.cloud_entity.take() {
                        commands.entity(c).despawn();
                    }
                    clear.0 = BACKGROUND;
                }
                ui.checkbox(&mut sb.show_results, "Results (Table 1)");
                if sb.show_results {
                    egui::Grid::new("results").striped(true).show(ui, |ui| {
                        ui.label("task");
                        ui.label("mouse s");
                        ui.label("wiimote s");
                        ui.label("speed-up");
                        ui.end_row();
                        for (task, m, w, s) in tasks::summary(&sb.results) {
                            let f = |v: Option<f64>| {
                                v.map(|v| format!("{v:.1}")).unwrap_or_else(|| "–".into())
                            };
                            ui.label(task);
                            ui.label(f(m));
                            ui.label(f(w));
                            ui.label(s.map(|s| format!("{s:+.0}%")).unwrap_or_else(|| "–".into()));
                            ui.end_row();
                        }
                    });
                }
                ui.separator();
                ui.strong("Files");
                ui.horizontal(|ui| {
                    ui.text_edit_singleline(&mut sb.export_path);
                    if ui.button("Export glTF").clicked() {
                        let msg = sb
                            .mesh_entity
                            .and_then(|e| mesh_q.get(e).ok())
                            .and_then(|m| meshes.get(&m.0))
                            .map(|m| match export_glb(m, &sb.export_path) {
                                Ok(()) => format!("exported {}", sb.export_path),
                                Err(e) => format!("export failed: {e}"),
                            })
                            .unwrap_or_else(|| "nothing to export".into());
                        sb.message = msg;
                    }
                });
                ui.horizontal(|ui| {
                    ui.text_edit_singleline(&mut sb.setup_path);
                    if ui.button("Save setup").clicked() {
                        let handle = sb
                            .handle_entity
                            .and_then(|h| transforms.get(h).ok().copied())
                            .unwrap_or_default();
                        sb.message = match save_setup(&sb, handle) {
                            Ok(()) => format!("saved {}", sb.setup_path),
                            Err(e) => format!("save failed: {e}"),
                        };
                    }
                    if ui.button("Load setup").clicked() {
                        match load_setup(&sb.setup_path) {
                            Ok(setup) => {
                                if setup.model != sb.model_name {
                                    sb.message = format!(
                                        "setup is for model {:?}; load it first",
                                        setup.model
                                    );
                                } else if setup.selection.len() != sb.selection.len() {
                                    sb.message = "setup does not match this mesh".into();
                                } else {
                                    restored_pose = Some(setup.pose());
                                    sb.selection = setup.selection;
                                    regions_changed = true;
                                    sb.message = format!("loaded {}", sb.setup_path);
                                }
                            }
                            Err(e) => sb.message = format!("load failed: {e}"),
                        }
                    }
                });
            });
        });
    if regions_changed {
        sync_regions(&mut commands, &mut sb, restored_pose);
        if let Some(m) = sb.mesh_entity.and_then(|e| mesh_q.get(e).ok()) {
            update_colors(&sb, &mut meshes, m);
        }
    }
    Ok(())
}
