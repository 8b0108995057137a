//! The view math every input shares: the arcball, turning a handle by a rotation given in the
//! camera's frame, the rotation of an affine space (scale divided out), and motion in the view
//! plane.

pub use crate::ecs::space::rotation_of_space;
use bevy::prelude::*;

/// The arcball rotation (in view space: x right, y up, z towards the viewer) that takes the
/// cursor from `from` to `to` (window coordinates, y down), for a ball of `radius` pixels
/// centred at `centre`. Points outside the ball lie on its rim, so dragging there rolls about
/// the view direction.
pub fn arcball_rotation(from: Vec2, to: Vec2, centre: Vec2, radius: f32) -> Quat {
    let to_sphere = |p: Vec2| {
        let v = (p - centre) / radius.max(1.0);
        let v = Vec2::new(v.x, -v.y);
        let d2 = v.length_squared();
        if d2 <= 1.0 {
            v.extend((1.0 - d2).sqrt())
        } else {
            (v / d2.sqrt()).extend(0.0)
        }
    };
    Quat::from_rotation_arc(to_sphere(from), to_sphere(to))
}

/// `rotation` (a handle's, in the space `space` maps to world) turned by `in_view`, a rotation
/// expressed in the camera's view frame.
pub fn turned_in_space(
    in_view: Quat,
    camera_transform: &GlobalTransform,
    space: &bevy::math::Affine3A,
    rotation: Quat,
) -> Quat {
    let camera_rotation = rotation_of_space(&camera_transform.affine());
    let in_world = camera_rotation * in_view * camera_rotation.inverse();
    // The rotation about a world axis, seen in the handle's space (its rotation part).
    let space_rotation = rotation_of_space(space);
    let in_space = space_rotation.inverse() * in_world * space_rotation;
    (in_space * rotation).normalize()
}

/// World-space motion of a point at `at`'s depth that follows the cursor from `from` to `to`.
pub fn view_plane_motion(
    camera: &Camera,
    camera_transform: &GlobalTransform,
    at: Vec3,
    from: Vec2,
    to: Vec2,
) -> Vec3 {
    let (Ok(a), Ok(b)) = (
        camera.viewport_to_world(camera_transform, from),
        camera.viewport_to_world(camera_transform, to),
    ) else {
        return Vec3::ZERO;
    };
    // Intersect both rays with the plane through `at` facing the camera.
    let normal = camera_transform.forward();
    let hit = |ray: Ray3d| {
        let denom = ray.direction.dot(*normal);
        if denom.abs() < 1e-6 {
            return None;
        }
        Some(ray.origin + *ray.direction * ((at - ray.origin).dot(*normal) / denom))
    };
    match (hit(a), hit(b)) {
        (Some(pa), Some(pb)) => pb - pa,
        _ => Vec3::ZERO,
    }
}
