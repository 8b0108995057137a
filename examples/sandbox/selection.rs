//! Painting the fixed (blue) and handle (red) regions, and turning them into the library's
//! `FixedRegion` and a `DeformHandle` driven by the chosen control.

use bevy::mesh::VertexAttributeValues;
use bevy::picking::mesh_picking::ray_cast::{MeshRayCast, MeshRayCastSettings, RayCastVisibility};
use bevy::prelude::*;
use bevy::window::PrimaryWindow;
use bevy_wii_deform::deform::centroid;
use bevy_wii_deform::prelude::*;
use glam::DVec3;

use crate::camera::{cursor_ray, not_over_ui, screen_ray};
use crate::challenge::ChallengeState;
use crate::history::{History, snapshot};
use crate::{EditMode, InputMethod, Model, SandboxSet};

/// Painting, selection edits, and the regions → components sync.
pub struct SelectionPlugin;

impl Plugin for SelectionPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<Selection>()
            .init_resource::<BrushHit>()
            .add_message::<RegionsChanged>()
            .add_message::<SelectionEdit>()
            .add_systems(
                Update,
                (
                    (brush_ray.run_if(not_over_ui), paint)
                        .chain()
                        .run_if(in_state(EditMode::Paint).and_then(in_state(ChallengeState::Off))),
                    edit_selection,
                )
                    .in_set(SandboxSet::Edit),
            )
            .add_systems(Update, apply_regions.in_set(SandboxSet::Regions));
    }
}

/// A vertex neither fixed nor in the handle.
pub const FREE: u8 = 0;
/// A fixed vertex.
pub const FIXED: u8 = 1;
/// A handle vertex.
pub const HANDLE: u8 = 2;

/// What the brush paints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tool {
    Fixed,
    Handle,
    Erase,
}

/// The painted label of every render vertex, and the brush.
#[derive(Resource)]
pub struct Selection {
    /// [`FREE`], [`FIXED`] or [`HANDLE`] per render vertex.
    pub labels: Vec<u8>,
    pub tool: Tool,
    /// Brush radius (model units).
    pub radius: f32,
    /// A stroke is in progress (its undo entry is taken).
    stroke: bool,
}

impl Default for Selection {
    fn default() -> Self {
        Self {
            labels: Vec::new(),
            tool: Tool::Fixed,
            radius: 0.08,
            stroke: false,
        }
    }
}

/// The painted regions changed: rebuild `FixedRegion` and a new handle, at `pose` (or at
/// rest).
#[derive(Message, Debug, Clone, Copy)]
pub struct RegionsChanged {
    pub pose: Option<Transform>,
}

/// A whole-selection edit from the panel.
#[derive(Message, Debug, Clone, Copy, PartialEq, Eq)]
pub enum SelectionEdit {
    /// Everything free.
    Clear,
    /// Free ↔ fixed (handles stay).
    InvertFixed,
}

/// Vertex colours for the labels.
pub fn selection_colors(labels: &[u8]) -> Vec<[f32; 4]> {
    labels
        .iter()
        .map(|s| match *s {
            FIXED => [0.25, 0.45, 0.95, 1.0],
            HANDLE => [0.95, 0.35, 0.25, 1.0],
            _ => [0.85, 0.82, 0.78, 1.0],
        })
        .collect()
}

/// Where the brush hits the mesh this frame, and whether a brush button is held (the left
/// mouse button, or A on a Wii Remote that points at the screen).
#[derive(Resource, Default)]
struct BrushHit {
    point: Option<Vec3>,
    held: bool,
}

fn brush_ray(
    model: Res<Model>,
    mut ray_cast: MeshRayCast,
    buttons: Res<ButtonInput<MouseButton>>,
    remotes: Query<&MotionController>,
    window: Query<&Window, With<PrimaryWindow>>,
    camera: Query<(&Camera, &GlobalTransform)>,
    mut hit_out: ResMut<BrushHit>,
) {
    *hit_out = BrushHit::default();
    let Some(mesh_entity) = model.entity else {
        return;
    };
    // The mouse first; else a remote pointing at the screen with A held paints where it points.
    let pointed = remotes
        .iter()
        .filter(|w| w.pressed(bevy_wii_deform::controllers::wiimote::protocol::Buttons::A))
        .find_map(|w| w.pointer);
    let ray = if buttons.pressed(MouseButton::Left) {
        cursor_ray(&window, &camera)
    } else if let (Some(p), Ok(w)) = (pointed, window.single()) {
        screen_ray(&window, &camera, p * Vec2::new(w.width(), w.height()))
    } else {
        return;
    };
    hit_out.held = true;
    let Some(ray) = ray else {
        return;
    };
    let only_mesh = |e: Entity| e == mesh_entity;
    let settings = MeshRayCastSettings::default()
        .with_visibility(RayCastVisibility::Any)
        .with_filter(&only_mesh);
    hit_out.point = ray_cast
        .cast_ray(ray, &settings)
        .first()
        .map(|(_, hit)| hit.point);
}

/// The model's mesh assets, entities and transforms, as painting needs them.
#[derive(bevy::ecs::system::SystemParam)]
struct ModelMesh<'w, 's> {
    meshes: ResMut<'w, Assets<Mesh>>,
    mesh3d: Query<'w, 's, &'static Mesh3d>,
    transforms: Query<'w, 's, &'static Transform>,
}

/// Paints the vertices (as posed now) within the brush; a stroke is one undo entry and
/// updates the regions when it ends.
fn paint(
    mut selection: ResMut<Selection>,
    mut history: ResMut<History>,
    model: Res<Model>,
    hit: Res<BrushHit>,
    mut parts: ModelMesh,
    mut regions: MessageWriter<RegionsChanged>,
) {
    let Some(mesh) = model
        .entity
        .and_then(|e| parts.mesh3d.get(e).ok())
        .map(|m| m.0.clone())
    else {
        return;
    };
    if !hit.held && selection.stroke {
        selection.stroke = false;
        regions.write(RegionsChanged { pose: None });
        return;
    }
    let Some(point) = hit.point else { return };
    if !selection.stroke {
        history.checkpoint(snapshot(&selection, &model, &parts.transforms));
        selection.stroke = true;
    }
    let value = match selection.tool {
        Tool::Fixed => FIXED,
        Tool::Handle => HANDLE,
        Tool::Erase => FREE,
    };
    let r2 = (selection.radius as f64).powi(2);
    let centre = point.as_dvec3();
    let current =
        current_positions(&parts.meshes, &mesh).unwrap_or_else(|| model.mesh.positions.clone());
    for (label, p) in selection.labels.iter_mut().zip(&current) {
        if p.distance_squared(centre) <= r2 {
            *label = value;
        }
    }
    recolor(&mut parts.meshes, &mesh, &selection.labels);
}

/// The posed positions of the model's mesh.
fn current_positions(meshes: &Assets<Mesh>, mesh: &Handle<Mesh>) -> Option<Vec<DVec3>> {
    match meshes.get(mesh)?.attribute(Mesh::ATTRIBUTE_POSITION)? {
        VertexAttributeValues::Float32x3(v) => {
            Some(v.iter().map(|p| Vec3::from_array(*p).as_dvec3()).collect())
        }
        _ => None,
    }
}

/// Colours the mesh by its labels.
pub fn recolor(meshes: &mut Assets<Mesh>, mesh: &Handle<Mesh>, labels: &[u8]) {
    if let Some(mut m) = meshes.get_mut(mesh) {
        m.insert_attribute(Mesh::ATTRIBUTE_COLOR, selection_colors(labels));
    }
}

fn edit_selection(
    mut edits: MessageReader<SelectionEdit>,
    mut selection: ResMut<Selection>,
    mut history: ResMut<History>,
    model: Res<Model>,
    transforms: Query<&Transform>,
    mut regions: MessageWriter<RegionsChanged>,
) {
    for edit in edits.read() {
        history.checkpoint(snapshot(&selection, &model, &transforms));
        for label in selection.labels.iter_mut() {
            *label = match (*edit, *label) {
                (SelectionEdit::Clear, _) => FREE,
                (SelectionEdit::InvertFixed, FIXED) => FREE,
                (SelectionEdit::InvertFixed, FREE) => FIXED,
                (SelectionEdit::InvertFixed, other) => other,
            };
        }
        regions.write(RegionsChanged { pose: None });
    }
}

/// Rebuilds the regions after the newest [`RegionsChanged`], and recolours the mesh.
pub fn apply_regions(
    mut changes: MessageReader<RegionsChanged>,
    mut commands: Commands,
    mut model: ResMut<Model>,
    selection: Res<Selection>,
    input: Res<State<InputMethod>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mesh3d: Query<&Mesh3d>,
) {
    let Some(change) = changes.read().last().copied() else {
        return;
    };
    spawn_regions(
        &mut commands,
        &mut model,
        &selection.labels,
        *input.get(),
        change.pose,
    );
    if let Some(m) = model.entity.and_then(|e| mesh3d.get(e).ok()) {
        recolor(&mut meshes, &m.0, &selection.labels);
    }
}

/// Pushes the labels into `FixedRegion` and a new `DeformHandle` (at `pose`, or at rest),
/// with the controls for `input`.
pub fn spawn_regions(
    commands: &mut Commands,
    model: &mut Model,
    labels: &[u8],
    input: InputMethod,
    pose: Option<Transform>,
) {
    let Some(mesh_entity) = model.entity else {
        return;
    };
    let with = |value: u8| -> Vec<u32> {
        (0..labels.len() as u32)
            .filter(|&i| labels[i as usize] == value)
            .collect()
    };
    let (fixed, handle) = (with(FIXED), with(HANDLE));
    commands.entity(mesh_entity).insert(FixedRegion(fixed));
    if let Some(h) = model.handle.take() {
        commands.entity(h).despawn();
    }
    if handle.is_empty() {
        return;
    }
    let pivot = centroid(&model.mesh.positions, &handle).as_vec3();
    let mut e = commands.spawn((
        DeformHandle {
            target: mesh_entity,
            vertices: handle,
            pivot: Some(pivot),
        },
        pose.unwrap_or(Transform::from_translation(pivot)),
        // The paper's mouse baseline (the library's arcball); enabled in Pose mode only.
        MouseHandleControl::default()
            .with_space(mesh_entity)
            .with_enabled(false),
        Name::new("handle"),
    ));
    if input == InputMethod::Controller {
        e.insert(MotionHandleControl::default().with_space(mesh_entity));
    }
    model.handle = Some(e.id());
}
