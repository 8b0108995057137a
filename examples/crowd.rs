//! A field of Foxes standing on a hilly, terraced terrain mesh, every one playing its own
//! animation and posed inside the frame over it: the terrain is `GroundMesh`, each Fox is dropped
//! onto it by a ray cast and stands on it with `PoseGround` (its paws found, cast down, planted
//! on the slope or the step under each; nothing below the surface) and `PoseBalance`; a look-at
//! effector turns each head toward a firefly that wanders over the field (the effectors are the
//! firefly's children: targets that follow another entity), and `PoseInFrame` solves all of
//! them every frame in parallel. The pose overrides the clip on the legs, neck and head only
//! (`PoseBlend` with a `JointMask`); the spine and tail play on, and the tail swings on spring
//! bones after the clip and the pose (`SpringBones`; **T** turns them off and on).
//!
//! ```text
//! cargo run --release --example crowd [-- N] [--screenshot PATH --frames N]
//! ```
//! N Foxes (default 100) from `assets/models/Fox.glb` (credits in `assets/CREDITS.md`). Solver time per frame for N
//! characters: `cargo run --release --example crowd_bench -- --characters N --json`.

use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_wii_deform::prelude::*;

use bevy_wii_deform_examples::cli;
use bevy_wii_deform_examples::screenshot;
use bevy_wii_deform_examples::springy_tails;
use bevy_wii_deform_examples::terrain;

/// The Fox, relative to the asset folder.
const FOX: &str = "models/Fox.glb";

const USAGE: &str = "\
usage: crowd [N] [--screenshot PATH [--frames N]]

  N                  Foxes in the field (default 100)
  --screenshot PATH  save frame N to PATH, exit
  --frames N         the frame to save (default 120)";
/// The Fox's joints (with their children) that the pose drives over the clip: its four legs,
/// and its neck and head.
const POSED_JOINTS: [&str; 5] = [
    "b_LeftLeg01_015",
    "b_RightLeg01_019",
    "b_LeftUpperArm_09",
    "b_RightUpperArm_06",
    "b_Neck_04",
];
/// Spacing of the Foxes, in the Fox's own units (it is about 100 long).
const SPACING: f32 = 160.0;

fn main() {
    let mut count = 100usize;
    let (mut screenshot, mut frames) = (None, 120);
    let mut parser = cli::Parser::from_env();
    while let Some(arg) = cli::next(&mut parser, USAGE) {
        match arg {
            cli::Arg::Value(n) => count = cli::parse_positional(n, USAGE),
            cli::Arg::Long("screenshot") => screenshot = Some(cli::string(&mut parser, USAGE)),
            cli::Arg::Long("frames") => frames = cli::value(&mut parser, USAGE),
            other => cli::unexpected(other, USAGE),
        }
    }
    let mut app = App::new();
    app.add_plugins(DefaultPlugins)
        .add_plugins((PosePlugin, IdlePlugin, FireflyPlugin))
        .add_plugins(springy_tails::SpringyTailsPlugin)
        .insert_resource(Crowd(count))
        .add_systems(Startup, setup)
        .add_systems(Update, drop_on_ground.before(PoseSystems::Request));
    if let Some(path) = screenshot {
        app.add_plugins(screenshot::ScreenshotPlugin { path, frames });
    }
    app.run();
}

/// Every Fox plays the "Survey" clip, each from its own phase and at its own speed.
struct IdlePlugin;

impl Plugin for IdlePlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Startup, load_idle)
            .add_systems(Update, play_idle);
    }
}

/// The idle clip's graph.
#[derive(Resource)]
struct Idle {
    graph: Handle<AnimationGraph>,
    node: AnimationNodeIndex,
}

fn load_idle(
    mut commands: Commands,
    assets: Res<AssetServer>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
) {
    let clip = assets.load(GltfAssetLabel::Animation(0).from_asset(FOX));
    let (graph, node) = AnimationGraph::from_clip(clip);
    commands.insert_resource(Idle {
        graph: graphs.add(graph),
        node,
    });
}

/// Starts the idle clip on each Fox's player as its scene spawns, phases and speeds spread.
fn play_idle(
    mut commands: Commands,
    idle: Res<Idle>,
    mut players: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
    mut started: Local<u32>,
) {
    for (entity, mut player) in &mut players {
        *started += 1;
        let k = *started as f32;
        player
            .play(idle.node)
            .repeat()
            .seek_to((k * 0.731).fract() * 3.0)
            .set_speed(0.8 + 0.4 * (k * 0.377).fract());
        commands
            .entity(entity)
            .insert(AnimationGraphHandle(idle.graph.clone()));
    }
}

/// A firefly wanders over the field; every Fox's head looks at it.
struct FireflyPlugin;

impl Plugin for FireflyPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(Startup, spawn_firefly)
            .add_systems(Update, (fly, look_at_firefly, fade_look_at));
    }
}

/// The firefly (its children are the look-at targets).
#[derive(Component)]
struct Firefly;

/// A Fox's look-at: its head joint and the way the Fox faces (world, level).
#[derive(Component)]
struct LookAt {
    head: Entity,
    forward: Vec3,
}

/// The strongest look-at, when the firefly is straight ahead.
const LOOK_WEIGHT: f32 = 0.5;

/// Fades each look-at out as the firefly goes round to the Fox's side: full within 25° of
/// where it faces, none past 70° (a head that would have to turn further does not try, as
/// game look-ats clamp their weight — FinalIK's `clampWeight`, Unity's Multi-Aim limits).
fn fade_look_at(
    firefly: Query<&GlobalTransform, With<Firefly>>,
    joints: Query<&GlobalTransform>,
    mut looks: Query<(&LookAt, &mut PoseEffector)>,
) {
    let Ok(firefly) = firefly.single() else {
        return;
    };
    let (full, none) = (25f32.to_radians().cos(), 70f32.to_radians().cos());
    for (look, mut effector) in &mut looks {
        let Ok(head) = joints.get(look.head) else {
            continue;
        };
        let to = (firefly.translation() - head.translation()).normalize_or_zero();
        let facing = to.dot(look.forward);
        let weight = LOOK_WEIGHT * ((facing - none) / (full - none)).clamp(0.0, 1.0);
        if (effector.weight - weight).abs() > 1e-3 {
            effector.weight = weight;
        }
    }
}

fn spawn_firefly(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((
        Firefly,
        Mesh3d(meshes.add(Sphere::new(12.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(1.0, 0.9, 0.3),
            emissive: LinearRgba::rgb(8.0, 6.0, 1.0),
            ..default()
        })),
        Transform::default(),
    ));
}

/// A slow figure eight above the field.
fn fly(time: Res<Time>, crowd: Res<Crowd>, mut firefly: Query<&mut Transform, With<Firefly>>) {
    let extent = (crowd.0 as f32).sqrt().ceil() * SPACING;
    let t = time.elapsed_secs() * 0.3;
    for mut transform in &mut firefly {
        transform.translation = Vec3::new(
            extent * (0.5 + 0.45 * t.sin()),
            90.0 + 30.0 * (2.0 * t).cos(),
            extent * (0.45 + 0.5 * (2.0 * t).sin()),
        );
    }
}

/// Once a Fox is poseable: a look-at effector on its head, a child of the firefly. The head's
/// local axis that looks is the Fox's forward (from its hips to its head) in the head's frame.
fn look_at_firefly(
    mut commands: Commands,
    foxes: Query<(Entity, &PosedSkeleton), Added<PosedSkeleton>>,
    joints: Query<&GlobalTransform>,
    firefly: Query<Entity, With<Firefly>>,
) {
    let Ok(firefly) = firefly.single() else {
        return;
    };
    for (fox, posed) in &foxes {
        let skeleton = posed.model.skeleton();
        let find = |part: &str| {
            let j = skeleton
                .joints()
                .iter()
                .position(|j| j.name.to_lowercase().contains(part))?;
            joints.get(posed.joints[j]).ok().map(|g| (j, *g))
        };
        let (Some((head, head_at)), Some((_, hips_at))) = (find("head"), find("hip")) else {
            continue;
        };
        let forward = (head_at.translation() - hips_at.translation())
            .with_y(0.0)
            .normalize_or(Vec3::Z);
        let axis = head_at.rotation().inverse() * forward;
        let effector = commands
            .spawn((
                PoseEffector::look_at(fox, posed.joints[head], axis).with_weight(0.0),
                LookAt {
                    head: posed.joints[head],
                    forward,
                },
                Transform::default(),
            ))
            .id();
        commands.entity(firefly).add_child(effector);
    }
}

/// How many Foxes.
#[derive(Resource)]
struct Crowd(usize);

/// A Fox not yet put on the ground (its height comes from a cast down on the terrain).
#[derive(Component)]
struct DropOnGround;

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    assets: Res<AssetServer>,
    crowd: Res<Crowd>,
) {
    let side = (crowd.0 as f32).sqrt().ceil() as usize;
    let extent = side as f32 * SPACING;
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(extent * 0.5, extent * 0.45, extent * 1.25)
            .looking_at(Vec3::new(extent * 0.5, 0.0, extent * 0.45), Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 9000.0,
            ..default()
        },
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    // The terrain: hills up to 30°, terraces a third of a leg high (the Fox is ~100 long, its
    // legs ~30), marked as the ground the characters stand on.
    let (positions, triangles) = terrain::terrain(&terrain::TerrainSpec {
        origin: glam::DVec2::splat(-SPACING as f64),
        size: glam::DVec2::splat((extent + SPACING) as f64),
        cells: 160,
        max_slope_deg: 30.0,
        step: 10.0,
        terrace: 2.0 * SPACING as f64,
    });
    commands.spawn((
        Mesh3d(meshes.add(mesh_from_triangles(&positions, &triangles))),
        MeshMaterial3d(materials.add(Color::srgb(0.3, 0.45, 0.3))),
        GroundMesh,
    ));
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(FOX));
    for k in 0..crowd.0 {
        let (x, z) = ((k % side) as f32 * SPACING, (k / side) as f32 * SPACING);
        commands.spawn((
            WorldAssetRoot(scene.clone()),
            Transform::from_xyz(x, 0.0, z),
            DropOnGround,
            Poseable::default(),
            PoseInFrame { iterations: 3 },
            // The pose holds the legs (feet on the ground) and the neck and head (the look);
            // the rest — spine, tail — plays the clip.
            PoseBlend {
                mask: Some(JointMask::names(POSED_JOINTS, true)),
                ..PoseBlend::overriding(1.0)
            },
            // Joints nothing pulls on stay with the animation.
            PoseStiffness(0.3),
            PoseGround::default(),
            PoseBalance::default(),
            // The tail swings after the clip and the pose (T turns it off and on).
            springy_tails::tail_springs(),
        ));
    }
}

/// Puts each new Fox on the terrain under it, once the ground exists.
fn drop_on_ground(
    mut commands: Commands,
    ground: Option<Res<SceneGround>>,
    mut foxes: Query<(Entity, &mut Transform), With<DropOnGround>>,
) {
    let Some(ground) = ground else {
        return;
    };
    for (fox, mut transform) in &mut foxes {
        let from = transform.translation.as_dvec3() + glam::DVec3::Y * 1e4;
        if let Some(hit) = ground.cast_down(from, glam::DVec3::NEG_Y, 2e4) {
            transform.translation.y = hit.point.y as f32;
            commands.entity(fox).remove::<DropOnGround>();
        }
    }
}
