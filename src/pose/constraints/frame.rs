//! Characters placed in a world: a model is built in *character space* (the frame of the
//! entity that stands for the character), so that every instance of one asset shares it, and
//! what a game asks for in world space is brought into that frame before a solve.
//!
//! A placement is a similarity (rotation, uniform scale, translation): under one, rigid
//! motions stay rigid and aims keep their angles. A character placed with a non-uniform
//! scale is built in world space instead ([`similarity`] says which).

use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::deform::RigidTransform;
use crate::pose::constraints::PoseConstraints;
use crate::pose::constraints::effectors::{Effector, EffectorGoal};
use crate::pose::rig::skeleton::rotation_of;

/// `affine` when it is a similarity (its linear part a rotation times a uniform scale, to
/// 1e-6), else `None`.
pub fn similarity(affine: &DAffine3) -> Option<DAffine3> {
    let m = affine.matrix3;
    let scale = m.determinant().cbrt();
    if !(scale.is_finite() && scale > 0.0 && affine.translation.is_finite()) {
        return None;
    }
    let r = m / scale;
    let off = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    (off < 1e-6).then_some(*affine)
}

/// How a similarity acts on the pieces of a constraint.
struct Similarity {
    affine: DAffine3,
    rotation: DQuat,
}

impl Similarity {
    fn new(affine: &DAffine3) -> Self {
        Self {
            affine: *affine,
            rotation: rotation_of(&affine.matrix3),
        }
    }

    fn point(&self, p: DVec3) -> DVec3 {
        self.affine.transform_point3(p)
    }

    fn motion(&self, m: &RigidTransform) -> RigidTransform {
        RigidTransform {
            rotation: (self.rotation * m.rotation * self.rotation.inverse()).normalize(),
            translation: self.affine.matrix3 * m.translation,
            pivot: self.point(m.pivot),
        }
    }

    fn goal(&self, goal: &EffectorGoal) -> EffectorGoal {
        match *goal {
            EffectorGoal::Position(p) => EffectorGoal::Position(self.point(p)),
            EffectorGoal::Orientation(q) => {
                EffectorGoal::Orientation((self.rotation * q).normalize())
            }
            EffectorGoal::Aim { axis, target, up } => EffectorGoal::Aim {
                axis,
                target: self.point(target),
                up: up.map(|(local, world)| (local, self.rotation * world)),
            },
        }
    }
}

impl Effector {
    /// This effector, its goal given in one frame, expressed in another (`to`, a
    /// [`similarity`]; see [`PoseConstraints::transformed`]).
    pub fn transformed(&self, to: &DAffine3) -> Effector {
        Effector {
            goal: Similarity::new(to).goal(&self.goal),
            ..*self
        }
    }
}

impl PoseConstraints {
    /// These constraints, given in one frame, expressed in another: `to` maps the first
    /// into the second (character ← world, the inverse of the character's placement) and must
    /// be a [`similarity`]. Vertex and joint indices, stiffness and limits (all local) are
    /// unchanged; a balance's support, gravity and margin, contacts' ground and planted points and
    /// a floor follow the frame.
    pub fn transformed(&self, to: &DAffine3) -> PoseConstraints {
        let s = Similarity::new(to);
        let mut out = self.clone();
        for h in &mut out.handles {
            h.transform = s.motion(&h.transform);
        }
        for h in &mut out.joint_handles {
            h.transform = s.motion(&h.transform);
        }
        for e in &mut out.effectors {
            e.goal = s.goal(&e.goal);
        }
        for c in &mut out.centroid_effectors {
            c.target = s.point(c.target);
        }
        if let Some(b) = &mut out.balance {
            for p in &mut b.support {
                *p = s.point(*p);
            }
            b.gravity = s.rotation * b.gravity;
            b.margin *= to.matrix3.x_axis.length();
        }
        let ground = |g: &mut crate::pose::ground::GroundPlane| {
            g.point = s.point(g.point);
            g.normal = (s.rotation * g.normal).normalize();
        };
        for c in &mut out.contacts {
            ground(&mut c.ground);
            for p in c.planted.iter_mut().flatten() {
                *p = s.point(*p);
            }
        }
        if let Some(f) = &mut out.floor {
            f.planes_mut().for_each(ground);
            if let crate::pose::ground::floor::Floor::Plane { band, .. } = f {
                *band *= to.matrix3.x_axis.length();
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::deform::Handle;
    use crate::pose::constraints::JointHandle;
    use crate::pose::constraints::effectors::CentroidEffector;

    #[test]
    fn similarities_are_told_apart() {
        let turn = DAffine3::from_scale_rotation_translation(
            DVec3::splat(100.0),
            DQuat::from_rotation_y(0.7),
            DVec3::new(1.0, 2.0, 3.0),
        );
        assert!(similarity(&turn).is_some());
        assert!(similarity(&DAffine3::from_scale(DVec3::new(1.2, 1.0, 1.0))).is_none());
        assert!(similarity(&DAffine3::from_scale(DVec3::splat(-1.0))).is_none());
    }

    /// A motion moved into another frame moves the moved points: `to(m(p)) = m'(to(p))`, and
    /// goals follow the frame; going there and back gives the constraints back.
    #[test]
    fn constraints_follow_a_change_of_frame() {
        let to = DAffine3::from_scale_rotation_translation(
            DVec3::splat(0.01),
            DQuat::from_rotation_z(-0.4) * DQuat::from_rotation_x(1.1),
            DVec3::new(-3.0, 0.5, 7.0),
        );
        let motion = RigidTransform::new(
            DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 0.6),
            DVec3::new(0.3, -0.2, 0.9),
            DVec3::new(1.0, 1.0, 0.0),
        );
        let c = PoseConstraints {
            handles: vec![Handle {
                vertices: vec![1, 2],
                transform: motion,
            }],
            joint_handles: vec![JointHandle {
                joint: 1,
                transform: motion,
            }],
            effectors: vec![
                Effector {
                    joint: 0,
                    goal: EffectorGoal::Aim {
                        axis: DVec3::Z,
                        target: DVec3::new(4.0, 0.0, 1.0),
                        up: Some((DVec3::Y, DVec3::Z)),
                    },
                    weight: 0.5,
                },
                Effector {
                    joint: 2,
                    goal: EffectorGoal::Orientation(DQuat::from_rotation_y(0.3)),
                    weight: 1.0,
                },
            ],
            centroid_effectors: vec![CentroidEffector {
                vertices: vec![3],
                target: DVec3::new(0.0, 2.0, 0.0),
                weight: 1.0,
            }],
            ..Default::default()
        };
        let moved = c.transformed(&to);
        let m = moved.handles[0].transform;
        for p in [DVec3::ZERO, DVec3::new(2.0, -1.0, 0.5)] {
            let a = to.transform_point3(motion.apply(p));
            let b = m.apply(to.transform_point3(p));
            assert!((a - b).length() < 1e-9, "{a} vs {b}");
        }
        let EffectorGoal::Aim { target, up, .. } = moved.effectors[0].goal else {
            panic!("an aim");
        };
        assert!((target - to.transform_point3(DVec3::new(4.0, 0.0, 1.0))).length() < 1e-12);
        let world_up = up.unwrap().1;
        assert!((world_up - rotation_of(&to.matrix3) * DVec3::Z).length() < 1e-12);
        let back = moved.transformed(&to.inverse());
        assert!(back.handles[0].transform.pivot.distance(motion.pivot) < 1e-9);
        assert!((back.handles[0].transform.translation - motion.translation).length() < 1e-9);
        assert!(
            back.centroid_effectors[0]
                .target
                .distance(DVec3::new(0.0, 2.0, 0.0))
                < 1e-9
        );
        let EffectorGoal::Orientation(q) = back.effectors[1].goal else {
            panic!("an orientation");
        };
        assert!(q.angle_between(DQuat::from_rotation_y(0.3)) < 1e-9);
    }
}
