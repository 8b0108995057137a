//! The Jacobians of the two-sided terms (effectors, centroids, stiffness) in the bone
//! parameters: one 3 × 3 block per residual 3-vector, for the parameters that move the term.

use glam::{DAffine3, DMat3, DVec3, DVec4};

use crate::pose::rig::skin::apply;
use crate::pose::solver::params::Param;
use crate::pose::solver::terms::{ExtraTerms, Rows, Term, outer, skew};

impl ExtraTerms<'_> {
    /// The Jacobian blocks (one 3 × 3 per residual 3-vector) of a two-sided term for one
    /// parameter.
    pub(super) fn jacobian(
        &self,
        term: &Term,
        param: Param,
        globals: &[DAffine3],
        skinning: &[DAffine3],
    ) -> Option<Rows<DMat3>> {
        let l = self.length_scale;
        let (a, rotation) = match param {
            Param::Rotation(a) => (a, true),
            Param::Translation(a) => (a, false),
        };
        let origin = globals[a].translation;
        // d(point) for a point moved rigidly with joint `a`'s subtree.
        let point = |p: DVec3| {
            if rotation {
                -skew(p - origin)
            } else {
                DMat3::IDENTITY
            }
        };
        // d(direction) for a direction turned with the subtree.
        let direction = |d: DVec3| if rotation { -skew(d) } else { DMat3::ZERO };
        match term {
            Term::Position { joint, .. } => self
                .moves(a, *joint)
                .then(|| Rows::of(&[point(globals[*joint].translation)])),
            Term::Orientation { joint, .. } => self.moves(a, *joint).then(|| {
                let r = Self::rotation(globals, *joint);
                Rows::of(&[r.x_axis, r.y_axis, r.z_axis].map(|c| direction(c) * l))
            }),
            Term::Aim {
                joint,
                axis,
                target,
                up,
                ..
            } => self.moves(a, *joint).then(|| {
                let r = Self::rotation(globals, *joint);
                let d = r * *axis;
                let to = *target - globals[*joint].translation;
                let dist = to.length().max(1e-9);
                let u = to / dist;
                let project = DMat3::IDENTITY - outer(u, u);
                // r = d − u; du = −P dp / dist.
                let change =
                    (direction(d) + project * point(globals[*joint].translation) / dist) * l;
                let mut out = Rows::of(&[change]);
                if up.is_some() {
                    let e = r * up.map_or(DVec3::Y, |u| u.0);
                    out.push(direction(e) * l);
                }
                out
            }),
            Term::Centroid { sums, .. } => self
                .centroid_jacobian(sums, a, rotation, origin, skinning)
                .map(|b| Rows::of(&[b])),
            // Summed elsewhere: a vertex along its ground's normal (`moments.rs`), balance as
            // rank-one parts (`system.rs`).
            Term::Above { .. } | Term::Balance { .. } => None,
            Term::Stiffness {
                joint,
                root_translation,
                ..
            } => {
                // Only the joint's own parameters: an ancestor turns the joint and its goal
                // together, so the residual turns rigidly and its length does not change — no
                // gradient and no curvature (the Gauss–Newton blocks `JᵀJ` it would add are
                // spurious stiffness on the ancestors). A translation is a root's own, and
                // counts only where the term holds the root's position.
                if a != *joint || (!rotation && root_translation.is_none()) {
                    return None;
                }
                let mut out = if rotation {
                    let r = Self::rotation(globals, *joint);
                    Rows::of(&[r.x_axis, r.y_axis, r.z_axis].map(|c| direction(c) * l))
                } else {
                    Rows::of(&[DMat3::ZERO; 3])
                };
                if root_translation.is_some() {
                    out.push(point(globals[*joint].translation));
                }
                Some(out)
            }
        }
    }

    /// The change of the weighted centroid `Σ_j S_j m_j` under parameter `a` (a rotation about
    /// `origin`, or a root's translation); `None` when no joint it moves has a share.
    pub(super) fn centroid_jacobian(
        &self,
        sums: &[(usize, DVec4)],
        a: usize,
        rotation: bool,
        origin: DVec3,
        skinning: &[DAffine3],
    ) -> Option<DMat3> {
        let mut moved = DVec3::ZERO;
        let mut mass = 0.0;
        for &(j, m) in sums.iter().filter(|(j, _)| self.moves(a, *j)) {
            moved += apply(&skinning[j], m);
            mass += m.w;
        }
        carried_change((moved, mass), rotation, origin)
    }
}

/// The change of the part of a weighted centroid a parameter carries — its skinned sum
/// `moved` and its weight `mass` — under the parameter: a turn about `origin`, or a root's
/// translation; `None` when it carries none of it.
pub(super) fn carried_change(
    (moved, mass): (DVec3, f64),
    rotation: bool,
    origin: DVec3,
) -> Option<DMat3> {
    (mass != 0.0).then(|| match rotation {
        true => -skew(moved - origin * mass),
        false => DMat3::IDENTITY * mass,
    })
}
