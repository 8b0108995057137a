//! Loading models without freezing the app: built-in names and OBJ/OFF files are read in the
//! background; glTF/GLB scenes go through Bevy's asset loader, and once the scene has spawned
//! its mesh primitives are merged into one editable mesh *with their node transforms*. Then
//! the model is normalised (and a challenge's target pose solved) in the background, and
//! spawned.

use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, futures::check_ready};
use bevy::window::FileDragAndDrop;
use bevy::world_serialization::{WorldAssetRoot, WorldInstanceReady};
use bevy_wii_deform::deform::TriMesh;
use bevy_wii_deform::prelude::*;
use glam::{DAffine3, DVec3};

use crate::challenge::{ChallengeSetup, TaskList, TaskTarget};
use crate::history::History;
use crate::selection::{FIXED, FREE, HANDLE, RegionsChanged, Selection, selection_colors};
use crate::{Model, SandboxSet, StatusLine, models, tasks};

/// Loads and spawns models; see the module docs.
pub struct LoadingPlugin;

impl Plugin for LoadingPlugin {
    fn build(&self, app: &mut App) {
        app.add_message::<LoadModel>()
            .add_message::<StartTask>()
            .init_resource::<Loading>()
            .add_observer(merge_spawned_scene)
            .add_systems(
                Update,
                (
                    queue_requests,
                    start_loading,
                    watch_scene_load,
                    finish_loading,
                )
                    .chain()
                    .in_set(SandboxSet::Load),
            );
    }
}

/// Load a model: a built-in name, or a path to an OBJ, OFF, glTF or GLB file.
#[derive(Message, Debug, Clone)]
pub struct LoadModel(pub String);

/// Start a challenge task by key or name (loads its model).
#[derive(Message, Debug, Clone)]
pub struct StartTask(pub String);

/// What to load next, and what is loading.
#[derive(Resource, Default)]
struct Loading {
    /// The newest request not started yet (later requests replace it).
    queued: Option<Request>,
    /// The load in progress (one at a time).
    job: Option<Job>,
}

#[derive(Clone)]
struct Request {
    name: String,
    task: Option<(String, tasks::Task)>,
}

enum Job {
    /// A glTF scene spawning (hidden) under this root.
    Scene(Entity),
    /// Reading, normalising and solving the target in the background.
    Prepare(Task<Result<Loaded, String>>),
}

/// A model (and challenge target) prepared off the main thread.
struct Loaded {
    name: String,
    mesh: TriMesh,
    task: Option<(String, tasks::Task)>,
    target: Option<Result<Vec<DVec3>, String>>,
}

/// On a glTF scene root spawned by the loader: what it is loaded for.
#[derive(Component)]
struct SceneImport(Request);

fn queue_requests(
    mut loads: MessageReader<LoadModel>,
    mut starts: MessageReader<StartTask>,
    mut drops: MessageReader<FileDragAndDrop>,
    tasks: Res<TaskList>,
    mut loading: ResMut<Loading>,
    mut status: ResMut<StatusLine>,
) {
    let dropped = drops.read().filter_map(|d| match d {
        FileDragAndDrop::DroppedFile { path_buf, .. } => {
            Some(path_buf.to_string_lossy().into_owned())
        }
        _ => None,
    });
    for name in loads.read().map(|l| l.0.clone()).chain(dropped) {
        loading.queued = Some(Request { name, task: None });
    }
    // A task wins over a plain model load in the same frame (it names its own model).
    for StartTask(key) in starts.read() {
        match tasks.find(key) {
            Some((key, task)) => {
                loading.queued = Some(Request {
                    name: task.model.clone(),
                    task: Some((key, task)),
                })
            }
            None => status.set(format!("unknown task {key:?}")),
        }
    }
}

fn is_gltf(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    lower.ends_with(".gltf") || lower.ends_with(".glb")
}

fn start_loading(
    mut commands: Commands,
    mut loading: ResMut<Loading>,
    assets: Res<AssetServer>,
    mut status: ResMut<StatusLine>,
) {
    if loading.job.is_some() {
        return; // one load at a time; the newest request waits its turn
    }
    let Some(request) = loading.queued.take() else {
        return;
    };
    status.set(format!("loading {}…", request.name));
    if is_gltf(&request.name) {
        // Bevy resolves relative paths against its assets folder; a user means the working
        // directory.
        let path = std::fs::canonicalize(&request.name)
            .map(|p| p.to_string_lossy().into_owned())
            .unwrap_or_else(|_| request.name.clone());
        let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(path));
        let root = commands
            .spawn((
                WorldAssetRoot(scene),
                Visibility::Hidden,
                SceneImport(request),
            ))
            .id();
        loading.job = Some(Job::Scene(root));
    } else {
        let name = request.name.clone();
        let read = move || read_model(&name);
        loading.job = Some(Job::Prepare(prepare(request, read)));
    }
}

/// Normalises the mesh and solves the challenge target in the background.
fn prepare(
    request: Request,
    read: impl FnOnce() -> Result<TriMesh, String> + Send + 'static,
) -> Task<Result<Loaded, String>> {
    AsyncComputeTaskPool::get().spawn(async move {
        let mut mesh = read()?;
        if !models::MODELS.contains(&request.name.as_str()) {
            mesh = normalise(mesh);
        }
        let target = request.task.as_ref().map(|(_, t)| t.target_pose(&mesh));
        Ok(Loaded {
            name: request.name,
            mesh,
            task: request.task,
            target,
        })
    })
}

/// Reads a built-in model by name or an OBJ/OFF file.
fn read_model(name: &str) -> Result<TriMesh, String> {
    if models::MODELS.contains(&name) {
        // Shipped in assets/models (written by `make_assets`); regenerated if missing.
        if let Ok(m) = TriMesh::read(format!("assets/models/{name}.obj")) {
            return Ok(m);
        }
        return models::generate(name).ok_or_else(|| format!("unknown model {name}"));
    }
    TriMesh::read(name).map_err(|e| format!("{name}: {e}"))
}

/// A glTF that failed to load ends the job with its error.
fn watch_scene_load(
    mut commands: Commands,
    mut loading: ResMut<Loading>,
    assets: Res<AssetServer>,
    roots: Query<(&WorldAssetRoot, &SceneImport)>,
    mut status: ResMut<StatusLine>,
) {
    let Some(Job::Scene(root)) = loading.job else {
        return;
    };
    let Ok((scene, import)) = roots.get(root) else {
        return;
    };
    if let Some(bevy::asset::LoadState::Failed(e)) = assets.get_load_state(&scene.0) {
        status.set(format!("{}: {e}", import.0.name));
        commands.entity(root).despawn();
        loading.job = None;
    }
}

/// Once a glTF scene has spawned: merges its triangle primitives (node transforms applied)
/// into one mesh and starts preparing it.
fn merge_spawned_scene(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    imports: Query<&SceneImport>,
    nodes: Query<(Option<&Transform>, Option<&Mesh3d>, Option<&Children>)>,
    meshes: Res<Assets<Mesh>>,
    mut loading: ResMut<Loading>,
) {
    let Ok(import) = imports.get(ready.entity) else {
        return;
    };
    let request = import.0.clone();
    let mut merged = TriMesh::default();
    let mut skipped = 0;
    if let Ok((_, _, Some(children))) = nodes.get(ready.entity) {
        for &child in children {
            merge_below(
                child,
                DAffine3::IDENTITY,
                &nodes,
                &meshes,
                &mut merged,
                &mut skipped,
            );
        }
    }
    commands.entity(ready.entity).despawn();
    let name = request.name.clone();
    let read = move || match (merged.positions.is_empty(), skipped) {
        (true, 0) => Err(format!("{name}: no meshes in the scene")),
        (true, _) => Err(format!(
            "{name}: {skipped} primitive(s), none a triangle list with positions"
        )),
        (false, _) => Ok(merged),
    };
    loading.job = Some(Job::Prepare(prepare(request, read)));
}

/// Appends the triangle primitives at and below `entity`; `parent` is the transform from the
/// parent's space to the scene root's.
fn merge_below(
    entity: Entity,
    parent: DAffine3,
    nodes: &Query<(Option<&Transform>, Option<&Mesh3d>, Option<&Children>)>,
    meshes: &Assets<Mesh>,
    out: &mut TriMesh,
    skipped: &mut usize,
) {
    let Ok((transform, mesh, children)) = nodes.get(entity) else {
        return;
    };
    let local = transform.map_or(DAffine3::IDENTITY, |t| {
        let a = t.compute_affine();
        DAffine3::from_mat4(Mat4::from(a).as_dmat4())
    });
    let to_root = parent * local;
    if let Some(mesh) = mesh {
        match meshes.get(&mesh.0).and_then(triangles_of) {
            Some((positions, triangles)) => {
                let base = out.positions.len() as u32;
                out.positions
                    .extend(positions.iter().map(|p| to_root.transform_point3(*p)));
                out.triangles
                    .extend(triangles.iter().map(|t| t.map(|i| base + i)));
            }
            None => *skipped += 1,
        }
    }
    for &child in children.into_iter().flatten() {
        merge_below(child, to_root, nodes, meshes, out, skipped);
    }
}

/// Positions and triangles of a triangle-list mesh with CPU-side positions.
fn triangles_of(mesh: &Mesh) -> Option<(Vec<DVec3>, Vec<[u32; 3]>)> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return None;
    }
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        return None;
    };
    let n = p.len() as u32;
    let indices: Vec<u32> = match mesh.indices() {
        Some(Indices::U16(i)) => i.iter().map(|&i| i as u32).collect(),
        Some(Indices::U32(i)) => i.clone(),
        None => (0..n).collect(),
    };
    let triangles = indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| i < n))
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let positions = p.iter().map(|q| Vec3::from_array(*q).as_dvec3()).collect();
    Some((positions, triangles))
}

/// Normalises a model to stand on y = 0 with height ~1.8 (imported meshes vary wildly).
fn normalise(mut m: TriMesh) -> TriMesh {
    let (lo, hi) = m.bounds();
    let size = (hi - lo).max_element().max(1e-9);
    let s = 1.8 / size;
    let centre = DVec3::new((lo.x + hi.x) / 2.0, lo.y, (lo.z + hi.z) / 2.0);
    for p in &mut m.positions {
        *p = (*p - centre) * s;
    }
    m
}

/// Spawns a prepared model in place of the old one, with the task's regions painted.
fn finish_loading(
    mut commands: Commands,
    mut loading: ResMut<Loading>,
    mut model: ResMut<Model>,
    mut parts: LoadTargets,
    mut status: ResMut<StatusLine>,
    mut regions: MessageWriter<RegionsChanged>,
    mut challenge: MessageWriter<ChallengeSetup>,
) {
    let Some(Job::Prepare(job)) = loading.job.as_mut() else {
        return;
    };
    let Some(result) = check_ready(job) else {
        return;
    };
    loading.job = None;
    let loaded = match result {
        Ok(l) => l,
        Err(e) => return status.set(e),
    };
    for e in [model.entity.take(), model.handle.take()]
        .into_iter()
        .flatten()
    {
        commands.entity(e).despawn();
    }
    let n = loaded.mesh.positions.len();
    let mut labels = vec![FREE; n];
    if let Some((_, task)) = &loaded.task {
        for v in task.fixed.resolve(&loaded.mesh.positions) {
            labels[v as usize] = FIXED;
        }
        for v in task.handle.resolve(&loaded.mesh.positions) {
            labels[v as usize] = HANDLE;
        }
    }
    let mut bevy_mesh = mesh_from_triangles(&loaded.mesh.positions, &loaded.mesh.triangles);
    bevy_mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, selection_colors(&labels));
    let material = parts.materials.add(StandardMaterial {
        base_color: Color::WHITE,
        perceptual_roughness: 0.6,
        ..default()
    });
    let entity = commands
        .spawn((
            Mesh3d(parts.meshes.add(bevy_mesh)),
            MeshMaterial3d(material),
            Deformable::default(),
            FixedRegion::default(),
            Transform::default(),
            Name::new(loaded.name.clone()),
        ))
        .id();
    let (lo, hi) = loaded.mesh.bounds();
    model.diagonal = (hi - lo).length();
    parts.orbit.focus = ((lo + hi) / 2.0).as_vec3();
    parts.orbit.distance = (model.diagonal as f32) * 1.6;
    model.name = loaded.name.clone();
    model.entity = Some(entity);
    parts.selection.labels = labels;
    parts.history.clear();
    status.set(format!(
        "loaded {}: {n} vertices, {} triangles",
        loaded.name,
        loaded.mesh.triangles.len()
    ));
    model.mesh = loaded.mesh;
    let task = loaded.task.zip(loaded.target);
    challenge.write(ChallengeSetup(
        task.map(|((key, task), target)| TaskTarget { key, task, target }),
    ));
    regions.write(RegionsChanged { pose: None });
}

/// What `finish_loading` resets or fills besides the model.
#[derive(bevy::ecs::system::SystemParam)]
struct LoadTargets<'w> {
    meshes: ResMut<'w, Assets<Mesh>>,
    materials: ResMut<'w, Assets<StandardMaterial>>,
    orbit: ResMut<'w, crate::camera::OrbitCamera>,
    selection: ResMut<'w, Selection>,
    history: ResMut<'w, History>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::ecs::system::RunSystemOnce;

    fn triangle(topology: PrimitiveTopology) -> Mesh {
        Mesh::new(topology, RenderAssetUsages::default())
            .with_inserted_attribute(
                Mesh::ATTRIBUTE_POSITION,
                vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            )
            .with_inserted_indices(Indices::U16(vec![0, 1, 2]))
    }

    /// Two primitives under nested nodes (translated, rotated, scaled), one line primitive:
    /// merged with every node transform applied, the line skipped and counted.
    #[test]
    fn a_scene_merges_its_primitives_with_their_node_transforms() {
        let mut world = World::new();
        let mut meshes = Assets::<Mesh>::default();
        let tri = meshes.add(triangle(PrimitiveTopology::TriangleList));
        let line = meshes.add(triangle(PrimitiveTopology::LineList));
        world.insert_resource(meshes);
        let outer = Transform::from_xyz(10.0, 0.0, 0.0).with_scale(Vec3::splat(2.0));
        let inner = Transform::from_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2));
        let root = world.spawn(Transform::from_xyz(100.0, 0.0, 0.0)).id();
        let node = world.spawn((outer, ChildOf(root))).id();
        world.spawn((Mesh3d(tri.clone()), ChildOf(node)));
        let child = world.spawn((inner, ChildOf(node))).id();
        world.spawn((Mesh3d(tri), ChildOf(child)));
        world.spawn((Mesh3d(line), ChildOf(child)));
        let (merged, skipped) = world
            .run_system_once(
                move |nodes: Query<(Option<&Transform>, Option<&Mesh3d>, Option<&Children>)>,
                      meshes: Res<Assets<Mesh>>| {
                    let mut out = TriMesh::default();
                    let mut skipped = 0;
                    let children = nodes.get(root).unwrap().2.unwrap();
                    for &c in children {
                        let identity = DAffine3::IDENTITY;
                        merge_below(c, identity, &nodes, &meshes, &mut out, &mut skipped);
                    }
                    (out, skipped)
                },
            )
            .unwrap();
        assert_eq!(skipped, 1);
        assert_eq!(merged.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        // The root's own transform is not applied (the scene in its own space).
        let expected = [
            [10.0, 0.0, 0.0],
            [12.0, 0.0, 0.0],
            [10.0, 2.0, 0.0],
            [10.0, 0.0, 0.0],
            [10.0, 2.0, 0.0],
            [8.0, 0.0, 0.0],
        ];
        for (p, e) in merged.positions.iter().zip(expected) {
            assert!(p.distance(DVec3::from_array(e)) < 1e-6, "{p} vs {e:?}");
        }
    }
}
