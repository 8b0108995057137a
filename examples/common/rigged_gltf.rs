//! Reads a rigged glTF (`.glb`/`.gltf`) with the `gltf` crate into the pose core's types,
//! without Bevy: the primitives of every mesh node bound to the first skin, that skin's joints
//! (parents from the node hierarchy, non-joint ancestors folded into the roots' parent frames). Used by
//! the benchmark; an app uses Bevy's loader and `Poseable` instead.

use std::path::Path;

use bevy_wii_deform::pose::{Joint, Skeleton, SkinnedMesh};
use glam::{DAffine3, Mat4, Vec3};

/// A character read from a glTF file.
pub struct RiggedGltf {
    /// Joints, parents first.
    pub skeleton: Skeleton,
    /// All primitives of the skinned mesh, concatenated.
    pub mesh: SkinnedMesh,
}

/// Loads the first skin of `path` and every mesh bound to it.
pub fn load(path: &Path) -> Result<RiggedGltf, String> {
    let (document, buffers, _) = gltf::import(path).map_err(|e| e.to_string())?;
    let mut parent = vec![None; document.nodes().len()];
    for node in document.nodes() {
        for child in node.children() {
            parent[child.index()] = Some(node.index());
        }
    }
    let local: Vec<DAffine3> = document
        .nodes()
        .map(|n| DAffine3::from_mat4(Mat4::from_cols_array_2d(&n.transform().matrix()).as_dmat4()))
        .collect();
    let global = |mut i: usize| {
        let mut m = local[i];
        while let Some(p) = parent[i] {
            m = local[p] * m;
            i = p;
        }
        m
    };
    let node = document
        .nodes()
        .find(|n| n.skin().is_some() && n.mesh().is_some())
        .ok_or("no skinned mesh in the file")?;
    let skin = node.skin().expect("checked");
    let joint_nodes: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    let inverse_binds: Vec<DAffine3> = match skin
        .reader(|b| Some(&buffers[b.index()]))
        .read_inverse_bind_matrices()
    {
        Some(m) => m
            .map(|m| DAffine3::from_mat4(Mat4::from_cols_array_2d(&m).as_dmat4()))
            .collect(),
        None => vec![DAffine3::IDENTITY; joint_nodes.len()],
    };
    let joint_of = |n: usize| joint_nodes.iter().position(|&j| j == n);
    let joints: Vec<Joint> = joint_nodes
        .iter()
        .enumerate()
        .map(|(k, &n)| {
            let mut up = parent[n];
            while let Some(p) = up {
                if joint_of(p).is_some() {
                    break;
                }
                up = parent[p];
            }
            let parent_joint = up.and_then(joint_of);
            Joint {
                name: document
                    .nodes()
                    .nth(n)
                    .and_then(|n| n.name().map(String::from))
                    .unwrap_or_else(|| format!("joint{k}")),
                parent: parent_joint,
                parent_frame: if parent_joint.is_none() {
                    parent[n].map_or(DAffine3::IDENTITY, global)
                } else {
                    DAffine3::IDENTITY
                },
                inverse_bind: inverse_binds[k],
            }
        })
        .collect();
    let (skeleton, order) = Skeleton::sorted(joints).map_err(|e| e.to_string())?;
    let mut new_index = vec![0u16; order.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old] = new as u16;
    }
    // Every mesh node bound to this skin (body, head and legs exported as separate nodes are
    // one character), in node order, as the pose plugin builds the model.
    let skin_index = skin.index();
    let primitives = document
        .nodes()
        .filter(|n| n.skin().is_some_and(|s| s.index() == skin_index))
        .filter_map(|n| n.mesh())
        .flat_map(|m| m.primitives().collect::<Vec<_>>());
    let mut mesh = SkinnedMesh::default();
    for primitive in primitives {
        append_primitive(&mut mesh, &primitive, &buffers, &new_index)?;
    }
    Ok(RiggedGltf { skeleton, mesh })
}

/// Appends a primitive's positions, skin attributes (joints renumbered by `new_index`) and
/// triangles to `mesh`.
fn append_primitive(
    mesh: &mut SkinnedMesh,
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    new_index: &[u16],
) -> Result<(), String> {
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let base = mesh.positions.len() as u32;
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or("a primitive has no positions")?
        .map(Vec3::from)
        .collect();
    let count = positions.len();
    mesh.positions.extend(positions);
    let joints: Vec<[u16; 4]> = reader
        .read_joints(0)
        .ok_or("a primitive has no JOINTS_0")?
        .into_u16()
        .collect();
    let weights: Vec<[f32; 4]> = reader
        .read_weights(0)
        .ok_or("a primitive has no WEIGHTS_0")?
        .into_f32()
        .collect();
    if joints.len() != count || weights.len() != count {
        return Err("skin attribute lengths differ from the positions".into());
    }
    mesh.joint_indices.extend(
        joints
            .into_iter()
            .map(|j| j.map(|j| *new_index.get(j as usize).unwrap_or(&u16::MAX))),
    );
    mesh.joint_weights.extend(weights);
    match reader.read_indices() {
        Some(i) => mesh.indices.extend(i.into_u32().map(|i| i + base)),
        None => mesh.indices.extend(base..base + count as u32),
    }
    Ok(())
}
