//! Deforming meshes in the ECS: [`Deformable`] on a mesh (or a glTF scene above meshes),
//! [`DeformHandle`] entities whose `Transform`s move vertex sets, [`FixedRegion`]s held at
//! rest. [`DeformPlugin`] solves ARAP on changed handles in Bevy's `AsyncComputeTaskPool`
//! (latest wins) and writes positions, normals and tangents back to the mesh asset; the
//! math is [`crate::deform`]. This file holds the data types; `plugin.rs` the plugin, its
//! system sets and systems.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin/` | The deformation plugin: its system sets, and the systems that prepare meshes, start solves, collect them and write them back. |

mod plugin;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::prelude::*;
use bevy::reflect::reflect_remote;
use glam::DVec3;

use crate::deform::{Acceleration, MeshError, PreviewRegion, RigidTransform, SolveError, centroid};

pub use plugin::{DeformPlugin, DeformState, DeformSystems, MESH_WAIT_FRAMES};

/// [`Acceleration`] (a core type, no Bevy) as the reflection of [`DeformConfig`] sees it, so
/// inspectors and scenes show and edit it.
#[reflect_remote(Acceleration)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AccelerationReflect {
    /// Plain local/global.
    None,
    /// Anderson acceleration.
    Anderson {
        /// Previous iterates combined.
        depth: usize,
    },
    /// L-BFGS.
    Lbfgs {
        /// Curvature pairs kept.
        depth: usize,
    },
    /// Truncated Newton.
    Newton {
        /// Conjugate-gradient steps per iteration at most.
        max_cg: u32,
    },
}

/// [`PreviewRegion`] (a core type) as reflection sees it.
#[reflect_remote(PreviewRegion)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreviewRegionReflect {
    /// Radius along the surface, as a fraction of the mesh's bounding-box diagonal.
    pub radius: f64,
    /// At most this many vertices move (the nearest to the handles).
    pub max_vertices: usize,
    /// Meshes with no more vertices than this get no preview.
    pub min_mesh_vertices: usize,
}

/// `Option<PreviewRegion>` as reflection sees it ([`DeformConfig::preview`]).
#[reflect_remote(Option<PreviewRegion>)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OptionalPreviewReflect {
    /// No preview: always wait for the whole mesh.
    None,
    /// Preview with this region.
    Some(#[reflect(remote = PreviewRegionReflect)] PreviewRegion),
}

/// Project-wide deformation defaults: inserted by [`DeformPlugin`] (its `config`); change at
/// run time.
#[derive(Resource, Debug, Clone, Reflect)]
#[reflect(Resource)]
pub struct DeformConfig {
    /// Iterations per solve when a [`Deformable`] does not override them. This is also the
    /// per-frame budget where solves cannot leave the frame's thread (the web: Bevy's task
    /// pools run on the browser's main thread, so a task runs between two frames): one solve
    /// per mesh and frame at most, the next warm-started from it (settling, or the latest
    /// request — a newer one still wins), as [`crate::deform::SlicedSolve`] does in the core.
    pub max_iterations: u32,
    /// Relative energy decrease below which a solve stops early.
    pub tolerance: f32,
    /// How the iterations are accelerated (L-BFGS by default: it settles in a fraction of the
    /// plain iterations, see the interaction figures in docs/benchmarks.md).
    #[reflect(remote = AccelerationReflect)]
    pub acceleration: Acceleration,
    /// After the handles stop moving, the plugin keeps iterating in the background with
    /// [`Self::settle_acceleration`] (warm-started solves of one Newton iteration, or
    /// `max_iterations` of the others) until the energy stops falling or this many iterations
    /// have run, so a released pose settles instead of freezing half-converged (0 = never).
    pub settle_iterations: u32,
    /// The iterations that settle a released pose (truncated Newton by default: 7 iterations
    /// on the 26k armadillo where L-BFGS needs ~167, see docs/benchmarks.md).
    #[reflect(remote = AccelerationReflect)]
    pub settle_acceleration: Acceleration,
    /// Where the first solve on a rest pose starts. When the handles move some vertex farther
    /// than this fraction of the mesh's bounding diagonal from rest (a loaded pose, a scripted
    /// jump), from the paper's uniform-Laplacian guess; otherwise from the rest pose itself (a
    /// pointer grab starts at rest, and the Laplacian guess would cost a second factorization
    /// for the same pose; `docs/design/solver.md`). A constraint
    /// set that changes mid-edit always continues from the displayed pose.
    pub laplacian_start_displacement: f32,
    /// A new constraint set on a mesh with more vertices than the region's `max_vertices` is
    /// first shown as a *preview*: only the vertices near the handles are solved (the rest
    /// held where they are shown), which takes a frame or two where the whole mesh's
    /// factorization takes several (today's figures: `arap_interaction` in
    /// `docs/benchmarks.md`). The whole mesh is then factored in the background and solved
    /// on from the preview. `None`: always wait for the whole mesh. Not used on a
    /// [`Deformable`] with its own region of interest.
    #[reflect(remote = OptionalPreviewReflect)]
    pub preview: Option<PreviewRegion>,
}

impl Default for DeformConfig {
    /// 4 L-BFGS iterations per solve, tolerance 1e-3, 40 settling iterations of truncated
    /// Newton, the Laplacian start beyond 5 % of the diagonal, and a preview on large meshes.
    fn default() -> Self {
        Self {
            max_iterations: 4,
            tolerance: 1e-3,
            acceleration: Acceleration::Lbfgs { depth: 8 },
            settle_iterations: 40,
            settle_acceleration: Acceleration::Newton { max_cg: 30 },
            laplacian_start_displacement: 0.05,
            preview: Some(PreviewRegion::default()),
        }
    }
}
/// Marks a `Mesh3d` entity as deformable. Handles refer to it by entity.
///
/// Put on an entity without a mesh — a glTF scene root (`WorldAssetRoot`) or any ancestor —
/// it applies to every mesh primitive below it once they exist (see [`DeformableScene`](crate::ecs::DeformableScene)).
///
/// Vertex indices everywhere in the plugin are *render* vertex indices of the mesh (as in its
/// index buffer); seams are welded internally so split vertices move together.
#[derive(Component, Debug, Clone, Reflect, PartialEq)]
#[reflect(Component, Default)]
#[require(DeformStatus)]
#[derive(Default)]
pub struct Deformable {
    /// Iterations per solve (`None` = [`DeformConfig::max_iterations`]).
    pub max_iterations: Option<u32>,
    /// Tolerance (`None` = [`DeformConfig::tolerance`]).
    pub tolerance: Option<f32>,
    /// Use raw (possibly negative) cotangent weights instead of clamped ones.
    pub raw_cotangent_weights: bool,
    /// Optional region of interest (render vertex indices); others stay at rest.
    pub region_of_interest: Option<Vec<u32>>,
}

/// Keeps a [`Deformable`]'s bend on the game's ground ([`crate::ecs::SceneGround`]: the
/// [`crate::ecs::GroundMesh`] meshes or the game's own): no vertex goes below it, and a handle
/// dragged into it slides along it instead ([`crate::deform::obstacle`]).
///
/// The ground under and around the mesh is sampled once into a height field (in the
/// background, again when the mesh entity moves or the ground changes), across world +Y:
/// `cells` samples along the mesh's rest bounding diagonal, `reach` diagonals of margin on
/// every side. Between samples the ground is bilinear: a wall or a step is a slope one cell
/// wide. A mesh that is itself [`crate::ecs::GroundMesh`] stops at its own old shape: do not
/// mark it.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct DeformGround {
    /// Samples along the mesh's rest bounding diagonal (at least 2).
    pub cells: u32,
    /// Margin around the mesh's rest bounds, in bounding diagonals.
    pub reach: f32,
}

impl Default for DeformGround {
    fn default() -> Self {
        Self {
            cells: 48,
            reach: 0.5,
        }
    }
}

/// Gives a [`Deformable`]'s bend inertia ([`crate::deform::dynamics`]): a grabbed mesh lags
/// behind a fast drag, and a released one overshoots and rings down to its rest — the pose its
/// handles hold (the new shape, when editing), or the original shape when `elastic` (the grab's
/// handle is let go at release). Replaces the static solves for this mesh: every frame runs
/// the time steps its time holds (in the frame up to [`DeformDynamics::IN_FRAME_BELOW`]
/// vertices, on the compute pool above).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct DeformDynamics {
    /// Ringing of the mesh's slowest mode as its Laplacian sees it, Hz (slender parts ring
    /// slower; [`crate::deform::DynamicsSettings::frequency`]).
    pub frequency: f32,
    /// Damping ratio of that mode (1: no overshoot).
    pub damping: f32,
    /// Spring back to the original shape when a grab lets go, rather than hold the new one.
    pub elastic: bool,
    /// Local/global iterations per time step (more: less numerical damping, more time).
    pub iterations: u32,
}

impl DeformDynamics {
    /// Meshes under this many vertices step in the frame; larger ones on the compute pool.
    pub const IN_FRAME_BELOW: usize = 4000;

    /// The core's settings.
    pub fn settings(&self) -> crate::deform::DynamicsSettings {
        crate::deform::DynamicsSettings {
            frequency: f64::from(self.frequency),
            damping: f64::from(self.damping),
            iterations: self.iterations.max(1),
            ..Default::default()
        }
    }
}

impl Default for DeformDynamics {
    fn default() -> Self {
        let core = crate::deform::DynamicsSettings::default();
        Self {
            frequency: core.frequency as f32,
            damping: core.damping as f32,
            elastic: false,
            iterations: core.iterations,
        }
    }
}

/// Vertices of a [`Deformable`] held at their rest position (render indices).
#[derive(Component, Debug, Clone, Default, Reflect, PartialEq)]
#[reflect(Component, Default)]
pub struct FixedRegion(pub Vec<u32>);

/// A handle: a set of vertices of `target` moved rigidly by this entity's `Transform`.
///
/// The `Transform` is read in the target mesh's local space. At rest it is
/// `Transform::from_translation(pivot)` (the rest centroid of the vertices): then
/// `translation − pivot` is the handle's translation and `rotation` turns it about the pivot.
/// Spawn it with [`DeformHandle::bundle`] to get that right, or leave `pivot` as `None` and
/// an identity `Transform`: the plugin fills both in when the mesh is ready.
#[derive(Component, Debug, Clone, Reflect, PartialEq)]
#[reflect(Component)]
pub struct DeformHandle {
    /// The [`Deformable`] mesh entity.
    #[entities]
    pub target: Entity,
    /// Render vertex indices of the handle.
    pub vertices: Vec<u32>,
    /// Rest centroid in mesh space (filled in by the plugin when `None`).
    pub pivot: Option<Vec3>,
}

impl DeformHandle {
    /// A handle with its rest transform computed from `mesh` (positions in mesh space).
    pub fn bundle(mesh: &Mesh, target: Entity, vertices: Vec<u32>) -> (Self, Transform) {
        let pivot = mesh_positions(mesh)
            .map(|p| {
                let p: Vec<DVec3> = p.iter().map(|q| q.as_dvec3()).collect();
                centroid(&p, &vertices).as_vec3()
            })
            .unwrap_or(Vec3::ZERO);
        (
            Self {
                target,
                vertices,
                pivot: Some(pivot),
            },
            Transform::from_translation(pivot),
        )
    }

    /// The rigid transform this handle applies, given its `Transform`.
    pub fn rigid_transform(&self, transform: &Transform) -> RigidTransform {
        let pivot = self.pivot.unwrap_or(Vec3::ZERO).as_dvec3();
        RigidTransform::new(
            transform.rotation.as_dquat().normalize(),
            transform.translation.as_dvec3() - pivot,
            pivot,
        )
    }
}

/// Where a deformable stands; readable by UIs.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
pub struct DeformStatus {
    /// What the background worker is doing.
    pub phase: DeformPhase,
    /// Welded vertex count (0 until prepared).
    pub vertices: usize,
    /// Iterations of the last solve.
    pub iterations: u32,
    /// Normalised ARAP energy after the last solve.
    pub energy: f64,
    /// Milliseconds of the last solve (including precompute when the sets changed); with
    /// [`DeformDynamics`], per time step of the last batch.
    pub solve_ms: f64,
    /// Completed solves so far (with [`DeformDynamics`]: poses written, one per frame that
    /// stepped).
    pub solves: u64,
    /// Vertices held on the ground by the last solve ([`DeformGround`]).
    pub ground_contacts: usize,
    /// The displayed pose is a preview ([`DeformConfig::preview`]): only the region near the
    /// handles was solved, while the whole mesh is factored; its solve follows.
    pub preview: bool,
    /// Last error, if the last attempt failed.
    #[reflect(ignore)]
    pub error: Option<DeformError>,
    /// Something missing that does not stop deforming: a dependency of the glTF scene this
    /// is on (a texture's image file) that failed to load, with the loader's message naming
    /// it (from [`MissingSceneAssets`](crate::ecs::MissingSceneAssets)).
    #[reflect(ignore)]
    pub warning: Option<String>,
}

/// Why a [`Deformable`] could not be prepared or solved (in [`DeformFailed`] and
/// [`DeformStatus::error`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeformError {
    /// The mesh has no CPU-side `Float32x3` positions (e.g. its asset usage is render-world
    /// only, or positions are another format).
    #[error("the mesh has no CPU-side Float32x3 positions")]
    NoPositions,
    /// The mesh is not a triangle list.
    #[error("the mesh topology is {0}, not a triangle list")]
    NotTriangleList(String),
    /// The mesh data is invalid (bad indices, NaN positions, …).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Precompute or solve failed (bad constraints, not positive definite, …).
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// A [`Deformable`] on an entity with no mesh below it (after its scene spawned).
    #[error(
        "no mesh below this entity: put Deformable on a Mesh3d entity, a glTF scene root or an ancestor of meshes"
    )]
    NoMeshBelow,
    /// The solve produced NaN or infinity; the mesh was left unchanged.
    #[error("the solve produced non-finite values; the mesh was left unchanged")]
    NonFinite,
    /// The glTF scene (a `WorldAssetRoot`) this [`Deformable`] is on failed to load: a
    /// missing or malformed file. The loader's message is kept.
    #[error("the scene failed to load: {0}")]
    SceneLoadFailed(String),
}

/// Background phase of a deformable.
#[derive(Debug, Clone, Copy, Default, Reflect, PartialEq, Eq)]
pub enum DeformPhase {
    /// Waiting for the mesh asset.
    #[default]
    WaitingForMesh,
    /// Welding and building the topology.
    BuildingTopology,
    /// Ready; no solve running.
    Idle,
    /// Factorizing (constraint sets changed).
    Factorizing,
    /// Iterating.
    Solving,
    /// The handles stopped; iterating on toward the converged pose
    /// ([`DeformConfig::settle_iterations`]).
    Settling,
    /// The mesh could not be prepared (see [`DeformStatus::error`]); nothing will be solved
    /// until the [`Deformable`] is re-inserted.
    Failed,
}

/// A solve finished and was written to the mesh.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct DeformSolved {
    /// The deformable entity.
    pub entity: Entity,
    /// Iterations done.
    pub iterations: u32,
    /// Normalised energy.
    pub energy: f64,
    /// Solve time in ms (worker thread).
    pub solve_ms: f64,
}

/// Preparing or solving a deformable failed; the mesh was left as it was.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct DeformFailed {
    /// The deformable entity.
    pub entity: Entity,
    /// What went wrong.
    pub error: DeformError,
}

/// The mesh's CPU-side `Float32x3` positions, if it has them.
pub(crate) fn mesh_positions(mesh: &Mesh) -> Option<Vec<Vec3>> {
    match mesh.try_attribute(Mesh::ATTRIBUTE_POSITION).ok()? {
        VertexAttributeValues::Float32x3(v) => {
            Some(v.iter().map(|p| Vec3::from_array(*p)).collect())
        }
        _ => None,
    }
}

/// Builds a triangle-list mesh (positions, normals, indices) from core data, keeping the
/// CPU copy so it can be deformed.
pub fn mesh_from_triangles(positions: &[DVec3], triangles: &[[u32; 3]]) -> Mesh {
    let pos: Vec<[f32; 3]> = positions.iter().map(|p| p.as_vec3().to_array()).collect();
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize].as_vec3());
        let n = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += n;
        }
    }
    let normals: Vec<[f32; 3]> = normals
        .iter()
        .map(|n| n.normalize_or(Vec3::Y).to_array())
        .collect();
    Mesh::new(
        bevy::mesh::PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, pos)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
    .with_inserted_indices(Indices::U32(triangles.iter().flatten().copied().collect()))
}

/// On an ancestor whose [`Deformable`] was handed to the mesh primitives below it: those
/// primitives, in hierarchy order.
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct DeformableScene {
    /// The primitive entities that are deformable because of this ancestor.
    #[entities]
    pub primitives: Vec<Entity>,
}

/// On a mesh primitive that is deformable because an ancestor is: that ancestor. Its
/// [`Deformable`] follows the ancestor's.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct DeformableFrom(#[entities] pub Entity);
