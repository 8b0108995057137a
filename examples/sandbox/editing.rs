//! Painting regions, mouse-control gating, undo history and keyboard shortcuts.

use super::*;

pub(super) fn snapshot(
    sb: &Sandbox,
    transforms: &Query<&mut Transform, Without<Camera3d>>,
) -> Snapshot {
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
pub(super) struct BrushHit(pub(super) Option<Vec3>);

pub(super) fn brush_ray(
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
pub(super) fn paint(
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
pub(super) fn gate_mouse_control(
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
pub(super) fn record_drags(
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
pub(super) struct UndoQueue(pub(super) Vec<Transform>);

/// Undo (`Some(true)`) or redo (`Some(false)`) requested from the panel.
#[derive(Resource, Default)]
pub(super) struct HistoryRequest(pub(super) Option<bool>);

#[allow(clippy::too_many_arguments)]
pub(super) fn keyboard_shortcuts(
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
