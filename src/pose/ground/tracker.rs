//! The per-frame contact tracker ([`ContactTracker`]): every frame it casts down from each
//! foot's patch, plants a contact whose patch comes within the plant height of the ground,
//! releases one the pose lifts past the release height, and reports casts that hit nothing
//! (the contact is free) or returned a non-finite hit (ignored, the contact keeps its last
//! ground).
//!
//! ## Where a planted limb starts
//!
//! Under an additive layer a solve starts each frame from the animation's new pose with the
//! last layer added ([`crate::pose::animation::blend::blend_pose`]). For a limb whose foot is planted that start
//! is a poor guess: the layer was solved against last frame's animation, and the clip moves the
//! stance leg on (at its own speed, on flat ground), so the start puts a planted paw 1–2 % of
//! the model's size off the points it is held at, and the solve spends its iterations bringing
//! it back (the figures are in `docs/design/ground.md`).
//!
//! [`ContactTracker::carry_planted_limbs`] starts a planted limb where the last solve left it
//! instead — its joints' rotations as solved — and re-aims it at its holds as the character
//! moved since: the limb's top joint turned so that the patch points at the held points, the
//! contact's joint turned back so that the sole keeps its tilt. It only moves the start: the
//! solve still meets the holds, the floor, the limits and balance itself.

use crate::pose::ground::contact::Contact;
use crate::pose::ground::feet::{SOLE_THICKNESS, horizontal, sole_patch};
use crate::pose::ground::gait::GaitPhases;
use crate::pose::ground::{Ground, GroundPlane};

use crate::pose::rig::model::SkinnedModel;
use crate::pose::rig::skeleton::SkeletonPose;
use glam::{DQuat, DVec3};

/// How far a patch planted tilted turns onto the ground per update (radians; 20°): a paw put
/// down toe first at the crowd's 90th percentile, 50°, lies flat two updates after planting.
/// (At 10° the crowd's soles still rolling put its soles' p95 at 4°.)
const ROLL_STEP: f64 = 20.0 * std::f64::consts::PI / 180.0;

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
    /// only while the clip has it down ([`crate::pose::ground::gait`]); where it plants is still decided on
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

    /// The planted patches' points (the support polygon's corners for [`crate::pose::ground::balance::Balance`]).
    pub fn support(&self) -> Vec<DVec3> {
        self.contacts
            .iter()
            .filter_map(|c| c.planted.as_ref())
            .flatten()
            .copied()
            .collect()
    }
}

/// The largest re-aim of a limb's top joint, radians: a hold far from where the limb points (a
/// first frame, a teleport) is left to the solve.
const MAX_REAIM: f64 = 0.35;

impl ContactTracker {
    /// Starts every planted contact's limb (its joint's subtree and the chain above it up to
    /// the first joint with other children, never the root) at its rotations in `last` (the
    /// last solved pose of `model`), re-aimed at the contact's held points (see the module
    /// docs). Returns how many limbs were carried; `start` is left as it was when `last` is
    /// not a finite pose of the same skeleton, or a carried start would not be finite, and a
    /// contact whose patch is not the model's is skipped.
    pub fn carry_planted_limbs(
        &self,
        model: &SkinnedModel,
        last: &SkeletonPose,
        start: &mut SkeletonPose,
    ) -> usize {
        let skeleton = model.skeleton();
        let joints = skeleton.len();
        if last.local.len() != joints
            || start.local.len() != joints
            || !last.local.iter().all(|t| t.is_valid())
        {
            return 0;
        }
        let before = start.clone();
        let vertices = model.bind_positions().len();
        let mut carried = 0;
        for contact in &self.contacts {
            let Some(held) = contact.planted.as_deref() else {
                continue;
            };
            if contact.patch.iter().any(|&v| v as usize >= vertices) {
                continue; // a patch of another model
            }
            let Some(top) = limb_top(skeleton, contact.joint) else {
                continue;
            };
            let mut stack = vec![contact.joint];
            while let Some(j) = stack.pop() {
                start.local[j].rotation = last.local[j].rotation;
                stack.extend_from_slice(skeleton.children(j));
            }
            let mut j = contact.joint;
            while j != top {
                j = skeleton.joints()[j].parent.unwrap_or(top);
                start.local[j].rotation = last.local[j].rotation;
            }
            if held.len() == contact.patch.len() && !held.is_empty() {
                reaim(model, (top, contact.joint), (&contact.patch, held), start);
            }
            carried += 1;
        }
        if !start.local.iter().all(|t| t.is_valid()) {
            *start = before;
            return 0;
        }
        carried
    }
}

/// The top joint of `joint`'s limb: the highest ancestor (or `joint` itself) reached without
/// passing a joint that carries other children too; `None` for a root joint (its limb would be
/// the whole body).
fn limb_top(skeleton: &crate::pose::rig::skeleton::Skeleton, joint: usize) -> Option<usize> {
    let joints = skeleton.joints();
    let mut top = joint;
    joints.get(joint)?.parent?;
    while let Some(parent) = joints[top].parent {
        if joints[parent].parent.is_none() || skeleton.children(parent).len() > 1 {
            break;
        }
        top = parent;
    }
    Some(top)
}

/// Turns the limb's `top` joint about its origin so that the patch's centroid points where its
/// held points' centroid is (at most [`MAX_REAIM`]), and the contact's `joint` back by as much
/// (its sole keeps its tilt).
fn reaim(
    model: &SkinnedModel,
    (top, joint): (usize, usize),
    (patch, held): (&[u32], &[DVec3]),
    start: &mut SkeletonPose,
) {
    let skeleton = model.skeleton();
    let globals = skeleton.global_transforms(start);
    let origin = globals[top].translation;
    let at = model.skinned_centroid(start, patch) - origin;
    let goal = held.iter().sum::<DVec3>() / held.len() as f64 - origin;
    let (Some(from), Some(to)) = (at.try_normalize(), goal.try_normalize()) else {
        return;
    };
    let turn = DQuat::from_rotation_arc(from, to);
    let angle = turn.angle_between(DQuat::IDENTITY);
    if !angle.is_finite() || angle < 1e-9 {
        return;
    }
    let turn = match angle > MAX_REAIM {
        true => DQuat::IDENTITY.slerp(turn, MAX_REAIM / angle),
        false => turn,
    };
    // A world-space turn at a joint is its parent's frame's conjugate of it, locally.
    let parent = skeleton.parent_rotation(&globals, top);
    let local = &mut start.local[top].rotation;
    *local = (parent.inverse() * turn * parent * *local).normalize();
    if joint != top {
        let globals = skeleton.global_transforms(start);
        let parent = skeleton.parent_rotation(&globals, joint);
        let local = &mut start.local[joint].rotation;
        *local = (parent.inverse() * turn.inverse() * parent * *local).normalize();
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
