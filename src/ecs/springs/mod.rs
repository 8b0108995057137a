//! Spring bones on posed characters ([`crate::pose::springs`] in the frame): a
//! [`SpringBones`] on a [`Poseable`](crate::ecs::Poseable) swings its chains after the pose
//! and the animation, before transforms propagate, every frame.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `plugin.rs` | The spring systems: resolve [`SpringBones`] against prepared characters, then step them in `PostUpdate` after the pose is applied and before transforms propagate. |
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_wii_deform::ecs::{SpringBones, SpringPlugin};
//! use bevy_wii_deform::pose::SpringJoint;
//!
//! fn swing_the_tail(mut commands: Commands, fox: Entity) {
//!     // The Fox has no VRM extension: its tail joints by name.
//!     commands.entity(fox).insert(SpringBones::by_names(
//!         &["tail"],
//!         SpringJoint { stiffness: 0.8, drag: 0.3, gravity_power: 0.4, ..SpringJoint::new(0) },
//!     ));
//! }
//! ```

mod plugin;

use std::sync::Arc;

use bevy::prelude::*;

use crate::pose::{SpringJoint, SpringRig, SpringState};

pub use plugin::{SpringPlugin, SpringSystems};

/// Where a character's spring chains come from.
#[derive(Debug, Clone)]
pub enum SpringSource {
    /// Every run of joints whose names contain one of these words, each joint with these
    /// settings ([`SpringRig::from_names`]).
    Names {
        /// Words to look for in joint names (case-insensitive).
        words: Vec<String>,
        /// The settings of every joint found.
        joint: SpringJoint,
    },
    /// A VRM 1.0 model's `VRMC_springBone` extension: the glTF file's bytes
    /// ([`crate::pose::read_vrm_springs`]).
    Vrm(Arc<[u8]>),
    /// A rig built for this character's skeleton (joint indices in its order).
    Rig(Arc<SpringRig>),
}

/// Spring bones on a [`Poseable`](crate::ecs::Poseable) character ([`SpringPlugin`]): its
/// chains lag behind the character's motion, swing and settle toward the animated or posed
/// pose. Resolved against the skeleton once the character is prepared; its
/// [`SpringStatus`] says what was found.
#[derive(Component, Debug, Clone)]
#[require(SpringStatus)]
pub struct SpringBones {
    /// The chains.
    pub source: SpringSource,
    /// Off: the joints show the pose as the pose plugin and the animation leave it (the motion
    /// starts again from rest when turned back on).
    pub enabled: bool,
}

impl SpringBones {
    /// Chains found by joint names ([`SpringSource::Names`]).
    pub fn by_names(words: &[&str], joint: SpringJoint) -> Self {
        Self {
            source: SpringSource::Names {
                words: words.iter().map(|w| w.to_string()).collect(),
                joint,
            },
            enabled: true,
        }
    }

    /// The chains of a VRM 1.0 file's `VRMC_springBone` ([`SpringSource::Vrm`]).
    pub fn vrm(gltf: impl Into<Arc<[u8]>>) -> Self {
        Self {
            source: SpringSource::Vrm(gltf.into()),
            enabled: true,
        }
    }

    /// A rig built in code ([`SpringSource::Rig`]).
    pub fn rig(rig: SpringRig) -> Self {
        Self {
            source: SpringSource::Rig(Arc::new(rig)),
            enabled: true,
        }
    }
}

/// What a character's [`SpringBones`] resolved to; readable by UIs and tests.
#[derive(Component, Debug, Clone, Default, Reflect)]
#[reflect(Component, Default)]
pub struct SpringStatus {
    /// Chains simulated.
    pub chains: usize,
    /// Joints in them (tails included).
    pub joints: usize,
    /// Why the springs could not be set up, if they could not.
    pub error: Option<String>,
}

/// The simulation of one character's springs (not reflected: runtime state).
#[derive(Component)]
pub(crate) struct SpringRuntime {
    rig: Arc<SpringRig>,
    state: SpringState,
    /// Per skeleton joint: the rotation the springs wrote last frame, and the animated one it
    /// replaced (a joint nobody rewrote since is still animated by that one).
    written: Vec<Option<(Quat, Quat)>>,
    /// The character's `PoseLimits`, resolved against its skeleton (until they change).
    limits: Option<Arc<crate::pose::JointLimits>>,
}
