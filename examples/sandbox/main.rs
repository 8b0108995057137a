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

#[path = "../common/models.rs"]
mod models;
mod tasks;

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

/// Loads a built-in model by name or a mesh file (OBJ/OFF via our reader, glTF/GLB via gltf).
fn load_model(name: &str) -> Result<TriMesh, String> {
    if models::MODELS.contains(&name) {
        // Shipped in assets/models (written by `make_assets`); regenerated if missing.
        if let Ok(m) = TriMesh::read(format!("assets/models/{name}.obj")) {
            return Ok(m);
        }
        return models::generate(name).ok_or_else(|| format!("unknown model {name}"));
    }
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".gltf") || lower.ends_with(".glb") {
        let (doc, buffers, _) = gltf::import(name).map_err(|e| format!("{name}: {e}"))?;
        let mut out = TriMesh::default();
        for mesh in doc.meshes() {
            for prim in mesh.primitives() {
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let Some(pos) = reader.read_positions() else {
                    continue;
                };
                let base = out.positions.len() as u32;
                out.positions
                    .extend(pos.map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)));
                let n = out.positions.len() as u32 - base;
                let idx: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..n).collect(),
                };
                for t in idx.chunks_exact(3) {
                    if t.iter().all(|&i| i < n) {
                        out.triangles.push([base + t[0], base + t[1], base + t[2]]);
                    }
                }
            }
        }
        if out.positions.is_empty() {
            return Err(format!("{name}: no triangle meshes"));
        }
        return Ok(out);
    }
    TriMesh::read(name).map_err(|e| format!("{name}: {e}"))
}

/// Normalises a model to stand on y = 0 with height ~1.8 (imported meshes vary wildly).
fn normalise(mut m: TriMesh) -> TriMesh {
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for p in &m.positions {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let size = (hi - lo).max_element().max(1e-9);
    let s = 1.8 / size;
    let centre = DVec3::new((lo.x + hi.x) / 2.0, lo.y, (lo.z + hi.z) / 2.0);
    for p in &mut m.positions {
        *p = (*p - centre) * s;
    }
    m
}

fn selection_colors(sel: &[u8]) -> Vec<[f32; 4]> {
    sel.iter()
        .map(|s| match *s {
            FIXED => [0.25, 0.45, 0.95, 1.0],
            HANDLE => [0.95, 0.35, 0.25, 1.0],
            _ => [0.85, 0.82, 0.78, 1.0],
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
/// A model (and challenge target) prepared off the main thread.
struct Loaded {
    name: String,
    mesh: TriMesh,
    task: Option<(String, tasks::Task)>,
    target: Option<Result<Vec<DVec3>, String>>,
}

/// The background load in progress (file parsing, model generation, challenge target solve),
/// so the UI never freezes.
#[derive(Resource, Default)]
struct Loading(Option<bevy::tasks::Task<Result<Loaded, String>>>);

fn start_loading(mut sb: ResMut<Sandbox>, mut loading: ResMut<Loading>) {
    if loading.0.is_some() {
        return; // one load at a time; later requests wait their turn
    }
    let task = sb.pending_task.take().and_then(|t| {
        let found = sb
            .tasks
            .iter()
            .find(|(k, task)| *k == t || task.name == t)
            .cloned();
        if found.is_none() {
            sb.message = format!("unknown task {t:?}");
        }
        found
    });
    if let Some((_, task)) = &task {
        sb.pending_load = Some(task.model.clone());
    }
    let Some(name) = sb.pending_load.take() else {
        return;
    };
    sb.message = format!("loading {name}…");
    loading.0 = Some(bevy::tasks::AsyncComputeTaskPool::get().spawn(async move {
        let mesh = match load_model(&name) {
            Ok(m) if models::MODELS.contains(&name.as_str()) => m,
            Ok(m) => normalise(m),
            Err(e) => return Err(e),
        };
        let target = task.as_ref().map(|(_, t)| t.target_pose(&mesh));
        Ok(Loaded {
            name,
            mesh,
            task,
            target,
        })
    }));
}

fn load_pending(
    mut commands: Commands,
    mut sb: ResMut<Sandbox>,
    mut loading: ResMut<Loading>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut orbit: ResMut<OrbitCamera>,
    mut clear: ResMut<ClearColor>,
) {
    let Some(job) = loading.0.as_mut() else {
        return;
    };
    let Some(result) = bevy::tasks::futures::check_ready(job) else {
        return;
    };
    loading.0 = None;
    let Loaded {
        name,
        mesh,
        task,
        target,
    } = match result {
        Ok(l) => l,
        Err(e) => {
            sb.message = e;
            return;
        }
    };
    for e in [
        sb.mesh_entity.take(),
        sb.handle_entity.take(),
        sb.cloud_entity.take(),
    ]
    .into_iter()
    .flatten()
    {
        commands.entity(e).despawn();
    }
    let mut bevy_mesh = mesh_from_triangles(&mesh.positions, &mesh.triangles);
    let n = mesh.positions.len();
    let mut selection = vec![FREE; n];
    if let Some((_, task)) = &task {
        for v in task.fixed.resolve(&mesh.positions) {
            selection[v as usize] = FIXED;
        }
        for v in task.handle.resolve(&mesh.positions) {
            selection[v as usize] = HANDLE;
        }
    }
    bevy_mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, selection_colors(&selection));
    let handle = meshes.add(bevy_mesh);
    let material = materials.add(StandardMaterial {
        base_color: Color::WHITE,
        perceptual_roughness: 0.6,
        ..default()
    });
    let entity = commands
        .spawn((
            Mesh3d(handle),
            MeshMaterial3d(material),
            Deformable::default(),
            FixedRegion::default(),
            Transform::default(),
            Name::new(name.clone()),
        ))
        .id();
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for p in &mesh.positions {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    sb.diagonal = (hi - lo).length();
    orbit.focus = ((lo + hi) / 2.0).as_vec3();
    orbit.distance = (sb.diagonal as f32) * 1.6;
    sb.model_name = name.clone();
    sb.mesh_entity = Some(entity);
    sb.selection = selection;
    sb.undo.clear();
    sb.redo.clear();
    sb.challenge = None;
    clear.0 = BACKGROUND;
    sb.message = format!(
        "loaded {name}: {n} vertices, {} triangles",
        mesh.triangles.len()
    );
    sb.mesh = mesh;
    if let (Some((key, task)), Some(target)) = (task, target) {
        match target {
            Ok(target) => {
                let cloud = point_cloud(&target, sb.diagonal);
                let cloud_mesh = meshes.add(cloud);
                let yellow = materials.add(StandardMaterial {
                    base_color: Color::srgb(1.0, 0.9, 0.1),
                    unlit: true,
                    ..default()
                });
                sb.cloud_entity = Some(
                    commands
                        .spawn((Mesh3d(cloud_mesh), MeshMaterial3d(yellow), Pickable::IGNORE))
                        .id(),
                );
                sb.message = format!("challenge: {} — match the yellow points", task.name);
                let start_error = target
                    .iter()
                    .zip(&sb.mesh.positions)
                    .map(|(t, r)| t.distance(*r))
                    .sum::<f64>()
                    / target.len().max(1) as f64;
                sb.challenge = Some(Challenge {
                    key,
                    task,
                    target,
                    start_error,
                    watch: Stopwatch::new(),
                    done: None,
                    progress: 0.0,
                });
                sb.mode = Mode::Pose;
            }
            Err(e) => sb.message = e,
        }
    }
    info!("{}", sb.message);
    sync_regions(&mut commands, &mut sb, None);
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

fn orbit_camera(
    mut orbit: ResMut<OrbitCamera>,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    egui_wants: Option<Res<bevy_egui::input::EguiWantsInput>>,
    mut camera: Query<&mut Transform, With<Camera3d>>,
) {
    let over_ui = egui_wants.is_some_and(|w| w.wants_any_pointer_input());
    if !over_ui {
        if buttons.pressed(MouseButton::Right) {
            orbit.yaw -= motion.delta.x * 0.006;
            orbit.pitch = (orbit.pitch + motion.delta.y * 0.006).clamp(-1.5, 1.5);
        }
        if buttons.pressed(MouseButton::Middle) {
            let rot = Quat::from_euler(EulerRot::YXZ, orbit.yaw, -orbit.pitch, 0.0);
            let d = orbit.distance * 0.0015;
            orbit.focus += rot * Vec3::new(-motion.delta.x * d, motion.delta.y * d, 0.0);
        }
        if scroll.delta.y != 0.0 {
            orbit.distance = (orbit.distance * (1.0 - scroll.delta.y * 0.1)).clamp(0.2, 50.0);
        }
    }
    for mut t in &mut camera {
        let rot = Quat::from_euler(EulerRot::YXZ, orbit.yaw, -orbit.pitch, 0.0);
        t.translation = orbit.focus + rot * Vec3::new(0.0, 0.0, orbit.distance);
        t.look_at(orbit.focus, Vec3::Y);
    }
}

fn cursor_ray(
    window: &Query<&Window, With<PrimaryWindow>>,
    camera: &Query<(&Camera, &GlobalTransform)>,
) -> Option<(Ray3d, Vec2)> {
    let window = window.single().ok()?;
    let cursor = window.cursor_position()?;
    let (cam, tf) = camera.iter().next()?;
    Some((cam.viewport_to_world(tf, cursor).ok()?, cursor))
}

fn snapshot(sb: &Sandbox, transforms: &Query<&mut Transform, Without<Camera3d>>) -> Snapshot {
    Snapshot {
        selection: sb.selection.clone(),
        handle: sb
            .handle_entity
            .and_then(|h| transforms.get(h).ok().copied())
            .unwrap_or_default(),
    }
}

/// Where the brush hits the mesh this frame (from a ray cast; applied by `apply_brush`).
#[derive(Resource, Default)]
struct BrushHit(Option<Vec3>);

fn brush_ray(
    sb: Res<Sandbox>,
    mut ray_cast: MeshRayCast,
    buttons: Res<ButtonInput<MouseButton>>,
    window: Query<&Window, With<PrimaryWindow>>,
    camera: Query<(&Camera, &GlobalTransform)>,
    mut hit_out: ResMut<BrushHit>,
) {
    hit_out.0 = None;
    if sb.mode != Mode::Paint || sb.challenge.is_some() || !buttons.pressed(MouseButton::Left) {
        return;
    }
    let Some(mesh_entity) = sb.mesh_entity else {
        return;
    };
    let Some((ray, _)) = cursor_ray(&window, &camera) else {
        return;
    };
    let only_mesh = |e: Entity| e == mesh_entity;
    let settings = MeshRayCastSettings::default()
        .with_visibility(RayCastVisibility::Any)
        .with_filter(&only_mesh);
    hit_out.0 = ray_cast
        .cast_ray(ray, &settings)
        .first()
        .map(|(_, hit)| hit.point);
}

#[allow(clippy::too_many_arguments)]
fn paint(
    mut commands: Commands,
    mut sb: ResMut<Sandbox>,
    buttons: Res<ButtonInput<MouseButton>>,
    hit: Res<BrushHit>,
    mut meshes: ResMut<Assets<Mesh>>,
    mesh_q: Query<&Mesh3d>,
    transforms: Query<&mut Transform, Without<Camera3d>>,
) {
    if sb.mode != Mode::Paint || sb.challenge.is_some() {
        return;
    }
    let Some(mesh_entity) = sb.mesh_entity else {
        return;
    };
    if buttons.just_released(MouseButton::Left) && sb.stroke {
        sb.stroke = false;
        sync_regions(&mut commands, &mut sb, None);
        return;
    }
    let Some(point) = hit.0 else { return };
    if !sb.stroke {
        let snap = snapshot(&sb, &transforms);
        sb.undo.push(snap);
        sb.redo.clear();
        sb.stroke = true;
    }
    let value = match sb.tool {
        Tool::Fixed => FIXED,
        Tool::Handle => HANDLE,
        Tool::Erase => FREE,
    };
    let r2 = (sb.radius as f64).powi(2);
    let centre = point.as_dvec3();
    let Ok(mesh3d) = mesh_q.get(mesh_entity) else {
        return;
    };
    let current: Vec<DVec3> = match meshes
        .get(&mesh3d.0)
        .and_then(|m| m.attribute(Mesh::ATTRIBUTE_POSITION).cloned())
    {
        Some(VertexAttributeValues::Float32x3(v)) => {
            v.iter().map(|p| Vec3::from_array(*p).as_dvec3()).collect()
        }
        _ => sb.mesh.positions.clone(),
    };
    for (i, p) in current.iter().enumerate() {
        if p.distance_squared(centre) <= r2 {
            sb.selection[i] = value;
        }
    }
    update_colors(&sb, &mut meshes, mesh3d);
}

/// Turns the library's [`MouseHandleControl`] on in Pose mode with mouse input (not when a
/// drag would start over the panel).
fn gate_mouse_control(
    sb: Res<Sandbox>,
    wants_pointer: Option<Res<bevy_egui::input::EguiWantsInput>>,
    mut controls: Query<&mut MouseHandleControl>,
) {
    let Some(mut control) = sb.handle_entity.and_then(|h| controls.get_mut(h).ok()) else {
        return;
    };
    let over_ui = wants_pointer.is_some_and(|w| w.wants_any_pointer_input());
    let enabled = sb.mode == Mode::Pose
        && sb.input == InputMethod::Mouse
        && (control.is_dragging() || !over_ui);
    if control.enabled != enabled {
        control.enabled = enabled;
    }
}

/// Turns each finished mouse drag or Wii Remote grab into an undo entry (the pose at its
/// start, as the controls recorded it: independent of system order).
fn record_drags(
    sb: Res<Sandbox>,
    controls: Query<(Option<&MouseHandleControl>, Option<&WiimoteHandleControl>)>,
    mut drag_start: Local<Option<Transform>>,
    mut undo_out: ResMut<UndoQueue>,
) {
    let start = sb
        .handle_entity
        .and_then(|h| controls.get(h).ok())
        .and_then(|(mouse, wii)| {
            mouse
                .and_then(MouseHandleControl::drag_start)
                .or_else(|| wii.and_then(WiimoteHandleControl::grab_start))
        });
    match (start, drag_start.take()) {
        (Some(start), _) => *drag_start = Some(start),
        (None, Some(start)) => undo_out.0.push(start),
        (None, None) => {}
    }
}

/// Handle poses at the start of mouse drags, turned into undo entries.
#[derive(Resource, Default)]
struct UndoQueue(Vec<Transform>);

/// Undo (`Some(true)`) or redo (`Some(false)`) requested from the panel.
#[derive(Resource, Default)]
struct HistoryRequest(Option<bool>);

#[allow(clippy::too_many_arguments)]
fn keyboard_shortcuts(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    mut sb: ResMut<Sandbox>,
    mut meshes: ResMut<Assets<Mesh>>,
    mesh_q: Query<&Mesh3d>,
    mut transforms: Query<&mut Transform, Without<Camera3d>>,
    mut undo_in: ResMut<UndoQueue>,
    mut history: ResMut<HistoryRequest>,
) {
    // Pose drags recorded by record_drags become undo entries.
    for t in undo_in.0.drain(..) {
        let snap = Snapshot {
            selection: sb.selection.clone(),
            handle: t,
        };
        sb.undo.push(snap);
        sb.redo.clear();
    }
    let ctrl = keys.pressed(KeyCode::ControlLeft) || keys.pressed(KeyCode::ControlRight);
    let request = history.0.take();
    let undo = ctrl && keys.just_pressed(KeyCode::KeyZ) || request == Some(true);
    let redo = ctrl && keys.just_pressed(KeyCode::KeyY) || request == Some(false);
    if !(undo || redo) {
        return;
    }
    let current = snapshot(&sb, &transforms);
    let target = if undo { sb.undo.pop() } else { sb.redo.pop() };
    let Some(target) = target else { return };
    if undo {
        sb.redo.push(current.clone());
    } else {
        sb.undo.push(current.clone());
    }
    let selection_changed = target.selection != sb.selection;
    sb.selection = target.selection;
    if selection_changed {
        sync_regions(&mut commands, &mut sb, Some(target.handle));
        if let Some(m) = sb.mesh_entity.and_then(|e| mesh_q.get(e).ok()) {
            update_colors(&sb, &mut meshes, m);
        }
    } else if let Some(h) = sb.handle_entity
        && let Ok(mut t) = transforms.get_mut(h)
    {
        *t = target.handle;
    }
}

/// `--demo`: once the emulated remote is calibrated it grabs (B), rolls 120° about its
/// pointing axis over 3 s and moves the handle up and right with the D-pad — the mannequin
/// waves.
fn demo_script(
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

fn challenge_progress(
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

fn unattended_frames(
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

#[allow(clippy::too_many_arguments)]
fn ui_panel(
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

#[derive(serde::Serialize, serde::Deserialize)]
struct Setup {
    model: String,
    selection: Vec<u8>,
    handle_translation: [f32; 3],
    handle_rotation: [f32; 4],
}

impl Setup {
    /// The saved handle pose.
    fn pose(&self) -> Transform {
        Transform::from_translation(Vec3::from_array(self.handle_translation))
            .with_rotation(Quat::from_array(self.handle_rotation).normalize())
    }
}

fn save_setup(sb: &Sandbox, handle: Transform) -> Result<(), String> {
    let s = Setup {
        model: sb.model_name.clone(),
        selection: sb.selection.clone(),
        handle_translation: handle.translation.to_array(),
        handle_rotation: handle.rotation.to_array(),
    };
    let text = ron::ser::to_string_pretty(&s, ron::ser::PrettyConfig::default())
        .map_err(|e| e.to_string())?;
    std::fs::write(&sb.setup_path, text).map_err(|e| e.to_string())
}

fn load_setup(path: &str) -> Result<Setup, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    ron::from_str(&text).map_err(|e| e.to_string())
}

/// Writes the posed mesh as a binary glTF (positions, normals, indices), validated by
/// re-reading it with the `gltf` crate before it is written.
fn export_glb(mesh: &Mesh, path: &str) -> Result<(), String> {
    let Ok(VertexAttributeValues::Float32x3(pos)) = mesh.try_attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        return Err("mesh has no positions".into());
    };
    let normals = match mesh.try_attribute(Mesh::ATTRIBUTE_NORMAL) {
        Ok(VertexAttributeValues::Float32x3(n)) => n.clone(),
        _ => vec![[0.0, 1.0, 0.0]; pos.len()],
    };
    let indices: Vec<u32> = mesh
        .try_indices()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|i| i as u32)
        .collect();
    let mut bin = Vec::new();
    for p in pos {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let normals_offset = bin.len();
    for n in &normals {
        for c in n {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let indices_offset = bin.len();
    for i in &indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in pos {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "bevy_wii_deform sandbox"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "posed"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2}]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": normals_offset, "target": 34962},
            {"buffer": 0, "byteOffset": normals_offset, "byteLength": indices_offset - normals_offset, "target": 34962},
            {"buffer": 0, "byteOffset": indices_offset, "byteLength": bin.len() - indices_offset, "target": 34963}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": pos.len(), "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": normals.len(), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}
        ]
    });
    let json = serde_json::to_vec(&json).map_err(|e| e.to_string())?;
    let glb = bevy_wii_deform::deform::glb_container(json, bin);
    let (doc, buffers, _) = gltf::import_slice(&glb).map_err(|e| format!("invalid glTF: {e}"))?;
    let count = doc
        .meshes()
        .next()
        .and_then(|m| m.primitives().next())
        .map(|p| {
            p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]))
                .read_positions()
                .map(|i| i.count())
                .unwrap_or(0)
        });
    if count != Some(pos.len()) {
        return Err("glTF round trip lost vertices".into());
    }
    std::fs::write(path, glb).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::ecs::world::CommandQueue;

    #[test]
    fn a_saved_setup_loads_back_with_its_selection_and_pose() {
        let mut sb = Sandbox::empty();
        sb.mesh = synth::bar(8, 10, 0.1, 1.0);
        let n = sb.mesh.positions.len();
        sb.selection = (0..n)
            .map(|i| match i {
                i if i < 8 => FIXED,
                i if i >= n - 10 => HANDLE,
                _ => FREE,
            })
            .collect();
        let path = std::env::temp_dir().join(format!("sandbox-setup-{}.ron", std::process::id()));
        sb.setup_path = path.display().to_string();
        let mut world = World::new();
        sb.mesh_entity = Some(world.spawn_empty().id());
        let pose = Transform::from_xyz(0.1, 0.9, 0.2).with_rotation(Quat::from_rotation_z(0.4));
        save_setup(&sb, pose).unwrap();
        let saved = std::mem::take(&mut sb.selection);
        let setup = load_setup(&sb.setup_path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert_eq!(setup.selection, saved);
        // Restored as the panel does: the selection, and a new handle at the saved pose.
        sb.selection = setup.selection.clone();
        let mut queue = CommandQueue::default();
        let mut commands = Commands::new(&mut queue, &world);
        sync_regions(&mut commands, &mut sb, Some(setup.pose()));
        queue.apply(&mut world);
        let handle = sb.handle_entity.expect("a handle");
        let restored = world.get::<Transform>(handle).unwrap();
        assert!(
            restored.translation.distance(pose.translation) < 1e-6,
            "{restored:?}"
        );
        assert!(
            restored.rotation.angle_between(pose.rotation) < 1e-6,
            "{restored:?}"
        );
        let fixed = world.get::<FixedRegion>(sb.mesh_entity.unwrap()).unwrap();
        assert_eq!(fixed.0, (0..8).collect::<Vec<u32>>());
    }
}
