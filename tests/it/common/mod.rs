//! Helpers shared by the integration tests.
#![allow(dead_code)] // each test crate uses some of them

pub mod bar;
pub use bevy_wii_deform_examples::headless_gltf;
pub mod scratch;
pub mod shared;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::skinning::{SkinnedMesh as BevySkin, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_wii_deform::pose::rig::synth_rig::SyntheticRig;
use bevy_wii_deform::prelude::{DeformHandle, PoseStatus};

/// Spawns the rig as a character entity (root) with a joint chain and a skinned mesh child,
/// placed at `offset`. Returns (root, joints, mesh entity).
pub fn spawn_rig(app: &mut App, rig: &SyntheticRig, offset: Vec3) -> (Entity, Vec<Entity>, Entity) {
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    );
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_POSITION,
        rig.mesh
            .positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    );
    mesh.insert_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(rig.mesh.joint_indices.clone()),
    );
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, rig.mesh.joint_weights.clone());
    mesh.insert_indices(Indices::U32(rig.mesh.indices.clone()));
    let world = app.world_mut();
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let ibp: Vec<Mat4> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| Mat4::from(j.inverse_bind.as_affine3a()))
        .collect();
    let ibp = world
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(SkinnedMeshInverseBindposes::from(ibp));
    let root = world
        .spawn((Transform::from_translation(offset), Name::new("character")))
        .id();
    let mut joints = Vec::new();
    for (k, joint) in rig.skeleton.joints().iter().enumerate() {
        let t = rig.rest.local[k];
        let parent = joint.parent.map_or(root, |p| joints[p]);
        let e = world
            .spawn((
                Transform::from_translation(t.translation.as_vec3()),
                Name::new(joint.name.clone()),
                ChildOf(parent),
            ))
            .id();
        joints.push(e);
    }
    let skinned = world
        .spawn((
            Mesh3d(mesh),
            BevySkin {
                inverse_bindposes: ibp,
                joints: joints.clone(),
            },
            Transform::default(),
            ChildOf(root),
        ))
        .id();
    (root, joints, skinned)
}

/// Builds a pose solver for `constraints` with targets relative to `reference` and solves
/// exactly `iterations` iterations from `start`.
pub fn solve_pose(
    model: &std::sync::Arc<bevy_wii_deform::pose::SkinnedModel>,
    reference: &bevy_wii_deform::pose::SkeletonPose,
    constraints: &bevy_wii_deform::pose::PoseConstraints,
    iterations: u32,
    start: bevy_wii_deform::pose::PoseStart<'_>,
) -> Result<bevy_wii_deform::pose::PoseSolution, bevy_wii_deform::pose::PoseError> {
    use bevy_wii_deform::pose::{PoseSolveOptions, PoseSolver, PoseSolverSettings};
    let solver = PoseSolver::new(
        model.clone(),
        constraints,
        reference,
        PoseSolverSettings::default(),
    )?;
    let options = PoseSolveOptions {
        max_iterations: iterations,
        tolerance: 0.0,
        ground_iterations: 0,
    };
    solver.solve(constraints, &options, start, &|| false)
}

/// The pose on the joint entities `joints` (their `Transform`s), in skeleton order.
pub fn pose_of(app: &App, joints: &[Entity]) -> bevy_wii_deform::pose::SkeletonPose {
    use bevy_wii_deform::pose::{JointTransform, SkeletonPose};
    SkeletonPose {
        local: joints
            .iter()
            .map(|&j| {
                let t = app.world().get::<Transform>(j).unwrap();
                JointTransform {
                    translation: t.translation.as_dvec3(),
                    rotation: t.rotation.as_dquat(),
                    scale: t.scale.as_dvec3(),
                }
            })
            .collect(),
    }
}

/// When a motion given to the app's emulated remotes and pads now may start, in their own
/// time (s): the app's clock (`Time<Real>`, which paces their `EmulatorClock`s) plus
/// `margin`. An emulator makes a report only once the clock has reached its time, and its
/// time is the clock's since it was opened (never ahead of it), so no sample made before the
/// motion was given falls after this start. (The last sample the app has read is no such
/// bound: a reader thread can lag the clock by tens of milliseconds on a loaded machine, and a
/// motion that starts before samples already made loses its first part — a gyro pointer test
/// moved 0.195 instead of 0.2 so.)
pub fn emulated_start(app: &App, margin: f64) -> f64 {
    app.world().resource::<Time<Real>>().elapsed_secs_f64() + margin
}

/// Updates until `done` holds, with a generous deadline for the background tasks.
pub fn update_until(app: &mut App, what: &str, done: impl Fn(&mut App) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !done(app) {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        app.update();
        std::thread::yield_now();
    }
}

pub fn solves(app: &App, e: Entity) -> u64 {
    app.world().get::<PoseStatus>(e).map_or(0, |s| s.solves)
}

/// Marks `handle`'s `Transform` changed `n` times, each time updating until one more solve of
/// `character` landed (a drag held still: the pose converges, with warm starts).
pub fn drive_solves(app: &mut App, character: Entity, handle: Entity, n: u32) {
    for _ in 0..n {
        let before = solves(app, character);
        app.world_mut()
            .get_mut::<Transform>(handle)
            .unwrap()
            .set_changed();
        update_until(app, "a solve", |a| solves(a, character) > before);
    }
}

/// Spawns a vertex handle (with `extra` components) on `target`, a character or deformable,
/// and updates until the plugin has put it at its pivot; returns the handle and the pivot.
pub fn spawn_handle(
    app: &mut App,
    target: Entity,
    vertices: Vec<u32>,
    extra: impl Bundle,
) -> (Entity, Vec3) {
    let handle = app
        .world_mut()
        .spawn((
            DeformHandle {
                target,
                vertices,
                pivot: None,
            },
            Transform::IDENTITY,
            extra,
        ))
        .id();
    update_until(app, "the pivot", |a| {
        a.world()
            .get::<DeformHandle>(handle)
            .unwrap()
            .pivot
            .is_some()
    });
    let pivot = app.world().get::<DeformHandle>(handle).unwrap().pivot;
    (handle, pivot.unwrap())
}

/// A headless app: minimal plugins, assets, meshes and transforms (no GPU, no window).
pub fn app() -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::asset::AssetPlugin::default(),
        bevy::mesh::MeshPlugin,
        bevy::transform::TransformPlugin,
    ));
    app
}

/// A headless [`app`] with a window, input and cameras (what pointers, the mouse and picking
/// read) and `plugins`, finished. Time runs as the caller sets it.
pub fn input_app<M>(plugins: impl bevy::app::Plugins<M>) -> App {
    let mut app = app();
    app.add_plugins((
        bevy::window::WindowPlugin::default(),
        bevy::input::InputPlugin,
        bevy::camera::CameraPlugin,
    ))
    .add_plugins(plugins);
    app.finish();
    app.cleanup();
    app
}

/// A 3D camera with the values the renderer would compute for a 1280×720 window (headless
/// tests have no renderer).
pub fn spawn_camera(app: &mut App, transform: Transform) -> Entity {
    let mut camera = Camera::default();
    camera.computed.target_info = Some(bevy::camera::RenderTargetInfo {
        physical_size: UVec2::new(1280, 720),
        scale_factor: 1.0,
    });
    let mut perspective = PerspectiveProjection::default();
    bevy::camera::CameraProjection::update(&mut perspective, 1280.0, 720.0);
    camera.computed.clip_from_view =
        bevy::camera::CameraProjection::get_clip_from_view(&perspective);
    app.world_mut()
        .spawn((
            Camera3d::default(),
            camera,
            Projection::Perspective(perspective),
            transform,
            GlobalTransform::from(transform),
        ))
        .id()
}

/// Where `at` (world) is on `camera`'s viewport.
pub fn to_screen(app: &mut App, camera: Entity, at: Vec3) -> Vec2 {
    let mut q = app.world_mut().query::<(&Camera, &GlobalTransform)>();
    let (c, t) = q.get(app.world(), camera).unwrap();
    c.world_to_viewport(t, at).unwrap()
}

/// Puts the primary window's cursor at `at` (window coordinates).
pub fn cursor_to(app: &mut App, at: Vec2) {
    let mut windows = app
        .world_mut()
        .query_filtered::<&mut Window, With<bevy::window::PrimaryWindow>>();
    windows
        .single_mut(app.world_mut())
        .unwrap()
        .set_cursor_position(Some(at));
}

/// Shift + press at `start`, drag to `end` in `steps` moves, release.
pub fn shift_drag(app: &mut App, start: Vec2, end: Vec2, steps: u32) {
    cursor_to(app, start);
    app.world_mut()
        .resource_mut::<ButtonInput<KeyCode>>()
        .press(KeyCode::ShiftLeft);
    app.world_mut()
        .resource_mut::<ButtonInput<MouseButton>>()
        .press(MouseButton::Left);
    app.update();
    for k in 1..=steps {
        cursor_to(app, start + (end - start) * k as f32 / steps as f32);
        app.update();
    }
    app.world_mut()
        .resource_mut::<ButtonInput<MouseButton>>()
        .release(MouseButton::Left);
    app.update();
}

/// Writes a raw pointer input for the mouse pointer at `at` on the primary window, as bevy's
/// input plugin would (a press is preceded by a move to the same spot).
pub fn pointer(app: &mut App, at: Vec2, action: bevy::picking::pointer::PointerAction) {
    let window = app
        .world_mut()
        .query_filtered::<Entity, With<bevy::window::PrimaryWindow>>()
        .single(app.world())
        .unwrap();
    let target = bevy::camera::RenderTarget::Window(bevy::window::WindowRef::Primary)
        .normalize(Some(window))
        .unwrap();
    let location = bevy::picking::pointer::Location {
        target,
        position: at,
    };
    use bevy::picking::pointer::{PointerAction, PointerId, PointerInput};
    // A real mouse is over the spot before it presses there: picking casts rays from where
    // pointers are, which only motion sets.
    if matches!(action, PointerAction::Press(_)) {
        app.world_mut().write_message(PointerInput::new(
            PointerId::Mouse,
            location.clone(),
            PointerAction::Move { delta: Vec2::ZERO },
        ));
    }
    app.world_mut()
        .write_message(PointerInput::new(PointerId::Mouse, location, action));
}

/// bevy_picking without a window backend's input: pointers, rays, hover and `Pointer<…>`
/// events (feed it with [`pointer`]).
pub fn picking_plugins() -> (
    bevy::picking::PickingPlugin,
    bevy::picking::InteractionPlugin,
    bevy::picking::input::PointerInputPlugin,
) {
    (
        bevy::picking::PickingPlugin,
        bevy::picking::InteractionPlugin,
        bevy::picking::input::PointerInputPlugin,
    )
}

/// A headless app that loads the Fox (`dir` holds `Fox.glb`) through Bevy's own glTF loader
/// with `plugins` (which must include `PosePlugin`), a `Poseable` on the scene root, updated
/// until its model is built. Returns the app and the root.
pub fn fox_app<M>(dir: &std::path::Path, plugins: impl bevy::app::Plugins<M>) -> (App, Entity) {
    character_app(dir, "Fox.glb", plugins)
}

/// A headless app that loads the rigged glTF `file` in `dir` through Bevy's own glTF loader
/// with `plugins` (which must include `PosePlugin`), a `Poseable` on the scene root, updated
/// until its model is built. Returns the app and the root.
pub fn character_app<M>(
    dir: &std::path::Path,
    file: &str,
    plugins: impl bevy::app::Plugins<M>,
) -> (App, Entity) {
    use bevy::time::TimeUpdateStrategy;
    use bevy_wii_deform::prelude::{Poseable, PosedSkeleton};
    let mut app = App::new();
    app.add_plugins(MinimalPlugins);
    headless_gltf::add_gltf_plugins(&mut app, dir);
    app.add_plugins(plugins);
    app.init_asset::<StandardMaterial>();
    // The glTF loader is registered in `Plugin::finish` (which `App::run` calls).
    app.finish();
    app.cleanup();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_millis(
        16,
    )));
    // The whole file is loaded once and kept (its clips too): loading a part of it later
    // with other settings would load the file again and respawn the scene.
    let path = file;
    let file = headless_gltf::load_gltf_without_materials(&app, path);
    let waiting = file.clone();
    update_until(&mut app, "the glTF file", move |a| {
        a.world()
            .resource::<Assets<bevy::gltf::Gltf>>()
            .get(&waiting)
            .is_some()
    });
    app.insert_resource(FoxFile(file));
    let scene = loaded_scene(&app);
    let root = app
        .world_mut()
        .spawn((
            bevy::world_serialization::WorldAssetRoot(scene),
            Poseable::default(),
        ))
        .id();
    update_until(&mut app, "the character's model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
            || a.world()
                .get::<PoseStatus>(root)
                .is_some_and(|s| s.error.is_some())
    });
    assert_eq!(app.world().get::<PoseStatus>(root).unwrap().error, None);
    (app, root)
}

/// The first scene of the file [`character_app`] loaded (spawn it again for another
/// instance of the character).
pub fn loaded_scene(app: &App) -> Handle<bevy::world_serialization::WorldAsset> {
    let file = &app.world().resource::<FoxFile>().0;
    let gltf = app.world().resource::<Assets<bevy::gltf::Gltf>>().get(file);
    gltf.expect("character_app loaded the file").scenes[0].clone()
}

/// Animation `index` of the Fox loaded by [`fox_app`] (0 Survey, 1 Walk, 2 Run).
pub fn fox_clip(app: &App, index: usize) -> Handle<AnimationClip> {
    let file = &app.world().resource::<FoxFile>().0;
    let gltf = app.world().resource::<Assets<bevy::gltf::Gltf>>().get(file);
    gltf.expect("fox_app loaded the file").animations[index].clone()
}

/// Keeps the Fox's glTF file (and so every asset in it) loaded.
#[derive(Resource)]
pub struct FoxFile(pub Handle<bevy::gltf::Gltf>);

/// The skinned model of a generated rig (default settings).
pub fn model_of(rig: &SyntheticRig) -> std::sync::Arc<bevy_wii_deform::pose::SkinnedModel> {
    std::sync::Arc::new(rig.model().unwrap())
}

/// Updates until the character has had no solve running and none landed for 10 frames (a
/// generous wall-clock deadline guards against a hang), then once more so `PostUpdate` writes
/// the pose to the joints. A pose that never settles fails with what the character was doing:
/// how many updates and solves it took, the last solve's iterations and energy, and its
/// phase and error.
pub fn settle_pose(app: &mut App, character: Entity) {
    use bevy_wii_deform::prelude::DeformPhase;
    let deadline = Instant::now() + Duration::from_secs(60);
    let first = solves(app, character);
    let mut idle = 0;
    let mut updates = 0u64;
    while idle < 10 {
        if Instant::now() >= deadline {
            let status = app.world().get::<PoseStatus>(character).unwrap();
            panic!(
                "the pose never settled: {updates} updates, {} solves landed, the last of {} \
                 iterations at energy {:e} ({} ms), phase {:?}, error {:?}",
                status.solves - first,
                status.iterations,
                status.energy,
                status.solve_ms,
                status.phase,
                status.error
            );
        }
        let before = solves(app, character);
        app.update();
        updates += 1;
        std::thread::yield_now();
        let status = app.world().get::<PoseStatus>(character).unwrap();
        idle = if status.phase == DeformPhase::Idle && status.solves == before {
            idle + 1
        } else {
            0
        };
    }
    app.update();
}

/// Spawns `rig` at the origin as a character with the components `settings` makes from its
/// joint entities (a `Poseable`, pins, …), and updates until its model is built. Returns the
/// root and the joint entities.
pub fn posed_rig<B: Bundle>(
    app: &mut App,
    rig: &SyntheticRig,
    settings: impl FnOnce(&[Entity]) -> B,
) -> (Entity, Vec<Entity>) {
    use bevy_wii_deform::prelude::PosedSkeleton;
    let (root, joints, _) = spawn_rig(app, rig, Vec3::ZERO);
    app.world_mut().entity_mut(root).insert(settings(&joints));
    update_until(app, "the model", |a| {
        a.world().get::<PosedSkeleton>(root).is_some()
    });
    (root, joints)
}

/// The entity holding the loaded scene's `AnimationPlayer`.
pub fn animation_player(app: &mut App) -> Entity {
    let w = app.world_mut();
    let mut q = w.query_filtered::<Entity, With<AnimationPlayer>>();
    q.iter(w).next().expect("the scene has an AnimationPlayer")
}

/// Waits for `clip` to load, gives `player` a graph of it and plays it (paused at 0); returns
/// the clip's node for [`show_clip_at`].
pub fn play_clip(app: &mut App, player: Entity, clip: Handle<AnimationClip>) -> AnimationNodeIndex {
    let waiting = clip.clone();
    update_until(app, "the clip", move |a| {
        a.world()
            .resource::<Assets<AnimationClip>>()
            .get(&waiting)
            .is_some()
    });
    let (graph, node) = AnimationGraph::from_clip(clip);
    let graph = app
        .world_mut()
        .resource_mut::<Assets<AnimationGraph>>()
        .add(graph);
    app.world_mut()
        .entity_mut(player)
        .insert(AnimationGraphHandle(graph));
    app.world_mut()
        .get_mut::<AnimationPlayer>(player)
        .unwrap()
        .stop_all()
        .play(node)
        .pause();
    node
}

/// Seeks the paused clip `node` of `player` to `time` and updates twice, so the animation
/// systems have written the joints.
pub fn show_clip_at(app: &mut App, player: Entity, node: AnimationNodeIndex, time: f32) {
    for _ in 0..2 {
        app.world_mut()
            .get_mut::<AnimationPlayer>(player)
            .unwrap()
            .animation_mut(node)
            .expect("the clip plays")
            .set_seek_time(time)
            .pause();
        app.update();
    }
}

/// The angle between two rotations, radians (stable near zero, where `acos` of the dot
/// product loses half the digits).
pub fn angle_between(a: Quat, b: Quat) -> f32 {
    bevy_wii_deform::pose::rotation_angle(a.as_dquat(), b.as_dquat()) as f32
}

/// Name, parent and animation-root flag of an entity: what `PosedSkeleton::joint_paths` asks.
pub fn node_of(world: &World, e: Entity) -> (Option<String>, Option<Entity>, bool) {
    (
        world.get::<Name>(e).map(|n| n.as_str().to_string()),
        world.get::<ChildOf>(e).map(|c| c.parent()),
        world.get::<AnimationPlayer>(e).is_some(),
    )
}
