//! The challenge: the paper's user study as a game. A task's target pose is shown as a yellow
//! point cloud; the timer runs until the mesh is close enough, the background turns green, and
//! the time goes into a results table (mouse vs Wii Remote, like the paper's Table 1).

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy::time::Stopwatch;
use bevy_wii_deform::deform::synth;
use bevy_wii_deform::prelude::*;
use glam::DVec3;

use crate::camera::BACKGROUND;
use crate::{EditMode, InputMethod, Model, SandboxSet, StatusLine, tasks};

/// Where finished challenges are appended.
pub const RESULTS_CSV: &str = "challenge_results.csv";
/// Done when the mean vertex distance to the target is below this fraction of the mean
/// distance between the rest pose and the target (i.e. 85% of the way there).
pub const CLOSE_ENOUGH: f64 = 0.15;
const SUCCESS: Color = Color::srgb(0.10, 0.35, 0.16);

/// Tasks, target clouds, the timer and the results table.
pub struct ChallengePlugin;

impl Plugin for ChallengePlugin {
    fn build(&self, app: &mut App) {
        app.init_state::<ChallengeState>()
            .insert_resource(TaskList(tasks::Task::load_all("assets/tasks")))
            .insert_resource(Results {
                rows: tasks::read_results(RESULTS_CSV),
                show: false,
            })
            .add_message::<ChallengeSetup>()
            .add_systems(Update, setup_challenge.in_set(SandboxSet::Edit))
            .add_systems(
                Update,
                track_progress
                    .after(DeformSystems::Writeback)
                    .run_if(in_state(ChallengeState::Running)),
            )
            .add_systems(OnEnter(ChallengeState::Running), start_clock)
            .add_systems(OnEnter(ChallengeState::Off), leave)
            .add_systems(OnEnter(ChallengeState::Done), celebrate);
    }
}

/// Whether a challenge is on.
#[derive(States, Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ChallengeState {
    /// Free editing.
    #[default]
    Off,
    /// The timer runs; painting is off.
    Running,
    /// Target reached; the time is recorded.
    Done,
}

/// The study's tasks (`assets/tasks/*.ron`), by key.
#[derive(Resource)]
pub struct TaskList(pub Vec<(String, tasks::Task)>);

impl TaskList {
    /// The task with this key or name.
    pub fn find(&self, key: &str) -> Option<(String, tasks::Task)> {
        self.0
            .iter()
            .find(|(k, task)| k == key || task.name == key)
            .cloned()
    }
}

/// Recorded times, and whether the panel shows them.
#[derive(Resource)]
pub struct Results {
    pub rows: Vec<tasks::ResultRow>,
    pub show: bool,
}

/// A model finished loading: the task it was loaded for and its solved target, if any.
#[derive(Message)]
pub struct ChallengeSetup(pub Option<TaskTarget>);

/// A task and its target pose (solved on the loaded model), or why it has none.
pub struct TaskTarget {
    pub key: String,
    pub task: tasks::Task,
    pub target: Result<Vec<DVec3>, String>,
}

/// The running (or finished) challenge.
#[derive(Resource)]
pub struct Challenge {
    pub key: String,
    pub task: tasks::Task,
    target: Vec<DVec3>,
    /// Mean distance rest → target.
    start_error: f64,
    pub watch: Stopwatch,
    pub done: Option<f64>,
    /// 0 at rest, 1 on target.
    pub progress: f64,
}

/// The yellow target cloud.
#[derive(Component)]
struct TargetCloud;

fn setup_challenge(
    mut setups: MessageReader<ChallengeSetup>,
    mut commands: Commands,
    model: Res<Model>,
    mut assets: (ResMut<Assets<Mesh>>, ResMut<Assets<StandardMaterial>>),
    clouds: Query<Entity, With<TargetCloud>>,
    mut states: (
        ResMut<NextState<ChallengeState>>,
        ResMut<NextState<EditMode>>,
    ),
    mut status: ResMut<StatusLine>,
) {
    let Some(ChallengeSetup(setup)) = setups.read().last() else {
        return;
    };
    clouds.iter().for_each(|c| commands.entity(c).despawn());
    let (key, task, target) = match setup {
        Some(TaskTarget {
            key,
            task,
            target: Ok(target),
        }) => (key.clone(), task.clone(), target.clone()),
        Some(TaskTarget { target: Err(e), .. }) => {
            status.set(e.clone());
            return states.0.set(ChallengeState::Off);
        }
        None => return states.0.set(ChallengeState::Off),
    };
    let cloud = assets.0.add(point_cloud(&target, model.diagonal));
    let yellow = assets.1.add(StandardMaterial {
        base_color: Color::srgb(1.0, 0.9, 0.1),
        unlit: true,
        ..default()
    });
    commands.spawn((
        Mesh3d(cloud),
        MeshMaterial3d(yellow),
        Pickable::IGNORE,
        TargetCloud,
    ));
    status.set(format!(
        "challenge: {} — match the yellow points",
        task.name
    ));
    let start_error = mean_distance(target.iter().copied(), &model.mesh.positions);
    commands.insert_resource(Challenge {
        key,
        task,
        target,
        start_error,
        watch: Stopwatch::new(),
        done: None,
        progress: 0.0,
    });
    states.0.set(ChallengeState::Running);
    states.1.set(EditMode::Pose);
}

fn mean_distance(a: impl Iterator<Item = DVec3>, b: &[DVec3]) -> f64 {
    a.zip(b).map(|(p, q)| p.distance(*q)).sum::<f64>() / b.len().max(1) as f64
}

/// A yellow cloud: one tiny octahedron per sampled target vertex, in a single mesh.
fn point_cloud(points: &[DVec3], diagonal: f64) -> Mesh {
    let step = (points.len() / 3000).max(1);
    let r = diagonal * 0.004;
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for p in points.iter().step_by(step) {
        let marker = synth::octahedron(*p, r);
        let base = pos.len() as u32;
        pos.extend(marker.positions.iter().map(|q| q.as_vec3().to_array()));
        idx.extend(marker.triangles.iter().flatten().map(|i| base + i));
    }
    let normals: Vec<[f32; 3]> = vec![[0.0, 1.0, 0.0]; pos.len()];
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, pos)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
    .with_inserted_indices(Indices::U32(idx))
}

/// Ticks the timer and measures how close the mesh is; records the time when done.
fn track_progress(
    mut challenge: ResMut<Challenge>,
    time: Res<Time>,
    model: Res<Model>,
    (meshes, mesh3d): (Res<Assets<Mesh>>, Query<&Mesh3d>),
    (input, controllers): (Res<State<InputMethod>>, Query<&MotionController>),
    mut done: ResMut<NextState<ChallengeState>>,
    mut record: (ResMut<Results>, ResMut<StatusLine>),
) {
    challenge.watch.tick(time.delta());
    let Some(VertexAttributeValues::Float32x3(current)) = model
        .entity
        .and_then(|e| mesh3d.get(e).ok())
        .and_then(|m| meshes.get(&m.0))
        .and_then(|m| m.attribute(Mesh::ATTRIBUTE_POSITION))
    else {
        return;
    };
    if current.len() != challenge.target.len() {
        return;
    }
    let posed = current.iter().map(|c| Vec3::from_array(*c).as_dvec3());
    let mean = mean_distance(posed, &challenge.target);
    challenge.progress = 1.0 - mean / challenge.start_error.max(1e-12);
    if mean >= CLOSE_ENOUGH * challenge.start_error + 1e-4 * model.diagonal {
        return;
    }
    let seconds = challenge.watch.elapsed_secs_f64();
    challenge.done = Some(seconds);
    done.set(ChallengeState::Done);
    // A controller's row names its kind (a DualSense is not a Wii Remote): the first one
    // connected, as the handle control drives it.
    let input = match input.get() {
        InputMethod::Controller => controllers
            .iter()
            .find(|c| c.connection == ConnectionState::Connected)
            .map_or(InputMethod::Controller.name(), |c| c.kind.name()),
        method => method.name(),
    };
    let row = tasks::ResultRow {
        task: challenge.key.clone(),
        input: input.into(),
        seconds,
    };
    record.1.set(match tasks::append_result(RESULTS_CSV, &row) {
        Ok(()) => format!("done in {seconds:.1} s with the {input} — saved to {RESULTS_CSV}"),
        Err(e) => format!("done in {seconds:.1} s (could not save: {e})"),
    });
    record.0.rows.push(row);
}

fn start_clock(mut clear: ResMut<ClearColor>) {
    clear.0 = BACKGROUND;
}

fn celebrate(mut clear: ResMut<ClearColor>) {
    clear.0 = SUCCESS;
}

fn leave(
    mut commands: Commands,
    clouds: Query<Entity, With<TargetCloud>>,
    mut clear: ResMut<ClearColor>,
) {
    clouds.iter().for_each(|c| commands.entity(c).despawn());
    commands.remove_resource::<Challenge>();
    clear.0 = BACKGROUND;
}
