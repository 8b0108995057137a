//! Spring rigs in RON, joints by name, for rigs without a VRM extension
//! ([`SpringRig::from_ron`]).

use glam::DVec3;
use serde::Deserialize;

use crate::pose::rig::skeleton::Skeleton;
use crate::pose::springs::{
    SpringChain, SpringCollider, SpringColliderShape, SpringError, SpringJoint, SpringRig,
    SpringSettings,
};

/// Why a RON spring rig could not be read.
#[derive(Debug, thiserror::Error)]
pub enum SpringRonError {
    /// The text is not the format of [`SpringRig::from_ron`].
    #[error("spring rig RON: {0}")]
    Parse(String),
    /// A chain or collider names a joint the skeleton does not have.
    #[error("spring chain or collider {owner:?} names joint {joint:?}, which the skeleton lacks")]
    UnknownJoint {
        /// The chain's name, or `collider N`.
        owner: String,
        /// The joint's name.
        joint: String,
    },
    /// The rig read does not fit the skeleton.
    #[error(transparent)]
    Rig(#[from] SpringError),
}

#[derive(Deserialize)]
struct RigFile {
    chains: Vec<ChainFile>,
    #[serde(default)]
    colliders: Vec<ColliderFile>,
    #[serde(default)]
    collider_groups: Vec<Vec<usize>>,
    #[serde(default)]
    settings: Option<SpringSettings>,
}

#[derive(Deserialize)]
struct ChainFile {
    name: String,
    joints: Vec<String>,
    stiffness: Option<f64>,
    drag: Option<f64>,
    gravity_power: Option<f64>,
    gravity_dir: Option<(f64, f64, f64)>,
    hit_radius: Option<f64>,
    #[serde(default)]
    collider_groups: Vec<usize>,
    center: Option<String>,
}

#[derive(Deserialize)]
struct ColliderFile {
    joint: String,
    offset: (f64, f64, f64),
    tail: Option<(f64, f64, f64)>,
    radius: f64,
}

impl SpringRig {
    /// A rig from RON text naming joints of `skeleton`, checked with
    /// [`SpringRig::validate`]:
    ///
    /// ```ron
    /// (
    ///     chains: [
    ///         (name: "tail", joints: ["b_Tail01_012", "b_Tail02_013", "b_Tail03_014"],
    ///          stiffness: 1.2, drag: 0.35, gravity_power: 0.3, gravity_dir: (0.0, -1.0, 0.0),
    ///          hit_radius: 0.02, collider_groups: [0]),
    ///     ],
    ///     colliders: [(joint: "b_Hip_01", offset: (0.0, 0.0, 0.0), radius: 10.0)],
    ///     collider_groups: [[0]],
    /// )
    /// ```
    ///
    /// One set of settings per chain (every joint of it shares them); a collider with a `tail`
    /// is a capsule, without one a sphere; settings left out take [`SpringJoint::new`]'s
    /// values, `settings` (the time stepping) [`SpringSettings::default`]'s.
    pub fn from_ron(text: &str, skeleton: &Skeleton) -> Result<SpringRig, SpringRonError> {
        // Settings are written plainly (`stiffness: 1.2`), not as `Some(1.2)`.
        let file: RigFile = ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .from_str(text)
            .map_err(|e| SpringRonError::Parse(e.to_string()))?;
        let find = |owner: &str, joint: &str| {
            skeleton
                .find(joint)
                .ok_or_else(|| SpringRonError::UnknownJoint {
                    owner: owner.to_string(),
                    joint: joint.to_string(),
                })
        };
        let mut chains = Vec::with_capacity(file.chains.len());
        for c in &file.chains {
            let base = SpringJoint::new(0);
            let settings = SpringJoint {
                stiffness: c.stiffness.unwrap_or(base.stiffness),
                drag: c.drag.unwrap_or(base.drag),
                gravity_power: c.gravity_power.unwrap_or(base.gravity_power),
                gravity_dir: c.gravity_dir.map_or(base.gravity_dir, DVec3::from),
                hit_radius: c.hit_radius.unwrap_or(base.hit_radius),
                ..base
            };
            let joints = c
                .joints
                .iter()
                .map(|j| {
                    Ok(SpringJoint {
                        joint: find(&c.name, j)?,
                        ..settings
                    })
                })
                .collect::<Result<Vec<_>, SpringRonError>>()?;
            let center = match &c.center {
                Some(j) => Some(find(&c.name, j)?),
                None => None,
            };
            chains.push(SpringChain {
                name: c.name.clone(),
                joints,
                collider_groups: c.collider_groups.clone(),
                center,
            });
        }
        let mut colliders = Vec::with_capacity(file.colliders.len());
        for (k, c) in file.colliders.iter().enumerate() {
            let offset = DVec3::from(c.offset);
            colliders.push(SpringCollider {
                joint: find(&format!("collider {k}"), &c.joint)?,
                shape: match c.tail {
                    None => SpringColliderShape::Sphere {
                        offset,
                        radius: c.radius,
                    },
                    Some(tail) => SpringColliderShape::Capsule {
                        offset,
                        tail: DVec3::from(tail),
                        radius: c.radius,
                    },
                },
            });
        }
        let rig = SpringRig {
            chains,
            colliders,
            collider_groups: file.collider_groups,
            settings: file.settings.unwrap_or_default(),
        };
        rig.validate(skeleton)?;
        Ok(rig)
    }
}
