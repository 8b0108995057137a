//! Requesting pose solves: each frame, a character's drivers (vertex handles, joint handles,
//! effectors) and pins are compared with the set its solver was built for; a new set rebases
//! the handles on the pose on screen, a moved one queues a solve (latest wins) in the
//! background.

use bevy::prelude::*;

use super::super::blend::BlendMemory;
use super::super::convert::{affine, composed_global};
use super::super::{
    HandlePositionOnly, PinnedJoints, PoseAnchor, PoseBalance, PoseBlend, PoseBlendMode,
    PoseEffector, PoseFailed, PoseGround, PoseInFrame, PoseJointHandle, PoseLimits, PoseStatus,
    PoseStiffness, Poseable, PosedSkeleton, SymmetricEditing,
};
use super::constraints::{
    SetKey, core_effector, joint_handle, rebase, resolve_limits, vertex_handles,
};
use super::ground_contacts::{FloorRecast, StartPose};
use super::solve::SolveJob;
use super::state::{CharacterSpace, GroundContacts, LastSolve, PoseDrivers, PoseSolves, fail};
use super::symmetry::Symmetry;
use crate::ecs::{DeformHandle, SceneGround};
use crate::pose::constraints::frame::similarity;
use crate::pose::{Effector, PoseConstraints, ReferenceStiffness, SkeletonPose};

/// A character grabbed with no anchor (compared in place every frame, never allocated).
static NO_ANCHOR: PoseAnchor = PoseAnchor {
    joints: Vec::new(),
    vertices: Vec::new(),
};

/// The per-character settings a solve reads besides handles and pins.
#[derive(bevy::ecs::query::QueryData)]
pub(super) struct CharacterSettings {
    limits: Option<Ref<'static, PoseLimits>>,
    stiffness: Option<Ref<'static, PoseStiffness>>,
    symmetric: Has<SymmetricEditing>,
    blend: Option<&'static PoseBlend>,
    global: Option<&'static GlobalTransform>,
    character_space: Has<CharacterSpace>,
    ground: Option<&'static PoseGround>,
    balance: Option<&'static PoseBalance>,
}

impl CharacterSettingsItem<'_, '_> {
    /// An additive blend layer: solves start from the pose on screen, results become the
    /// layer over the animation.
    fn additive(&self) -> bool {
        self.blend
            .is_some_and(|b| b.mode == PoseBlendMode::Additive)
    }
}

/// Vertex-set handles of every character.
type VertexHandles<'w, 's> = Query<
    'w,
    's,
    (Entity, &'static mut DeformHandle, &'static mut Transform),
    Without<PoseJointHandle>,
>;
/// Joint handles of every character.
type JointHandles<'w, 's> = Query<
    'w,
    's,
    (Entity, &'static mut PoseJointHandle, &'static mut Transform),
    Without<DeformHandle>,
>;
/// Effectors of every character, with where their targets are.
type Effectors<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        Ref<'static, PoseEffector>,
        Ref<'static, GlobalTransform>,
    ),
>;
/// The joints' local transforms (what is on screen).
type JointTransforms<'w, 's> =
    Query<'w, 's, &'static Transform, (Without<DeformHandle>, Without<PoseJointHandle>)>;

/// What a solve request reads of a character.
type RequestingCharacter = (
    (Entity, Has<PoseInFrame>),
    &'static Poseable,
    &'static mut PosedSkeleton,
    Option<Ref<'static, PinnedJoints>>,
    Option<&'static PoseAnchor>,
    CharacterSettings,
    (
        &'static mut PoseDrivers,
        &'static mut GroundContacts,
        &'static mut PoseSolves,
        &'static mut LastSolve,
        &'static BlendMemory,
    ),
    &'static mut PoseStatus,
);

/// One character's drivers this frame, each list in entity order.
struct Drivers<'a> {
    handles: Vec<(Entity, Mut<'a, DeformHandle>, Mut<'a, Transform>)>,
    joint_handles: Vec<(Entity, Mut<'a, PoseJointHandle>, Mut<'a, Transform>)>,
    effectors: Vec<(Entity, Ref<'a, PoseEffector>, Ref<'a, GlobalTransform>)>,
    /// Handles whose centroid follows them, orientation free ([`HandlePositionOnly`]).
    followers: Vec<Entity>,
}

impl<'a> Drivers<'a> {
    /// The drivers of `character`.
    fn of(
        character: Entity,
        handles: &'a mut VertexHandles,
        joint_handles: &'a mut JointHandles,
        effectors: &'a Effectors,
        position_only: &Query<(), With<HandlePositionOnly>>,
    ) -> Self {
        let mut handles: Vec<_> = handles
            .iter_mut()
            .filter(|(_, h, _)| h.target == character)
            .collect();
        let mut joint_handles: Vec<_> = joint_handles
            .iter_mut()
            .filter(|(_, h, _)| h.target == character)
            .collect();
        let mut effectors: Vec<_> = effectors
            .iter()
            .filter(|(_, e, _)| e.character == character)
            .collect();
        handles.sort_by_key(|(e, _, _)| *e);
        joint_handles.sort_by_key(|(e, _, _)| *e);
        effectors.sort_by_key(|(e, _, _)| *e);
        let followers = handles
            .iter()
            .map(|(e, _, _)| *e)
            .filter(|e| position_only.contains(*e))
            .collect();
        Self {
            handles,
            joint_handles,
            effectors,
            followers,
        }
    }

    fn is_empty(&self) -> bool {
        self.handles.is_empty() && self.joint_handles.is_empty() && self.effectors.is_empty()
    }

    /// Each effector and the joint it drives.
    fn effector_keys(&self) -> Vec<(Entity, Entity)> {
        self.effectors
            .iter()
            .map(|(e, p, _)| (*e, p.joint))
            .collect()
    }

    /// The key of this set of drivers, pins and anchor.
    fn key(&self, pins: &[Entity], anchor: &PoseAnchor) -> SetKey {
        SetKey {
            handles: self
                .handles
                .iter()
                .map(|(e, h, _)| (*e, h.vertices.clone()))
                .collect(),
            joint_handles: self
                .joint_handles
                .iter()
                .map(|(e, h, _)| (*e, h.joint))
                .collect(),
            pins: pins.to_vec(),
            anchor: anchor.clone(),
            position_only: self.followers.clone(),
            effectors: self.effector_keys(),
        }
    }

    /// Whether the set differs from `key` (or a handle has not been placed yet).
    fn set_changed(&self, key: Option<&SetKey>, pins: &[Entity], anchor: &PoseAnchor) -> bool {
        let same = key.is_some_and(|k| {
            k.matches(&self.handles, &self.joint_handles, pins)
                && k.anchor == *anchor
                && k.position_only == self.followers
                && k.effectors == self.effector_keys()
        });
        !same
            || self.handles.iter().any(|(_, h, _)| h.pivot.is_none())
            || self.joint_handles.iter().any(|(_, h, _)| h.rest.is_none())
    }

    /// Whether a handle or an effector's target moved this frame.
    fn moved(&self) -> bool {
        self.handles.iter().any(|(_, _, t)| t.is_changed())
            || self.joint_handles.iter().any(|(_, _, t)| t.is_changed())
            || self
                .effectors
                .iter()
                .any(|(_, e, g)| e.is_changed() || g.is_changed())
    }
}

/// What is on screen: the joints as they are now (the held pose, whatever a playing or paused
/// clip left on them, or the clip plus an additive layer).
fn on_screen(posed: &PosedSkeleton, joints: &JointTransforms) -> SkeletonPose {
    posed.shown_pose(|j| joints.get(j).ok().copied())
}

/// Starts a new set of drivers: the reference pose is what is on screen (an override blend's
/// layer is its own pose), the handles are rebased on it, and the solver is rebuilt.
fn start_set(
    (state, last): (&mut PoseDrivers, &mut LastSolve),
    posed: &mut PosedSkeleton,
    drivers: &mut Drivers,
    key: SetKey,
    extras: &CharacterSettingsItem,
    joints: &JointTransforms,
) {
    let reference = if extras.additive() {
        on_screen(posed, joints)
    } else {
        if extras.blend.is_none() {
            let now = on_screen(posed, joints);
            if now != posed.pose {
                posed.pose = now;
            }
        }
        posed.pose.clone()
    };
    // A handle that turned rigid (a grab being turned) keeps its target: its world position
    // and the turn just given to it, now about the patch as it is on screen.
    let turned: Vec<(Entity, Transform)> = state
        .key
        .as_ref()
        .map(|k| {
            drivers
                .handles
                .iter()
                .filter(|(e, h, _)| {
                    h.pivot.is_some()
                        && k.position_only.contains(e)
                        && drivers.followers.binary_search(e).is_err()
                })
                .map(|(e, _, t)| (*e, **t))
                .collect()
        })
        .unwrap_or_default();
    rebase(
        posed,
        &reference,
        &mut drivers.handles,
        &mut drivers.joint_handles,
    );
    for (e, kept) in turned {
        if let Some((_, _, t)) = drivers.handles.iter_mut().find(|(f, _, _)| *f == e) {
            **t = kept;
        }
    }
    state.key = Some(key);
    state.reference = Some(reference);
    last.forget_solver();
}

/// The constraints of the current drivers, and where the solve starts when not from the held
/// pose (an additive layer starts from what is on screen, its planted limbs where `last`, the
/// last solved pose, left them).
fn constraints_of(
    (state, memory, last): (&mut PoseDrivers, &BlendMemory, Option<&SkeletonPose>),
    (contacts, ground): (&mut GroundContacts, Option<&SceneGround>),
    posed: &PosedSkeleton,
    drivers: &Drivers,
    (pins, anchor): (&[Entity], &PoseAnchor),
    extras: &CharacterSettingsItem,
    (joints, status): (&JointTransforms, &mut PoseStatus),
) -> Result<(PoseConstraints, Option<SkeletonPose>), super::super::PoseableError> {
    let limits = resolve_limits(posed, extras.limits.as_ref(), &mut state.limits)?;
    let mut fixed_joints: Vec<usize> = pins
        .iter()
        .chain(&anchor.joints)
        .filter_map(|e| posed.joint_index(*e))
        .collect();
    fixed_joints.sort_unstable();
    fixed_joints.dedup();
    let (handles, centroid_effectors) = vertex_handles(
        posed,
        state.reference.as_ref(),
        &drivers.handles,
        &drivers.followers,
    );
    let mut effectors: Vec<Effector> = Vec::with_capacity(drivers.effectors.len());
    state.effector_sources.clear();
    for (entity, e, g) in &drivers.effectors {
        if let Some(effector) = core_effector(posed, e, g) {
            state
                .effector_sources
                .push((effectors.len(), *entity, (**e).clone()));
            effectors.push(effector);
        }
    }
    // An additive layer holds what nothing pulls on where the animation puts it now.
    let mut start = extras.additive().then(|| on_screen(posed, joints));
    // Preferred angles: the animation itself under an additive layer (so the layer relaxes
    // back to nothing where nothing pulls), else the reference the drivers were set on.
    let animated = extras
        .additive()
        .then(|| memory.animated_pose())
        .filter(|p| p.local.len() == posed.joints.len());
    let stiffness = extras
        .stiffness
        .as_ref()
        .zip(
            animated
                .clone()
                .or_else(|| start.clone())
                .or_else(|| state.reference.clone()),
        )
        .map(|(k, pose)| ReferenceStiffness::by_inertia(pose, k.0.clamp(0.0, 1.0) as f64));
    let world = PoseConstraints {
        centroid_effectors,
        handles,
        fixed_vertices: anchor.vertices.clone(),
        fixed_joints,
        joint_handles: drivers
            .joint_handles
            .iter()
            .filter_map(|(_, h, t)| joint_handle(posed, h, t))
            .collect(),
        effectors,
        stiffness,
        limits,
        balance: None,
        contacts: Vec::new(),
        floor: None,
        // The animation is the shape an additive layer keeps: with nothing pulling, the layer
        // is nothing (not the body relaxing towards its bind shape, frame after frame).
        shape_rest: animated,
    };
    // The model is in character space: so are its constraints.
    let mut constraints = world.transformed(&posed.placement.inverse());
    if extras.symmetric {
        let c = &mut constraints;
        state
            .symmetry
            .get_or_insert_with(|| Symmetry::new(posed))
            .mirror_drivers(
                &mut c.effectors,
                &mut c.handles,
                &mut c.centroid_effectors,
                &c.fixed_vertices,
            );
    }
    if let (Some(settings), Some(ground)) = (extras.ground, ground) {
        let pose = match start.as_mut() {
            Some(pose) => StartPose::Given { pose, last },
            None => StartPose::Held(&posed.pose),
        };
        let balance = extras.balance.filter(|b| b.enabled);
        let standee = (&mut *contacts, posed, pose);
        let standing = super::ground_contacts::stand_on(
            &mut constraints,
            standee,
            (settings, balance),
            ground,
        );
        standing.report(status, posed);
    }
    Ok((constraints, start))
}

/// Keeps [`PosedSkeleton::placement`] on where the character is now (a model in character
/// space only): its transform composed up its hierarchy — moved earlier in this `Update` (a
/// character controller), its `GlobalTransform` is still last frame's — else its
/// `GlobalTransform`. True when it moved, so that world-space drivers are solved again.
fn follow_placement(
    (posed, entity): (&mut Mut<PosedSkeleton>, Entity),
    extras: &CharacterSettingsItem,
    (joints, parents): (&JointTransforms, &Query<&ChildOf>),
) -> bool {
    if !extras.character_space {
        return false;
    }
    let now = composed_global(entity, |e| {
        let t = joints.get(e).ok()?;
        Some((*t, parents.get(e).ok().map(ChildOf::parent)))
    });
    let Some(global) = now.as_ref().or(extras.global) else {
        return false;
    };
    let Some(now) = similarity(&affine(global)) else {
        return false;
    };
    if now.abs_diff_eq(posed.placement, 1e-9) {
        return false;
    }
    posed.placement = now;
    true
}

/// Starts a solve when a character's handles, pins or pose changed (latest wins).
pub(super) fn request_pose_solves(
    mut characters: Query<RequestingCharacter>,
    mut handles: VertexHandles,
    mut joint_handles: JointHandles,
    (joints, parents): (JointTransforms, Query<&ChildOf>),
    (position_only, effectors): (Query<(), With<HandlePositionOnly>>, Effectors),
    mut failed: MessageWriter<PoseFailed>,
    ground: Option<Res<SceneGround>>,
) {
    for ((entity, in_frame), poseable, mut posed, pins, anchor, extras, parts, mut status) in
        &mut characters
    {
        let (mut drivers_state, mut contacts, mut solves, mut last, memory) = parts;
        let placed = follow_placement((&mut posed, entity), &extras, (&joints, &parents));
        let mut drivers = Drivers::of(
            entity,
            &mut handles,
            &mut joint_handles,
            &effectors,
            &position_only,
        );
        // A character standing on the ground is driven by it (a first stance, a move of the
        // character or of the ground), with or without handles.
        let grounded = extras.ground.is_some() && ground.is_some();
        if drivers.is_empty() && !grounded {
            drivers_state.bypass_change_detection().key = None;
            continue; // nothing drives the pose
        }
        let pinned = pins.as_ref().map_or(&[][..], |p| &p.0[..]);
        let anchor = anchor.unwrap_or(&NO_ANCHOR);
        if drivers.set_changed(drivers_state.key.as_ref(), pinned, anchor) {
            let key = drivers.key(pinned, anchor);
            let state = (
                drivers_state.bypass_change_detection(),
                last.bypass_change_detection(),
            );
            start_set(state, &mut posed, &mut drivers, key, &extras, &joints);
            continue; // the rebased Transforms trigger the solve next frame
        }
        let settings_changed = extras.limits.as_ref().is_some_and(|l| l.is_changed())
            || extras.stiffness.as_ref().is_some_and(|s| s.is_changed());
        let stance = grounded
            && (contacts.tracker.is_none() || ground.as_ref().is_some_and(|g| g.is_changed()));
        let changed = drivers.moved()
            || placed
            || stance
            || pins.as_ref().is_some_and(|p| p.is_changed())
            || settings_changed
            || extras.additive() && memory.moved;
        if !changed && solves.pending.is_none() {
            continue;
        }
        let driver_state = drivers_state.bypass_change_detection();
        // An in-frame character stands in `PostUpdate`, on this frame's animation, in
        // parallel with the others (`in_frame.rs`).
        let stand_here = if in_frame { None } else { ground.as_deref() };
        let built = constraints_of(
            (driver_state, memory, last.solved_pose()),
            (contacts.bypass_change_detection(), stand_here),
            &posed,
            &drivers,
            (pinned, anchor),
            &extras,
            (&joints, status.bypass_change_detection()),
        );
        let (constraints, start) = match built {
            Ok(c) => c,
            Err(e) => {
                fail(entity, e, &mut status, &mut failed);
                continue;
            }
        };
        let solves = solves.bypass_change_detection();
        solves.pending = Some(constraints);
        solves.start = start;
        if in_frame {
            continue; // solved in `PostUpdate`, after animation (`in_frame.rs`)
        }
        solves.task.supersede();
        if !solves.task.is_running() {
            let options = poseable.solve_options();
            let recast = extras
                .ground
                .zip(ground.as_deref())
                .map(|(settings, ground)| FloorRecast::new(settings, ground, &posed));
            let last = last.bypass_change_detection();
            let job = (options, recast);
            SolveJob::launch(solves, driver_state, last, &posed, job, &mut status);
        }
    }
}
