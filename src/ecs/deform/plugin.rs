//! The deformation plugin: its system sets, and the systems that prepare meshes, start
//! solves, collect them and write them back.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use bevy::asset::RenderAssetUsages;
use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy::tasks::futures::check_ready;
use bevy::tasks::{AsyncComputeTaskPool, Task};

use super::{
    DeformConfig, DeformError, DeformFailed, DeformHandle, DeformPhase, DeformSolved, DeformStatus,
    Deformable, FixedRegion, mesh_positions,
};
use crate::deform::{
    Acceleration, ArapSolver, Constraints, Handle as CoreHandle, InitialGuess, Preview,
    PreviewRegion, Solution, SolveError, SolveOptions, SolveStats, SolverSettings, Topology,
    WeightMode, centroid,
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
#[derive(Debug, Clone)]
pub struct DeformPlugin {
    /// Default iterations per solve (warm-started solves need few).
    pub max_iterations: u32,
    /// Default tolerance.
    pub tolerance: f32,
    /// Default acceleration ([`DeformConfig::acceleration`]).
    pub acceleration: Acceleration,
    /// Default settling budget ([`DeformConfig::settle_iterations`]).
    pub settle_iterations: u32,
    /// Default settling iterations ([`DeformConfig::settle_acceleration`]).
    pub settle_acceleration: Acceleration,
    /// Default start rule ([`DeformConfig::laplacian_start_displacement`]).
    pub laplacian_start_displacement: f32,
    /// Default first pose of a new constraint set on a large mesh ([`DeformConfig::preview`]).
    pub preview: Option<PreviewRegion>,
}

impl Default for DeformPlugin {
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

impl Plugin for DeformPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(DeformConfig {
            max_iterations: self.max_iterations,
            tolerance: self.tolerance,
            acceleration: self.acceleration,
            settle_iterations: self.settle_iterations,
            settle_acceleration: self.settle_acceleration,
            laplacian_start_displacement: self.laplacian_start_displacement,
            preview: self.preview,
        })
        .register_type::<Deformable>()
        .register_type::<FixedRegion>()
        .register_type::<DeformHandle>()
        .register_type::<DeformStatus>()
        .register_type::<DeformConfig>()
        .register_type::<crate::ecs::scene::DeformableScene>()
        .register_type::<crate::ecs::scene::DeformableFrom>()
        .add_observer(crate::ecs::scene::mark_scene_spawned)
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
                    crate::ecs::scene::expand_deformable_ancestors,
                    crate::ecs::scene::sync_deformable_ancestors,
                    prepare_deformables,
                )
                    .chain()
                    .in_set(DeformSystems::Prepare),
                request_solves.in_set(DeformSystems::Request),
                poll_tasks.in_set(DeformSystems::Poll),
                write_back.in_set(DeformSystems::Writeback),
            ),
        );
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

/// Internal per-deformable state (not reflected).
#[derive(Component)]
pub(crate) struct DeformState {
    rest: Option<Arc<Rest>>,
    building: Option<Task<Result<Rest, DeformError>>>,
    solver: Option<Arc<ArapSolver>>,
    last: Option<Arc<Solution>>,
    task: Option<Task<SolveOutput>>,
    requested: Arc<AtomicU64>,
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
}

impl DeformState {
    /// The welded topology of the rest pose, once prepared.
    pub(crate) fn topology(&self) -> Option<&Arc<Topology>> {
        self.rest.as_ref().map(|r| &r.topology)
    }

    /// Makes the mesh's current pose its rest pose: the deformable is prepared again, keeping
    /// the weld and adjacency of this rest pose when it has one ([`Topology::rebased`]).
    pub(crate) fn bake(&self, entity: Entity, commands: &mut Commands) {
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

#[allow(clippy::type_complexity)]
fn prepare_deformables(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut new: Query<
        (
            Entity,
            &mut Mesh3d,
            &mut DeformStatus,
            Option<&PreviousTopology>,
        ),
        (With<Deformable>, Without<DeformState>),
    >,
    mut building: Query<(Entity, &mut DeformState, &mut DeformStatus)>,
    mut failed: MessageWriter<DeformFailed>,
) {
    for (entity, mut mesh3d, mut status, previous) in &mut new {
        let Some(mesh) = meshes.get(&mesh3d.0) else {
            continue; // not loaded yet
        };
        let previous = previous.map(|p| p.0.clone());
        commands.entity(entity).try_remove::<PreviousTopology>();
        let topology = mesh.primitive_topology();
        let triangles = topology == bevy::mesh::PrimitiveTopology::TriangleList;
        // Copy per instance: glTF entities may share one mesh asset.
        let mut copy = mesh.clone();
        let positions = mesh_positions(&copy);
        let indices: Option<Vec<u32>> = copy
            .try_indices()
            .ok()
            .map(|i| i.iter().map(|x| x as u32).collect());
        let normals = match copy.try_attribute(Mesh::ATTRIBUTE_NORMAL) {
            Ok(VertexAttributeValues::Float32x3(v)) => {
                Some(v.iter().map(|p| Vec3::from_array(*p)).collect::<Vec<_>>())
            }
            _ => None,
        };
        // A file's NaN or zero normals never reach the mesh: those are recomputed from the
        // surface (area-weighted face normals).
        let normals = match (normals, &positions, &indices) {
            (Some(n), Some(p), i) if n.len() == p.len() && n.iter().any(|v| !is_unit_like(*v)) => {
                let unindexed = || (0..p.len() as u32).collect::<Vec<_>>();
                let repaired = repair_normals(p, &i.clone().unwrap_or_else(unindexed), &n);
                copy.insert_attribute(
                    Mesh::ATTRIBUTE_NORMAL,
                    repaired.iter().map(|v| v.to_array()).collect::<Vec<_>>(),
                );
                Some(repaired)
            }
            (n, _, _) => n,
        };
        let tangents = match copy.try_attribute(Mesh::ATTRIBUTE_TANGENT) {
            Ok(VertexAttributeValues::Float32x4(v)) => {
                Some(v.iter().map(|p| Vec4::from_array(*p)).collect())
            }
            _ => None,
        };
        copy.asset_usage = RenderAssetUsages::default();
        mesh3d.0 = meshes.add(copy);
        let task = AsyncComputeTaskPool::get().spawn(async move {
            if !triangles {
                return Err(DeformError::NotTriangleList(format!("{topology:?}")));
            }
            let positions = positions.ok_or(DeformError::NoPositions)?;
            let indices = match indices {
                Some(i) => i,
                None => (0..positions.len() as u32).collect(),
            };
            // A baked pose of the same mesh keeps its weld; anything else is built afresh.
            let topology = match previous.map(|p| p.rebased(&positions, &indices)) {
                Some(Ok(rebased)) => rebased,
                _ => Topology::from_render_mesh(&positions, &indices)?,
            };
            // Here, off the path of a first grab: every constraint set restricts it.
            topology.prepare_elimination_order();
            Ok(Rest {
                topology: Arc::new(topology),
                normals,
                tangents,
            })
        });
        status.phase = DeformPhase::BuildingTopology;
        commands.entity(entity).try_insert(DeformState {
            rest: None,
            building: Some(task),
            solver: None,
            last: None,
            task: None,
            requested: Arc::new(AtomicU64::new(0)),
            pending: None,
            ready: None,
            attempted: false,
            settle_left: 0,
            preview: None,
            factoring: None,
            latest: None,
        });
    }
    for (entity, mut state, mut status) in &mut building {
        let state = state.bypass_change_detection();
        let Some(task) = state.building.as_mut() else {
            continue;
        };
        if let Some(result) = check_ready(task) {
            state.building = None;
            match result {
                Ok(rest) => {
                    status.vertices = rest.topology.vertex_count();
                    status.phase = DeformPhase::Idle;
                    state.rest = Some(Arc::new(rest));
                }
                Err(error) => {
                    warn!("Deformable {entity}: {error}");
                    status.phase = DeformPhase::Failed;
                    status.error = Some(error.clone());
                    failed.write(DeformFailed { entity, error });
                }
            }
        }
    }
}

/// Builds core constraints (welded indices) for one deformable.
fn build_constraints(
    topology: &Topology,
    fixed: Option<&FixedRegion>,
    handles: &[(&DeformHandle, &Transform)],
) -> Constraints {
    Constraints {
        fixed: fixed.map(|f| topology.welded_set(&f.0)).unwrap_or_default(),
        handles: handles
            .iter()
            .map(|(h, t)| CoreHandle {
                vertices: topology.welded_set(&h.vertices),
                transform: h.rigid_transform(t),
            })
            .collect(),
        targets: Vec::new(),
    }
}

#[allow(clippy::type_complexity)]
fn request_solves(
    config: Res<DeformConfig>,
    mut deformables: Query<(
        Entity,
        &Deformable,
        Option<Ref<FixedRegion>>,
        &mut DeformState,
        &mut DeformStatus,
    )>,
    mut handles: Query<(Entity, &mut DeformHandle, &mut Transform)>,
    mut removed: RemovedComponents<DeformHandle>,
    changed_deformable: Query<(), Changed<Deformable>>,
) {
    // Fill in missing pivots (rest centroid) once the topology exists; a handle left at the
    // identity Transform is put at its pivot, its rest pose (else it would jump by −pivot).
    for (_, mut h, mut transform) in &mut handles {
        if h.pivot.is_some() {
            continue;
        }
        let Ok((_, _, _, state, _)) = deformables.get(h.target) else {
            continue;
        };
        let Some(rest) = &state.rest else { continue };
        let topo = &rest.topology;
        let map = topo.render_to_welded();
        let welded: Vec<u32> = h
            .vertices
            .iter()
            .filter_map(|&v| map.get(v as usize).copied())
            .collect();
        let c = centroid(topo.positions(), &welded).as_vec3();
        h.pivot = Some(c);
        if *transform == Transform::IDENTITY {
            transform.translation = c;
        }
    }
    // Consume the removals so each one triggers exactly one re-solve.
    let any_removed = removed.read().count() > 0;
    for (entity, deformable, fixed, mut state, mut status) in &mut deformables {
        let Some(rest) = state.rest.clone() else {
            continue;
        };
        // (Mutable access only to read change ticks: nothing is written here.)
        let mine: Vec<(Entity, Mut<DeformHandle>, Mut<Transform>)> = handles
            .iter_mut()
            .filter(|(_, h, _)| h.target == entity)
            .collect();
        let changed = mine
            .iter()
            .any(|(_, h, t)| t.is_changed() || h.pivot.is_none())
            || fixed.as_ref().is_some_and(|f| f.is_changed())
            || changed_deformable.contains(entity)
            || any_removed
            || !state.attempted && !mine.is_empty();
        if !changed && state.pending.is_none() {
            continue;
        }
        if mine.iter().any(|(_, h, _)| h.pivot.is_none()) {
            continue; // next frame, once the pivots exist
        }
        let mut sorted: Vec<(Entity, &DeformHandle, &Transform)> =
            mine.iter().map(|(e, h, t)| (*e, &**h, &**t)).collect();
        sorted.sort_by_key(|(e, _, _)| *e);
        let pairs: Vec<(&DeformHandle, &Transform)> =
            sorted.iter().map(|(_, h, t)| (*h, *t)).collect();
        let constraints = build_constraints(&rest.topology, fixed.as_deref(), &pairs);
        let state = state.bypass_change_detection();
        state.attempted = true;
        state.pending = Some(constraints);
        state.settle_left = config.settle_iterations;
        state.requested.fetch_add(1, Ordering::Relaxed);
        if state.task.is_some() {
            continue; // the running task is cancelled at its next iteration; respawn on landing
        }
        spawn_solve(state, &rest, deformable, &config, &mut status, false);
    }
}

/// Starts a solve of the pending constraints (`settling`: the handles have not changed since
/// the last solve, which did not converge).
fn spawn_solve(
    state: &mut DeformState,
    rest: &Arc<Rest>,
    deformable: &Deformable,
    config: &DeformConfig,
    status: &mut DeformStatus,
    settling: bool,
) {
    let Some(constraints) = state.pending.take() else {
        return;
    };
    let generation = state.requested.load(Ordering::Relaxed);
    let requested = state.requested.clone();
    let rest = rest.clone();
    let settings = solver_settings(deformable, &rest.topology);
    // The factorization depends on the constraint sets *and* the settings (weights, region
    // of interest): reuse it only when both are unchanged.
    let reuse = state
        .solver
        .clone()
        .filter(|s| s.accepts(&constraints) && *s.settings() == settings);
    // Without the whole mesh's factorization: the current preview follows the handles, or a
    // new constraint set gets a preview of its own (a large mesh, no region of interest).
    let follow = match reuse {
        Some(_) => None,
        None => state.preview.as_ref().and_then(|(preview, solver)| {
            let followed = preview.follow(&constraints)?;
            Some((preview.clone(), solver.clone(), followed))
        }),
    };
    let region = match deformable.region_of_interest {
        None if !settling => config.preview,
        _ => None,
    };
    status.phase = match (&reuse, &follow, settling) {
        (None, None, _) => DeformPhase::Factorizing,
        (_, _, false) => DeformPhase::Solving,
        (_, _, true) => DeformPhase::Settling,
    };
    state.latest = Some(constraints.clone());
    // A new factorization (set change) still continues from the displayed pose; the solver
    // drops acceleration history that belongs to another factorization.
    let warm = state.last.clone();
    let laplacian_start = warm.is_none()
        && constraints.largest_displacement(rest.topology.positions())
            > f64::from(config.laplacian_start_displacement) * rest.topology.bounding_diagonal();
    let max_iterations = deformable
        .max_iterations
        .unwrap_or(config.max_iterations)
        .max(1);
    let options = match (settling, config.settle_acceleration) {
        // One Newton iteration is already several back-substitutions: land each one.
        (true, newton @ Acceleration::Newton { .. }) => SolveOptions {
            max_iterations: 1,
            tolerance: 0.0,
            acceleration: newton,
        },
        (true, acceleration) => SolveOptions {
            max_iterations,
            tolerance: 0.0,
            acceleration,
        },
        (false, _) => SolveOptions {
            max_iterations,
            tolerance: deformable.tolerance.unwrap_or(config.tolerance).max(0.0) as f64,
            acceleration: config.acceleration,
        },
    };
    state.task = Some(AsyncComputeTaskPool::get().spawn(async move {
        let t0 = std::time::Instant::now();
        let result = (|| {
            let (solver, preview, followed) = match (reuse, follow) {
                (Some(solver), _) => (solver, None, None),
                (None, Some((preview, solver, followed))) => {
                    (solver, Some(preview), Some(followed))
                }
                (None, None) => {
                    let current = warm
                        .as_ref()
                        .map_or(rest.topology.positions(), |w| &w.positions[..]);
                    let preview = region
                        .and_then(|r| r.preview(&rest.topology, &constraints, current))
                        .map(Arc::new);
                    let factored = preview.as_ref().map_or(&constraints, |p| p.constraints());
                    let solver = ArapSolver::precompute(rest.topology.clone(), factored, settings)?;
                    (Arc::new(solver), preview, None)
                }
            };
            let solving = match (&followed, &preview) {
                (Some(followed), _) => followed,
                (None, Some(preview)) => preview.constraints(),
                (None, None) => &constraints,
            };
            let init = match &warm {
                Some(w) => InitialGuess::Warm(w),
                None if laplacian_start => InitialGuess::Laplacian,
                None => InitialGuess::Rest,
            };
            let calls = std::cell::Cell::new(0u32);
            let cancel = || {
                calls.set(calls.get() + 1);
                calls.get() > 1 && requested.load(Ordering::Relaxed) != generation
            };
            let solution = solver.solve(solving, &options, init, &cancel)?;
            let pose = render_pose(&rest, &solution);
            Ok(Solved {
                solver,
                solution: Arc::new(solution),
                pose,
                preview,
            })
        })();
        let unsettled = result
            .as_ref()
            .is_ok_and(|s| still_converging(&s.solution.stats, &options));
        SolveOutput {
            result,
            ms: t0.elapsed().as_secs_f64() * 1e3,
            constraints,
            unsettled,
        }
    }));
}

/// Relative energy decrease per iteration below which a pose counts as converged for settling.
const SETTLED_DECREASE: f64 = 1e-9;
/// Normalised energy below which a pose counts as converged (rounding noise, e.g. at rest).
const SETTLED_ENERGY: f64 = 1e-14;

/// Whether a solve stopped short of convergence: it ran all its iterations (no cancel, no
/// tolerance stop) and its last iteration still lowered the energy noticeably.
fn still_converging(stats: &SolveStats, options: &SolveOptions) -> bool {
    if stats.iterations < options.max_iterations || stats.cancelled {
        return false;
    }
    let before = match stats.energies.len() {
        0 => return false,
        1 => stats.initial_energy,
        n => Some(stats.energies[n - 2]),
    };
    let last = stats.final_energy();
    match before {
        Some(b) => b > SETTLED_ENERGY && b - last > SETTLED_DECREASE * b,
        None => last > SETTLED_ENERGY,
    }
}

/// The solver settings a [`Deformable`] asks for (welded region-of-interest mask).
fn solver_settings(deformable: &Deformable, topology: &Topology) -> SolverSettings {
    SolverSettings {
        weights: if deformable.raw_cotangent_weights {
            WeightMode::RawCotangent
        } else {
            WeightMode::ClampedCotangent
        },
        region_of_interest: deformable.region_of_interest.as_ref().map(|roi| {
            let mut mask = vec![false; topology.vertex_count()];
            for w in topology.welded_set(roi) {
                mask[w as usize] = true;
            }
            mask
        }),
        ..Default::default()
    }
}

/// Positions, rotated rest normals and tangents in render order (f32), validated finite.
fn render_pose(rest: &Rest, solution: &Solution) -> RenderPose {
    let map = rest.topology.render_to_welded();
    let positions: Vec<[f32; 3]> = map
        .iter()
        .map(|&w| solution.positions[w as usize].as_vec3().to_array())
        .collect();
    let rot = |w: u32| -> Quat { solution.rotations[w as usize].as_quat() };
    let normals = rest.normals.as_ref().map(|n| {
        n.iter()
            .zip(map)
            .map(|(n, &w)| (rot(w) * *n).normalize_or_zero().to_array())
            .collect()
    });
    let tangents = rest.tangents.as_ref().map(|t| {
        t.iter()
            .zip(map)
            .map(|(t, &w)| {
                let v = (rot(w) * t.truncate()).normalize_or_zero();
                [v.x, v.y, v.z, t.w]
            })
            .collect()
    });
    RenderPose {
        positions,
        normals,
        tangents,
    }
}

fn finite(pose: &RenderPose) -> bool {
    pose.positions.iter().flatten().all(|x| x.is_finite())
        && pose
            .normals
            .iter()
            .flatten()
            .flatten()
            .all(|x| x.is_finite())
        && pose
            .tangents
            .iter()
            .flatten()
            .flatten()
            .all(|x| x.is_finite())
}

fn poll_tasks(
    config: Res<DeformConfig>,
    mut deformables: Query<(Entity, &Deformable, &mut DeformState, &mut DeformStatus)>,
    mut solved: MessageWriter<DeformSolved>,
    mut failed: MessageWriter<DeformFailed>,
) {
    for (entity, deformable, mut state, mut status) in &mut deformables {
        let state = state.bypass_change_detection();
        poll_factoring(entity, deformable, &config, state, &mut status, &mut failed);
        let Some(task) = state.task.as_mut() else {
            continue;
        };
        let Some(out) = check_ready(task) else {
            continue;
        };
        state.task = None;
        let mut previewed = false;
        match out.result {
            Ok(s) if finite(&s.pose) => {
                status.iterations = s.solution.stats.iterations;
                status.energy = s.solution.stats.final_energy();
                status.solve_ms = out.ms;
                status.solves += 1;
                status.error = None;
                status.phase = DeformPhase::Idle;
                status.preview = s.preview.is_some();
                solved.write(DeformSolved {
                    entity,
                    iterations: s.solution.stats.iterations,
                    energy: status.energy,
                    solve_ms: out.ms,
                });
                match s.preview {
                    Some(preview) => {
                        previewed = true;
                        state.preview = Some((preview, s.solver));
                        factor_whole_mesh(state, deformable, &out.constraints);
                    }
                    None => {
                        state.solver = Some(s.solver);
                        state.preview = None;
                    }
                }
                state.last = Some(s.solution);
                state.ready = Some(s.pose);
            }
            Ok(_) => {
                status.phase = DeformPhase::Idle;
                status.error = Some(DeformError::NonFinite);
                failed.write(DeformFailed {
                    entity,
                    error: DeformError::NonFinite,
                });
            }
            Err(e) => {
                status.phase = DeformPhase::Idle;
                let error = DeformError::from(e);
                status.error = Some(error.clone());
                failed.write(DeformFailed { entity, error });
            }
        }
        // A newer request arrived while solving: start it now with the freshest constraints.
        // Otherwise, if that solve did not converge, settle on with the same constraints (a
        // preview does not settle: the whole mesh's solve follows it).
        let settle =
            out.unsettled && !previewed && state.pending.is_none() && state.settle_left > 0;
        let settling = settle && status.error.is_none();
        if settling {
            state.settle_left = state.settle_left.saturating_sub(status.iterations.max(1));
            state.pending = Some(out.constraints);
        }
        if state.pending.is_some()
            && let Some(rest) = state.rest.clone()
        {
            spawn_solve(state, &rest, deformable, &config, &mut status, settling);
        }
        if state.task.is_none() && state.factoring.is_some() {
            status.phase = DeformPhase::Factorizing;
        }
    }
}

/// After a preview of `constraints`: factor the whole mesh for them in the background,
/// unless that is done or under way.
fn factor_whole_mesh(state: &mut DeformState, deformable: &Deformable, constraints: &Constraints) {
    let Some(rest) = state.rest.clone() else {
        return;
    };
    let settings = solver_settings(deformable, &rest.topology);
    let factored = state
        .solver
        .as_ref()
        .is_some_and(|s| s.accepts(constraints) && *s.settings() == settings);
    let under_way = state
        .factoring
        .as_ref()
        .is_some_and(|(c, _)| c.same_sets(constraints));
    if factored || under_way {
        return;
    }
    let sets = constraints.clone();
    let task = AsyncComputeTaskPool::get()
        .spawn(async move { ArapSolver::precompute(rest.topology.clone(), &sets, settings) });
    // A factorization for older sets is dropped (cancelled if it has not started).
    state.factoring = Some((constraints.clone(), task));
}

/// A finished whole-mesh factorization replaces the preview and solves the latest
/// constraints from the displayed pose (at once, or when the running solve lands).
fn poll_factoring(
    entity: Entity,
    deformable: &Deformable,
    config: &DeformConfig,
    state: &mut DeformState,
    status: &mut DeformStatus,
    failed: &mut MessageWriter<DeformFailed>,
) {
    let Some((_, task)) = state.factoring.as_mut() else {
        return;
    };
    let Some(result) = check_ready(task) else {
        return;
    };
    state.factoring = None;
    match result {
        Ok(solver) => {
            let latest = state.latest.clone();
            if !latest.as_ref().is_some_and(|c| solver.accepts(c)) {
                return; // the sets changed since: their own preview and factorization follow
            }
            state.solver = Some(Arc::new(solver));
            state.preview = None;
            if state.pending.is_none() {
                state.pending = latest;
                state.settle_left = config.settle_iterations;
            }
            if state.task.is_none()
                && let Some(rest) = state.rest.clone()
            {
                spawn_solve(state, &rest, deformable, config, status, false);
            }
        }
        Err(e) => {
            // The preview stays on screen; the next change of the sets tries again.
            if state.task.is_none() {
                status.phase = DeformPhase::Idle;
            }
            let error = DeformError::from(e);
            status.error = Some(error.clone());
            failed.write(DeformFailed { entity, error });
        }
    }
}

/// Number of values of a vertex attribute, if present.
fn attribute_len(mesh: &Mesh, id: bevy::mesh::MeshVertexAttribute) -> Option<usize> {
    mesh.try_attribute(id).ok().map(|v| v.len())
}

fn write_back(mut meshes: ResMut<Assets<Mesh>>, mut q: Query<(&Mesh3d, &mut DeformState)>) {
    for (mesh3d, mut state) in &mut q {
        let state = state.bypass_change_detection();
        let Some(pose) = state.ready.take() else {
            continue;
        };
        let Some(mut mesh) = meshes.get_mut(&mesh3d.0) else {
            continue;
        };
        // The worker built whole attribute buffers: move them in (no per-vertex copy on the
        // main thread), but only over attributes of the same length.
        if attribute_len(&mesh, Mesh::ATTRIBUTE_POSITION) == Some(pose.positions.len()) {
            let _ = mesh.try_insert_attribute(Mesh::ATTRIBUTE_POSITION, pose.positions);
        }
        if let Some(n) = pose.normals
            && attribute_len(&mesh, Mesh::ATTRIBUTE_NORMAL) == Some(n.len())
        {
            let _ = mesh.try_insert_attribute(Mesh::ATTRIBUTE_NORMAL, n);
        }
        if let Some(t) = pose.tangents
            && attribute_len(&mesh, Mesh::ATTRIBUTE_TANGENT) == Some(t.len())
        {
            let _ = mesh.try_insert_attribute(Mesh::ATTRIBUTE_TANGENT, t);
        }
    }
}

/// Whether a normal can be used: finite and not (nearly) zero.
fn is_unit_like(n: Vec3) -> bool {
    n.is_finite() && n.length_squared() > 1e-12
}

/// `normals` with every unusable one (NaN, infinite, zero) replaced by the area-weighted
/// normal of the triangles around its vertex (or +Y where those are degenerate too).
fn repair_normals(positions: &[Vec3], indices: &[u32], normals: &[Vec3]) -> Vec<Vec3> {
    let mut summed = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        if a.max(b).max(c) >= positions.len() {
            continue; // bad indices fail later with a typed error
        }
        let face = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        if face.is_finite() {
            for v in [a, b, c] {
                summed[v] += face;
            }
        }
    }
    normals
        .iter()
        .zip(summed)
        .map(|(&n, s)| {
            if is_unit_like(n) {
                n
            } else {
                s.try_normalize().unwrap_or(Vec3::Y)
            }
        })
        .collect()
}
