//! Posed characters as a bevy_picking backend: hits on the CPU-skinned surface.
//!
//! Bevy's mesh picking tests the *bind pose* of a skinned mesh, so a bent arm would be
//! picked where it was before posing. This backend reports, for every pointer ray, the nearest
//! hit on each [`PosedSkeleton`]'s posed triangles as a hit on the character entity (the one
//! holding the `PosedSkeleton`). Picking then orders those hits with meshes and UI, so UI over
//! a character or a mesh in front of it takes the press, [`Pickable`] on the character works,
//! and `On<Pointer<Press>>` observers fire on the character (and bubble to its ancestors). The
//! character's skinned mesh entities get [`Pickable::IGNORE`] (unless they carry their own
//! `Pickable`), so their bind pose never shadows the posed surface.

use bevy::picking::Pickable;
use bevy::picking::backend::ray::RayMap;
use bevy::picking::backend::{HitData, PointerHits};
use bevy::prelude::*;

use super::super::PosedSkeleton;

/// Writes [`PointerHits`] for posed characters (runs in `PickingSystems::Backend` when
/// bevy_picking's `RayMap` exists).
pub(super) fn pick_posed_characters(
    rays: Res<RayMap>,
    cameras: Query<&Camera>,
    characters: Query<(Entity, &PosedSkeleton, Option<&Pickable>)>,
    mut hits: MessageWriter<PointerHits>,
) {
    if characters.is_empty() || rays.iter().next().is_none() {
        return;
    }
    // Each character is skinned once per frame, whatever the number of pointers and cameras.
    let posed: Vec<(Entity, &PosedSkeleton, Vec<glam::DVec3>)> = characters
        .iter()
        .filter(|(_, _, pickable)| pickable.is_none_or(|p| p.is_hoverable))
        .map(|(entity, posed, _)| (entity, posed, posed.skin_welded_world()))
        .collect();
    for (&ray_id, &ray) in rays.iter() {
        let Ok(camera) = cameras.get(ray_id.camera) else {
            continue;
        };
        let picks: Vec<(Entity, HitData)> = posed
            .iter()
            .filter_map(|(entity, posed, skinned)| {
                let (point, depth) = posed.ray_cast_skinned(skinned, ray)?;
                Some((
                    *entity,
                    HitData::new(ray_id.camera, depth, Some(point), None),
                ))
            })
            .collect();
        if !picks.is_empty() {
            hits.write(PointerHits::new(ray_id.pointer, picks, camera.order as f32));
        }
    }
}

/// Keeps Bevy's mesh picking off a newly posed character's skinned meshes (their bind pose).
pub(super) fn ignore_bind_pose_picking(
    mut commands: Commands,
    posed: Query<&PosedSkeleton, Added<PosedSkeleton>>,
    pickable: Query<(), With<Pickable>>,
) {
    for skeleton in &posed {
        for &(primitive, _) in &skeleton.primitives {
            if !pickable.contains(primitive) {
                commands.entity(primitive).try_insert(Pickable::IGNORE);
            }
        }
    }
}
