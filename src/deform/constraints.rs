//! Positional constraints: fixed vertices, rigid handles and free-form targets.

use glam::{DQuat, DVec3};

/// A rigid motion about a pivot: `p' = pivot + rotation · (p − pivot) + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidTransform {
    /// Rotation about the pivot.
    pub rotation: DQuat,
    /// Translation applied after the rotation.
    pub translation: DVec3,
    /// Centre of rotation (usually the handle's rest centroid).
    pub pivot: DVec3,
}

impl Default for RigidTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl RigidTransform {
    /// No motion.
    pub const IDENTITY: Self = Self {
        rotation: DQuat::IDENTITY,
        translation: DVec3::ZERO,
        pivot: DVec3::ZERO,
    };

    /// A rotation about `pivot` followed by a translation.
    pub fn new(rotation: DQuat, translation: DVec3, pivot: DVec3) -> Self {
        Self {
            rotation,
            translation,
            pivot,
        }
    }

    /// Applies the motion to a point.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.pivot + self.rotation * (p - self.pivot) + self.translation
    }

    /// True when every component is finite and the rotation is a unit quaternion.
    pub fn is_valid(&self) -> bool {
        self.rotation.is_finite()
            && (self.rotation.length() - 1.0).abs() < 1e-6
            && self.translation.is_finite()
            && self.pivot.is_finite()
    }
}

/// A set of vertices moved rigidly.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Handle {
    /// Welded vertex indices of the handle.
    pub vertices: Vec<u32>,
    /// Current rigid transform of the handle.
    pub transform: RigidTransform,
}

/// Everything pinned during a solve.
///
/// The *sets* (which vertices are fixed, which belong to each handle, which have targets)
/// determine the factorization; the *values* (handle transforms, target positions) can change
/// every frame at the cost of a back-substitution only. A vertex may appear in at most one
/// set ([`ConstraintError::Overlap`] otherwise).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Constraints {
    /// Vertices held at their rest position.
    pub fixed: Vec<u32>,
    /// Rigid handles.
    pub handles: Vec<Handle>,
    /// Individual vertices with explicit target positions.
    pub targets: Vec<(u32, DVec3)>,
}

/// Invalid constraints.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConstraintError {
    /// A constrained vertex index is not a vertex of the mesh.
    #[error("constrained vertex {vertex} is out of range for {vertex_count} vertices")]
    OutOfRange {
        /// The index.
        vertex: u32,
        /// Number of welded vertices.
        vertex_count: usize,
    },
    /// A vertex is in two sets (e.g. fixed and a handle).
    #[error("vertex {vertex} is constrained twice (fixed/handle/target sets must not overlap)")]
    Overlap {
        /// The vertex.
        vertex: u32,
    },
    /// A handle transform or target is NaN/infinite or its rotation is not unit length.
    #[error("a handle transform or target position is not finite (or the rotation is not unit)")]
    NonFinite,
    /// The region of interest mask has the wrong length.
    #[error("region of interest has {got} entries, the mesh has {expected} vertices")]
    RegionLength {
        /// Mask length given.
        got: usize,
        /// Vertex count.
        expected: usize,
    },
}

/// True when `a` and `b` have the same length and equal `key`s in the same order (the sets
/// of two constraint lists match, whatever their values).
pub(crate) fn same_keys<T, K: PartialEq + ?Sized>(
    a: &[T],
    b: &[T],
    key: impl Fn(&T) -> &K,
) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| key(x) == key(y))
}

/// Role of a vertex in a constraint set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    Free,
    Fixed,
    Handle(u32),
    Target(u32),
}

impl Constraints {
    /// These constraints given in *render* (input) vertex indices, mapped to the welded
    /// indices of `topology`. Several render vertices of one welded vertex count once; a target
    /// given for several of them keeps the first. A render index out of range is
    /// [`ConstraintError::OutOfRange`] (with the render vertex count).
    pub fn from_render(&self, topology: &super::Topology) -> Result<Constraints, ConstraintError> {
        let map = topology.render_to_welded();
        let check = |v: u32| {
            if (v as usize) < map.len() {
                Ok(())
            } else {
                Err(ConstraintError::OutOfRange {
                    vertex: v,
                    vertex_count: map.len(),
                })
            }
        };
        let all = self
            .fixed
            .iter()
            .chain(self.handles.iter().flat_map(|h| &h.vertices))
            .chain(self.targets.iter().map(|(v, _)| v));
        for &v in all {
            check(v)?;
        }
        let mut targets: Vec<(u32, DVec3)> = Vec::with_capacity(self.targets.len());
        let mut taken = vec![false; topology.vertex_count()];
        for &(v, p) in &self.targets {
            let w = map[v as usize];
            if !std::mem::replace(&mut taken[w as usize], true) {
                targets.push((w, p));
            }
        }
        Ok(Constraints {
            fixed: topology.welded_set(&self.fixed),
            handles: self
                .handles
                .iter()
                .map(|h| Handle {
                    vertices: topology.welded_set(&h.vertices),
                    transform: h.transform,
                })
                .collect(),
            targets,
        })
    }

    /// Creates constraints with a fixed set and one handle.
    pub fn with_handle(fixed: Vec<u32>, handle: Vec<u32>, transform: RigidTransform) -> Self {
        Self {
            fixed,
            handles: vec![Handle {
                vertices: handle,
                transform,
            }],
            targets: Vec::new(),
        }
    }

    /// True when no vertex is constrained.
    pub fn is_empty(&self) -> bool {
        self.fixed.is_empty()
            && self.handles.iter().all(|h| h.vertices.is_empty())
            && self.targets.is_empty()
    }

    /// True when `other` constrains exactly the same vertex sets (values may differ), so a
    /// factorization built for one serves the other.
    pub fn same_sets(&self, other: &Self) -> bool {
        self.fixed == other.fixed
            && same_keys(&self.handles, &other.handles, |h| &h.vertices)
            && same_keys(&self.targets, &other.targets, |t| &t.0)
    }

    /// How far the constraints move any constrained vertex from its position in `rest`
    /// (welded positions; indices out of range are skipped, non-finite values give NaN): how
    /// far an edit is from its rest pose, e.g. to choose where its iterations start.
    pub fn largest_displacement(&self, rest: &[DVec3]) -> f64 {
        let handles = self.handles.iter().flat_map(|h| {
            h.vertices.iter().filter_map(|&v| {
                let p = *rest.get(v as usize)?;
                Some(h.transform.apply(p).distance(p))
            })
        });
        let targets = self
            .targets
            .iter()
            .filter_map(|&(v, t)| Some(t.distance(*rest.get(v as usize)?)));
        handles.chain(targets).fold(0.0, |a: f64, d| {
            if a.is_nan() || d.is_nan() {
                f64::NAN
            } else {
                a.max(d)
            }
        })
    }

    /// Validates the constraints against a mesh with `n` vertices and returns each vertex'
    /// role.
    pub(crate) fn roles(&self, n: usize) -> Result<Vec<Role>, ConstraintError> {
        let mut roles = vec![Role::Free; n];
        let mut set = |v: u32, role: Role| -> Result<(), ConstraintError> {
            let slot = roles
                .get_mut(v as usize)
                .ok_or(ConstraintError::OutOfRange {
                    vertex: v,
                    vertex_count: n,
                })?;
            if *slot != Role::Free && *slot != role {
                return Err(ConstraintError::Overlap { vertex: v });
            }
            *slot = role;
            Ok(())
        };
        for &v in &self.fixed {
            set(v, Role::Fixed)?;
        }
        for (h, handle) in self.handles.iter().enumerate() {
            for &v in &handle.vertices {
                set(v, Role::Handle(h as u32))?;
            }
        }
        for (t, &(v, _)) in self.targets.iter().enumerate() {
            set(v, Role::Target(t as u32))?;
        }
        Ok(roles)
    }

    /// Checks that every value (transforms, targets) is finite.
    pub(crate) fn check_values(&self) -> Result<(), ConstraintError> {
        let handles_ok = self.handles.iter().all(|h| h.transform.is_valid());
        let targets_ok = self.targets.iter().all(|(_, p)| p.is_finite());
        if handles_ok && targets_ok {
            Ok(())
        } else {
            Err(ConstraintError::NonFinite)
        }
    }

    /// Position of a constrained vertex under these constraints.
    pub(crate) fn position_of(&self, role: Role, rest: DVec3) -> DVec3 {
        match role {
            Role::Free | Role::Fixed => rest,
            Role::Handle(h) => self.handles[h as usize].transform.apply(rest),
            Role::Target(t) => self.targets[t as usize].1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_displacement_measures_handles_and_targets() {
        let rest = [DVec3::ZERO, DVec3::X, DVec3::new(0.0, 2.0, 0.0)];
        let mut c = Constraints::with_handle(
            vec![0],
            vec![1],
            RigidTransform::new(DQuat::IDENTITY, DVec3::new(0.0, 0.3, 0.0), DVec3::ZERO),
        );
        assert!((c.largest_displacement(&rest) - 0.3).abs() < 1e-15);
        // A rotation about the pivot moves the handle vertex by |2 sin(θ/2)| · radius.
        c.handles[0].transform = RigidTransform::new(
            DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
            DVec3::ZERO,
            DVec3::ZERO,
        );
        let expected = 2.0 * (std::f64::consts::FRAC_PI_4).sin();
        assert!((c.largest_displacement(&rest) - expected).abs() < 1e-12);
        c.targets.push((2, DVec3::new(0.0, 4.0, 0.0)));
        assert!((c.largest_displacement(&rest) - 2.0).abs() < 1e-15);
        // NaN anywhere (here in the handle, before a finite target) is reported.
        c.handles[0].transform.translation.x = f64::NAN;
        assert!(c.largest_displacement(&rest).is_nan());
        assert_eq!(Constraints::default().largest_displacement(&rest), 0.0);
    }

    #[test]
    fn rigid_transform_rotates_about_pivot() {
        let t = RigidTransform::new(
            DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
        );
        let p = t.apply(DVec3::new(2.0, 0.0, 0.0));
        assert!((p - DVec3::new(1.0, 1.0, 1.0)).length() < 1e-12);
        assert!(t.apply(t.pivot).abs_diff_eq(t.pivot + t.translation, 1e-12));
    }

    #[test]
    fn overlap_and_range_are_errors() {
        let c = Constraints::with_handle(vec![0, 1], vec![1, 2], RigidTransform::IDENTITY);
        assert_eq!(
            c.roles(5).unwrap_err(),
            ConstraintError::Overlap { vertex: 1 }
        );
        let c = Constraints::with_handle(vec![0], vec![7], RigidTransform::IDENTITY);
        assert!(matches!(
            c.roles(5).unwrap_err(),
            ConstraintError::OutOfRange { vertex: 7, .. }
        ));
        // A vertex repeated inside one set is fine.
        let c = Constraints::with_handle(vec![0, 0], vec![2], RigidTransform::IDENTITY);
        assert!(c.roles(5).is_ok());
    }

    #[test]
    fn nan_values_are_rejected() {
        let mut c = Constraints::with_handle(vec![0], vec![1], RigidTransform::IDENTITY);
        assert!(c.check_values().is_ok());
        c.handles[0].transform.translation.x = f64::NAN;
        assert_eq!(c.check_values(), Err(ConstraintError::NonFinite));
        c.handles[0].transform = RigidTransform::IDENTITY;
        c.handles[0].transform.rotation = DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0);
        assert_eq!(c.check_values(), Err(ConstraintError::NonFinite));
    }

    #[test]
    fn same_sets_ignores_values() {
        let a = Constraints::with_handle(vec![0], vec![1], RigidTransform::IDENTITY);
        let mut b = a.clone();
        b.handles[0].transform.translation = DVec3::X;
        assert!(a.same_sets(&b));
        b.handles[0].vertices.push(2);
        assert!(!a.same_sets(&b));
    }
}
