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
use bevy_wii_deform::deform::{Topology, TriMesh};
use bevy_wii_deform::prelude::*;
use glam::{DAffine3, DVec3};

use crate::challenge::{ChallengeSetup, TaskList, TaskTarget};
use crate::history::History;
use crate::missing_textures::MissingImages;
use crate::parts::{PartRange, needs_parts, spawn_parts};
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
                    mention_missing_images,
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
    look: Look,
    task: Option<(String, tasks::Task)>,
    target: Option<Result<Vec<DVec3>, String>>,
}

/// What a glTF model looks like, kept while its merged mesh is edited: texture coordinates
/// per vertex (when any primitive has them), the material of its first primitive that has
/// one, and each primitive's range and material (a model of several materials is drawn part
/// by part: `parts.rs`).
#[derive(Default)]
struct Look {
    uvs: Option<Vec<[f32; 2]>>,
    material: Option<Handle<StandardMaterial>>,
    parts: Vec<PartRange>,
}

/// A glTF scene's primitives merged into one mesh, with their look.
#[derive(Default)]
struct Merged {
    mesh: TriMesh,
    uvs: Vec<[f32; 2]>,
    any_uvs: bool,
    material: Option<Handle<StandardMaterial>>,
    /// Each primitive's vertices, triangles and material.
    parts: Vec<PartRange>,
    /// Primitives that are not triangle lists with positions.
    skipped: usize,
    /// Why primitives are broken.
    errors: Vec<String>,
}

impl Merged {
    /// The merged mesh and its look.
    fn into_parts(self) -> (TriMesh, Look) {
        let look = Look {
            uvs: self.any_uvs.then_some(self.uvs),
            material: self.material,
            parts: self.parts,
        };
        (self.mesh, look)
    }
}

/// A node of a spawned glTF scene, as the merge reads it.
type SceneNode = (
    Option<&'static Transform>,
    Option<&'static Mesh3d>,
    Option<&'static MeshMaterial3d<StandardMaterial>>,
    Option<&'static Children>,
);

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
        let read = move || read_model(&name).map(|m| (m, Look::default()));
        loading.job = Some(Job::Prepare(prepare(request, read)));
    }
}

/// Normalises the mesh and solves the challenge target in the background.
fn prepare(
    request: Request,
    read: impl FnOnce() -> Result<(TriMesh, Look), String> + Send + 'static,
) -> Task<Result<Loaded, String>> {
    AsyncComputeTaskPool::get().spawn(async move {
        let (mut mesh, look) = read()?;
        if !models::MODELS.contains(&request.name.as_str()) {
            // A file: checked before it replaces the model (NaN or infinite positions, indices
            // out of range, degenerate meshes get their reason on the status line).
            Topology::new(&mesh.positions, &mesh.triangles)
                .map_err(|e| format!("{}: {e}", request.name))?;
            mesh = normalise(mesh);
        }
        let target = request.task.as_ref().map(|(_, t)| t.target_pose(&mesh));
        Ok(Loaded {
            name: request.name,
            mesh,
            look,
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
    nodes: Query<SceneNode>,
    meshes: Res<Assets<Mesh>>,
    mut loading: ResMut<Loading>,
) {
    let Ok(import) = imports.get(ready.entity) else {
        return;
    };
    let request = import.0.clone();
    let mut merged = Merged::default();
    if let Ok((_, _, _, Some(children))) = nodes.get(ready.entity) {
        for &child in children {
            merge_below(child, DAffine3::IDENTITY, &nodes, &meshes, &mut merged);
        }
    }
    commands.entity(ready.entity).despawn();
    let name = request.name.clone();
    let read = move || match (merged.mesh.positions.is_empty(), merged.skipped) {
        _ if !merged.errors.is_empty() => Err(format!("{name}: {}", merged.errors[0])),
        (true, 0) => Err(format!("{name}: no meshes in the scene")),
        (true, skipped) => Err(format!(
            "{name}: {skipped} primitive(s), none a triangle list with positions"
        )),
        (false, _) => Ok(merged.into_parts()),
    };
    loading.job = Some(Job::Prepare(prepare(request, read)));
}

/// Appends the triangle primitives at and below `entity` (positions, texture coordinates, the
/// first material); `parent` is the transform from the parent's space to the scene root's.
fn merge_below(
    entity: Entity,
    parent: DAffine3,
    nodes: &Query<SceneNode>,
    meshes: &Assets<Mesh>,
    out: &mut Merged,
) {
    let Ok((transform, mesh, material, children)) = nodes.get(entity) else {
        return;
    };
    let local = transform.map_or(DAffine3::IDENTITY, |t| {
        let a = t.compute_affine();
        DAffine3::from_mat4(Mat4::from(a).as_dmat4())
    });
    let to_root = parent * local;
    if let Some(mesh) = mesh {
        let mesh = meshes.get(&mesh.0);
        match mesh.and_then(triangles_of) {
            Some(Err(e)) => out.errors.push(e),
            Some(Ok((positions, triangles))) => {
                let base = out.mesh.positions.len() as u32;
                let first_triangle = out.mesh.triangles.len();
                out.mesh
                    .positions
                    .extend(positions.iter().map(|p| to_root.transform_point3(*p)));
                out.mesh
                    .triangles
                    .extend(triangles.iter().map(|t| t.map(|i| base + i)));
                match mesh.and_then(|m| m.attribute(Mesh::ATTRIBUTE_UV_0)) {
                    Some(VertexAttributeValues::Float32x2(uv)) if uv.len() == positions.len() => {
                        out.uvs.extend_from_slice(uv);
                        out.any_uvs = true;
                    }
                    _ => out.uvs.resize(out.mesh.positions.len(), [0.0; 2]),
                }
                if out.material.is_none() {
                    out.material = material.map(|m| m.0.clone());
                }
                out.parts.push(PartRange {
                    vertices: base..out.mesh.positions.len() as u32,
                    triangles: first_triangle..out.mesh.triangles.len(),
                    material: material.map(|m| m.0.clone()),
                });
            }
            None => out.skipped += 1,
        }
    }
    for &child in children.into_iter().flatten() {
        merge_below(child, to_root, nodes, meshes, out);
    }
}

/// A primitive's positions and triangles.
type Primitive = (Vec<DVec3>, Vec<[u32; 3]>);

/// Positions and triangles of a triangle-list mesh with CPU-side positions (`None`: not one);
/// an index past the vertices is an error.
fn triangles_of(mesh: &Mesh) -> Option<Result<Primitive, String>> {
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
    if let Some(bad) = indices.iter().find(|&&i| i >= n) {
        return Some(Err(format!(
            "a primitive's index {bad} is past its {n} vertices"
        )));
    }
    let triangles = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let positions = p.iter().map(|q| Vec3::from_array(*q).as_dvec3()).collect();
    Some(Ok((positions, triangles)))
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

/// What the status line says before a missing image's path.
const MISSING_MARK: &str = " | missing image ";

/// A loaded model whose images are missing says which (it is drawn without them:
/// `MissingTexturesPlugin`).
fn mention_missing_images(missing: Option<Res<MissingImages>>, mut status: ResMut<StatusLine>) {
    if let Some(last) = missing.as_ref().and_then(|m| m.0.last())
        && status.0.starts_with("loaded ")
        && !status.0.contains(MISSING_MARK)
    {
        let message = format!("{}{MISSING_MARK}{last}: drawn without it", status.0);
        status.set(message);
    }
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
    if let Some(uvs) = loaded.look.uvs.clone() {
        bevy_mesh.insert_attribute(Mesh::ATTRIBUTE_UV_0, uvs);
    }
    let material = material_of(&loaded.look, &parts.materials);
    let material = parts.materials.add(material);
    let drawn_in_parts = needs_parts(&loaded.look.parts).then(|| bevy_mesh.clone());
    let entity = commands
        .spawn((
            Mesh3d(parts.meshes.add(bevy_mesh)),
            MeshMaterial3d(material.clone()),
            Deformable::default(),
            FixedRegion::default(),
            Transform::default(),
            Name::new(loaded.name.clone()),
        ))
        .id();
    if let Some(merged) = drawn_in_parts {
        spawn_parts(
            &mut commands,
            &mut parts.meshes,
            entity,
            &merged,
            &loaded.look.parts,
            &material,
        );
    }
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

/// The model's own material (its textures, colours, roughness) when it has one, else a plain
/// white one; the selection's vertex colours tint it either way.
fn material_of(look: &Look, materials: &Assets<StandardMaterial>) -> StandardMaterial {
    look.material
        .as_ref()
        .and_then(|h| materials.get(h))
        .cloned()
        .unwrap_or(StandardMaterial {
            base_color: Color::WHITE,
            perceptual_roughness: 0.6,
            ..default()
        })
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
            .run_system_once(move |nodes: Query<SceneNode>, meshes: Res<Assets<Mesh>>| {
                let mut out = Merged::default();
                let children = nodes.get(root).unwrap().3.unwrap();
                for &c in children {
                    merge_below(c, DAffine3::IDENTITY, &nodes, &meshes, &mut out);
                }
                (out.mesh, out.skipped)
            })
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

    /// `file` of the repository's `assets/models` through Bevy's glTF loader (its materials as
    /// `StandardMaterial`s, as the renderer makes them), merged as the sandbox merges a scene.
    fn merge_model_scene(file: &str) -> (App, Merged) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/models");
        let mut app = App::new();
        app.add_plugins(MinimalPlugins);
        crate::headless_gltf::add_gltf_plugins(&mut app, &dir);
        app.finish();
        app.cleanup();
        crate::headless_gltf::add_standard_materials(&mut app);
        let scene = app
            .world()
            .resource::<AssetServer>()
            .load(GltfAssetLabel::Scene(0).from_asset(file.to_string()));
        let root = app.world_mut().spawn(WorldAssetRoot(scene)).id();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
        while app.world().get::<Children>(root).is_none() {
            assert!(std::time::Instant::now() < deadline, "{file} never spawned");
            app.update();
            std::thread::yield_now();
        }
        let merged = app
            .world_mut()
            .run_system_once(move |nodes: Query<SceneNode>, meshes: Res<Assets<Mesh>>| {
                let mut out = Merged::default();
                for &c in nodes.get(root).unwrap().3.unwrap() {
                    merge_below(c, DAffine3::IDENTITY, &nodes, &meshes, &mut out);
                }
                out
            })
            .unwrap();
        (app, merged)
    }

    /// The Fox through Bevy's glTF loader, merged as the sandbox merges a scene: its texture
    /// coordinates come along (one per vertex) and the Fox's material — its base-colour
    /// texture — is the merged mesh's; one material, so it is drawn by the merged mesh itself.
    #[test]
    fn the_sandbox_keeps_gltf_materials() {
        let (app, merged) = merge_model_scene("Fox.glb");
        let (mesh, look) = merged.into_parts();
        let uvs = look.uvs.as_ref().expect("the Fox's texture coordinates");
        assert_eq!(uvs.len(), mesh.positions.len());
        assert!(uvs.iter().any(|uv| uv[0] != 0.0 || uv[1] != 0.0));
        let materials = app.world().resource::<Assets<StandardMaterial>>();
        let material = material_of(&look, materials);
        assert!(
            material.base_color_texture.is_some(),
            "the Fox's base-colour texture is on the merged mesh's material"
        );
        assert!(!needs_parts(&look.parts), "one material, no parts");
    }

    /// The alien (Kenney's Space Kit: five materials over eighteen primitives): every
    /// primitive keeps its own material, so the merged mesh is drawn part by part with the
    /// file's five base colours, and the parts cover every vertex and triangle once.
    #[test]
    fn the_sandbox_keeps_each_primitives_material() {
        let (app, merged) = merge_model_scene("alien.glb");
        let (mesh, look) = merged.into_parts();
        assert!(needs_parts(&look.parts));
        let materials = app.world().resource::<Assets<StandardMaterial>>();
        let mut colours: Vec<[u8; 4]> = look
            .parts
            .iter()
            .map(|p| {
                let m = materials
                    .get(p.material.as_ref().expect("every primitive has a material"))
                    .expect("a loaded material");
                m.base_color.to_srgba().to_u8_array()
            })
            .collect();
        colours.sort();
        colours.dedup();
        assert_eq!(colours.len(), 5, "the alien's five materials: {colours:?}");
        let vertices: u32 = look.parts.iter().map(|p| p.vertices.len() as u32).sum();
        let triangles: usize = look.parts.iter().map(|p| p.triangles.len()).sum();
        assert_eq!(vertices as usize, mesh.positions.len());
        assert_eq!(triangles, mesh.triangles.len());
    }

    /// Broken glTF files loaded into the sandbox as a user drops them: each ends with a
    /// message naming the file on the status line (the model kept), usable ones load, and
    /// the app keeps running.
    #[test]
    fn broken_gltf_files_reach_the_status_line_and_the_app_runs_on() {
        let dir = std::env::temp_dir().join(format!("bwd_sandbox_gltf_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = crate::broken_gltf::write_files(&dir);
        let mut app = App::new();
        app.add_plugins(MinimalPlugins);
        // The broken files are read by absolute path (unapproved paths allowed).
        crate::headless_gltf::add_gltf_plugins(&mut app, std::path::Path::new("assets"));
        app.init_asset::<StandardMaterial>()
            .init_resource::<Model>()
            .init_resource::<StatusLine>()
            .init_resource::<Selection>()
            .init_resource::<History>()
            .init_resource::<crate::camera::OrbitCamera>()
            .insert_resource(TaskList(Vec::new()))
            .add_message::<FileDragAndDrop>()
            .add_message::<RegionsChanged>()
            .add_message::<ChallengeSetup>()
            .add_plugins(LoadingPlugin);
        app.finish();
        app.cleanup();
        for (name, usable) in files {
            let path = dir.join(name).display().to_string();
            app.world_mut().write_message(LoadModel(path.clone()));
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
            loop {
                app.update();
                let loading = app.world().resource::<Loading>();
                if loading.job.is_none() && loading.queued.is_none() {
                    break;
                }
                assert!(
                    std::time::Instant::now() < deadline,
                    "{name} never finished"
                );
                std::thread::yield_now();
            }
            let status = app.world().resource::<StatusLine>().0.clone();
            let model = app.world().resource::<Model>().name.clone();
            if usable {
                assert_eq!(model, path, "{name} should load: {status}");
            } else {
                assert!(
                    status.contains(name),
                    "{name}: the status line says {status:?}"
                );
                assert_ne!(model, path, "{name} was loaded as a model");
            }
        }
        // Still running.
        for _ in 0..5 {
            app.update();
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
