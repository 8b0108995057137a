//! Preparing deformables: finding meshes (on the entity or below a scene), welding and
//! precomputing topology in the background, rest poses and regions of interest.

use super::*;
use crate::ecs::tasks::poll_slot;

/// What the background preparation of a deformable needs from its mesh.
struct MeshInput {
    triangles: bool,
    topology: bevy::mesh::PrimitiveTopology,
    positions: Option<Vec<Vec3>>,
    indices: Option<Vec<u32>>,
    normals: Option<Vec<Vec3>>,
    tangents: Option<Vec<Vec4>>,
}

impl MeshInput {
    /// A per-instance copy of `mesh` (glTF entities may share one asset) with its broken
    /// normals repaired, and what preparing it needs.
    fn read(mesh: &Mesh) -> (Mesh, Self) {
        let topology = mesh.primitive_topology();
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
        let input = Self {
            triangles: topology == bevy::mesh::PrimitiveTopology::TriangleList,
            topology,
            positions,
            indices,
            normals,
            tangents,
        };
        (copy, input)
    }

    /// Welds the mesh and orders its elimination, in the background (a baked pose of the same
    /// mesh keeps its weld, `previous`).
    fn prepare(self, previous: Option<Arc<Topology>>) -> Task<Result<Rest, DeformError>> {
        let Self {
            triangles,
            topology,
            positions,
            indices,
            normals,
            tangents,
        } = self;
        AsyncComputeTaskPool::get().spawn(async move {
            if !triangles {
                return Err(DeformError::NotTriangleList(format!("{topology:?}")));
            }
            let positions = positions.ok_or(DeformError::NoPositions)?;
            let indices = match indices {
                Some(i) => i,
                None => (0..positions.len() as u32).collect(),
            };
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
        })
    }
}

impl DeformState {
    /// The state of a deformable whose rest pose is being prepared by `building`.
    fn building(building: Task<Result<Rest, DeformError>>) -> Self {
        Self {
            rest: None,
            building: Some(building),
            solver: None,
            last: None,
            solve: ChainedTask::default(),
            pending: None,
            ready: None,
            attempted: false,
            settle_left: 0,
            preview: None,
            factoring: None,
            latest: None,
            ground: None,
        }
    }
}

/// Starts preparing new deformables (their mesh copied per instance) and collects prepared
/// rest poses.
#[allow(clippy::type_complexity)] // a system's queries, named by their parameters
pub(super) fn prepare_deformables(
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
        let (copy, input) = MeshInput::read(mesh);
        mesh3d.0 = meshes.add(copy);
        status.phase = DeformPhase::BuildingTopology;
        commands
            .entity(entity)
            .try_insert(DeformState::building(input.prepare(previous)));
    }
    for (entity, mut state, mut status) in &mut building {
        let state = state.bypass_change_detection();
        let Some(result) = poll_slot(&mut state.building) else {
            continue;
        };
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
