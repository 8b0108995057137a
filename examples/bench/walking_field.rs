//! `crowd_bench --terrain`: the crowd example's terrain as `Ground`, characters walking across
//! it, and what is measured of their contacts.

use bevy::prelude::*;
use bevy_wii_deform::pose::{Ground as CastDown, TriangleGround};
use bevy_wii_deform::prelude::*;
use glam::{DVec2, DVec3};

/// A walking character (moved along +x, kept on the ground under its root).
#[derive(Component)]
pub struct Walker;

/// Walking speed, in the Fox's units per second (about a third of its length).
const SPEED: f32 = 40.0;

/// The terrain (for placing and measuring: the characters' own casts go through `SceneGround`)
/// and the measurements so far.
#[derive(Resource, Clone)]
pub struct Field {
    ground: std::sync::Arc<TriangleGround>,
    penetration_max: f64,
    plants_at_start: Option<u64>,
}

/// Spawns the terrain under a `side` × `side` field (150 apart), long enough for `frames` of
/// walking, and the walking system; returns the field.
pub fn spawn(app: &mut App, side: usize, frames: usize) -> Field {
    let extent = side as f64 * 150.0;
    let walk = frames as f64 * 0.016 * f64::from(SPEED) + 300.0;
    let (positions, triangles) = super::terrain::terrain(&super::terrain::TerrainSpec {
        origin: DVec2::splat(-150.0),
        size: DVec2::new(extent + walk, extent + 150.0),
        cells: 240,
        max_slope_deg: 30.0,
        step: 10.0,
        terrace: 300.0,
    });
    let mesh = mesh_from_triangles(&positions, &triangles);
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    app.world_mut()
        .spawn((Mesh3d(handle), Transform::IDENTITY, Ground));
    let field = Field {
        ground: std::sync::Arc::new(TriangleGround::new(positions, triangles, DVec3::NEG_Y)),
        penetration_max: 0.0,
        plants_at_start: None,
    };
    app.insert_resource(field.clone())
        .add_systems(Update, walk_on.before(PoseSystems::Request));
    field
}

impl Field {
    /// The terrain's height under `at`.
    pub fn height(&self, at: Vec3) -> f32 {
        self.ground
            .cast_down(DVec3::new(at.x as f64, 1e4, at.z as f64), DVec3::NEG_Y, 2e4)
            .map_or(0.0, |hit| hit.point.y as f32)
    }

    /// Records the deepest skinned vertex below the terrain now (and the plants of the first
    /// stance, at the first sample).
    pub fn sample(&mut self, app: &App, roots: &[Entity]) {
        if self.plants_at_start.is_none() {
            self.plants_at_start = Some(plants(app, roots));
        }
        for &root in roots {
            let Some(posed) = app.world().get::<PosedSkeleton>(root) else {
                continue;
            };
            let size = posed.model.topology().bounding_diagonal();
            for p in posed.to_world(posed.model.skin_render(&posed.pose)) {
                if let Some(hit) = self.ground.cast_down(p + DVec3::Y * 1e3, DVec3::NEG_Y, 2e3) {
                    let depth = (hit.point.y - p.y) / size;
                    self.penetration_max = self.penetration_max.max(depth);
                }
            }
        }
    }

    /// The JSON fields of the terrain run.
    pub fn report(
        &self,
        app: &App,
        roots: &[Entity],
    ) -> serde_json::Map<String, serde_json::Value> {
        let planted: u32 = roots
            .iter()
            .filter_map(|&r| app.world().get::<PoseStatus>(r))
            .map(|s| s.contacts_planted)
            .sum();
        let mut out = serde_json::Map::new();
        out.insert("terrain".into(), true.into());
        out.insert("penetration_max".into(), self.penetration_max.into());
        out.insert(
            "planted_per_character".into(),
            (planted as f64 / roots.len().max(1) as f64).into(),
        );
        out.insert(
            "replants".into(),
            (plants(app, roots) - self.plants_at_start.unwrap_or(0)).into(),
        );
        out
    }
}

/// Contacts planted so far, all characters.
fn plants(app: &App, roots: &[Entity]) -> u64 {
    roots
        .iter()
        .filter_map(|&r| app.world().get::<PoseStatus>(r))
        .map(|s| s.plants)
        .sum()
}

/// Moves every walker along +x and puts its root on the terrain under it.
fn walk_on(time: Res<Time>, field: Res<Field>, mut walkers: Query<&mut Transform, With<Walker>>) {
    for mut t in &mut walkers {
        t.translation.x += SPEED * time.delta_secs();
        t.translation.y = field.height(t.translation);
    }
}
