//! The grab plugin: picking and pointer input to grab messages, and the systems that start,
//! place, move and end grabs.

use std::collections::HashMap;
use std::sync::Arc;

use bevy::picking::events::PointerPress;
use bevy::picking::pointer::{PointerAction, PointerId, PointerInput};
use bevy::prelude::*;

use crate::deform::Topology;
use crate::ecs::input::view::{arcball_rotation, turned_in_space, view_plane_motion};
use crate::ecs::input::{InputSystems, configure_input_sets};
use crate::ecs::pose::{HandlePositionOnly, PinnedJoints, PoseAnchor, PosedSkeleton};
use crate::ecs::{
    DeformDynamics, DeformHandle, DeformState, Deformable, DeformableFrom, FixedRegion,
};

use super::{
    ActiveGrab, ActiveGrabs, GrabButton, GrabEnd, GrabHandle, GrabMove, GrabStart, GrabTurn,
    GrabTwist, Grabbable,
};

/// Adds pointer grabs: press on a [`Grabbable`] deformable, drag, release — the surface under
/// the pointer follows it, and the pose stays. Requires [`DeformPlugin`]; add a picking
/// backend (such as `MeshPickingPlugin`) for the pointer events.
///
/// A grab is driven by messages — [`GrabStart`], [`GrabMove`], [`GrabTwist`], [`GrabEnd`] —
/// which this plugin writes from Bevy's picking: presses from `Pointer<Press>` hits, motion,
/// wheel and release from the raw `PointerInput`. Other input (a Wii Remote cursor, VR
/// controllers, tests) can write them directly.
///
/// On a press, the grabbed patch is every vertex within [`Grabbable::radius`] of the hit
/// *measured along the surface* (Dijkstra over the welded mesh, so a brush does not jump
/// across a thin gap). With no [`FixedRegion`] on the mesh, the vertices within
/// [`Grabbable::region_radius`] become the region of interest and everything beyond is held
/// at rest: grabbing a 100k-vertex mesh solves a small local system. Dragging moves the patch
/// in the camera's view plane, at its depth; with Shift held it turns the patch instead (an
/// arcball about its position on screen, all three axes). On release the handle stays where
/// it is, so the pose is kept; the next grab of the same mesh first makes the current pose
/// the new rest pose, so bends accumulate. Radii are in world units (the mesh's scale is
/// divided out). The wheel turns a held patch about the camera's view axis ([`GrabTwist`]).
///
/// **Characters.** [`Grabbable`] on a [`Poseable`](crate::ecs::Poseable) character (the
/// entity that gets the [`PosedSkeleton`]) grabs the *posed* surface: the pose plugin is a
/// picking backend that hits the CPU-skinned triangles (Bevy's mesh picking tests the bind
/// pose of skinned meshes), the patch is found along the welded surface the same way, and the
/// handle is an ordinary world-space [`DeformHandle`] aimed at the character, so dragging
/// solves a skeleton pose; on release the handle goes and the character holds its pose. A
/// character with no [`PinnedJoints`] is anchored while grabbed by a [`PoseAnchor`] (the
/// joints the grab's region does not reach), so a grab bends it rather than carrying it
/// along.
///
/// **Which press grabs.** Presses come from bevy_picking's `Pointer<Press>`, so its hit order
/// decides: UI over a mesh, or another entity in front of it, takes the press. Only the
/// [`GrabButton`] (primary by default) grabs; its release ends the grab.
///
/// [`DeformPlugin`]: crate::ecs::DeformPlugin
#[derive(Debug, Clone, Default)]
pub struct GrabPlugin;

impl Plugin for GrabPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<Grabbable>()
            .register_type::<GrabHandle>()
            .register_type::<GrabButton>()
            .init_resource::<GrabButton>()
            .init_resource::<ActiveGrabs>()
            // Registered here too, so the plugin runs (idle) without a picking plugin.
            .add_message::<PointerPress>()
            .add_message::<GrabStart>()
            .add_message::<PointerInput>()
            .add_message::<GrabMove>()
            .add_message::<GrabTwist>()
            .add_message::<GrabTurn>()
            .add_message::<GrabEnd>()
            // New grabs before `Prepare` (a baked mesh starts re-preparing in the same frame);
            // handles placed after it (the rest pose may have become ready this frame).
            .add_systems(
                Update,
                ((presses_to_grabs, pointer_inputs_to_grabs), start_grabs)
                    .chain()
                    .in_set(InputSystems::StartGrabs),
            )
            .add_systems(
                Update,
                (place_grabs, move_grabs, end_grabs, let_elastic_meshes_go)
                    .chain()
                    .in_set(InputSystems::MoveHandles),
            );
        configure_input_sets(app);
    }
}

/// What a press may grab: deformable meshes and posed characters.
type GrabTargets = Or<(With<Deformable>, With<PosedSkeleton>)>;

/// A press of the [`GrabButton`] on a grabbable deformable or posed character starts a grab.
/// Presses come from bevy_picking, so its hit ordering applies: UI over a mesh or a character,
/// or another entity in front of it, takes the press instead. Characters report hits on their
/// posed (CPU-skinned) surface through the pose plugin's picking backend.
fn presses_to_grabs(
    mut presses: MessageReader<PointerPress>,
    button: Res<GrabButton>,
    grabbable: Query<(), With<Grabbable>>,
    from: Query<&DeformableFrom>,
    targets: Query<(), GrabTargets>,
    mut start: MessageWriter<GrabStart>,
) {
    let mut nearest: HashMap<PointerId, (f32, GrabStart)> = HashMap::new();
    for p in presses.read() {
        if p.button != button.0 {
            continue;
        }
        let target = p.entity;
        let is_grabbable =
            grabbable.contains(target) || from.get(target).is_ok_and(|f| grabbable.contains(f.0));
        let (true, true, Some(point)) = (is_grabbable, targets.contains(target), p.hit.position)
        else {
            continue;
        };
        let grab = GrabStart {
            pointer: p.pointer.id,
            entity: target,
            point,
            camera: p.hit.camera,
        };
        let depth = p.hit.depth;
        if nearest.get(&grab.pointer).is_none_or(|(d, _)| depth < *d) {
            nearest.insert(grab.pointer, (depth, grab));
        }
    }
    start.write_batch(nearest.into_values().map(|(_, grab)| grab));
}

/// Pointer motion moves grabs (turns them with Shift held), the wheel twists them, a primary
/// release ends them. Read from the raw pointer input rather than picking's `Pointer<Drag>` /
/// `Pointer<Release>`, which need a hit under the pointer: a grabbed character has none (Bevy
/// picks its bind pose), and a release off the mesh must end the grab too. Messages for
/// pointers that grab nothing are ignored later.
fn pointer_inputs_to_grabs(
    mut inputs: MessageReader<PointerInput>,
    button: Res<GrabButton>,
    keys: Option<Res<ButtonInput<KeyCode>>>,
    mut moves: MessageWriter<GrabMove>,
    mut twists: MessageWriter<GrabTwist>,
    mut ends: MessageWriter<GrabEnd>,
) {
    let rotate = keys.is_some_and(|k| k.any_pressed([KeyCode::ShiftLeft, KeyCode::ShiftRight]));
    let mut motion = Vec::new();
    for input in inputs.read() {
        let pointer = input.pointer_id;
        match input.action {
            PointerAction::Move { delta } => {
                let to = input.location.position;
                motion.push(GrabMove {
                    pointer,
                    from: to - delta,
                    to,
                    rotate,
                });
            }
            // Motion before a press in the same frame is not part of the grab it starts.
            PointerAction::Press(pressed) if pressed == button.0 => {
                motion.retain(|m| m.pointer != pointer)
            }
            PointerAction::Scroll { unit, y, .. } => {
                let per_step = match unit {
                    bevy::input::mouse::MouseScrollUnit::Line => 10f32.to_radians(),
                    bevy::input::mouse::MouseScrollUnit::Pixel => 0.5f32.to_radians(),
                };
                twists.write(GrabTwist {
                    pointer,
                    radians: y * per_step,
                });
            }
            PointerAction::Release(released) if released == button.0 => {
                ends.write(GrabEnd { pointer });
            }
            PointerAction::Cancel => {
                ends.write(GrabEnd { pointer });
            }
            _ => {}
        }
    }
    moves.write_batch(motion);
}

/// What [`start_grabs`] reads of a grabbed mesh.
type GrabbedMesh<'a> = (
    &'a GlobalTransform,
    Option<&'a GrabHandle>,
    Option<&'a Grabbable>,
    Option<&'a DeformableFrom>,
    Has<PosedSkeleton>,
);

/// Registers new grabs; a mesh grabbed before first makes its current pose the rest pose.
fn start_grabs(
    mut commands: Commands,
    mut starts: MessageReader<GrabStart>,
    mut grabs: ResMut<ActiveGrabs>,
    meshes: Query<GrabbedMesh>,
    settings: Query<&Grabbable>,
    states: Query<&DeformState>,
) {
    for s in starts.read() {
        let Ok((global, previous, own, from, character)) = meshes.get(s.entity) else {
            continue;
        };
        if grabs.0.values().any(|g| g.mesh == s.entity) {
            continue; // one pointer per mesh at a time
        }
        let Some(grabbable) = own
            .cloned()
            .or_else(|| from.and_then(|f| settings.get(f.0).ok().cloned()))
        else {
            continue;
        };
        // Radii to mesh units (a character's welded surface is in world units).
        let scale = global.compute_transform().scale.abs();
        let mean_scale = match character {
            true => 1.0,
            false => ((scale.x + scale.y + scale.z) / 3.0).max(1e-6),
        };
        let settings = Grabbable {
            radius: grabbable.radius / mean_scale,
            region_radius: grabbable.region_radius / mean_scale,
            max_region_vertices: grabbable.max_region_vertices,
        };
        if let Some(GrabHandle(handle)) = previous {
            // Bake: the deformed mesh becomes the new rest (prepared again in the background);
            // a character keeps its pose as it is.
            commands.entity(*handle).try_despawn();
            commands.entity(s.entity).try_remove::<GrabHandle>();
            if let (false, Ok(state)) = (character, states.get(s.entity)) {
                state.bake(s.entity, &mut commands);
            }
        }
        let point = match character {
            true => s.point,
            false => global.affine().inverse().transform_point3(s.point),
        };
        grabs.0.insert(
            s.pointer,
            ActiveGrab {
                mesh: s.entity,
                camera: s.camera,
                point,
                settings,
                handle: None,
                early_motion: None,
                character,
            },
        );
    }
}

/// Places the handle of grabs whose mesh is ready: the geodesic patch and region.
fn place_grabs(
    mut commands: Commands,
    mut grabs: ResMut<ActiveGrabs>,
    mut meshes: Query<(&DeformState, &mut Deformable, Has<FixedRegion>)>,
    characters: Query<(&PosedSkeleton, Option<&PinnedJoints>)>,
) {
    for grab in grabs.0.values_mut().filter(|g| g.handle.is_none()) {
        let vertices = if grab.character {
            let Ok((posed, pins)) = characters.get(grab.mesh) else {
                continue;
            };
            let pinned = pins.is_some_and(|p| !p.0.is_empty());
            // The seed on the surface as posed; distances along the welded bind surface
            // (rigid bones keep them).
            let skinned = posed.skin_welded_world();
            let Some(seed) = nearest_vertex(&skinned, grab.point) else {
                continue;
            };
            let topology = posed.model.topology();
            let (patch, region) = geodesic_regions_from(topology, seed, &grab.settings);
            if !pinned {
                commands
                    .entity(grab.mesh)
                    .try_insert(anchor_for(posed, &region, seed));
            }
            render_vertices(topology, &patch)
        } else {
            let Ok((state, mut deformable, has_fixed)) = meshes.get_mut(grab.mesh) else {
                continue;
            };
            let Some(topology) = state.topology() else {
                continue; // still (re)building the rest pose
            };
            let (patch, region) = geodesic_regions(topology, grab.point, &grab.settings);
            if !has_fixed {
                let region = render_vertices(topology, &region);
                if deformable.region_of_interest.as_ref() != Some(&region) {
                    deformable.region_of_interest = Some(region);
                }
            }
            render_vertices(topology, &patch)
        };
        if vertices.is_empty() {
            continue;
        }
        let mut handle = commands.spawn((
            DeformHandle {
                target: grab.mesh,
                vertices,
                pivot: None,
            },
            Transform::IDENTITY,
            Name::new("grab handle"),
        ));
        if grab.character {
            // A character's grabbed point follows the pointer; the body decides how it turns.
            handle.insert(HandlePositionOnly);
        }
        let handle = handle.id();
        commands.entity(grab.mesh).try_insert(GrabHandle(handle));
        grab.handle = Some(handle);
    }
}

/// One pointer step applied to a grab's handle.
#[derive(Clone, Copy)]
enum Step {
    /// The pointer moved from → to; `true` turns (arcball) instead of moving.
    Drag(Vec2, Vec2, bool),
    /// Turn about the view axis, radians counter-clockwise on screen.
    Twist(f32),
    /// Turn by a rotation in the camera's frame.
    Turn(Quat),
}

/// Moves grabbed handles in their camera's view plane, turns them (Shift: arcball) and
/// twists them about the view axis (wheel).
fn move_grabs(
    mut commands: Commands,
    (mut moves, mut twists, mut turns): (
        MessageReader<GrabMove>,
        MessageReader<GrabTwist>,
        MessageReader<GrabTurn>,
    ),
    mut grabs: ResMut<ActiveGrabs>,
    cameras: Query<(&Camera, &GlobalTransform)>,
    spaces: Query<&GlobalTransform>,
    mut handles: Query<(&DeformHandle, &mut Transform)>,
) {
    let mut pending: Vec<(PointerId, Step)> = moves
        .read()
        .map(|m| (m.pointer, Step::Drag(m.from, m.to, m.rotate)))
        .chain(twists.read().map(|t| (t.pointer, Step::Twist(t.radians))))
        .chain(turns.read().map(|t| (t.pointer, Step::Turn(t.rotation))))
        .collect();
    // Motion that arrived before a handle existed is applied once it does.
    for (pointer, grab) in grabs.0.iter_mut() {
        if grab.handle.is_some()
            && let Some((from, to)) = grab.early_motion.take()
        {
            pending.insert(0, (*pointer, Step::Drag(from, to, false)));
        }
    }
    for (pointer, step) in pending {
        let Some(grab) = grabs.0.get_mut(&pointer) else {
            continue;
        };
        let Some(handle) = grab.handle else {
            if let Step::Drag(from, to, _) = step {
                let first = grab.early_motion.map_or(from, |(f, _)| f);
                grab.early_motion = Some((first, to));
            }
            continue;
        };
        let space = match grab.character {
            true => Ok(GlobalTransform::IDENTITY),
            false => spaces.get(grab.mesh).copied(),
        };
        let (Ok((camera, camera_transform)), Ok(space), Ok((h, mut transform))) =
            (cameras.get(grab.camera), space, handles.get_mut(handle))
        else {
            continue;
        };
        if h.pivot.is_none() {
            // The plugin has not put the handle at its pivot yet: keep the motion for later.
            if let Step::Drag(from, to, _) = step {
                grab.early_motion = Some((from, to));
            }
            continue;
        }
        let space = space.affine();
        let at = space.transform_point3(transform.translation);
        let in_view = match step {
            // Counter-clockwise on screen = about the view axis pointing at the viewer (+Z).
            Step::Twist(radians) => Quat::from_rotation_z(radians),
            Step::Turn(rotation) => rotation,
            Step::Drag(from, to, true) => {
                let (Ok(centre), Some(size)) = (
                    camera.world_to_viewport(camera_transform, at),
                    camera.logical_viewport_size(),
                ) else {
                    continue;
                };
                arcball_rotation(from, to, centre, 0.35 * size.min_element())
            }
            Step::Drag(from, to, false) => {
                let delta = view_plane_motion(camera, camera_transform, at, from, to);
                let local = space.inverse().transform_vector3(delta);
                if local.is_finite() {
                    transform.translation += local;
                }
                continue;
            }
        };
        let rotation = turned_in_space(in_view, camera_transform, &space, transform.rotation);
        if rotation.is_finite() {
            transform.rotation = rotation;
        }
        if grab.character {
            // Turning needs the grabbed part's orientation: the handle becomes rigid.
            commands.entity(handle).try_remove::<HandlePositionOnly>();
        }
    }
}

fn end_grabs(
    mut commands: Commands,
    mut ends: MessageReader<GrabEnd>,
    mut grabs: ResMut<ActiveGrabs>,
) {
    for e in ends.read() {
        let Some(grab) = grabs.0.remove(&e.pointer) else {
            continue;
        };
        // A character holds its pose by itself: its handle goes, so loading or resetting a
        // pose afterwards is not pulled back by a stale target.
        if grab.character
            && let Some(handle) = grab.handle
        {
            commands.entity(handle).try_despawn();
            commands
                .entity(grab.mesh)
                .try_remove::<(GrabHandle, PoseAnchor)>();
        }
    }
}

/// What holds a character while a grab of `region` (welded) bends it (see [`PoseAnchor`]):
/// the joints the region does not reach, or, for a single chain, the farther half of the
/// surface from `seed` (and every part not connected to it).
fn anchor_for(posed: &PosedSkeleton, region: &[u32], seed: usize) -> PoseAnchor {
    let joints: Vec<Entity> = posed
        .model
        .joints_not_reaching(region, 0.1)
        .into_iter()
        .filter_map(|j| posed.joints.get(j).copied())
        .collect();
    if !joints.is_empty() {
        return PoseAnchor {
            joints,
            vertices: Vec::new(),
        };
    }
    let topology = posed.model.topology();
    let all = topology.geodesic_distances(&[seed as u32], f64::INFINITY, usize::MAX);
    let mut held = vec![true; topology.vertex_count()];
    for (v, _) in &all[..all.len() / 2] {
        held[*v as usize] = false;
    }
    PoseAnchor {
        joints,
        vertices: (0..topology.vertex_count() as u32)
            .filter(|v| held[*v as usize])
            .collect(),
    }
}

/// Welded vertices within `radius` (the patch) and within `region_radius` (the region) of the
/// vertex nearest to `point`, by shortest paths along mesh edges.
fn geodesic_regions(
    topology: &Topology,
    point: Vec3,
    settings: &Grabbable,
) -> (Vec<u32>, Vec<u32>) {
    match nearest_vertex(topology.positions(), point) {
        Some(seed) => geodesic_regions_from(topology, seed, settings),
        None => (Vec::new(), Vec::new()),
    }
}

/// The index of the position nearest to `point`.
fn nearest_vertex(positions: &[glam::DVec3], point: Vec3) -> Option<usize> {
    let point = point.as_dvec3();
    (0..positions.len()).min_by(|&a, &b| {
        positions[a]
            .distance_squared(point)
            .total_cmp(&positions[b].distance_squared(point))
    })
}

/// [`geodesic_regions`] from a given welded vertex.
fn geodesic_regions_from(
    topology: &Topology,
    seed: usize,
    settings: &Grabbable,
) -> (Vec<u32>, Vec<u32>) {
    let limit = settings.region_radius.max(settings.radius) as f64;
    let cap = settings.max_region_vertices as usize;
    let distance = topology.geodesic_distances(&[seed as u32], limit, cap.max(1));
    let within = |r: f32| -> Vec<u32> {
        distance
            .iter()
            .take_while(|(_, d)| *d <= r as f64)
            .map(|(v, _)| *v)
            .collect()
    };
    let mut patch = within(settings.radius);
    if patch.is_empty() {
        patch.push(seed as u32);
    }
    patch.sort_unstable();
    let mut region = within(settings.region_radius.max(settings.radius));
    region.sort_unstable();
    (patch, region)
}

/// Every render vertex whose welded vertex is in `welded` (sorted).
fn render_vertices(topology: &Arc<Topology>, welded: &[u32]) -> Vec<u32> {
    topology
        .render_to_welded()
        .iter()
        .enumerate()
        .filter(|(_, w)| welded.binary_search(w).is_ok())
        .map(|(r, _)| r as u32)
        .collect()
}

/// An elastic [`DeformDynamics`] mesh springs back when its grab lets go: the grab's handle
/// goes (a static mesh keeps it, holding the new shape).
pub(super) fn let_elastic_meshes_go(
    mut commands: Commands,
    grabs: Res<ActiveGrabs>,
    released: Query<(Entity, &DeformDynamics, &GrabHandle)>,
) {
    for (mesh, dynamics, handle) in &released {
        let held = grabs.meshes().any(|m| m == mesh);
        if dynamics.elastic && !held {
            commands.entity(handle.0).try_despawn();
            commands.entity(mesh).try_remove::<GrabHandle>();
        }
    }
}
