//! Where the ground is and how a character's feet meet it: the game's ground as the pose
//! solver sees it (something a ray cast down hits), the contacts that stand a character on it,
//! the floor under the whole skin, and balance over the feet.
//!
//! | question | file |
//! |---|---|
//! | what a ground is: a ray cast along gravity ([`Ground`]); an infinite plane ([`GroundPlane`]) | `mod.rs` |
//! | any triangle mesh (terrain, stairs) as a ground, cast along gravity through a grid | `mesh.rs` ([`TriangleGround`]) |
//! | which joints a character stands on, and the skin patch (sole) under each | `feet.rs` ([`lowest_joints`], [`sole_patch`]) |
//! | one contact: a skin patch free above the ground or planted on it, raised, rolled flat | `contact.rs` ([`Contact`]) |
//! | every skin vertex near the ground kept above it (a plane per vertex, cast) | `floor.rs` ([`Floor`]) |
//! | the floor's coarse grid of casts on a lattice fixed to the ground, remembered frame to frame | `floor_grid.rs` ([`FloorMemory`]) |
//! | the centre of mass over the support polygon; the allowed region; leaning as a clip does | `balance.rs` ([`Balance`]) |
//! | contacts planted and released frame after frame; where a planted limb starts its solve | `tracker.rs` ([`ContactTracker`]) |
//! | when a walking clip has a foot down or up | `gait.rs` ([`GaitPhases`]) |
//!
//! The terms these become inside a solve are in `solver/terms/` (`ground.rs`, `floor_groups.rs`,
//! `moments.rs`, `raised_floor.rs`); the design and its figures are in `docs/design/ground.md`.
//!
//! [`TriangleGround`]: mesh::TriangleGround
//! [`lowest_joints`]: feet::lowest_joints
//! [`sole_patch`]: feet::sole_patch
//! [`Contact`]: contact::Contact
//! [`Floor`]: floor::Floor
//! [`FloorMemory`]: floor::FloorMemory
//! [`Balance`]: balance::Balance
//! [`ContactTracker`]: tracker::ContactTracker
//! [`GaitPhases`]: gait::GaitPhases

use glam::DVec3;

pub mod balance;
pub mod contact;
pub mod feet;
pub mod floor;
mod floor_grid;
pub mod gait;
pub mod mesh;
pub mod tracker;

pub use feet::{lowest_joints, sole_patch};
pub use mesh::TriangleGround;
pub use tracker::{ContactEvent, ContactTracker};

/// A surface a ray cast along gravity can hit.
pub trait Ground {
    /// The first surface below `from` along `down` (unit), within `max` (world units), as the
    /// hit point and the surface's normal there (facing against `down`).
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane>;

    /// A bound on how high the ground rises against `down` (unit) within `radius` of `centre`
    /// across it, as an elevation `-p·down` (`-∞` where there is no ground); `None` when the
    /// ground cannot say. [`floor::Floor::cast`] uses it to find ridges and steps between
    /// its casts; the default says nothing, and the floor then trusts its casts alone.
    fn highest_within(&self, _centre: DVec3, _radius: f64, _down: DVec3) -> Option<f64> {
        None
    }
}

impl Ground for GroundPlane {
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        let along = self.normal.dot(down);
        if along >= -1e-12 {
            return None; // parallel, or seen from below
        }
        let t = self.height(from) / -along;
        (0.0..=max).contains(&t).then_some(GroundPlane {
            point: from + down * t,
            normal: self.normal,
        })
    }
}

impl<F: Fn(DVec3, DVec3, f64) -> Option<GroundPlane>> Ground for F {
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        self(from, down, max)
    }
}

/// A plane of the ground: a point on it and its normal (unit, pointing out of the ground).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundPlane {
    /// A point on the ground.
    pub point: DVec3,
    /// The ground's normal, unit, pointing up out of it.
    pub normal: DVec3,
}

impl GroundPlane {
    /// A plane through `point` with `normal` (normalised); `None` when either is not finite or
    /// the normal is zero.
    pub fn new(point: DVec3, normal: DVec3) -> Option<Self> {
        let normal = normal.try_normalize()?;
        point.is_finite().then_some(Self { point, normal })
    }

    /// The least-squares plane through several ground hits, its normal turned to the side of
    /// `up`; `None` for fewer than three hits, non-finite ones, or hits on one line (then use
    /// one hit's own normal).
    pub fn fit(hits: &[DVec3], up: DVec3) -> Option<Self> {
        if hits.len() < 3 || !hits.iter().all(|p| p.is_finite()) {
            return None;
        }
        let centre = hits.iter().sum::<DVec3>() / hits.len() as f64;
        // The normal is the covariance's least eigenvector: the cross product of the two
        // spread directions, found as the largest of the rows' cross products.
        let mut cov = [[0.0f64; 3]; 3];
        for p in hits {
            let d = (*p - centre).to_array();
            for r in 0..3 {
                for c in 0..3 {
                    cov[r][c] += d[r] * d[c];
                }
            }
        }
        let rows = cov.map(DVec3::from_array);
        let candidates = [
            rows[0].cross(rows[1]),
            rows[0].cross(rows[2]),
            rows[1].cross(rows[2]),
        ];
        let normal = candidates
            .into_iter()
            .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
        let scale = rows.iter().map(|r| r.length_squared()).sum::<f64>();
        if normal.length_squared() <= 1e-18 * scale * scale {
            return None;
        }
        let normal = normal.normalize();
        let normal = if normal.dot(up) < 0.0 {
            -normal
        } else {
            normal
        };
        Self::new(centre, normal)
    }

    /// Height of `p` above the plane (negative below).
    pub fn height(&self, p: DVec3) -> f64 {
        self.normal.dot(p - self.point)
    }

    /// `p` moved along the normal onto the plane.
    pub fn project(&self, p: DVec3) -> DVec3 {
        p - self.normal * self.height(p)
    }
}
