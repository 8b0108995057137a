//! A rigged character read from a glTF file without Bevy: the skeleton of the first skinned
//! mesh's skin, the skin of every mesh bound to that skin as one mesh, and the pose the file's
//! nodes hold. The same reading the ECS layer does on a scene Bevy spawned (joint parents are
//! the nearest joint ancestors; a root joint's parent frame is its parent node's world
//! transform), for tools, benchmarks, retargeting sources and targets, and the fuzz targets.
//!
//! Everything a file claims is checked: the node hierarchy must be a forest (no node with two
//! parents, no cycle), at most [`MAX_JOINTS`] joints, every transform finite, every accessor
//! within the [`GltfFile`] bounds, every index in range.

use std::path::Path;

use glam::{DAffine3, DMat4, DQuat, DVec3, Vec3};

use crate::pose::error::PoseError;
use crate::pose::rig::gltf_file::{AccessorUse, GltfFile, GltfFileError};
use crate::pose::rig::model::{ModelSettings, SkinnedMesh, SkinnedModel};
use crate::pose::rig::skeleton::{Joint, JointTransform, Skeleton, SkeletonPose};

/// The most joints a character read from a file may have (a humanoid with fingers and a face
/// rig has about 200).
pub const MAX_JOINTS: usize = 1024;

/// A rigged character as a glTF file describes it.
#[derive(Debug, Clone)]
pub struct GltfCharacter {
    /// The skin's joints, parents first.
    pub skeleton: Skeleton,
    /// The pose the file's nodes hold (the rest pose a clip's unanimated joints keep), one
    /// local transform per joint of [`GltfCharacter::skeleton`].
    pub rest: SkeletonPose,
    /// Every primitive skinned to the skin, as one mesh (bind-pose positions, joint indices
    /// into [`GltfCharacter::skeleton`]).
    pub mesh: SkinnedMesh,
    /// Per joint of the skeleton, its node's index in the file.
    pub nodes: Vec<usize>,
}

impl GltfCharacter {
    /// The character prepared for posing ([`SkinnedModel::new`] at its rest pose).
    pub fn model(&self, settings: ModelSettings) -> Result<SkinnedModel, PoseError> {
        SkinnedModel::new(self.skeleton.clone(), &self.mesh, &self.rest, settings)
    }
}

/// Why a character could not be read from a file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CharacterReadError {
    /// The file could not be read, or claims more than the readers' bounds.
    #[error(transparent)]
    File(#[from] GltfFileError),
    /// No node has both a mesh and a skin.
    #[error("the file has no skinned mesh")]
    NoSkinnedMesh,
    /// A node is the child of two nodes, or its own ancestor.
    #[error("node {node} has two parents or is its own ancestor")]
    NodeHierarchy {
        /// The node.
        node: usize,
    },
    /// A node's transform is not finite, or its rotation has no length.
    #[error("node {node} has a non-finite transform")]
    NonFiniteNode {
        /// The node.
        node: usize,
    },
    /// The skin has more joints than [`MAX_JOINTS`].
    #[error("the skin has {count} joints, past the bound of {limit}")]
    TooManyJoints {
        /// Joints in the skin.
        count: usize,
        /// [`MAX_JOINTS`].
        limit: usize,
    },
    /// A node is listed twice among the skin's joints.
    #[error("node {node} is listed twice among the skin's joints")]
    DuplicateJoint {
        /// The node.
        node: usize,
    },
    /// The skin has fewer inverse bind matrices than joints, or one is not finite.
    #[error("the skin has {matrices} usable inverse bind matrices for {joints} joints")]
    InverseBinds {
        /// Finite matrices read.
        matrices: usize,
        /// Joints in the skin.
        joints: usize,
    },
    /// A skinned primitive lacks an attribute posing needs.
    #[error("mesh {mesh} primitive {primitive} has no {attribute}")]
    MissingAttribute {
        /// The mesh's index.
        mesh: usize,
        /// The primitive's index within the mesh.
        primitive: usize,
        /// `POSITION`, `JOINTS_0` or `WEIGHTS_0`.
        attribute: &'static str,
    },
    /// A primitive's index names a vertex it does not have, or its triangle list is cut short.
    #[error(
        "mesh {mesh} primitive {primitive} has indices that do not form triangles of its vertices"
    )]
    BadIndices {
        /// The mesh's index.
        mesh: usize,
        /// The primitive's index within the mesh.
        primitive: usize,
    },
    /// The skeleton or the skin is invalid (joint order, weights, attribute lengths).
    #[error(transparent)]
    Pose(#[from] PoseError),
}

/// Reads the character of a glTF file's bytes (`folder` is where a `.gltf`'s external buffers
/// are looked for).
pub fn read_gltf_character(
    bytes: &[u8],
    folder: Option<&Path>,
) -> Result<GltfCharacter, CharacterReadError> {
    GltfCharacter::from_file(&GltfFile::parse(bytes, folder)?)
}

impl GltfCharacter {
    /// Reads the character of the glTF file at `path`.
    pub fn read(path: &Path) -> Result<Self, CharacterReadError> {
        Self::from_file(&GltfFile::read(path)?)
    }

    /// The character of an already parsed file (whose clips may be read next).
    pub fn from_file(file: &GltfFile) -> Result<Self, CharacterReadError> {
        character_of(file)
    }
}

fn character_of(file: &GltfFile) -> Result<GltfCharacter, CharacterReadError> {
    let document = file.document();
    let nodes = NodeForest::new(document)?;
    let Some(skinned) = document
        .nodes()
        .find(|n| n.mesh().is_some() && n.skin().is_some())
    else {
        return Err(CharacterReadError::NoSkinnedMesh);
    };
    let Some(skin) = skinned.skin() else {
        return Err(CharacterReadError::NoSkinnedMesh);
    };
    let joint_nodes: Vec<usize> = skin.joints().map(|n| n.index()).collect();
    if joint_nodes.len() > MAX_JOINTS {
        return Err(CharacterReadError::TooManyJoints {
            count: joint_nodes.len(),
            limit: MAX_JOINTS,
        });
    }
    let mut joint_of_node = vec![usize::MAX; nodes.parent.len()];
    for (j, &node) in joint_nodes.iter().enumerate() {
        if joint_of_node[node] != usize::MAX {
            return Err(CharacterReadError::DuplicateJoint { node });
        }
        joint_of_node[node] = j;
    }
    let inverse_binds = inverse_binds(file, &skin, joint_nodes.len())?;
    let mut list = Vec::with_capacity(joint_nodes.len());
    for (j, &node) in joint_nodes.iter().enumerate() {
        let mut up = nodes.parent[node];
        let mut parent = None;
        while let Some(p) = up {
            if joint_of_node[p] != usize::MAX {
                parent = Some(joint_of_node[p]);
                break;
            }
            up = nodes.parent[p];
        }
        let parent_frame = match (parent, nodes.parent[node]) {
            (None, Some(p)) => nodes.world[p],
            _ => DAffine3::IDENTITY,
        };
        let name = document
            .nodes()
            .nth(node)
            .and_then(|n| n.name().map(str::to_string))
            .unwrap_or_else(|| format!("node {node}"));
        list.push(Joint {
            name,
            parent,
            parent_frame,
            inverse_bind: inverse_binds[j],
        });
    }
    let (skeleton, order) = Skeleton::sorted(list)?;
    let mut new_index = vec![u16::MAX; order.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old] = new as u16;
    }
    let mut mesh = skinned_mesh(file, skin.index())?;
    for ji in &mut mesh.joint_indices {
        *ji = ji.map(|j| new_index.get(j as usize).copied().unwrap_or(u16::MAX));
    }
    let rest = SkeletonPose {
        local: order
            .iter()
            .map(|&old| nodes.local[joint_nodes[old]])
            .collect(),
    };
    Ok(GltfCharacter {
        skeleton,
        rest,
        mesh,
        nodes: order.iter().map(|&old| joint_nodes[old]).collect(),
    })
}

/// The node hierarchy, checked to be a forest, with each node's local and world transform.
struct NodeForest {
    parent: Vec<Option<usize>>,
    local: Vec<JointTransform>,
    world: Vec<DAffine3>,
}

impl NodeForest {
    fn new(document: &gltf::Document) -> Result<Self, CharacterReadError> {
        let count = document.nodes().len();
        let mut parent = vec![None; count];
        let mut local = Vec::with_capacity(count);
        for node in document.nodes() {
            for child in node.children() {
                let c = child.index();
                if parent[c].is_some() || c == node.index() {
                    return Err(CharacterReadError::NodeHierarchy { node: c });
                }
                parent[c] = Some(node.index());
            }
            let (t, r, s) = node.transform().decomposed();
            let rotation = DQuat::from_array(r.map(f64::from));
            let transform = JointTransform {
                translation: DVec3::from_array(t.map(f64::from)),
                rotation: rotation.normalize(),
                scale: DVec3::from_array(s.map(f64::from)),
            };
            if !rotation.is_finite() || rotation.length() < 1e-6 || !transform.is_valid() {
                return Err(CharacterReadError::NonFiniteNode { node: node.index() });
            }
            local.push(transform);
        }
        // World transforms parents first; a node met again while its own chain is being
        // walked is in a cycle.
        const UNSEEN: u8 = 0;
        const WALKING: u8 = 1;
        const DONE: u8 = 2;
        let mut state = vec![UNSEEN; count];
        let mut world = vec![DAffine3::IDENTITY; count];
        let mut chain = Vec::new();
        for start in 0..count {
            let mut at = Some(start);
            while let Some(n) = at {
                match state[n] {
                    DONE => break,
                    WALKING => return Err(CharacterReadError::NodeHierarchy { node: n }),
                    _ => {
                        state[n] = WALKING;
                        chain.push(n);
                        at = parent[n];
                    }
                }
            }
            while let Some(n) = chain.pop() {
                let above = parent[n].map_or(DAffine3::IDENTITY, |p| world[p]);
                world[n] = above * local[n].to_affine();
                if !(world[n].matrix3.is_finite() && world[n].translation.is_finite()) {
                    return Err(CharacterReadError::NonFiniteNode { node: n });
                }
                state[n] = DONE;
            }
        }
        Ok(Self {
            parent,
            local,
            world,
        })
    }
}

/// The skin's inverse bind matrices (identity when the skin has none, as glTF says).
fn inverse_binds(
    file: &GltfFile,
    skin: &gltf::Skin<'_>,
    joints: usize,
) -> Result<Vec<DAffine3>, CharacterReadError> {
    let Some(accessor) = skin.inverse_bind_matrices() else {
        return Ok(vec![DAffine3::IDENTITY; joints]);
    };
    file.admit(&accessor, AccessorUse::Matrices)?;
    let reader = skin.reader(|b| file.buffer(b));
    let matrices: Vec<DAffine3> = reader
        .read_inverse_bind_matrices()
        .ok_or_else(|| GltfFileError::Unreadable {
            what: format!("skin {}'s inverse bind matrices", skin.index()),
        })?
        .take(joints)
        .map(|m| DAffine3::from_mat4(DMat4::from_cols_array_2d(&m.map(|c| c.map(f64::from)))))
        .take_while(|a| a.matrix3.is_finite() && a.translation.is_finite())
        .collect();
    if matrices.len() < joints {
        return Err(CharacterReadError::InverseBinds {
            matrices: matrices.len(),
            joints,
        });
    }
    Ok(matrices)
}

/// Every triangle primitive of every node skinned by skin `skin`, as one mesh (points and lines
/// have no surface and are left out; strips and fans become triangle lists).
fn skinned_mesh(file: &GltfFile, skin: usize) -> Result<SkinnedMesh, CharacterReadError> {
    let mut mesh = SkinnedMesh::default();
    let skinned = file
        .document()
        .nodes()
        .filter(|n| n.skin().is_some_and(|s| s.index() == skin))
        .filter_map(|n| n.mesh());
    for gltf_mesh in skinned {
        for primitive in gltf_mesh.primitives() {
            let (m, p) = (gltf_mesh.index(), primitive.index());
            let missing = |attribute| CharacterReadError::MissingAttribute {
                mesh: m,
                primitive: p,
                attribute,
            };
            use gltf::mesh::Mode;
            let mode = primitive.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                continue;
            }
            for (semantic, element) in [
                (gltf::Semantic::Positions, AccessorUse::Positions),
                (gltf::Semantic::Joints(0), AccessorUse::Joints),
                (gltf::Semantic::Weights(0), AccessorUse::Weights),
            ] {
                if let Some(accessor) = primitive.get(&semantic) {
                    file.admit(&accessor, element)?;
                }
            }
            if let Some(indices) = primitive.indices() {
                file.admit(&indices, AccessorUse::Indices)?;
            }
            let reader = primitive.reader(|b| file.buffer(b));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or_else(|| missing("POSITION"))?
                .map(Vec3::from_array)
                .collect();
            let joints: Vec<[u16; 4]> = reader
                .read_joints(0)
                .ok_or_else(|| missing("JOINTS_0"))?
                .into_u16()
                .collect();
            let weights: Vec<[f32; 4]> = reader
                .read_weights(0)
                .ok_or_else(|| missing("WEIGHTS_0"))?
                .into_f32()
                .collect();
            let count = positions.len();
            let corners: Vec<u32> = match reader.read_indices() {
                Some(indices) => indices.into_u32().collect(),
                None => (0..count as u32).collect(),
            };
            let bad = || CharacterReadError::BadIndices {
                mesh: m,
                primitive: p,
            };
            if corners.iter().any(|&i| i as usize >= count) {
                return Err(bad());
            }
            let triangles = triangle_list(mode, &corners).ok_or_else(bad)?;
            let base = mesh.positions.len() as u32;
            mesh.indices.extend(triangles.iter().map(|i| i + base));
            mesh.positions.extend(positions);
            mesh.joint_indices.extend(joints);
            mesh.joint_weights.extend(weights);
            // Attribute lengths that differ are refused by the model's skin check; keep the
            // concatenation aligned so one primitive's shortfall is not hidden by the next.
            let longest = mesh
                .positions
                .len()
                .max(mesh.joint_indices.len())
                .max(mesh.joint_weights.len());
            if longest != mesh.positions.len()
                || longest != mesh.joint_indices.len()
                || longest != mesh.joint_weights.len()
            {
                return Err(PoseError::AttributeLength {
                    positions: mesh.positions.len(),
                    joints: mesh.joint_indices.len(),
                    weights: mesh.joint_weights.len(),
                }
                .into());
            }
        }
    }
    if mesh.positions.is_empty() {
        return Err(CharacterReadError::NoSkinnedMesh);
    }
    Ok(mesh)
}

/// A primitive's corners as a triangle list; `None` when a list is cut short.
fn triangle_list(mode: gltf::mesh::Mode, corners: &[u32]) -> Option<Vec<u32>> {
    use gltf::mesh::Mode;
    match mode {
        Mode::TriangleStrip => Some(
            (2..corners.len())
                .flat_map(|k| {
                    if k % 2 == 0 {
                        [corners[k - 2], corners[k - 1], corners[k]]
                    } else {
                        [corners[k - 1], corners[k - 2], corners[k]]
                    }
                })
                .collect(),
        ),
        Mode::TriangleFan => Some(
            (2..corners.len())
                .flat_map(|k| [corners[0], corners[k - 1], corners[k]])
                .collect(),
        ),
        _ => corners.len().is_multiple_of(3).then(|| corners.to_vec()),
    }
}
