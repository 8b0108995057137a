//! A character standing on the scene's ground: its automatic contacts, the floor under it and
//! its balance, added to the constraints of a solve (in character space).

use glam::{DAffine3, DVec3};

use super::super::{GroundContactState, PoseBalance, PoseGround, PoseStatus, PosedSkeleton};
use super::state::GroundContacts;
use crate::ecs::SceneGround;
use crate::pose::{
    Balance, ContactTracker, Floor, FloorMemory, FloorSampling, Ground, GroundPlane,
    PoseConstraints, SkeletonPose, SkinnedModel, SupportPolygon, THROUGH_THE_GROUND,
    centre_of_mass, lowest_joints,
};

/// Adds to `constraints` (character space) the character's ground contacts — found on the
/// first call, cast on `ground` (world space) from the patches as `pose` carries them, planted
/// and released (when the animation under an additive layer, `constraints.shape_rest`, puts a
/// foot down or lifts it) — the floor under its skin and, with `balance`, the centre of mass over the
/// planted patches.
pub(super) fn stand_on(
    constraints: &mut PoseConstraints,
    (contacts, posed, pose): Standee<'_>,
    (settings, balance): (&PoseGround, Option<&PoseBalance>),
    ground: &SceneGround,
) -> Standing {
    let GroundContacts { tracker, floor } = contacts;
    let at = CharacterGround::new(ground, posed.placement);
    let (to_world, to_character, down) = (at.to_world, at.to_character, at.down);
    let cast = |from: DVec3, along: DVec3, max: f64| at.cast(from, along, max);
    let model = &posed.model;
    let size = model.topology().bounding_diagonal();
    let (tracker, placed_at) = tracker.get_or_insert_with(|| {
        let tolerance = f64::from(settings.feet_tolerance) * size;
        let feet = lowest_joints(model, pose.pose(), down, tolerance);
        (
            ContactTracker::new(model, pose.pose(), &feet, down),
            to_world,
        )
    });
    if *placed_at != to_world {
        // The character moved: planted patches stay where they touched in the world.
        follow_the_world(tracker, &(to_character * *placed_at));
        *placed_at = to_world;
    }
    let pose: &SkeletonPose = match pose {
        StartPose::Held(pose) => pose,
        StartPose::Given { pose, last } => {
            if let Some(last) = last {
                tracker.carry_planted_limbs(model, last, pose);
            }
            pose
        }
    };
    // One skin for the contacts and the floor. Under an additive layer the clip decides when
    // a foot is down (`pose::gait`).
    let skinned = model.skin_welded(pose);
    let clip = constraints.shape_rest.as_ref();
    let events = tracker.update_guided(model, (pose, &skinned), clip, &cast);
    let planted_now = events
        .iter()
        .filter(|e| **e == crate::pose::ContactEvent::Planted)
        .count() as u32;
    constraints.contacts = tracker.active();
    // Every skin vertex near the ground under it kept above it (a plane per vertex: terrain).
    let memory = remembered_on(floor, ground);
    constraints.floor = Some(at.floor_under(&at.in_world(&skinned), settings, size, memory));
    let support = tracker.support();
    let corners = support
        .iter()
        .max_by(|a, b| a.dot(down).total_cmp(&b.dot(down)))
        .map_or(Vec::new(), |lowest| {
            SupportPolygon::new(&support, down).corners_at(*lowest)
        });
    if let Some(b) = balance
        && !support.is_empty()
    {
        let margin = f64::from(b.margin.max(0.0)) * size;
        constraints.balance = Some(Balance {
            lean: clip.map_or(0.0, |clip| clip_lean(model, clip, &support, down, margin)),
            support,
            gravity: down,
            margin,
            weight: f64::from(b.weight.clamp(0.0, 1.0)),
            masses: None,
        });
    } else {
        constraints.balance = None;
    }
    let planted = tracker
        .contacts
        .iter()
        .filter(|c| c.planted.is_some())
        .count() as u32;
    let contacts = tracker
        .contacts
        .iter()
        .zip(&tracker.grounded)
        .map(|(c, grounded)| GroundContactState {
            joint: c.joint,
            patch: c.patch.clone(),
            planted: c.planted.is_some(),
            held: c
                .planted
                .iter()
                .flatten()
                .map(|p| to_world.transform_point3(*p).as_vec3())
                .collect(),
            grounded: *grounded,
            ground_normal: (to_world.matrix3 * c.ground.normal)
                .normalize_or(DVec3::Y)
                .as_vec3(),
            up: c.up.map(|u| u.as_vec3()),
        })
        .collect();
    Standing {
        planted,
        planted_now,
        corners,
        contacts,
    }
}

/// What casting the floor again under a solve's skin needs: the character's ground settings,
/// the scene's ground and where the character stood when the solve was taken
/// ([`FloorRecast::floor_where_it_ended`]).
#[derive(Clone)]
pub(super) struct FloorRecast {
    settings: PoseGround,
    ground: SceneGround,
    placement: DAffine3,
}

impl FloorRecast {
    /// For a solve of `posed` as it is placed now.
    pub(super) fn new(settings: &PoseGround, ground: &SceneGround, posed: &PosedSkeleton) -> Self {
        Self {
            settings: *settings,
            ground: ground.clone(),
            placement: posed.placement,
        }
    }

    /// The floor cast again under the skin of `solved` (of `model`) when that skin is through
    /// it by more than [`THROUGH_THE_GROUND`] of the size (`None`: the solve's floor held). A
    /// solve's floor is cast where the skin starts; a vertex the solve carries across the
    /// ground (a walking paw swung on into a rise, hips pulled onto a box in one move) meets
    /// ground that was not under it then, and that plane is only found by casting where it
    /// ended — the narrow phase after the motion, as a physics engine does.
    pub(super) fn floor_where_it_ended(
        &self,
        model: &SkinnedModel,
        solved: &SkeletonPose,
    ) -> Option<Floor> {
        let at = CharacterGround::new(&self.ground, self.placement);
        let size = model.topology().bounding_diagonal();
        let skinned = model.skin_welded(solved);
        let through = THROUGH_THE_GROUND * size;
        // Most solves end with all their skin above the ground: seen without casting a floor
        // (in the world, where the ground is).
        let in_world = at.in_world(&skinned);
        let sampling = at.world_sampling(&self.settings, size);
        if !Floor::may_be_under(&in_world, &self.ground, &sampling, through * at.scale) {
            return None;
        }
        let floor = at.floor_under(&in_world, &self.settings, size, &mut FloorMemory::default());
        (floor.deepest(&skinned) < -through).then_some(floor)
    }
}

/// A character to stand: its contacts (the tracker made on the first call, with the placement
/// it was updated for, and its floor's memory), its skeleton, and the pose a solve starts
/// from.
pub(super) type Standee<'a> = (&'a mut GroundContacts, &'a PosedSkeleton, StartPose<'a>);

/// The pose a character is stood on the ground in: the one its solve starts from.
pub(super) enum StartPose<'a> {
    /// The pose held now (the solve goes on from the last solution).
    Held(&'a SkeletonPose),
    /// A start given for this solve (an additive layer's: this frame's animation with the
    /// layer added). Its planted limbs are started where `last`, the last solved pose, left
    /// them ([`ContactTracker::carry_planted_limbs`]).
    Given {
        pose: &'a mut SkeletonPose,
        last: Option<&'a SkeletonPose>,
    },
}

impl StartPose<'_> {
    /// The pose.
    fn pose(&self) -> &SkeletonPose {
        match self {
            StartPose::Held(pose) => pose,
            StartPose::Given { pose, .. } => pose,
        }
    }
}

/// What [`stand_on`] found.
pub(super) struct Standing {
    /// Contacts planted now.
    pub planted: u32,
    /// Contacts planted by this call.
    pub planted_now: u32,
    /// The support polygon's corners (character space).
    pub corners: Vec<DVec3>,
    /// Every contact's state.
    pub contacts: Vec<GroundContactState>,
}

impl Standing {
    /// Writes what was found to the character's status (the polygon in world space).
    pub(super) fn report(self, status: &mut PoseStatus, posed: &PosedSkeleton) {
        status.contacts_planted = self.planted;
        status.plants += u64::from(self.planted_now);
        status.support_polygon = self
            .corners
            .iter()
            .map(|c| posed.placement.transform_point3(*c).as_vec3())
            .collect();
        status.contacts = self.contacts;
    }
}

/// How far out of `margin` inside the support the clip under an additive layer carries the
/// centre of mass (0 when it keeps it inside): the lean balance allows a walk
/// ([`Balance::lean`]).
fn clip_lean(
    model: &crate::pose::SkinnedModel,
    clip: &SkeletonPose,
    support: &[DVec3],
    down: DVec3,
    margin: f64,
) -> f64 {
    centre_of_mass(model, clip, None)
        .map(|com| SupportPolygon::new(support, down).signed_distance(com))
        .filter(|inside| inside.is_finite())
        .map_or(0.0, |inside| (margin - inside).max(0.0))
}

/// Re-expresses the contacts' grounds and planted points after the character moved: `moved`
/// maps the old character space into the new one.
fn follow_the_world(tracker: &mut ContactTracker, moved: &DAffine3) {
    for c in &mut tracker.contacts {
        c.move_by(moved);
    }
}

/// The scene's ground seen from a character's space (placed in the world by `to_world`).
struct CharacterGround<'a> {
    ground: &'a SceneGround,
    to_world: DAffine3,
    to_character: DAffine3,
    /// Gravity, in character space.
    down: DVec3,
    /// How much longer a length is in the world than in character space.
    scale: f64,
}

impl<'a> CharacterGround<'a> {
    fn new(ground: &'a SceneGround, to_world: DAffine3) -> Self {
        let to_character = to_world.inverse();
        Self {
            ground,
            to_world,
            to_character,
            down: (to_character.matrix3 * DVec3::NEG_Y).normalize_or(DVec3::NEG_Y),
            scale: to_world.matrix3.x_axis.length(),
        }
    }

    /// A cast in character space: the ray taken into the world, the hit brought back (`None`
    /// for a miss or a hit that is not finite).
    fn cast(&self, from: DVec3, along: DVec3, max: f64) -> Option<GroundPlane> {
        let (to_world, to_character) = (&self.to_world, &self.to_character);
        let direction = (to_world.matrix3 * along).try_normalize()?;
        let hit =
            self.ground
                .cast_down(to_world.transform_point3(from), direction, max * self.scale)?;
        GroundPlane::new(
            to_character.transform_point3(hit.point),
            to_character.matrix3 * hit.normal,
        )
    }

    /// Points of character space in the world.
    fn in_world(&self, points: &[DVec3]) -> Vec<DVec3> {
        points
            .iter()
            .map(|p| self.to_world.transform_point3(*p))
            .collect()
    }

    /// The floor under the welded skin `in_world` (placed in the world, [`Self::in_world`])
    /// of a model of `size` (its bounding diagonal, character space): every vertex within
    /// `settings`' band of the ground under it. Cast in the world, where the ground's lattice
    /// is (the casts `memory` holds are answered from it, [`Floor::cast_remembering`]), and
    /// brought back to character space.
    fn floor_under(
        &self,
        in_world: &[DVec3],
        settings: &PoseGround,
        size: f64,
        memory: &mut FloorMemory,
    ) -> Floor {
        let sampling = self.world_sampling(settings, size);
        let (floor, _) = Floor::cast_remembering(in_world, self.ground, &sampling, memory);
        let to_character = &self.to_character;
        match floor {
            Floor::Under(under) => Floor::Under(
                under
                    .into_iter()
                    .filter_map(|(v, plane)| {
                        let point = to_character.transform_point3(plane.point);
                        GroundPlane::new(point, to_character.matrix3 * plane.normal)
                            .map(|plane| (v, plane))
                    })
                    .collect(),
            ),
            plane => plane,
        }
    }

    /// How the floor under a character of `size` (character space) is sampled on the ground
    /// in the world.
    fn world_sampling(&self, settings: &PoseGround, size: f64) -> FloorSampling {
        let band = f64::from(settings.floor_band);
        FloorSampling::for_size(size * self.scale, band, DVec3::NEG_Y)
    }
}

/// The floor memory of a character on `ground`: forgotten when the scene's ground is another
/// than the one it was cast on.
fn remembered_on<'m>(
    remembered: &'m mut Option<(SceneGround, FloorMemory)>,
    ground: &SceneGround,
) -> &'m mut FloorMemory {
    if !remembered
        .as_ref()
        .is_some_and(|(on, _)| on.same_source(ground))
    {
        *remembered = None;
    }
    &mut remembered
        .get_or_insert_with(|| (ground.clone(), FloorMemory::default()))
        .1
}

impl Ground for CharacterGround<'_> {
    fn cast_down(&self, from: DVec3, down: DVec3, max: f64) -> Option<GroundPlane> {
        self.cast(from, down, max)
    }

    /// The scene's bound, asked in the world and brought back to character space.
    fn highest_within(&self, centre: DVec3, radius: f64, down: DVec3) -> Option<f64> {
        let world_down = (self.to_world.matrix3 * down).try_normalize()?;
        let world_centre = self.to_world.transform_point3(centre);
        let top = self
            .ground
            .highest_within(world_centre, radius * self.scale, world_down)?;
        if !top.is_finite() {
            return Some(top);
        }
        // The point over the centre at that height, seen from the character.
        let over = world_centre - world_down * (top + world_centre.dot(world_down));
        Some(-self.to_character.transform_point3(over).dot(down))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A character's floor memory answers the grid's nodes again on the same scene ground,
    /// and is forgotten when the scene's ground is another (a rebuilt or replaced ground:
    /// nothing it cast before answers). (Fails if the memory outlives its ground.)
    #[test]
    fn the_floor_memory_is_kept_on_its_ground_and_forgotten_on_another() {
        let flat = || SceneGround::custom(GroundPlane::new(DVec3::ZERO, DVec3::Y).unwrap());
        let (first, second) = (flat(), flat());
        let skin = [DVec3::new(0.0, 0.02, 0.0), DVec3::new(1.0, 0.3, 0.5)];
        let sampling = FloorSampling::for_size(2.0, 0.3, DVec3::NEG_Y);
        let mut remembered = None;
        let mut cast_on = |ground: &SceneGround| {
            let memory = remembered_on(&mut remembered, ground);
            Floor::cast_remembering(&skin, ground, &sampling, memory).1
        };
        assert_eq!(cast_on(&first).grid_nodes_remembered, 0);
        let again = cast_on(&first);
        assert!(
            again.grid_nodes_remembered > 0 && again.grid_casts == 0,
            "{again:?}"
        );
        let other = cast_on(&second);
        assert_eq!(other.grid_nodes_remembered, 0, "{other:?}");
        assert!(other.grid_casts > 0);
    }
}
