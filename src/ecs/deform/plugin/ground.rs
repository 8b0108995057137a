//! The ground under a [`DeformGround`] mesh, for its solves: the scene's ground sampled into
//! a height field by the first solve that needs it (off the main thread), seen from the mesh's
//! own coordinates.

use std::sync::{Arc, OnceLock};

use bevy::prelude::*;
use glam::{DAffine3, DVec3};

use super::DeformGround;
use crate::deform::{HeightField, Obstacle, SurfaceSample, bounding_box};
use crate::ecs::SceneGround;

/// Samples per side of a height field at most (a mesh dragged far from a huge ground).
const MAX_SAMPLES_PER_SIDE: usize = 512;

/// What a deformable's ground is made from, and the obstacle once built (shared by the solves
/// of that ground and placement).
#[derive(Clone)]
pub(super) struct GroundCache {
    ground: SceneGround,
    settings: DeformGround,
    placement: GlobalTransform,
    built: Arc<OnceLock<Option<LocalGround>>>,
}

impl GroundCache {
    pub(super) fn new(
        ground: SceneGround,
        settings: DeformGround,
        placement: GlobalTransform,
    ) -> Self {
        Self {
            ground,
            settings,
            placement,
            built: Arc::default(),
        }
    }

    /// Whether this cache was made from the same ground, settings and placement.
    pub(super) fn is_for(
        &self,
        ground: &SceneGround,
        settings: &DeformGround,
        placement: &GlobalTransform,
    ) -> bool {
        self.ground.same_source(ground)
            && self.settings == *settings
            && self.placement == *placement
    }

    /// The ground in the mesh's coordinates (`rest`: its welded rest positions), sampled on
    /// first use; `None` when no ground was found under the mesh.
    pub(super) fn obstacle(&self, rest: &[DVec3]) -> Option<&LocalGround> {
        self.built
            .get_or_init(|| {
                LocalGround::sample(&self.ground, &self.settings, &self.placement, rest)
            })
            .as_ref()
    }
}

/// A height field of the world's ground (across +Y) seen from a mesh's coordinates.
pub(super) struct LocalGround {
    field: HeightField,
    to_world: DAffine3,
    to_local: DAffine3,
}

impl LocalGround {
    fn sample(
        ground: &SceneGround,
        settings: &DeformGround,
        placement: &GlobalTransform,
        rest: &[DVec3],
    ) -> Option<Self> {
        let to_world = DAffine3::from_mat4(placement.to_matrix().as_dmat4());
        let to_local = to_world.inverse();
        if !to_local.is_finite() || rest.is_empty() {
            return None;
        }
        let world: Vec<DVec3> = rest.iter().map(|p| to_world.transform_point3(*p)).collect();
        let (lo, hi) = bounding_box(&world);
        let diagonal = (hi - lo).length();
        if !(diagonal > 0.0 && diagonal.is_finite()) {
            return None;
        }
        let margin = f64::from(settings.reach.max(0.0)) * diagonal;
        let cell = diagonal / f64::from(settings.cells.max(2));
        let samples = |extent: f64| {
            (((extent + 2.0 * margin) / cell).ceil() as usize + 1).clamp(2, MAX_SAMPLES_PER_SIDE)
        };
        let size = [samples(hi.x - lo.x), samples(hi.z - lo.z)];
        // Spread the samples over the whole area when the cap made them sparser.
        let cell = cell
            .max((hi.x - lo.x + 2.0 * margin) / (size[0] - 1) as f64)
            .max((hi.z - lo.z + 2.0 * margin) / (size[1] - 1) as f64);
        let top = hi.y + margin;
        let depth = top - (lo.y - margin - diagonal);
        let origin = DVec3::new(lo.x - margin, 0.0, lo.z - margin);
        let field = HeightField::sample(origin, DVec3::Y, DVec3::X, cell, size, |p| {
            ground
                .cast_down(DVec3::new(p.x, top, p.z), DVec3::NEG_Y, depth)
                .map(|plane| plane.point.y)
        })
        .ok()?;
        (field.known_samples() > 0).then_some(Self {
            field,
            to_world,
            to_local,
        })
    }
}

impl Obstacle for LocalGround {
    fn surface_at(&self, p: DVec3) -> Option<SurfaceSample> {
        let s = self.field.surface_at(self.to_world.transform_point3(p))?;
        // A plane's normal goes back through the transpose of the linear part.
        let normal = (self.to_world.matrix3.transpose() * s.normal).try_normalize()?;
        Some(SurfaceSample {
            point: self.to_local.transform_point3(s.point),
            normal,
        })
    }

    fn up(&self) -> DVec3 {
        self.to_local
            .transform_vector3(DVec3::Y)
            .try_normalize()
            .unwrap_or(DVec3::Y)
    }
}
