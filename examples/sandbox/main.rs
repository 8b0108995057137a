//! Sandbox: load a model, paint fixed/handle regions, pose with the mouse (arcball) or a Wii
//! Remote — and a challenge mode that replays the paper's user study as a game.
//!
//! ```text
//! cargo run --release --example sandbox [-- MODEL|PATH.obj|PATH.gltf|PATH.glb]
//!     [--task NAME] [--demo] [--emulate] [--screenshot PATH --frames N] [--windowless]
//! ```
//! Mouse: right-drag orbits, wheel zooms, middle-drag pans. In *Paint* mode left-drag paints
//! with the brush; in *Pose* mode left-drag turns the handle with an arcball, Shift+left-drag
//! moves it in the view plane. Wiimote: hold B and turn the remote (1:1), D-pad/+/− move,
//! Home recentres. Ctrl+Z / Ctrl+Y undo and redo.
//!
//! Where things are: `main.rs` — app wiring, state, scene and region sync; `loading.rs` —
//! models in the background; `camera.rs` — orbit camera; `editing.rs` — painting, undo,
//! shortcuts; `scripted.rs` — demo, challenge timer, unattended frames; `ui.rs` — the egui
//! panel; `files.rs` — setup files and GLB export; `tasks.rs` — the study's tasks.

mod camera;
mod editing;
mod files;
mod loading;
#[path = "../common/models.rs"]
mod models;
mod scripted;
mod tasks;
mod ui;

use camera::*;
use editing::*;
use files::*;
use loading::*;
use scripted::*;
use ui::*;

use std::time::Duration;

use bevy::asset::RenderAssetUsages;
use bevy::camera::RenderTarget;
use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::picking::mesh_picking::ray_cast::{MeshRayCast, MeshRayCastSettings, RayCastVisibility};
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::render_resource::TextureFormat;
use bevy::render::settings::WgpuSettings;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::time::Stopwatch;
use bevy::window::{ExitCondition, FileDragAndDrop, PrimaryWindow};
use bevy::winit::WinitPlugin;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};
use bevy_wii_deform::deform::{TriMesh, synth};
use bevy_wii_deform::prelude::*;
use bevy_wii_deform::wiimote::protocol::Buttons;
use bevy_wii_deform::wiimote::{DemoMotion, FnMotion, RemoteCommand, Still};
use glam::DVec3;

const RESULTS_CSV: &str = "challenge_results.csv";
/// Done when the mean vertex distance to the target is below this fraction of the mean
/// distance between the rest pose and the target (i.e. 85% of the way there).
const CLOSE_ENOUGH: f64 = 0.15;
const BACKGROUND: Color = Color::srgb(0.12, 0.13, 0.16);
const SUCCESS: Color = Color::srgb(0.10, 0.35, 0.16);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tool {
    Fixed,
    Handle,
    Erase,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Paint,
    Pose,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum InputMethod {
    Mouse,
    Wiimote,
}

impl InputMethod {
    fn name(self) -> &'static str {
        match self {
            InputMethod::Mouse => "mouse",
            InputMethod::Wiimote => "wiimote",
        }
    }
}

const FREE: u8 = 0;
const FIXED: u8 = 1;
const HANDLE: u8 = 2;

#[derive(Clone, PartialEq)]
struct Snapshot {
    selection: Vec<u8>,
    handle: Transform,
}

struct Challenge {
    key: String,
    task: tasks::Task,
    target: Vec<DVec3>,
    /// Mean distance rest → target.
    start_error: f64,
    watch: Stopwatch,
    done: Option<f64>,
    /// 0 at rest, 1 on target.
    progress: f64,
}

#[derive(Resource)]
struct Sandbox {
    model_name: String,
    mesh: TriMesh,
    diagonal: f64,
    mesh_entity: Option<Entity>,
    handle_entity: Option<Entity>,
    cloud_entity: Option<Entity>,
    selection: Vec<u8>,
    tool: Tool,
    radius: f32,
    mode: Mode,
    input: InputMethod,
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
    stroke: bool,
    message: String,
    tasks: Vec<(String, tasks::Task)>,
    challenge: Option<Challenge>,
    results: Vec<tasks::ResultRow>,
    pending_load: Option<String>,
    pending_task: Option<String>,
    show_results: bool,
    setup_path: String,
    export_path: String,
}

impl Sandbox {
    /// No model, no tasks, mouse input, Paint mode.
    fn empty() -> Self {
        Self {
            model_name: String::new(),
            mesh: TriMesh::default(),
            diagonal: 1.0,
            mesh_entity: None,
            handle_entity: None,
            cloud_entity: None,
            selection: Vec::new(),
            tool: Tool::Fixed,
            radius: 0.08,
            mode: Mode::Paint,
            input: InputMethod::Mouse,
            undo: Vec::new(),
            redo: Vec::new(),
            stroke: false,
            message: String::new(),
            tasks: Vec::new(),
            challenge: None,
            results: Vec::new(),
            pending_load: None,
            pending_task: None,
            show_results: false,
            setup_path: "sandbox_setup.ron".into(),
            export_path: "posed.glb".into(),
        }
    }
}

#[derive(Resource, Default)]
struct OrbitCamera {
    yaw: f32,
    pitch: f32,
    distance: f32,
    focus: Vec3,
}

#[derive(Resource)]
struct Unattended {
    screenshot: Option<String>,
    frames: u32,
    frame: u32,
    demo: bool,
    windowless: bool,
    check_not_blank: bool,
    requested: bool,
}

#[derive(Resource, Clone)]
struct RenderTargetImage(Handle<Image>);

fn arg_value(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
}

fn main() -> AppExit {
    let args: Vec<String> = std::env::args().collect();
    let windowless = args.iter().any(|a| a == "--windowless");
    let demo = args.iter().any(|a| a == "--demo");
    let emulate = demo || args.iter().any(|a| a == "--emulate") || windowless;
    let model = args
        .iter()
        .skip(1)
        .find(|a| {
            !a.starts_with("--")
                && !args
                    .iter()
                    .any(|b| b.starts_with("--") && arg_value(&args, b).as_ref() == Some(*a))
        })
        .cloned()
        .unwrap_or_else(|| "mannequin".into());
    let unattended = Unattended {
        screenshot: arg_value(&args, "--screenshot"),
        frames: arg_value(&args, "--frames")
            .and_then(|v| v.parse().ok())
            .unwrap_or(30),
        frame: 0,
        demo,
        windowless,
        check_not_blank: args.iter().any(|a| a == "--check-not-blank"),
        requested: false,
    };

    let mut app = App::new();
    let render = RenderPlugin {
        synchronous_pipeline_compilation: true,
        render_creation: WgpuSettings::default().into(),
        ..default()
    };
    if windowless {
        app.add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: None,
                    exit_condition: ExitCondition::DontExit,
                    ..default()
                })
                .set(render)
                .disable::<WinitPlugin>(),
        )
        .add_plugins(bevy::app::ScheduleRunnerPlugin::run_loop(
            Duration::from_millis(5),
        ));
    } else {
        app.add_plugins(
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        title: "bevy_wii_deform sandbox".into(),
                        resolution: (1280, 800).into(),
                        ..default()
                    }),
                    ..default()
                })
                .set(render),
        )
        .add_plugins(EguiPlugin::default())
        .add_systems(EguiPrimaryContextPass, ui_panel);
    }
    let wiimote = if emulate {
        WiimotePlugin::emulated()
    } else {
        WiimotePlugin::default()
    };
    let mut sandbox = Sandbox {
        input: if demo {
            InputMethod::Wiimote
        } else {
            InputMethod::Mouse
        },
        tasks: tasks::Task::load_all("assets/tasks"),
        results: tasks::read_results(RESULTS_CSV),
        pending_load: Some(model),
        pending_task: arg_value(&args, "--task"),
        ..Sandbox::empty()
    };
    if demo && sandbox.pending_task.is_none() {
        sandbox.pending_task = Some("mannequin_wave".into());
    }
    app.add_plugins((
        DeformPlugin::default(),
        wiimote,
        WiimoteControlPlugin,
        MouseControlPlugin,
    ))
    .add_plugins(MeshPickingPlugin)
    .insert_resource(ClearColor(BACKGROUND))
    .insert_resource(sandbox)
    .insert_resource(unattended)
    .init_resource::<UndoQueue>()
    .init_resource::<BrushHit>()
    .init_resource::<Loading>()
    .init_resource::<HistoryRequest>()
    .insert_resource(OrbitCamera {
        // The demo looks straight at the model so the remote's roll maps onto the task's
        // rotation axis; interactive sessions start with a three-quarter view.
        yaw: if demo { 0.0 } else { 0.3 },
        pitch: if demo { 0.05 } else { 0.15 },
        distance: 3.0,
        focus: Vec3::new(0.0, 0.8, 0.0),
    })
    .add_systems(Startup, setup_scene)
    .add_systems(
        Update,
        (
            start_loading,
            load_pending,
            file_drop,
            orbit_camera,
            brush_ray.run_if(not_over_ui),
            paint,
            gate_mouse_control,
            record_drags,
            keyboard_shortcuts,
            demo_script,
        )
            .chain()
            .before(DeformSystems::Request),
    )
    .add_systems(
        Update,
        (challenge_progress, unattended_frames).after(DeformSystems::Writeback),
    )
    .run()
}

fn not_over_ui(world: &World) -> bool {
    world
        .get_resource::<bevy_egui::input::EguiWantsInput>()
        .is_none_or(|w| !w.wants_any_pointer_input())
}

fn setup_scene(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    unattended: Res<Unattended>,
) {
    let mut camera = commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 1.0, 3.0)));
    if unattended.windowless {
        let target = images.add(Image::new_target_texture(
            800,
            600,
            TextureFormat::Rgba8UnormSrgb,
            None,
        ));
        camera.insert(RenderTarget::Image(target.clone().into()));
        commands.insert_resource(RenderTargetImage(target));
    }
    commands.spawn((
        DirectionalLight {
            illuminance: 9000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_xyz(2.0, 4.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.insert_resource(GlobalAmbientLight {
        brightness: 400.0,
        ..default()
    });
}

/// A yellow cloud: one tiny octahedron per sampled target vertex, in a single mesh.
fn point_cloud(points: &[DVec3], diagonal: f64) -> Mesh {
    let step = (points.len() / 3000).max(1);
    let r = diagonal * 0.004;
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for p in points.iter().step_by(step) {
        let marker = synth::octahedron(*p, r);
        let base = pos.len() as u32;
        pos.extend(marker.positions.iter().map(|q| q.as_vec3().to_array()));
        idx.extend(marker.triangles.iter().flatten().map(|i| base + i));
    }
    let normals: Vec<[f32; 3]> = vec![[0.0, 1.0, 0.0]; pos.len()];
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, pos)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
    .with_inserted_indices(Indices::U32(idx))
}

/// Pushes the painted selection into FixedRegion / DeformHandle (a new handle, at `pose` or at
/// rest).
fn sync_regions(commands: &mut Commands, sb: &mut Sandbox, pose: Option<Transform>) {
    let Some(mesh_entity) = sb.mesh_entity else {
        return;
    };
    let fixed: Vec<u32> = (0..sb.selection.len() as u32)
        .filter(|&i| sb.selection[i as usize] == FIXED)
        .collect();
    let handle: Vec<u32> = (0..sb.selection.len() as u32)
        .filter(|&i| sb.selection[i as usize] == HANDLE)
        .collect();
    commands.entity(mesh_entity).insert(FixedRegion(fixed));
    if let Some(h) = sb.handle_entity.take() {
        commands.entity(h).despawn();
    }
    if !handle.is_empty() {
        let pivot = handle
            .iter()
            .map(|&i| sb.mesh.positions[i as usize])
            .sum::<DVec3>()
            / handle.len() as f64;
        let pivot = pivot.as_vec3();
        let mut e = commands.spawn((
            DeformHandle {
                target: mesh_entity,
                vertices: handle,
                pivot: Some(pivot),
            },
            pose.unwrap_or(Transform::from_translation(pivot)),
            Name::new("handle"),
        ));
        if sb.input == InputMethod::Wiimote {
            e.insert(WiimoteHandleControl::default().with_space(mesh_entity));
        }
        // The paper's mouse baseline (the library's arcball); enabled in Pose mode only.
        e.insert(
            MouseHandleControl::default()
                .with_space(mesh_entity)
                .with_enabled(false),
        );
        sb.handle_entity = Some(e.id());
    }
}

fn update_colors(sb: &Sandbox, meshes: &mut Assets<Mesh>, mesh3d: &Mesh3d) {
    if let Some(mut m) = meshes.get_mut(&mesh3d.0) {
        m.insert_attribute(Mesh::ATTRIBUTE_COLOR, selection_colors(&sb.selection));
    }
}

fn file_drop(mut drops: MessageReader<FileDragAndDrop>, mut sb: ResMut<Sandbox>) {
    for d in drops.read() {
        if let FileDragAndDrop::DroppedFile { path_buf, .. } = d {
            sb.pending_load = Some(path_buf.to_string_lossy().into_owned());
        }
    }
}
