//! Loading models in the background: built-in names, OBJ/OFF, glTF/GLB.

use super::*;

/// Loads a built-in model by name or a mesh file (OBJ/OFF via our reader, glTF/GLB via gltf).
pub(super) fn load_model(name: &str) -> Result<TriMesh, String> {
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
pub(super) fn normalise(mut m: TriMesh) -> TriMesh {
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

pub(super) fn selection_colors(sel: &[u8]) -> Vec<[f32; 4]> {
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
pub(super) struct Loaded {
    pub(super) name: String,
    pub(super) mesh: TriMesh,
    pub(super) task: Option<(String, tasks::Task)>,
    pub(super) target: Option<Result<Vec<DVec3>, String>>,
}

/// The background load in progress (file parsing, model generation, challenge target solve),
/// so the UI never freezes.
#[derive(Resource, Default)]
pub(super) struct Loading(pub(super) Option<bevy::tasks::Task<Result<Loaded, String>>>);

pub(super) fn start_loading(mut sb: ResMut<Sandbox>, mut loading: ResMut<Loading>) {
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

pub(super) fn load_pending(
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
