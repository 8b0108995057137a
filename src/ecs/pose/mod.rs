//! Posing rigged glTF characters in the ECS: [`Poseable`] on a character, handles that move
//! vertex sets ([`crate::ecs::DeformHandle`]) or joints ([`PoseJointHandle`]), pins
//! ([`PinnedJoints`]), and the solved skeleton pose written to the joint entities'
//! `Transform`s. The math is [`crate::pose`]; this is the glue.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `blend.rs` | The blend layer: a [`Poseable`](super::Poseable) character's pose blended over the animation that plays on its joints, by a weight, in override or additive mode, optionally on a mask of joints. |
//! | `convert.rs` | Conversions between Bevy's transforms and the pose core's (f32 → f64), one home for the stages that need them. |
//! | `plugin/` | The character plugin: its system sets and the wiring of the stages — `prepare.rs` (skins → models), `request.rs` (drivers → solves), `poll.rs` (landed background solves, timelines), `in_frame.rs` (solves inside the frame) and `apply.rs` (the pose onto the joints after animation). |
//! | `posed_skeleton.rs` | [`PosedSkeleton`]: what the plugin keeps of a prepared character — its model, joints and the pose it holds — and what a game reads of it: skinned positions, the pose on screen, the joints it stands on, pose files and clip tracks, and picking on the posed skin. |
//! | `standing.rs` | What a character standing on the game's ground is told and tells: [`PoseGround`] and [`PoseBalance`] (settings), [`GroundContactState`] (each contact, in [`super::PoseStatus::contacts`]). |
//! | `timeline.rs` | Authoring keyframed clips on a character: a [`PoseTimeline`] holds a [`PoseClip`](crate::pose::PoseClip), the time it is shown at, and playback; the plugin shows the clip's pose at that time on the character (in [`PoseSystems::Timeline`](super::PoseSystems::Timeline)). |
//!
//! # Spaces
//! A character's handles live in **world space** (a skinned mesh is drawn where its joints
//! put it, whatever its own transform): a `DeformHandle` aimed at a character has its pivot
//! at the world centroid of its vertices, and its `Transform` is a world transform. Drive it
//! with [`crate::ecs::MouseHandleControl`] / [`crate::ecs::MotionHandleControl`] with
//! `space: None`, exactly like a static mesh's handle.
//!
//! Handle targets are relative to the pose the character was in when the constraint *set*
//! last changed (a handle or pin added or removed): the plugin then rebases every handle to
//! that pose — its pivot moves to where its vertices (or joint) are, its `Transform` to the
//! pivot — so nothing jumps when a second handle is grabbed mid-pose.
//!
//! # Animation
//! The solved pose is kept in [`PosedSkeleton::pose`] and written to the joints in
//! `PostUpdate`, after `AnimationSystems` and before transform propagation:
//! * **Posing a paused clip**: pause the `AnimationPlayer` (or stop it), then pose; the
//!   pose starts from whatever the clip left on the joints.
//! * **Override on top of a playing clip**: with [`Poseable::hold_pose`] (the default) the
//!   pose is written every frame after the animation systems, so it wins over the clip on
//!   every joint; with `hold_pose: false` it is written only when it changes and the playing
//!   clip takes the joints back on the next frame.
//! * **Blended over a playing clip**: a [`PoseBlend`] mixes the pose with the clip by a
//!   weight, or adds it on top (additive), on all joints or a [`JointMask`].
//!
//! Set [`PosedSkeleton::pose`] yourself (e.g. from a [`crate::pose::PoseFile`]) to load a
//! pose; the next solve starts from it.

mod blend;
pub(crate) mod convert;
mod plugin;
pub(crate) use plugin::resolve_limits;
mod posed_skeleton;
mod standing;
mod timeline;

use std::sync::Arc;

use bevy::prelude::*;

use crate::pose::{JointLimits, LimitError, PoseError, SkinnedModel};

pub use blend::{JointMask, PoseBlend, PoseBlendMode};
pub use plugin::{PosePlugin, PoseSystems};
pub use posed_skeleton::PosedSkeleton;
pub use standing::{GroundContactState, PoseBalance, PoseGround};
pub use timeline::PoseTimeline;

/// Makes a rigged character poseable. Put it on the glTF scene root (`WorldAssetRoot`), any
/// ancestor of the skinned mesh, or the skinned mesh entity itself; the plugin finds the
/// skinned primitives (`SkinnedMesh`) below it and their joints (a scene root once its
/// instance has spawned; any other entity at once — nothing skinned there is a
/// [`PoseableError::NoSkinnedMesh`]). Primitives sharing the
/// first primitive's joint list form one model (their render vertices numbered one after the
/// other, in hierarchy order); other skins below are ignored.
#[derive(Component, Debug, Clone, Reflect, PartialEq)]
#[reflect(Component, Default)]
#[require(PoseStatus)]
pub struct Poseable {
    /// Iterations per solve (warm-started solves need few). A solve that uses them all is
    /// followed by another with the same targets, so a released pose keeps settling until
    /// an iteration improves it by less than `tolerance`.
    pub max_iterations: u32,
    /// Relative energy decrease below which a solve stops early (and the pose is settled).
    pub tolerance: f32,
    /// Further iterations a solve may take while the skin is still through the ground
    /// ([`crate::pose::PoseSolveOptions::ground_iterations`]; with [`PoseGround`]). A scene
    /// saved before it existed loads with the default (`#[reflect(Default)]`).
    pub ground_iterations: u32,
    /// Rotation clusters (k-means in weight space).
    pub clusters: u32,
    /// Write the pose to the joints every frame (overrides a playing clip), or only when it
    /// changes.
    pub hold_pose: bool,
}

impl Default for Poseable {
    fn default() -> Self {
        Self {
            max_iterations: 4,
            tolerance: 1e-5,
            ground_iterations: crate::pose::PoseSolveOptions::default().ground_iterations,
            clusters: 100,
            hold_pose: true,
        }
    }
}

impl Poseable {
    /// The options of a background solve of this character.
    pub(crate) fn solve_options(&self) -> crate::pose::PoseSolveOptions {
        self.options_with(self.max_iterations)
    }

    /// The options of a solve of at most `iterations` iterations (an in-frame budget).
    pub(crate) fn options_with(&self, iterations: u32) -> crate::pose::PoseSolveOptions {
        crate::pose::PoseSolveOptions {
            max_iterations: iterations.max(1),
            tolerance: self.tolerance.max(0.0) as f64,
            ground_iterations: self.ground_iterations,
        }
    }
}

/// Solve this character inside the frame instead of in the background: the solve of a
/// frame's targets runs in `PostUpdate` (in [`PoseSystems::Apply`], after animation and
/// before transform propagation), so its pose is on the joints in the frame the targets moved
/// — for gameplay-driven targets (a hand on a door, feet on stairs). At most `iterations`
/// iterations a frame (warm-started from the last frame's); all in-frame characters of a
/// frame are solved in parallel on Bevy's compute pool. Effector targets are read again
/// there, from the local transforms up their hierarchy after animation, so a target an
/// animation or a late system carried is met in the frame it moved. Without it (editing),
/// solves run in the background and land a frame or more later.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component)]
pub struct PoseInFrame {
    /// Iterations per frame (the frame's budget for this character).
    pub iterations: u32,
}

impl Default for PoseInFrame {
    /// 3 iterations a frame.
    fn default() -> Self {
        Self { iterations: 3 }
    }
}

/// Joints (entities) of a [`Poseable`] character kept where they are: the feet planted.
#[derive(Component, Debug, Clone, Default, Reflect, PartialEq)]
#[reflect(Component, Default)]
pub struct PinnedJoints(#[entities] pub Vec<Entity>);

/// A handle that moves a joint (grab the hand joint). Its `Transform` is the joint's target
/// world transform; at rest it is the joint's world transform (filled in by the plugin with
/// [`PoseJointHandle::rest`] when `rest` is `None`).
#[derive(Component, Debug, Clone, Reflect, PartialEq)]
#[reflect(Component)]
pub struct PoseJointHandle {
    /// The [`Poseable`] character.
    #[entities]
    pub target: Entity,
    /// The joint entity.
    #[entities]
    pub joint: Entity,
    /// The joint's world transform when the handle was (re)based.
    pub rest: Option<Transform>,
}

impl PoseJointHandle {
    /// A handle on `joint` of `target`, rebased by the plugin.
    pub fn new(target: Entity, joint: Entity) -> Self {
        Self {
            target,
            joint,
            rest: None,
        }
    }
}

/// Joints and vertices of a [`Poseable`] character held where they are for the current
/// driver set, besides its [`PinnedJoints`]: an anchor for a solve that should bend the body
/// rather than carry it. The pose plugin treats it like pins; it is the mechanism, not a
/// policy. The grab plugin ([`GrabPlugin`](crate::ecs::GrabPlugin)) decides one when a
/// character with no [`PinnedJoints`] is grabbed and removes it when the grab ends: it pins
/// every joint the grab's region ([`Grabbable::region_radius`] along the surface from the
/// grabbed point) does not reach — no vertex of the region is weighted to the joint or to any
/// joint below it — so grabbing the head pins the legs and the tail, the feet stay and the
/// spine, neck and head bend; a character of one chain (every joint reaches the region) is
/// held by the farther half of its surface instead. Insert it yourself to anchor any solve.
/// (The grab's decision to add one lives in `ecs/input/grab`.)
///
/// [`Grabbable::region_radius`]: crate::ecs::Grabbable::region_radius
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct PoseAnchor {
    /// Joint entities pinned (position and orientation) where they are.
    #[entities]
    pub joints: Vec<Entity>,
    /// Welded vertex indices of the model kept where they are.
    pub vertices: Vec<u32>,
}

/// On a [`DeformHandle`](crate::ecs::DeformHandle) aimed at a character: only the centroid
/// of the handle's vertices follows the handle's translation, their orientation is left to
/// the body (a position effector on the vertex set, [`crate::pose::CentroidEffector`]). Drag a
/// character's ear up and the head tilts as the neck lets it, where a rigid handle would ask
/// the ear to rise without turning. The grab plugin puts it on a character grab's handle and
/// takes it off when the grab is turned (Shift-drag, wheel), which needs the orientation.
#[derive(Component, Debug, Clone, Copy, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct HandlePositionOnly;

/// A goal for one joint of a [`Poseable`] character, read from this entity's
/// `GlobalTransform` every frame: its translation is the point (a position effector, the aim
/// target), its rotation the orientation. Make it a child of another entity (a door handle,
/// the player) and the goal follows it. Blended in by `weight` (0 = no effect, 1 = met when
/// reachable; see [`crate::pose::constraints::effectors`]). Several may act on one character at once,
/// together with handles, pins, limits ([`PoseLimits`]) and stiffness ([`PoseStiffness`]).
#[derive(Component, Debug, Clone, PartialEq, Reflect)]
#[reflect(Component)]
#[require(Transform)]
pub struct PoseEffector {
    /// The [`Poseable`] character.
    #[entities]
    pub character: Entity,
    /// The joint entity it acts on.
    #[entities]
    pub joint: Entity,
    /// What it asks of the joint.
    pub kind: PoseEffectorKind,
    /// Weight in [0, 1].
    pub weight: f32,
}

impl PoseEffector {
    /// A position effector of weight 1 (the joint's orientation stays free: plant a foot).
    pub fn position(character: Entity, joint: Entity) -> Self {
        Self {
            character,
            joint,
            kind: PoseEffectorKind::Position,
            weight: 1.0,
        }
    }

    /// A look-at of weight 1: the joint's local `axis` points at this entity.
    pub fn look_at(character: Entity, joint: Entity, axis: Vec3) -> Self {
        Self {
            character,
            joint,
            kind: PoseEffectorKind::Aim { axis, up: None },
            weight: 1.0,
        }
    }

    /// The same effector with another weight.
    pub fn with_weight(mut self, weight: f32) -> Self {
        self.weight = weight;
        self
    }
}

/// What a [`PoseEffector`] asks of its joint.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub enum PoseEffectorKind {
    /// The joint's origin at the effector's position; its orientation free.
    Position,
    /// The joint's world rotation equal to the effector's; its position free.
    Orientation,
    /// The joint's local `axis` points at the effector's position; with `up`, the joint's local
    /// `up` turns towards world +Y about the aim.
    Aim {
        /// The aiming axis in the joint's frame.
        axis: Vec3,
        /// Optional local up axis.
        up: Option<Vec3>,
    },
}

/// Joint limits of a [`Poseable`] character, applied to every solve (see
/// [`crate::pose::constraints::limits`]). Resolved when the character's model is ready; a file that names
/// a joint the skeleton lacks, or a bad value, fails the character with
/// [`PoseableError::Limits`] naming the joint.
#[derive(Component, Debug, Clone)]
pub enum PoseLimits {
    /// The humanoid preset chosen by joint names (Mixamo, Rigify, VRM; see
    /// [`crate::pose::rig::humanoid`]).
    Humanoid,
    /// A RON limits file's text, keyed by joint name.
    Ron(String),
    /// Limits built in code for this character's skeleton.
    Custom(Arc<JointLimits>),
}

/// A pull of every joint towards where it was when the current handles, pins and effectors
/// were set (the pose on screen: the animation's, or the held pose), in [0, 1]: joints nothing
/// pulls on stay put. Under an additive [`PoseBlend`] the pull is towards the animation as it
/// plays now, so the layer relaxes back to nothing where nothing pulls. 0 (or no component)
/// leaves them to the shape energy alone.
///
/// Each joint's pull is weighted by the share of the body its rotation carries
/// ([`crate::pose::StiffnessWeighting::Inertia`]): turning the hips, which carry the whole
/// body, costs far more than turning the neck, so a look-at turns the neck and head and
/// leaves the legs on the animation (an unmasked look-at over the Fox's idle clip moves its
/// hips ≤ 2 % of its size off the clip; with every joint weighed alike, up to 15 %).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component)]
pub struct PoseStiffness(pub f32);

/// Symmetric editing: every [`PoseEffector`] on a joint with a left/right partner (paired by
/// name, [`crate::pose::rig::mirror`]) drives the partner too, with its goal mirrored across the
/// character's symmetry plane; every grab (a [`crate::ecs::DeformHandle`] on the character,
/// rigid or position-only) drives the vertices nearest to its vertices' mirror image (in the
/// bind pose) with the mirrored motion. A set on the plane (the head) mirrors onto itself and
/// adds nothing; a mirrored set that would share vertices with another constraint is left out.
#[derive(Component, Debug, Clone, Copy, Default, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct SymmetricEditing;

/// A character's skin, found and read from the ECS as the pose plugin reads it
/// ([`CharacterSkin::read`]): the skinned primitives' combined mesh (and where each starts),
/// the skin's joints in skeleton order (parents first: the nearest joint ancestor; a root's
/// parent frame is its parent entity's transform) with their current local transforms. The
/// plugin builds a character's [`SkinnedModel`](crate::pose::SkinnedModel) from exactly this:
/// `SkinnedModel::new(skeleton, &mesh, &reference, settings)`.
#[derive(Debug, Clone)]
pub struct CharacterSkin {
    /// The primitives' meshes as one (joint indices in skeleton order).
    pub mesh: crate::pose::SkinnedMesh,
    /// Each skinned primitive entity and its first vertex in [`CharacterSkin::mesh`].
    pub primitives: Vec<(Entity, u32)>,
    /// The joints, parents first.
    pub skeleton: crate::pose::Skeleton,
    /// The joint entities, indexed like [`CharacterSkin::skeleton`].
    pub joints: Vec<Entity>,
    /// The joints' local transforms when read: the pose the model is built in.
    pub reference: crate::pose::SkeletonPose,
}

/// Where a poseable character stands; readable by UIs.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
pub struct PoseStatus {
    /// What the background worker is doing (shared with static meshes).
    pub phase: crate::ecs::DeformPhase,
    /// Joints of the skeleton (0 until prepared).
    pub joints: usize,
    /// Welded vertices of the model.
    pub vertices: usize,
    /// Iterations of the last solve.
    pub iterations: u32,
    /// Normalised objective after the last solve.
    pub energy: f64,
    /// Milliseconds of the last solve (including the constraint precompute when sets changed).
    pub solve_ms: f64,
    /// Completed solves so far.
    pub solves: u64,
    /// Last error (shown by inspectors; not written to scenes: a loaded scene prepares its
    /// characters again).
    #[reflect(skip_serializing)]
    pub error: Option<PoseableError>,
    /// Something missing that does not stop posing: a dependency of the character's glTF
    /// (a texture's image file) that failed to load, with the loader's message naming it
    /// (from [`MissingSceneAssets`](crate::ecs::MissingSceneAssets)).
    #[reflect(skip_serializing)]
    pub warning: Option<String>,
    /// With [`PoseGround`]: the contacts planted after the last request.
    pub contacts_planted: u32,
    /// With [`PoseGround`]: contacts planted so far, the first stance's included (a walk
    /// re-plants each patch left behind).
    pub plants: u64,
    /// With [`PoseGround`]: the support polygon of the planted contacts (world space, at the
    /// height of their lowest point; empty when nothing is planted), to draw.
    pub support_polygon: Vec<Vec3>,
    /// With [`PoseGround`]: every contact as the last request left it.
    pub contacts: Vec<GroundContactState>,
}

/// Why a character could not be made poseable or posed (in [`PoseFailed`] and
/// [`PoseStatus::error`]). Reflected as an opaque value (its `Debug` text in inspectors).
#[derive(Debug, Clone, PartialEq, thiserror::Error, Reflect)]
#[reflect(opaque, Debug, PartialEq, Clone)]
pub enum PoseableError {
    /// No `SkinnedMesh` at or below the entity (after its scene spawned).
    #[error("no skinned mesh at or below this entity: Poseable needs a rigged character")]
    NoSkinnedMesh,
    /// The mesh lacks CPU-side positions, joint indices or weights in Bevy's formats.
    #[error("the skinned mesh lacks CPU-side {0}")]
    MissingAttribute(&'static str),
    /// The mesh is not an indexed or plain triangle list.
    #[error("the skinned mesh is not a triangle list")]
    NotTriangleList,
    /// The skin, skeleton or a solve was rejected.
    #[error(transparent)]
    Pose(#[from] PoseError),
    /// The glTF scene (a `WorldAssetRoot`) this [`Poseable`] is on failed to load: a missing
    /// or malformed file. The loader's message is kept.
    #[error("the scene failed to load: {0}")]
    SceneLoadFailed(String),
    /// The character's [`PoseLimits`] were refused (names the joint).
    #[error(transparent)]
    Limits(#[from] LimitError),
    /// A joint entity of the skin does not exist or has no `Transform`.
    #[error("joint entity {0} of the skin is missing")]
    MissingJoint(Entity),
}

/// A solve finished and its pose was stored (and written to the joints).
#[derive(Message, Debug, Clone, PartialEq)]
pub struct PoseSolved {
    /// The [`Poseable`] entity.
    pub entity: Entity,
    /// Iterations done.
    pub iterations: u32,
    /// Normalised objective.
    pub energy: f64,
    /// Milliseconds.
    pub solve_ms: f64,
}

/// Preparing or solving a character failed; the last good pose is kept.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct PoseFailed {
    /// The [`Poseable`] entity.
    pub entity: Entity,
    /// Why.
    pub error: PoseableError,
}

/// The models of the prepared characters, one per asset: characters spawned from one glTF
/// (the same meshes, skin and model settings, the same nodes between the [`Poseable`] entity
/// and its skeleton) share one [`SkinnedModel`] through an `Arc`, built once — the model is
/// in character space, so where each instance stands does not matter. Read
/// [`PoseModels::built`] to count the builds.
#[derive(Resource, Default)]
pub struct PoseModels {
    pub(super) entries: std::collections::HashMap<ModelKey, SharedModel>,
    pub(super) built: u64,
}

impl PoseModels {
    /// How many models have been built since the app started.
    pub fn built(&self) -> u64 {
        self.built
    }

    /// How many distinct models are alive (held by at least one character).
    pub fn alive(&self) -> usize {
        self.entries
            .values()
            .filter(|e| matches!(e, SharedModel::Ready(m) if m.strong_count() > 0))
            .count()
    }
}

/// What decides a character's model (see [`PoseModels`]).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(super) struct ModelKey {
    pub(super) meshes: Vec<AssetId<Mesh>>,
    pub(super) bindposes: AssetId<bevy::mesh::skinning::SkinnedMeshInverseBindposes>,
    pub(super) clusters: u32,
    /// Root parent frames and joint scales, rounded to 1e-5.
    pub(super) numbers: Vec<i64>,
}

/// A shared model: being built by one instance, or built (held by the characters using it).
pub(super) enum SharedModel {
    Building,
    Ready(std::sync::Weak<SkinnedModel>),
}
