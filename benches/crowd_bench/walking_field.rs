//! `crowd_bench --terrain`: the crowd example's terrain as `GroundMesh`, characters walking across
//! it, and what is measured of their contacts.

use bevy::prelude::*;
use bevy_wii_deform::pose::{Ground as CastDown, SupportPolygon, TriangleGround, centre_of_mass};
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
    /// Each sampled (character, frame) pair's deepest vertex / size.
    depths: Vec<f64>,
    /// Each planted patch's slide in each frame / size.
    slides: Vec<f64>,
    plants_at_start: Option<u64>,
    /// Planted soles' up (carried by the joint) against their ground's normal, degrees.
    sole_errors_deg: Vec<f64>,
    /// Largest per-frame slide of a planted patch across its ground / size.
    slide_max: f64,
    /// Each sampled (character, frame) pair's last solve's iterations.
    iterations: Vec<u32>,
    /// (character, frame) pairs with the centre of mass over the planted patches, and all.
    supported: u64,
    pairs: u64,
    /// Pairs with nothing planted (counted unsupported).
    unsupported_no_support: u64,
    /// Each character's planted patches last frame (world space).
    previous: std::collections::HashMap<Entity, Vec<Option<Planted>>>,
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
        .spawn((Mesh3d(handle), Transform::IDENTITY, GroundMesh));
    let field = Field {
        ground: std::sync::Arc::new(TriangleGround::new(positions, triangles, DVec3::NEG_Y)),
        penetration_max: 0.0,
        depths: Vec::new(),
        slides: Vec::new(),
        plants_at_start: None,
        sole_errors_deg: Vec::new(),
        slide_max: 0.0,
        iterations: Vec::new(),
        supported: 0,
        pairs: 0,
        unsupported_no_support: 0,
        previous: Default::default(),
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

    /// Measures this frame: the planted soles' turn to the ground, their slide since the last
    /// frame, the centre of mass against the support polygon, and (with `skin`) the deepest
    /// skinned vertex below the terrain; the plants of the first stance at the first call.
    pub fn sample(&mut self, app: &App, roots: &[Entity], skin: bool) {
        if self.plants_at_start.is_none() {
            self.plants_at_start = Some(plants(app, roots));
        }
        for &root in roots {
            let (Some(posed), Some(status)) = (
                app.world().get::<PosedSkeleton>(root),
                app.world().get::<PoseStatus>(root),
            ) else {
                continue;
            };
            self.iterations.push(status.iterations);
            // The pose on screen: the walk clip with the pose's layer added.
            let pose = posed.shown_pose(|j| app.world().get::<Transform>(j).copied());
            let scale = posed.placement.matrix3.x_axis.length();
            let size = posed.model.topology().bounding_diagonal() * scale;
            if skin {
                // The deepest vertex of this character this frame: its distance under the
                // face above it, along that face's normal (straight down, a vertex under a
                // terrace's 53° riser reads 1 / cos 53° = 1.7 times as deep as it is).
                let mut deepest = 0.0f64;
                for p in posed.to_world(posed.model.skin_render(&pose)) {
                    if let Some(hit) = self.ground.cast_down(p + DVec3::Y * 1e3, DVec3::NEG_Y, 2e3)
                    {
                        deepest = deepest.max(-hit.height(p) / size);
                    }
                }
                self.penetration_max = self.penetration_max.max(deepest);
                self.depths.push(deepest);
            }
            let welded = posed.to_world(posed.model.skin_welded(&pose));
            let globals = posed.model.skeleton().global_transforms(&pose);
            let mut now = Vec::with_capacity(status.contacts.len());
            for c in &status.contacts {
                if !c.planted {
                    now.push(None);
                    continue;
                }
                let normal = c.ground_normal.as_dvec3();
                if let Some(up) = c.up {
                    let up = posed.placement.matrix3 * (globals[c.joint].matrix3 * up.as_dvec3());
                    let up = up.normalize_or(DVec3::Y);
                    self.sole_errors_deg
                        .push(up.angle_between(normal).to_degrees());
                }
                now.push(Some(Planted {
                    drawn: c.patch.iter().map(|&v| welded[v as usize]).collect(),
                    held: c.held.iter().map(|h| h.as_dvec3()).collect(),
                }));
            }
            if let Some(before) = self.previous.get(&root) {
                for ((a, b), c) in before.iter().zip(&now).zip(&status.contacts) {
                    let (Some(a), Some(b)) = (a, b) else {
                        continue;
                    };
                    let n = c.ground_normal.as_dvec3();
                    let across = |d: DVec3| (d - n * d.dot(n)).length() / size;
                    // The same plant in both frames: held where it was (a landing patch comes
                    // down along the normal). A patch released and planted again elsewhere
                    // within the frame is a new plant, not a slide.
                    let same_plant = a.held.len() == b.held.len()
                        && a.held
                            .iter()
                            .zip(&b.held)
                            .all(|(p, q)| across(*q - *p) < 1e-4);
                    if !same_plant {
                        continue;
                    }
                    let slide = a
                        .drawn
                        .iter()
                        .zip(&b.drawn)
                        .map(|(p, q)| across(*q - *p))
                        .fold(0.0f64, f64::max);
                    self.slides.push(slide);
                    self.slide_max = self.slide_max.max(slide);
                }
            }
            self.previous.insert(root, now);
            self.pairs += 1;
            let corners: Vec<DVec3> = status
                .support_polygon
                .iter()
                .map(|c| c.as_dvec3())
                .collect();
            if corners.is_empty() {
                self.unsupported_no_support += 1;
            } else if let Some(com) = centre_of_mass(&posed.model, &pose, None) {
                let com = posed.placement.transform_point3(com);
                let polygon = SupportPolygon::new(&corners, DVec3::NEG_Y);
                self.supported += u64::from(polygon.signed_distance(com) >= 0.0);
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
        let sorted = |v: &[f64]| {
            let mut v = v.to_vec();
            v.sort_by(f64::total_cmp);
            v
        };
        let quantile = |v: &[f64], q: f64| {
            v.get(((v.len().max(1) - 1) as f64 * q).round() as usize)
                .copied()
        };
        let errors = sorted(&self.sole_errors_deg);
        let p95 = quantile(&errors, 0.95);
        let pairs = self.pairs.max(1) as f64;
        let mut out = serde_json::Map::new();
        out.insert("terrain".into(), true.into());
        out.insert("penetration_max".into(), self.penetration_max.into());
        let (depths, slides) = (sorted(&self.depths), sorted(&self.slides));
        out.insert("penetration_p90".into(), quantile(&depths, 0.9).into());
        out.insert("penetration_p99".into(), quantile(&depths, 0.99).into());
        out.insert("planted_slide_p99".into(), quantile(&slides, 0.99).into());
        out.insert("sole_normal_error_deg_p95".into(), p95.into());
        out.insert(
            "soles_at_limit_share".into(),
            (errors.iter().filter(|e| **e > 3.0).count() as f64 / errors.len().max(1) as f64)
                .into(),
        );
        out.insert("planted_slide_max".into(), self.slide_max.into());
        let iterations: u64 = self.iterations.iter().map(|&i| u64::from(i)).sum();
        out.insert(
            "iterations_per_solve_mean".into(),
            (iterations as f64 / self.iterations.len().max(1) as f64).into(),
        );
        out.insert(
            "com_supported_share".into(),
            (self.supported as f64 / pairs).into(),
        );
        out.insert(
            "no_support_share".into(),
            (self.unsupported_no_support as f64 / pairs).into(),
        );
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

/// A planted patch in one frame (world space): where it is drawn and where it is held.
#[derive(Clone)]
struct Planted {
    drawn: Vec<DVec3>,
    held: Vec<DVec3>,
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
