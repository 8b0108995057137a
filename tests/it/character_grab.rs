//! A pointer grab on a real character (the Fox through Bevy's glTF loader) with no pinned
//! joints bends it: the grab pins the joints its region does not reach (`GrabAnchor`) and
//! drags the grabbed point, leaving its orientation to the body (`HandlePositionOnly`).

use bevy::picking::pointer::PointerId;
use bevy::prelude::*;
use bevy_wii_deform::ecs::{GrabAnchor, GrabHandle};
use bevy_wii_deform::prelude::*;

use crate::common;
use common::{spawn_camera, to_screen, update_until};

/// The joints of a posed character whose names say "foot".
fn foot_joints(posed: &PosedSkeleton) -> Vec<Entity> {
    posed
        .model
        .skeleton()
        .joints()
        .iter()
        .enumerate()
        .filter(|(_, j)| j.name.to_lowercase().contains("foot"))
        .map(|(k, _)| posed.joints[k])
        .collect()
}

/// Whether the grab on `target` has a handle placed at its pivot.
fn grab_handle_placed(app: &App, target: Entity) -> bool {
    app.world()
        .get::<GrabHandle>(target)
        .and_then(|h| app.world().get::<DeformHandle>(h.0))
        .is_some_and(|h| h.pivot.is_some())
}

/// The centroid of `vertices` as the character is drawn now.
fn skinned_centroid(app: &App, character: Entity, vertices: &[u32]) -> Vec3 {
    let now = app
        .world()
        .get::<PosedSkeleton>(character)
        .unwrap()
        .skinned_positions();
    vertices.iter().map(|&v| now[v as usize]).sum::<Vec3>() / vertices.len() as f32
}

#[test]
fn a_character_grab_without_pins_bends_it() {
    let Some(dir) = common::shared::shared_asset("models") else {
        return;
    };
    let (mut app, fox) = common::fox_app(&dir, (PosePlugin, DeformPlugin::default(), GrabPlugin));
    let posed = app.world().get::<PosedSkeleton>(fox).unwrap().clone();
    assert!(app.world().get::<PinnedJoints>(fox).is_none());
    let drawn = posed.skinned_positions();
    let size = posed.model.topology().bounding_diagonal() as f32;
    let centre = drawn.iter().sum::<Vec3>() / drawn.len() as f32;
    // Seen from its side, a little above.
    let camera = spawn_camera(
        &mut app,
        Transform::from_translation(centre + Vec3::new(2.0 * size, 0.3 * size, 0.0))
            .looking_at(centre, Vec3::Y),
    );
    app.world_mut().entity_mut(fox).insert(Grabbable {
        radius: 0.08 * size,
        region_radius: 0.4 * size,
        ..default()
    });
    // The snout: the drawn vertex farthest forward (the Fox faces +z). (Its ear tips are its
    // topmost points: with the four feet held, no bend of rigid bones lifts them by a tenth of
    // its size, so the snout is the point a head-lift drag pulls.)
    let ear = drawn
        .iter()
        .copied()
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .unwrap();
    let feet = foot_joints(&posed);
    assert!(feet.len() >= 4, "the Fox's feet");
    let feet_at = |app: &App| -> Vec<Vec3> {
        feet.iter()
            .map(|&f| app.world().get::<GlobalTransform>(f).unwrap().translation())
            .collect()
    };
    let feet_before = feet_at(&app);
    app.world_mut().write_message(GrabStart {
        pointer: PointerId::Mouse,
        entity: fox,
        point: ear,
        camera,
    });
    update_until(&mut app, "the grab's handle at its pivot", |a| {
        grab_handle_placed(a, fox)
    });
    let anchor = app
        .world()
        .get::<GrabAnchor>(fox)
        .expect("an anchor")
        .clone();
    assert!(
        anchor.joints.iter().any(|j| feet.contains(j)),
        "the feet are not among the anchored joints"
    );
    let handle = app.world().get::<GrabHandle>(fox).unwrap().0;
    let patch = app
        .world()
        .get::<DeformHandle>(handle)
        .unwrap()
        .vertices
        .clone();
    let patch_centroid = |app: &App| skinned_centroid(app, fox, &patch);
    let start = patch_centroid(&app);
    // Drag up on screen by 10 % of the Fox's size (at the snout's depth).
    let from = to_screen(&mut app, camera, ear);
    let above = to_screen(&mut app, camera, ear + Vec3::Y * 0.1 * size);
    app.world_mut().write_message(GrabMove {
        pointer: PointerId::Mouse,
        from,
        to: above,
        rotate: false,
    });
    // Let the solves converge (a held drag keeps solving while iterations run out).
    common::settle_pose(&mut app, fox);
    let moved = patch_centroid(&app) - start;
    let drag = Vec3::Y * 0.1 * size;
    assert!(
        moved.dot(drag.normalize()) > 0.9 * drag.length(),
        "the snout moved {moved} for a drag of {drag}"
    );
    for (before, now) in feet_before.iter().zip(feet_at(&app)) {
        assert!(
            (now - *before).length() < 0.02 * size,
            "a foot moved {} ({} % of the size)",
            now - *before,
            100.0 * (now - *before).length() / size
        );
    }
    // Released: the anchor goes with the grab.
    app.world_mut().write_message(GrabEnd {
        pointer: PointerId::Mouse,
    });
    app.update();
    app.update();
    assert!(app.world().get::<GrabAnchor>(fox).is_none());
}
