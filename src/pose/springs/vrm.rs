//! Reading VRM 1.0's `VRMC_springBone` extension from a glTF document.
//!
//! Springs name glTF nodes by index; the skeleton names joints by node name (Bevy's loader
//! names an unnamed node `GltfNode{index}`, and so does this reader). Settings missing from a
//! joint take the specification's defaults (stiffness 1, drag 0.5, gravity 0 along −Y, hit
//! radius 0). glTF is right-handed with +Y up, as Bevy: no axis conversion.

use glam::DVec3;
use serde_json::Value;

use crate::pose::rig::skeleton::Skeleton;
use crate::pose::springs::{
    SpringChain, SpringCollider, SpringColliderShape, SpringError, SpringJoint, SpringRig,
};

/// Why a `VRMC_springBone` extension could not be read.
#[derive(Debug, thiserror::Error)]
pub enum VrmSpringError {
    /// The bytes are neither glTF JSON nor a binary glTF.
    #[error("not a glTF document: {0}")]
    NotGltf(String),
    /// The document has no `VRMC_springBone` extension.
    #[error("the glTF has no VRMC_springBone extension")]
    NoExtension,
    /// A field has the wrong type or is missing (its JSON path).
    #[error("VRMC_springBone: {0} is missing or malformed")]
    Malformed(String),
    /// A spring or collider names a node that is not a joint of the skeleton.
    #[error("VRMC_springBone names node {node} ({name:?}), which is not a joint of the skin")]
    NotAJoint {
        /// The node index.
        node: usize,
        /// Its name.
        name: String,
    },
    /// The springs read do not fit the skeleton.
    #[error(transparent)]
    Rig(#[from] SpringError),
}

/// The spring rig of a VRM 1.0 model: `gltf` is the file's bytes (`.gltf` JSON, or `.glb`),
/// `skeleton` its skin as the pose layer reads it.
pub fn read_vrm_springs(gltf: &[u8], skeleton: &Skeleton) -> Result<SpringRig, VrmSpringError> {
    let json = crate::pose::rig::gltf_file::json_of(gltf)
        .map_err(|e| VrmSpringError::NotGltf(e.to_string()))?;
    let root: Value =
        serde_json::from_slice(&json).map_err(|e| VrmSpringError::NotGltf(e.to_string()))?;
    let ext = root
        .pointer("/extensions/VRMC_springBone")
        .ok_or(VrmSpringError::NoExtension)?;
    let nodes = root
        .get("nodes")
        .and_then(Value::as_array)
        .ok_or_else(|| malformed("nodes"))?;
    let joint_of = |node: &Value, path: &str| -> Result<usize, VrmSpringError> {
        let i = node.as_u64().ok_or_else(|| malformed(path))? as usize;
        let name = nodes
            .get(i)
            .ok_or_else(|| malformed(path))?
            .get("name")
            .and_then(Value::as_str)
            .map_or_else(|| format!("GltfNode{i}"), str::to_string);
        skeleton
            .find(&name)
            .ok_or(VrmSpringError::NotAJoint { node: i, name })
    };

    let mut colliders = Vec::new();
    for (c, collider) in array(ext, "colliders")?.iter().enumerate() {
        let path = format!("colliders[{c}]");
        let joint = joint_of(
            collider.get("node").unwrap_or(&Value::Null),
            &format!("{path}.node"),
        )?;
        let shape = collider
            .get("shape")
            .ok_or_else(|| malformed(&format!("{path}.shape")))?;
        let shape = if let Some(s) = shape.get("sphere") {
            SpringColliderShape::Sphere {
                offset: vec3(s.get("offset"), DVec3::ZERO, &path)?,
                radius: number(s.get("radius"), 0.0, &path)?,
            }
        } else if let Some(s) = shape.get("capsule") {
            SpringColliderShape::Capsule {
                offset: vec3(s.get("offset"), DVec3::ZERO, &path)?,
                tail: vec3(s.get("tail"), DVec3::ZERO, &path)?,
                radius: number(s.get("radius"), 0.0, &path)?,
            }
        } else {
            return Err(malformed(&format!("{path}.shape")));
        };
        colliders.push(SpringCollider { joint, shape });
    }
    let mut collider_groups = Vec::new();
    for (g, group) in array(ext, "colliderGroups")?.iter().enumerate() {
        let members = group
            .get("colliders")
            .and_then(Value::as_array)
            .ok_or_else(|| malformed(&format!("colliderGroups[{g}].colliders")))?;
        let members: Option<Vec<usize>> = members
            .iter()
            .map(|m| m.as_u64().map(|m| m as usize))
            .collect();
        collider_groups.push(members.ok_or_else(|| malformed(&format!("colliderGroups[{g}]")))?);
    }
    let mut chains = Vec::new();
    for (s, spring) in array(ext, "springs")?.iter().enumerate() {
        let path = format!("springs[{s}]");
        let mut joints = Vec::new();
        for (k, joint) in spring
            .get("joints")
            .and_then(Value::as_array)
            .ok_or_else(|| malformed(&format!("{path}.joints")))?
            .iter()
            .enumerate()
        {
            let jp = format!("{path}.joints[{k}]");
            let node = joint.get("node").unwrap_or(&Value::Null);
            joints.push(SpringJoint {
                joint: joint_of(node, &format!("{jp}.node"))?,
                stiffness: number(joint.get("stiffness"), 1.0, &jp)?,
                drag: number(joint.get("dragForce"), 0.5, &jp)?,
                gravity_power: number(joint.get("gravityPower"), 0.0, &jp)?,
                gravity_dir: vec3(joint.get("gravityDir"), DVec3::NEG_Y, &jp)?,
                hit_radius: number(joint.get("hitRadius"), 0.0, &jp)?,
            });
        }
        let groups = spring
            .get("colliderGroups")
            .and_then(Value::as_array)
            .map(|g| {
                g.iter()
                    .filter_map(|v| v.as_u64().map(|v| v as usize))
                    .collect()
            })
            .unwrap_or_default();
        let center = match spring.get("center") {
            Some(node) => Some(joint_of(node, &format!("{path}.center"))?),
            None => None,
        };
        chains.push(SpringChain {
            name: spring
                .get("name")
                .and_then(Value::as_str)
                .map_or_else(|| format!("spring {s}"), str::to_string),
            joints,
            collider_groups: groups,
            center,
        });
    }
    let rig = SpringRig {
        chains,
        colliders,
        collider_groups,
        ..Default::default()
    };
    rig.validate(skeleton)?;
    Ok(rig)
}

fn malformed(path: &str) -> VrmSpringError {
    VrmSpringError::Malformed(path.to_string())
}

/// `ext[key]` as an array; an absent key is an empty one.
fn array<'a>(ext: &'a Value, key: &str) -> Result<&'a [Value], VrmSpringError> {
    match ext.get(key) {
        None => Ok(&[]),
        Some(v) => v
            .as_array()
            .map(Vec::as_slice)
            .ok_or_else(|| malformed(key)),
    }
}

fn number(v: Option<&Value>, default: f64, path: &str) -> Result<f64, VrmSpringError> {
    match v {
        None => Ok(default),
        Some(v) => v
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| malformed(path)),
    }
}

fn vec3(v: Option<&Value>, default: DVec3, path: &str) -> Result<DVec3, VrmSpringError> {
    let Some(v) = v else { return Ok(default) };
    let a = v
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| malformed(path))?;
    let x: Option<Vec<f64>> = a.iter().map(Value::as_f64).collect();
    let x = x.ok_or_else(|| malformed(path))?;
    Ok(DVec3::new(x[0], x[1], x[2]))
}
