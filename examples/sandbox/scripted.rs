//! Scripted runs: the `--demo` wave, the challenge timer and `--windowless`/`--screenshot` frames.

use super::*;

/// `--demo`: once the emulated remote is calibrated it grabs (B), rolls 120° about its
/// pointing axis over 3 s and moves the handle up and right with the D-pad — the mannequin
/// waves.
pub(super) fn demo_script(
    unattended: Res<Unattended>,
    time: Res<Time>,
    emulators: Option<Res<WiimoteEmulators>>,
    remotes: Query<&Wiimote>,
    mut started: Local<Option<f32>>,
) {
    if !unattended.demo {
        return;
    }
    let Some(emu) = emulators.and_then(|e| e.0.first().cloned()) else {
        return;
    };
    let calibrated = remotes
        .iter()
        .any(|w| matches!(w.calibration, WiimoteCalibration::Calibrated(_)));
    if !calibrated {
        return;
    }
    let now = time.elapsed_secs();
    let t0 = *started.get_or_insert_with(|| {
        // The emulator's clock started with the app; script the roll in its time.
        let start = now as f64 + 0.5;
        emu.set_motion(std::sync::Arc::new(FnMotion(move |t: f64| {
            let angle = ((t - start) / 3.0).clamp(0.0, 1.0) * 120f64.to_radians();
            (glam::DQuat::from_rotation_y(angle), DVec3::ZERO)
        })));
        now
    });
    let t = now - t0;
    let mut b = if t > 0.3 { Buttons::B } else { 0 };
    if (0.5..2.0).contains(&t) {
        b |= Buttons::UP;
    }
    if (2.0..2.2).contains(&t) {
        b |= Buttons::RIGHT;
    }
    emu.set_buttons(Buttons(b));
}

pub(super) fn challenge_progress(
    mut sb: ResMut<Sandbox>,
    time: Res<Time>,
    mut clear: ResMut<ClearColor>,
    meshes: Res<Assets<Mesh>>,
    mesh_q: Query<&Mesh3d>,
) {
    let input = sb.input;
    let diagonal = sb.diagonal;
    let Some(mesh_entity) = sb.mesh_entity else {
        return;
    };
    let Some(ch) = sb.challenge.as_mut() else {
        return;
    };
    if ch.done.is_some() {
        return;
    }
    ch.watch.tick(time.delta());
    let Some(VertexAttributeValues::Float32x3(current)) = mesh_q
        .get(mesh_entity)
        .ok()
        .and_then(|m| meshes.get(&m.0))
        .and_then(|m| m.attribute(Mesh::ATTRIBUTE_POSITION))
    else {
        return;
    };
    if current.len() != ch.target.len() {
        return;
    }
    let mean = current
        .iter()
        .zip(&ch.target)
        .map(|(c, t)| Vec3::from_array(*c).as_dvec3().distance(*t))
        .sum::<f64>()
        / current.len() as f64;
    ch.progress = 1.0 - mean / ch.start_error.max(1e-12);
    if mean < CLOSE_ENOUGH * ch.start_error + 1e-4 * diagonal {
        let secs = ch.watch.elapsed_secs_f64();
        ch.done = Some(secs);
        clear.0 = SUCCESS;
        let row = tasks::ResultRow {
            task: ch.key.clone(),
            input: input.name().into(),
            seconds: secs,
        };
        let msg = match tasks::append_result(RESULTS_CSV, &row) {
            Ok(()) => format!(
                "done in {secs:.1} s with the {} — saved to {RESULTS_CSV}",
                input.name()
            ),
            Err(e) => format!("done in {secs:.1} s (could not save: {e})"),
        };
        sb.results.push(row);
        sb.message = msg;
    }
}

pub(super) fn unattended_frames(
    mut commands: Commands,
    mut u: ResMut<Unattended>,
    target: Option<Res<RenderTargetImage>>,
    statuses: Query<&DeformStatus>,
    sb: Res<Sandbox>,
    mut exit: MessageWriter<AppExit>,
) {
    u.frame += 1;
    let Some(path) = u.screenshot.clone() else {
        return;
    };
    // Wait for the model to be prepared so the frame shows it.
    let ready = statuses.iter().any(|s| s.vertices > 0);
    if u.requested || u.frame < u.frames || !ready {
        if u.frame > u.frames + 2000 {
            eprintln!("gave up waiting for the model");
            exit.write(AppExit::error());
        }
        return;
    }
    u.requested = true;
    if let Some(ch) = &sb.challenge {
        info!(
            "challenge {}: {:.0}% of the way{}",
            ch.key,
            ch.progress.max(0.0) * 100.0,
            if ch.done.is_some() { " — done" } else { "" }
        );
    }
    let check = u.check_not_blank;
    let shot = match target {
        Some(t) => Screenshot::image(t.0.clone()),
        None => Screenshot::primary_window(),
    };
    commands
        .spawn(shot)
        .observe(save_to_disk(path.clone()))
        .observe(
            move |captured: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
                let img: &Image = &captured;
                let data = img.data.as_deref().unwrap_or(&[]);
                let mut distinct = std::collections::HashSet::new();
                for px in data.chunks_exact(4).step_by(7) {
                    distinct.insert([px[0] / 8, px[1] / 8, px[2] / 8]);
                }
                println!(
                    "screenshot {path}: {} bytes, {} distinct colours",
                    data.len(),
                    distinct.len()
                );
                if check && distinct.len() < 8 {
                    eprintln!("render check failed: the frame is blank");
                    exit.write(AppExit::error());
                } else {
                    // Give save_to_disk a moment before exiting.
                    std::thread::sleep(Duration::from_millis(300));
                    exit.write(AppExit::Success);
                }
            },
        );
}
