//! The game's ground as the pose solver sees it: something a ray cast down hits, and the
//! automatic contacts that stand a character on it.
//!
//! * [`Ground`]: a ray cast along gravity that returns the surface hit with its normal. An
//!   infinite [`GroundPlane`], a [`TriangleGround`] (any triangle mesh — terrain, stairs — with
//!   a grid across gravity so a cast tests only the triangles under it), a closure, or the ECS
//!   layer's scene ray casts implement it.
//! * [`lowest_joints`] and [`sole_patch`]: the joints a character stands on (feet, paws, a
//!   single base) and the skin patch under each.
//! * [`ContactTracker`]: every frame, casts down from each patch, plants a contact whose patch
//!   comes within the plant height of the ground, releases one the pose lifts past the release
//!   height, and reports casts that hit nothing (the contact is free) or returned a non-finite
//!   hit (ignored, the contact keeps its last ground).

use glam::DVec3;

use super::contacts::{Contact, GroundPlane};
use super::gait::GaitPhases;
use super::model::SkinnedModel;
use super::skeleton::SkeletonPose;
pub use super::triangle_ground::TriangleGround;

/// A sole's thickness, as a share of the model's size (its bounding diagonal): a foot's patch
/// is its skin within this of its lowest vertex ([`sole_patch`] as the tracker uses it).
const SOLE_THICKNESS: f64 = 0.02;
/// How far a patch planted tilted turns onto the ground per update (radians; 20°): a paw put
/// down toe first at the crowd's 90th percentile, 50°, lies flat two updates after planting.
/// (At 10° the crowd's soles still rolling put its soles' p95 at 4°.)
const ROLL_STEP: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// A surface a ray cast along gravity can hit.
pub trait Ground {
    /// The first surface below `from` along `down` (unit), within `max` (world units), as the
    /// hit point and the surface's normal there (facing against `down`).
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane>;
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

/// The length of `v` across gravity (`down`, unit).
fn horizontal(v: DVec3, down: DVec3) -> f64 {
    (v - down * v.dot(down)).length()
}

/// The joints a character stands on in `pose`: those whose most-weighted vertices reach within
/// `tolerance` (world units) of the lowest skinned vertex along `down` (feet, paws, the base
/// of a one-joint prop), lowest first.
///
/// A joint above another chosen joint of its own leg whose skin stays more than a sole's
/// thickness (2 % of the model's size) higher is the leg over a foot — a
/// quadruped's raised hock, a shin — not a foot, and is left out: planted, it would be laid
/// on the ground it does not reach, against the foot under it. A heel and its toes (a biped's
/// foot and toe joints), both down, are both kept.
pub fn lowest_joints(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    down: DVec3,
    tolerance: f64,
) -> Vec<usize> {
    let skinned = model.skin_welded(pose);
    let mut deepest = vec![f64::NEG_INFINITY; model.skeleton().len()];
    for (v, inf) in model.influences().iter().enumerate() {
        let main = inf.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|i| i.0);
        if let Some(j) = main {
            deepest[j as usize] = deepest[j as usize].max(skinned[v].dot(down));
        }
    }
    let lowest = deepest.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let joints: Vec<usize> = (0..deepest.len())
        .filter(|&j| deepest[j] > f64::NEG_INFINITY && deepest[j] >= lowest - tolerance)
        .collect();
    let thickness = SOLE_THICKNESS * model.topology().bounding_diagonal();
    let skeleton = model.skeleton();
    let over_a_lower_foot = |j: usize| {
        joints
            .iter()
            .any(|&d| d != j && skeleton.descends_from(d, j) && deepest[d] > deepest[j] + thickness)
    };
    let mut feet: Vec<usize> = joints
        .iter()
        .copied()
        .filter(|&j| !over_a_lower_foot(j))
        .collect();
    feet.sort_by(|a, b| deepest[*b].total_cmp(&deepest[*a]));
    feet
}

/// The skin patch under `joint` in `pose`: its most-weighted vertices within `thickness` (world
/// units) of its lowest one along `down` (a sole).
pub fn sole_patch(
    model: &SkinnedModel,
    pose: &SkeletonPose,
    joint: usize,
    down: DVec3,
    thickness: f64,
) -> Vec<u32> {
    let skinned = model.skin_welded(pose);
    let carried: Vec<u32> = model
        .influences()
        .iter()
        .enumerate()
        .filter(|(_, inf)| {
            inf.iter()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .is_some_and(|i| i.0 as usize == joint && i.1 > 0.0)
        })
        .map(|(v, _)| v as u32)
        .collect();
    let lowest = carried
        .iter()
        .map(|&v| skinned[v as usize].dot(down))
        .fold(f64::NEG_INFINITY, f64::max);
    carried
        .into_iter()
        .filter(|&v| skinned[v as usize].dot(down) >= lowest - thickness)
        .collect()
}

/// What happened to one tracked contact in [`ContactTracker::update`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactEvent {
    /// Nothing changed.
    Unchanged,
    /// The patch came within the plant height: planted.
    Planted,
    /// The pose lifted the patch past the release height: released.
    Released,
    /// The character moved on while the patch stayed planted: it trailed more than the stride
    /// from where the character carries it, and was released to be planted again under it.
    Stepped,
    /// The cast hit nothing: the contact is free (no ground under it).
    NoGround,
    /// The cast returned a non-finite hit: ignored, the contact keeps its last ground.
    NonFiniteHit,
}

/// Automatic contacts of one character, planted and released frame after frame (see the
/// module docs).
#[derive(Debug, Clone)]
pub struct ContactTracker {
    /// The contacts (one per tracked joint), with their grounds and planted points.
    pub contacts: Vec<Contact>,
    /// Whether each contact has ground under it (its last cast hit something).
    pub grounded: Vec<bool>,
    /// Gravity (unit).
    pub down: DVec3,
    /// A patch whose lowest vertex comes this close to the ground is planted (world units).
    pub plant_height: f64,
    /// A planted patch lifted entirely above this height is released (world units).
    pub release_height: f64,
    /// How far above the patch a cast starts, and how far below it it reaches.
    pub reach: f64,
    /// A planted patch whose centroid is this far (across gravity) from where the character
    /// carries it ([`ContactTracker::home`]), or from where the pose a solve starts from puts
    /// it (an animation's step), is released: the character walked on (world units).
    pub stride: f64,
    /// Each patch's centroid where the character carries it, in the pose the tracker was made
    /// for (character space).
    pub home: Vec<DVec3>,
    /// A patch planted above the ground after the first update is lowered onto it by at most
    /// this much per update ([`Contact::landing`], world units); the first stance is laid on
    /// the ground at once.
    pub landing_step: f64,
    /// A patch planted tilted after the first update turns onto the ground by at most this
    /// much per update ([`Contact::plant_rolling`], radians); the first stance is laid flat at
    /// once.
    pub roll_step: f64,
    /// Updates so far.
    pub updates: u64,
    /// When an animation has a foot down or up ([`ContactTracker::update_guided`]).
    pub gait: GaitPhases,
}

impl ContactTracker {
    /// Tracks `joints` of `model` (their sole patches in `pose`, their up the way up is in
    /// each joint's frame in `pose`: [`Contact::up`]), with heights as fractions of
    /// the model's size: a patch within 8 % of the ground is planted (laid on it: a foot over a
    /// lower step or downhill comes down to it, as foot placement does), one lifted more than
    /// 12 % is released, one the character has walked 15 % away from is released to be planted
    /// again under it; casts reach 50 %; a patch planted above the ground comes down 0.5 % of
    /// the size per update.
    pub fn new(model: &SkinnedModel, pose: &SkeletonPose, joints: &[usize], down: DVec3) -> Self {
        let down = down.try_normalize().unwrap_or(DVec3::NEG_Y);
        let size = model.topology().bounding_diagonal();
        let globals = model
            .skeleton()
            .global_transforms(&model.skeleton().bind_pose());
        let contacts = joints
            .iter()
            .map(|&j| {
                let patch = sole_patch(model, pose, j, down, SOLE_THICKNESS * size);
                let mut contact = Contact::new(
                    j,
                    patch,
                    GroundPlane {
                        point: DVec3::ZERO,
                        normal: -down,
                    },
                );
                // The foot's up: the way up is in the joint's own frame in the pose the
                // character stands in (a joint's axes follow its bone, seldom the world's up;
                // a converter's bind pose may lie on its back).
                contact.up = globals
                    .get(j)
                    .filter(|g| g.matrix3.determinant().abs() > 1e-12)
                    .and_then(|g| (g.matrix3.inverse() * -down).try_normalize())
                    .or(contact.up);
                contact
            })
            .collect::<Vec<_>>();
        let skinned = model.skin_welded(pose);
        let home = contacts
            .iter()
            .map(|c| {
                c.patch.iter().map(|&v| skinned[v as usize]).sum::<DVec3>()
                    / c.patch.len().max(1) as f64
            })
            .collect();
        Self {
            home,
            stride: 0.15 * size,
            grounded: vec![false; contacts.len()],
            contacts,
            down,
            plant_height: 0.08 * size,
            release_height: 0.12 * size,
            reach: 0.5 * size,
            landing_step: 0.005 * size,
            roll_step: ROLL_STEP,
            updates: 0,
            gait: GaitPhases::new(&skinned, down, size),
        }
    }

    /// Casts down from each patch of `model` in `pose` onto `ground`, updates grounds, plants
    /// and releases; returns what happened to each contact. A patch planted (or lowered while
    /// landing) on the plane under its centre is raised out of the ground where the ground
    /// under it is not that plane ([`Contact::raise_onto`]: one cast per patch vertex).
    pub fn update(
        &mut self,
        model: &SkinnedModel,
        pose: &SkeletonPose,
        ground: &dyn Ground,
    ) -> Vec<ContactEvent> {
        let skinned = model.skin_welded(pose);
        self.update_guided(model, (pose, &skinned), None, ground)
    }

    /// [`ContactTracker::update`] for a pose added to an animation (`animation`: the clip's
    /// pose under the layer): a planted patch the clip lifts is released, a free one plants
    /// only while the clip has it down ([`super::gait`]); where it plants is still decided on
    /// the ground, from `pose` (`skinned`: its welded skin, `model.skin_welded(pose)`, which
    /// the caller usually has for the floor too).
    pub fn update_guided(
        &mut self,
        model: &SkinnedModel,
        (pose, skinned): (&SkeletonPose, &[DVec3]),
        animation: Option<&SkeletonPose>,
        ground: &dyn Ground,
    ) -> Vec<ContactEvent> {
        let phases = animation.and_then(|a| {
            let patches: Vec<&[u32]> = self.contacts.iter().map(|c| &c.patch[..]).collect();
            self.gait.heights(model, a, &patches, self.down)
        });
        let globals = model.skeleton().global_transforms(pose);
        let mut events = Vec::with_capacity(self.contacts.len());
        let first = self.updates == 0;
        self.updates += 1;
        for (k, ((c, grounded), home)) in self
            .contacts
            .iter_mut()
            .zip(&mut self.grounded)
            .zip(&self.home)
            .enumerate()
        {
            // The clip's phase for this patch: lifted, down, or between (no guide: down).
            let clip_height = phases.as_ref().map_or(0.0, |h| h[k]);
            let patch: Vec<DVec3> = c.patch.iter().map(|&v| skinned[v as usize]).collect();
            if patch.is_empty() {
                events.push(ContactEvent::NoGround);
                continue;
            }
            let centre = patch.iter().sum::<DVec3>() / patch.len() as f64;
            // Walked on: a planted patch left behind — by the character's motion (from where
            // it carries the patch at rest) or by the animation the solve starts from (from
            // where the clip puts the paw) — is released, to be planted again under it.
            if let Some(planted) = &c.planted {
                let held = planted.iter().sum::<DVec3>() / planted.len().max(1) as f64;
                // (With a clip the clip's lift ends a stance; the rest pose says nothing.)
                let trailing =
                    phases.is_none() && horizontal(held - *home, self.down) > self.stride;
                if trailing || horizontal(held - centre, self.down) > self.stride {
                    c.release();
                    events.push(ContactEvent::Stepped);
                    continue;
                }
            }
            let from = centre - self.down * self.reach;
            let event = match ground.cast_down(from, self.down, 2.0 * self.reach) {
                None => {
                    *grounded = false;
                    c.release();
                    ContactEvent::NoGround
                }
                Some(hit) if !(hit.point.is_finite() && hit.normal.is_finite()) => {
                    ContactEvent::NonFiniteHit
                }
                Some(hit) => match GroundPlane::new(hit.point, hit.normal) {
                    None => ContactEvent::NonFiniteHit,
                    Some(plane) => {
                        // A planted contact keeps the ground it was planted on.
                        if c.planted.is_none() {
                            c.ground = plane;
                        }
                        *grounded = true;
                        let lowest = patch
                            .iter()
                            .map(|p| c.ground.height(*p))
                            .fold(f64::INFINITY, f64::min);
                        match &c.planted {
                            Some(_)
                                if c.lifted(&patch, self.release_height)
                                    || clip_height > self.gait.lift =>
                            {
                                c.release();
                                ContactEvent::Released
                            }
                            Some(_) => {
                                // Rolled about its pivot and lowered along the plane's
                                // normal: kept out of the ground where it is not that plane.
                                let rolled = c.roll(self.roll_step);
                                if rolled || c.landing > 0.0 {
                                    c.descend(self.landing_step);
                                    c.raise_onto(ground, self.down, self.reach);
                                }
                                ContactEvent::Unchanged
                            }
                            // Without a clip, a patch a step released plants again once
                            // the body has carried it back within half a stride (no plant
                            // where it trails); with one, when the clip puts it down.
                            None if lowest <= self.plant_height
                                && clip_height <= self.gait.touch
                                && (phases.is_some()
                                    || horizontal(centre - *home, self.down)
                                        <= 0.5 * self.stride) =>
                            {
                                let up = c.up.map(|u| {
                                    (globals[c.joint].matrix3 * u).normalize_or(-self.down)
                                });
                                if first {
                                    c.plant(&patch, up);
                                } else {
                                    c.plant_rolling(&patch, up, self.roll_step);
                                }
                                c.raise_onto(ground, self.down, self.reach);
                                ContactEvent::Planted
                            }
                            _ => ContactEvent::Unchanged,
                        }
                    }
                },
            };
            events.push(event);
        }
        events
    }

    /// The contacts that have ground under them (to hand to the solve).
    pub fn active(&self) -> Vec<Contact> {
        self.contacts
            .iter()
            .zip(&self.grounded)
            .filter(|(_, g)| **g)
            .map(|(c, _)| c.clone())
            .collect()
    }

    /// The planted patches' points (the support polygon's corners for [`super::Balance`]).
    pub fn support(&self) -> Vec<DVec3> {
        self.contacts
            .iter()
            .filter_map(|c| c.planted.as_ref())
            .flatten()
            .copied()
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_and_a_closure_are_grounds() {
        let plane = GroundPlane::new(DVec3::ZERO, DVec3::new(0.0, 1.0, 0.5)).unwrap();
        let hit = plane
            .cast_down(DVec3::new(0.0, 2.0, 0.0), DVec3::NEG_Y, 5.0)
            .unwrap();
        assert!(plane.height(hit.point).abs() < 1e-12);
        let nothing = |_: DVec3, _: DVec3, _: f64| None;
        assert_eq!(nothing.cast_down(DVec3::ZERO, DVec3::NEG_Y, 1.0), None);
    }
}
