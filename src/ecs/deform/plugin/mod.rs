//! The deformation plugin: its system sets, and the systems that prepare meshes, start
//! solves, collect them and write them back.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `ancestors.rs` | [`Deformable`] on an ancestor: a glTF `WorldAssetRoot` or any node of a hierarchy. |
//! | `dynamics.rs` | [`DeformDynamics`]: meshes stepped in time instead of solved to rest. |
//! | `ground.rs` | The ground under a [`DeformGround`] mesh, for its solves: the scene's ground sampled into a height field by the first solve that needs it (off the main thread), seen from the mesh's own coordinates. |
//! | `poll.rs` | Collecting landed solves (the pose handed to write-back, settling continued) and the whole mesh's factorization that follows a preview. |
//! | `prepare.rs` | Preparing deformables: finding meshes (on the entity or below a scene), welding and precomputing topology in the background, rest poses and regions of interest. |
//! | `request.rs` | Requesting solves: constraints from handles and regions, background solves (latest wins) with a preview of a large mesh first, settling a released pose. |
//! | `writeback.rs` | Writing solved poses back to the mesh asset: positions, normals (repaired where a file's were missing or broken) and tangents. |

mod ancestors;
mod dynamics;
mod ground;
mod poll;
mod prepare;
mod request;
mod writeback;

pub use ancestors::MESH_WAIT_FRAMES;
use poll::*;
use prepare::*;
use request::*;
use std::sync::Arc;
use writeback::*;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;

use crate::ecs::tasks::ChainedTask;
use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task};

use super::{
    DeformConfig, DeformDynamics, DeformError, DeformFailed, DeformGround, DeformHandle,
    DeformPhase, DeformSolved, DeformStatus, Deformable, FixedRegion, mesh_positions,
};
use crate::deform::{
    Acceleration, ArapSolver, Constraints, Handle as CoreHandle, InitialGuess, Preview, Solution,
    SolveError, SolveOptions, SolveStats, SolverSettings, Topology, WeightMode, centroid,
};

/// Ordered phases of the deformation systems, all in `Update` (chained in this order).
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeformSystems {
    /// New [`Deformable`] meshes: copy the mesh asset per instance and start building the
    /// topology in the background.
    Prepare,
    /// Collect handle transforms and fixed regions; start a solve task when something changed
    /// and none is running (latest wins: a running stale solve is cancelled at its next
    /// iteration). Put systems that move handles *before* this set.
    Request,
    /// Poll finished tasks; send [`DeformSolved`] / [`DeformFailed`].
    Poll,
    /// Write solved positions, normals and tangents into the mesh assets (before
    /// `PostUpdate`, so bounds and extraction see them this frame).
    Writeback,
}
/// Adds ARAP deformation of [`Deformable`] meshes driven by [`DeformHandle`] entities.
///
/// Its settings are the [`DeformConfig`] resource it inserts (change that at run time):
/// `DeformPlugin { config: DeformConfig { max_iterations: 8, ..default() } }`.
#[derive(Debug, Clone, Default)]
pub struct DeformPlugin {
    /// The project-wide defaults, inserted as the [`DeformConfig`] resource.
    pub config: DeformConfig,
}

impl Plugin for DeformPlugin {
    fn build(&self, app: &mut App) {
        crate::ecs::scene::add_scene_roots(app);
        if !app.is_plugin_added::<crate::ecs::GroundPlugin>() {
            app.add_plugins(crate::ecs::GroundPlugin);
        }
        app.insert_resource(self.config.clone())
            .register_type::<Deformable>()
            .register_type::<FixedRegion>()
            .register_type::<DeformGround>()
            .register_type::<DeformDynamics>()
            .register_type::<DeformHandle>()
            .register_type::<DeformStatus>()
            .register_type::<DeformConfig>()
            .register_type::<super::DeformableScene>()
            .register_type::<super::DeformableFrom>()
            .add_message::<DeformSolved>()
            .add_message::<DeformFailed>()
            .configure_sets(
                Update,
                (
                    DeformSystems::Prepare,
                    DeformSystems::Request,
                    DeformSystems::Poll,
                    DeformSystems::Writeback,
                )
                    .chain(),
            )
            .add_systems(
                Update,
                (
                    (
                        ancestors::expand_deformable_ancestors,
                        ancestors::sync_deformable_ancestors,
                        prepare_deformables,
                    )
                        .chain()
                        .in_set(DeformSystems::Prepare),
                    (request_solves, dynamics::step_dynamics)
                        .chain()
                        .in_set(DeformSystems::Request),
                    poll_tasks.in_set(DeformSystems::Poll),
                    write_back.in_set(DeformSystems::Writeback),
                    crate::ecs::scene::note_missing_scene_assets::<DeformStatus>,
                ),
            );
    }
}

impl crate::ecs::scene::SceneWarning for DeformStatus {
    fn warning_mut(&mut self) -> &mut Option<String> {
        &mut self.warning
    }
}

/// Rest data of a prepared mesh.
struct Rest {
    topology: Arc<Topology>,
    normals: Option<Vec<Vec3>>,
    tangents: Option<Vec<Vec4>>,
}

/// What a solve task produced.
struct Solved {
    solver: Arc<ArapSolver>,
    solution: Arc<Solution>,
    pose: RenderPose,
    /// The preview `solver` belongs to, when the pose is one ([`DeformConfig::preview`]).
    preview: Option<Arc<Preview>>,
}

/// A request handed to the running solve: it goes on with it when its factorization fits
/// (same constraint sets and settings), else gives it back.
struct FollowOn {
    constraints: Constraints,
    settings: SolverSettings,
    options: SolveOptions,
    ground: Option<ground::GroundCache>,
}

struct SolveOutput {
    result: Result<Solved, SolveError>,
    ms: f64,
    /// The constraints solved for (a settling solve reuses them).
    constraints: Constraints,
    /// The solve ran all its iterations without meeting the tolerance or being cancelled.
    unsettled: bool,
}

/// Render-ordered attributes ready to copy into the mesh.
struct RenderPose {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    tangents: Option<Vec<[f32; 4]>>,
}

/// The plugin's state of one prepared [`Deformable`] (on its entity): the rest pose, the
/// solver, the running and pending solves. Other plugins read it through its methods (the
/// grab plugin takes the welded topology for geodesic regions and bakes released poses); its
/// internals are the plugin's. Not reflected (runtime state rebuilt from the mesh).
#[derive(Component)]
pub struct DeformState {
    rest: Option<Arc<Rest>>,
    building: Option<Task<Result<Rest, DeformError>>>,
    solver: Option<Arc<ArapSolver>>,
    last: Option<Arc<Solution>>,
    /// The running solve; it takes the requests that arrive while it runs (the latest wins).
    solve: ChainedTask<FollowOn, SolveOutput>,
    pending: Option<Constraints>,
    ready: Option<RenderPose>,
    attempted: bool,
    /// Settling iterations left since the handles last changed.
    settle_left: u32,
    /// The preview of the current constraint sets and its solver, while the whole mesh is
    /// factored ([`DeformConfig::preview`]).
    preview: Option<(Arc<Preview>, Arc<ArapSolver>)>,
    /// The whole mesh's factorization after a preview, in the background, and the
    /// constraints it is for.
    factoring: Option<(Constraints, Task<Result<ArapSolver, SolveError>>)>,
    /// The constraints of the latest solve started (what a finished factorization resumes).
    latest: Option<Constraints>,
    /// The ground the solves keep the mesh above ([`DeformGround`]).
    ground: Option<ground::GroundCache>,
}

impl DeformState {
    /// The welded topology of the rest pose, once prepared (`None` while preparing).
    pub fn topology(&self) -> Option<&Arc<Topology>> {
        self.rest.as_ref().map(|r| &r.topology)
    }

    /// Whether a solve is running in the background.
    pub fn is_solving(&self) -> bool {
        self.solve.is_running()
    }

    /// Whether a background solve has landed since the last [`DeformSystems::Poll`]: its pose
    /// is written in the next frame's [`DeformSystems::Writeback`].
    pub fn has_landed(&self) -> bool {
        self.solve.has_landed()
    }

    /// Makes the mesh's current pose its rest pose: the deformable `entity` (the one this
    /// state is on) is prepared again, keeping the weld and adjacency of this rest pose when it
    /// has one ([`Topology::rebased`]).
    pub fn bake(&self, entity: Entity, commands: &mut Commands) {
        let mut entity = commands.entity(entity);
        entity.try_remove::<DeformState>();
        if let Some(topology) = self.topology() {
            entity.try_insert(PreviousTopology(topology.clone()));
        }
    }
}

/// The topology of a baked rest pose, reused (same weld and adjacency, new weights) when the
/// deformable is prepared again.
#[derive(Component)]
struct PreviousTopology(Arc<Topology>);
