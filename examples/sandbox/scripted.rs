//! Unattended runs: the `--demo` wave, `--bend` (any loaded model bent by script),
//! `--screenshot PATH --frames N` and `--windowless` (rendering into an image, for CI's render
//! check).

use std::time::Duration;

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy_wii_deform::controllers::wiimote::FnMotion;
use bevy_wii_deform::controllers::wiimote::protocol::Buttons;
use bevy_wii_deform::deform::centroid;
use bevy_wii_deform::prelude::*;
use glam::DVec3;

use crate::challenge::Challenge;
use crate::selection::{FIXED, FREE, HANDLE, RegionsChanged, Selection};
use crate::{Model, SandboxSet};

/// Scripted input and frame capture, from the command line.
pub struct UnattendedPlugin(pub Unattended);

impl Plugin for UnattendedPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(self.0.clone())
            .add_systems(PostStartup, render_to_image)
            .add_systems(Update, (demo_script, bend_script).in_set(SandboxSet::Edit))
            .add_systems(Update, unattended_frames.after(DeformSystems::Writeback));
    }
}

/// What the command line asked for.
#[derive(Resource, Clone, Default)]
pub struct Unattended {
    pub screenshot: Option<String>,
    pub frames: u32,
    pub frame: u32,
    pub demo: bool,
    /// `--bend`: once the model is prepared, its lowest quarter is fixed and its top fifth
    /// turned 35° and moved sideways.
    pub bend: bool,
    pub windowless: bool,
    pub check_not_blank: bool,
    pub requested: bool,
}

/// The image the camera renders into with `--windowless`.
#[derive(Resource, Clone)]
struct RenderTargetImage(Handle<Image>);

/// `--windowless`: the camera renders into an image.
fn render_to_image(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    unattended: Res<Unattended>,
    camera: Query<Entity, With<Camera3d>>,
) {
    if !unattended.windowless {
        return;
    }
    let target = images.add(Image::new_target_texture(
        800,
        600,
        TextureFormat::Rgba8UnormSrgb,
        None,
    ));
    for camera in &camera {
        commands
            .entity(camera)
            .insert(RenderTarget::Image(target.clone().into()));
    }
    commands.insert_resource(RenderTargetImage(target));
}

/// `--demo`: once the emulated remote is calibrated it grabs (B), rolls 120° about its
/// pointing axis over 3 s and moves the handle up and right with the D-pad — the mannequin
/// waves.
fn demo_script(
    unattended: Res<Unattended>,
    time: Res<Time>,
    emulators: Option<Res<ControllerEmulators>>,
    remotes: Query<&MotionController>,
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
        .any(|w| matches!(w.calibration, ControllerCalibration::Calibrated(_)));
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

/// `--bend`: paints the model's lowest quarter (by height) fixed and its top fifth as the
/// handle, and poses the handle turned 35° about the view axis and moved a fifth of the
/// model's size sideways — any model, built-in or loaded, bent with no hands.
fn bend_script(
    unattended: Res<Unattended>,
    model: Res<Model>,
    statuses: Query<&DeformStatus>,
    mut selection: ResMut<Selection>,
    mut regions: MessageWriter<RegionsChanged>,
    mut done: Local<Option<Entity>>,
) {
    let Some(entity) = model.entity else {
        return;
    };
    if !unattended.bend || *done == Some(entity) {
        return;
    }
    if !statuses.get(entity).is_ok_and(|s| s.vertices > 0) {
        return;
    }
    let positions = &model.mesh.positions;
    let (lo, hi) = model.mesh.bounds();
    let height = (hi.y - lo.y).max(1e-9);
    selection.labels = positions
        .iter()
        .map(|p| match (p.y - lo.y) / height {
            h if h < 0.25 => FIXED,
            h if h > 0.8 => HANDLE,
            _ => FREE,
        })
        .collect();
    let handle: Vec<u32> = (0..positions.len() as u32)
        .filter(|&i| selection.labels[i as usize] == HANDLE)
        .collect();
    let pivot = centroid(positions, &handle).as_vec3();
    let sideways = Vec3::X * (height as f32) * 0.2;
    regions.write(RegionsChanged {
        pose: Some(
            Transform::from_translation(pivot + sideways)
                .with_rotation(Quat::from_rotation_z(-35f32.to_radians())),
        ),
    });
    *done = Some(entity);
}

fn unattended_frames(
    mut commands: Commands,
    mut u: ResMut<Unattended>,
    target: Option<Res<RenderTargetImage>>,
    statuses: Query<&DeformStatus>,
    challenge: Option<Res<Challenge>>,
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
    if let Some(ch) = &challenge {
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
