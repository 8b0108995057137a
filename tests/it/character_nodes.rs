//! Rigged characters as converters export them: a humanoid whose mesh is split over three
//! mesh nodes (body, head, legs) sharing one skin, its origin at the hips (as FBX conversions
//! often come out), and one bound with a non-uniform scale under a ×100 armature, each
//! written as a glTF file and loaded through Bevy's own glTF loader.

use bevy::prelude::*;
use bevy_wii_deform::deform::glb_container;
use bevy_wii_deform::pose::rig::synth_rig::{SyntheticRig, mannequin_rig};
use bevy_wii_deform::prelude::*;
use glam::DVec3;
use serde_json::json;

use crate::common::scratch::ScratchDir;
use crate::common::{self, drive_solves, settle_pose, spawn_handle};

/// The parts the mesh is split into, by the height of each triangle's centroid (bind pose,
/// feet at y = 0): legs below the hips, the head above the neck, the body between.
fn part_of(y: f64) -> usize {
    match y {
        y if y < 0.9 => 2,
        y if y > 1.45 => 1,
        _ => 0,
    }
}

const PARTS: [&str; 3] = ["body", "head", "legs"];

/// The binary buffer, buffer views and accessors of a glTF being written.
#[derive(Default)]
struct GlbBuffers {
    bin: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl GlbBuffers {
    /// Appends `bytes` (4-byte aligned) with their accessor; returns the accessor's index.
    fn push(&mut self, bytes: Vec<u8>, accessor: serde_json::Value) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend(bytes);
        let mut a = accessor;
        a["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

/// The vertices (mesh indices) and local triangles of one part (triangles by the height of
/// their centre).
fn part_triangles(
    mesh: &bevy_wii_deform::pose::SkinnedMesh,
    part: usize,
) -> (Vec<usize>, Vec<u32>) {
    let mut index_of = vec![u32::MAX; mesh.positions.len()];
    let mut vertices: Vec<usize> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    for t in mesh.indices.chunks_exact(3) {
        let y = t
            .iter()
            .map(|&i| f64::from(mesh.positions[i as usize].y))
            .sum::<f64>()
            / 3.0;
        if part_of(y) != part {
            continue;
        }
        for &i in t {
            if index_of[i as usize] == u32::MAX {
                index_of[i as usize] = vertices.len() as u32;
                vertices.push(i as usize);
            }
            indices.push(index_of[i as usize]);
        }
    }
    (vertices, indices)
}

/// Smooth normals, as exporters write them (without, Bevy's loader would split every
/// triangle for flat normals).
fn smooth_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<glam::Vec3> {
    let mut normals = vec![glam::Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| glam::Vec3::from_array(positions[t[k] as usize]));
        let area_normal = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += area_normal;
        }
    }
    normals
        .iter()
        .map(|v| v.normalize_or(glam::Vec3::Y))
        .collect()
}

/// One part (`vertices` of `mesh` and its local triangles) as a glTF mesh named `name`, each
/// bind position written as `place` gives it, and its vertex count.
fn part_mesh(
    buffers: &mut GlbBuffers,
    mesh: &bevy_wii_deform::pose::SkinnedMesh,
    (vertices, indices): (Vec<usize>, Vec<u32>),
    name: &str,
    place: &dyn Fn(DVec3) -> DVec3,
) -> (serde_json::Value, usize) {
    let positions: Vec<[f32; 3]> = vertices
        .iter()
        .map(|&v| place(mesh.positions[v].as_dvec3()).as_vec3().to_array())
        .collect();
    let (lo, hi) = positions
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(l, h), p| {
            (
                [l[0].min(p[0]), l[1].min(p[1]), l[2].min(p[2])],
                [h[0].max(p[0]), h[1].max(p[1]), h[2].max(p[2])],
            )
        });
    let n = vertices.len();
    let bytes = |floats: &mut dyn Iterator<Item = f32>| -> Vec<u8> {
        floats.flat_map(|f| f.to_le_bytes()).collect()
    };
    let normals = smooth_normals(&positions, &indices);
    let normal = buffers.push(
        bytes(&mut normals.iter().flat_map(|v| v.to_array())),
        json!({"componentType": 5126, "count": n, "type": "VEC3"}),
    );
    let position = buffers.push(
        bytes(&mut positions.iter().flatten().copied()),
        json!({"componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}),
    );
    let joints = buffers.push(
        vertices
            .iter()
            .flat_map(|&v| mesh.joint_indices[v])
            .flat_map(|j| j.to_le_bytes())
            .collect(),
        json!({"componentType": 5123, "count": n, "type": "VEC4"}),
    );
    let weights = buffers.push(
        bytes(&mut vertices.iter().flat_map(|&v| mesh.joint_weights[v])),
        json!({"componentType": 5126, "count": n, "type": "VEC4"}),
    );
    let index = buffers.push(
        indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
        json!({"componentType": 5125, "count": indices.len(), "type": "SCALAR"}),
    );
    let json = json!({"name": name, "primitives": [{
        "attributes": {"POSITION": position, "NORMAL": normal, "JOINTS_0": joints, "WEIGHTS_0": weights},
        "indices": index,
    }]});
    (json, n)
}

/// The joint nodes (the root joint at the origin: the hips).
fn joint_nodes(rig: &SyntheticRig) -> Vec<serde_json::Value> {
    rig.skeleton
        .joints()
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let t = if joint.parent.is_some() {
                rig.rest.local[j].translation
            } else {
                DVec3::ZERO
            };
            let children: Vec<usize> = rig.skeleton.children(j).to_vec();
            let mut node = json!({"name": joint.name, "translation": t.as_vec3().to_array()});
            if !children.is_empty() {
                node["children"] = json!(children);
            }
            node
        })
        .collect()
}

/// Writes `rig` as a binary glTF: the joint nodes under a root node, three mesh nodes
/// sharing one skin, everything moved so that the hips are at the origin.
fn three_node_glb(rig: &SyntheticRig) -> (Vec<u8>, [usize; 3]) {
    let hips = rig.rest.local[0].translation;
    let mut buffers = GlbBuffers::default();
    let mut meshes = Vec::new();
    let mut counts = [0usize; 3];
    for (part, count) in counts.iter_mut().enumerate() {
        let triangles = part_triangles(&rig.mesh, part);
        let (mesh, n) = part_mesh(&mut buffers, &rig.mesh, triangles, PARTS[part], &|p| {
            p - hips
        });
        meshes.push(mesh);
        *count = n;
    }
    let joints = rig.skeleton.joints();
    let inverse_binds: Vec<u8> = joints
        .iter()
        .flat_map(|j| {
            // Bind-space positions moved by -hips: the inverse bind follows.
            let m = j.inverse_bind * glam::DAffine3::from_translation(hips);
            glam::Mat4::from(m.as_affine3a()).to_cols_array()
        })
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let ibm = buffers.push(
        inverse_binds,
        json!({"componentType": 5126, "count": joints.len(), "type": "MAT4"}),
    );
    let mut nodes = joint_nodes(rig);
    let first_part = nodes.len();
    for (part, name) in PARTS.iter().enumerate() {
        nodes.push(json!({"name": name, "mesh": part, "skin": 0}));
    }
    nodes.push(
        json!({"name": "Character", "children": [0, first_part, first_part + 1, first_part + 2]}),
    );
    let root = nodes.len() - 1;
    let document = json!({
        "asset": {"version": "2.0", "generator": "bevy_wii_deform tests"},
        "scene": 0,
        "scenes": [{"nodes": [root]}],
        "nodes": nodes,
        "meshes": meshes,
        "skins": [{"joints": (0..joints.len()).collect::<Vec<_>>(), "inverseBindMatrices": ibm, "skeleton": 0}],
        "accessors": buffers.accessors,
        "bufferViews": buffers.views,
        "buffers": [{"byteLength": buffers.bin.len()}],
    });
    (
        glb_container(serde_json::to_vec(&document).unwrap(), buffers.bin),
        counts,
    )
}

/// What [`drag_head_with_feet_pinned`] saw.
struct HeadDrag {
    /// The head's vertices (render indices).
    head: Vec<u32>,
    /// Their mean motion.
    moved: Vec3,
    /// The farthest a pinned foot moved.
    foot_drift: f32,
    /// Every vertex as drawn after the drag (world).
    now: Vec<Vec3>,
}

/// Pins `character`'s ankles, grabs its head (the vertices within `band` of the top of
/// `drawn`, its render vertices as drawn, world space), drags it by `shift` and lets the pose
/// settle.
fn drag_head_with_feet_pinned(
    app: &mut App,
    character: Entity,
    drawn: &[Vec3],
    band: f32,
    shift: Vec3,
) -> HeadDrag {
    let posed = app.world().get::<PosedSkeleton>(character).unwrap().clone();
    let skeleton = posed.model.skeleton();
    let joint = |name: &str| posed.joints[skeleton.find(name).expect(name)];
    let feet = vec![joint("ankle_l"), joint("ankle_r")];
    app.world_mut()
        .entity_mut(character)
        .insert(PinnedJoints(feet.clone()));
    let world_of =
        |app: &App, e: Entity| app.world().get::<GlobalTransform>(e).unwrap().translation();
    let feet_before: Vec<Vec3> = feet.iter().map(|&f| world_of(app, f)).collect();
    let top = drawn.iter().map(|p| p.y).fold(f32::MIN, f32::max);
    let head: Vec<u32> = (0..drawn.len() as u32)
        .filter(|&i| drawn[i as usize].y > top - band)
        .collect();
    let (handle, pivot) = spawn_handle(app, character, head.clone(), ());
    app.world_mut()
        .get_mut::<Transform>(handle)
        .unwrap()
        .translation = pivot + shift;
    drive_solves(app, character, handle, 20);
    settle_pose(app, character);
    let now = app
        .world()
        .get::<PosedSkeleton>(character)
        .unwrap()
        .skinned_positions();
    let moved = head
        .iter()
        .map(|&i| now[i as usize] - drawn[i as usize])
        .sum::<Vec3>()
        / head.len() as f32;
    let foot_drift = feet
        .iter()
        .zip(&feet_before)
        .map(|(f, before)| world_of(app, *f).distance(*before))
        .fold(0.0, f32::max);
    app.world_mut().despawn(handle);
    HeadDrag {
        head,
        moved,
        foot_drift,
        now,
    }
}

/// The model holds all three nodes' vertices, and a drag on the head bends the body (its
/// vertices by the neck go a quarter of the way or more) with the seams between the nodes
/// closed, while the pinned feet stay (within 1e-3 of the size) and the head follows the drag
/// (within 10 %).
#[test]
fn a_character_of_several_mesh_nodes_poses_as_one() {
    let rig = mannequin_rig(12);
    let (glb, counts) = three_node_glb(&rig);
    assert!(
        counts.iter().all(|&c| c > 20),
        "each part has vertices: {counts:?}"
    );
    let dir = ScratchDir::new("character_nodes");
    std::fs::write(dir.join("humanoid.glb"), glb).unwrap();
    let (mut app, root) = common::character_app(&dir, "humanoid.glb", PosePlugin);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    assert_eq!(posed.primitives.len(), 3, "one model from the three nodes");
    let drawn = posed.skinned_positions();
    assert_eq!(drawn.len(), counts.iter().sum::<usize>());
    // The head: the highest vertices as drawn (the origin is at the hips: the head is at
    // y ≈ 0.6-0.8 here, the feet below zero).
    let size = posed.model.topology().bounding_diagonal() as f32;
    assert!(
        drawn.iter().any(|p| p.y < -0.5),
        "the feet are below the origin"
    );
    let shift = Vec3::new(0.12, -0.05, 0.0);
    let drag = drag_head_with_feet_pinned(&mut app, root, &drawn, 0.1, shift);
    let (moved, now) = (drag.moved, drag.now);
    assert!(
        moved.distance(shift) < 0.1 * shift.length(),
        "the head moved {moved}, the drag was {shift}"
    );
    assert!(
        drag.foot_drift < 1e-3 * size,
        "a pinned foot moved {} (size {size})",
        drag.foot_drift
    );
    // The body carries the head: its vertices near the neck moved with the drag, and the
    // seams between the nodes stay closed (a vertex on a seam is in two nodes: both copies
    // end up at one place).
    let body = posed.primitives[0].1 as usize..posed.primitives[1].1 as usize;
    let body_moved = body
        .clone()
        .map(|i| (now[i] - drawn[i]).dot(shift.normalize()))
        .fold(f32::MIN, f32::max);
    assert!(
        body_moved > 0.25 * shift.length(),
        "the body did not bend towards the drag (at most {body_moved})"
    );
    let mut seams = 0;
    let mut worst_gap = 0.0f32;
    for i in 0..drawn.len() {
        for j in i + 1..drawn.len() {
            if drawn[i].distance(drawn[j]) < 1e-6 {
                seams += 1;
                worst_gap = worst_gap.max(now[i].distance(now[j]));
            }
        }
    }
    assert!(seams > 10, "the parts share seam vertices ({seams})");
    assert!(worst_gap < 1e-5, "a seam opened by {worst_gap}");
}

/// How a converter laid the rig out: the armature node's scale (joint translations are divided
/// by it) and turn, the skinned mesh node's scale (not uniform) and turn — the node's bind
/// folded into the inverse bind matrices — and whether a second root bone chain (an IK
/// target, bound to no vertex) hangs under the armature beside the body's.
#[derive(Clone, Copy, Debug)]
struct ConverterLayout {
    armature_scale: f64,
    turn: glam::DQuat,
    mesh_scale: DVec3,
    second_root_chain: bool,
}

impl ConverterLayout {
    /// A converter's layout: ×100 armature, the mesh node a sibling scaled (1.2, 1, 1).
    const SCALED: Self = Self {
        armature_scale: 100.0,
        turn: glam::DQuat::IDENTITY,
        mesh_scale: DVec3::new(1.2, 1.0, 1.0),
        second_root_chain: false,
    };

    /// The layout common FBX converters write for a Z-up rig: two root bone chains
    /// under one armature node scaled ×100 and turned −90° about X, the skinned mesh node its
    /// sibling with the same turn and a (1.21, 1, 1) scale.
    fn turned() -> Self {
        Self {
            armature_scale: 100.0,
            turn: glam::DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2),
            mesh_scale: DVec3::new(1.21, 1.0, 1.0),
            second_root_chain: true,
        }
    }

    /// The armature node's transform.
    fn armature(&self) -> glam::DAffine3 {
        glam::DAffine3::from_rotation_translation(self.turn, DVec3::ZERO)
            * glam::DAffine3::from_scale(DVec3::splat(self.armature_scale))
    }

    /// The skinned mesh node's transform.
    fn mesh_node(&self) -> glam::DAffine3 {
        glam::DAffine3::from_rotation_translation(self.turn, DVec3::ZERO)
            * glam::DAffine3::from_scale(self.mesh_scale)
    }
}

/// Writes `rig` as an FBX converter does (`layout`): the joints under the armature node (a
/// joint's local transform `X` written as `C⁻¹ X C`, `C` the armature's transform, so that the
/// armature brings them back where the rig has them), the skinned mesh node beside the
/// armature with its vertices in its own frame, and that node's bind folded into the inverse
/// bind matrices — so the mesh is drawn where the rig's bind positions are, but every skin
/// matrix carries the armature's scale and turn and the node's non-uniform scale. Returns the
/// file and, per vertex, the position written (the mesh node's frame) and the inverse bind
/// matrices of the rig's joints (the second chain's follow them in the file).
fn converted_glb(
    rig: &SyntheticRig,
    layout: ConverterLayout,
) -> (Vec<u8>, Vec<DVec3>, Vec<glam::DAffine3>) {
    use glam::DAffine3;
    let node = layout.mesh_node();
    let armature = layout.armature();
    let to_node = node.inverse();
    let mut buffers = GlbBuffers::default();
    let vertices: Vec<usize> = (0..rig.mesh.positions.len()).collect();
    let (mesh, _) = part_mesh(
        &mut buffers,
        &rig.mesh,
        (vertices, rig.mesh.indices.clone()),
        "Body",
        &|p| to_node.transform_point3(p),
    );
    let written = rig
        .mesh
        .positions
        .iter()
        .map(|p| to_node.transform_point3(p.as_dvec3()))
        .collect();
    let joints = rig.skeleton.joints();
    let inverse_binds: Vec<DAffine3> = joints
        .iter()
        .map(|j| armature.inverse() * j.inverse_bind * node)
        .collect();
    // In the file's frame: a joint's local `X` becomes `C⁻¹ X C`.
    let in_file = |x: DAffine3| armature.inverse() * x * armature;
    let node_of = |name: &str, x: DAffine3, children: Vec<usize>| {
        let (_, rotation, translation) = in_file(x).to_scale_rotation_translation();
        let mut n = json!({
            "name": name,
            "translation": translation.as_vec3().to_array(),
            "rotation": rotation.as_quat().normalize().to_array(),
        });
        if !children.is_empty() {
            n["children"] = json!(children);
        }
        n
    };
    let mut nodes: Vec<serde_json::Value> = joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let local = rig.rest.local[j];
            let x = DAffine3::from_rotation_translation(local.rotation, local.translation);
            node_of(&joint.name, x, rig.skeleton.children(j).to_vec())
        })
        .collect();
    let mut all_inverse_binds = inverse_binds.clone();
    let mut roots = vec![0];
    if layout.second_root_chain {
        // An IK target beside the feet and its tip: joints of the skin, bound to no vertex.
        let first = nodes.len();
        let base = DAffine3::from_translation(DVec3::new(0.3, 0.05, 0.2));
        let tip = DAffine3::from_translation(DVec3::new(0.0, 0.1, 0.0));
        nodes.push(node_of("ik_target", base, vec![first + 1]));
        nodes.push(node_of("ik_target_tip", tip, vec![]));
        for global in [base, base * tip] {
            all_inverse_binds.push(armature.inverse() * global.inverse() * node);
        }
        roots.push(first);
    }
    let skin_joints: Vec<usize> = (0..nodes.len()).collect();
    let ibm = buffers.push(
        all_inverse_binds
            .iter()
            .flat_map(|m| glam::Mat4::from(m.as_affine3a()).to_cols_array())
            .flat_map(|f| f.to_le_bytes())
            .collect(),
        json!({"componentType": 5126, "count": all_inverse_binds.len(), "type": "MAT4"}),
    );
    let body = nodes.len();
    let (_, node_turn, _) = node.to_scale_rotation_translation();
    nodes.push(json!({"name": "Body", "mesh": 0, "skin": 0,
        "rotation": node_turn.as_quat().normalize().to_array(),
        "scale": layout.mesh_scale.as_vec3().to_array()}));
    let s = layout.armature_scale;
    nodes.push(json!({"name": "Armature", "scale": [s, s, s],
        "rotation": layout.turn.as_quat().normalize().to_array(), "children": roots}));
    nodes.push(json!({"name": "Character", "children": [body + 1, body]}));
    let document = json!({
        "asset": {"version": "2.0", "generator": "bevy_wii_deform tests (FBX-converter layout)"},
        "scene": 0,
        "scenes": [{"nodes": [body + 2]}],
        "nodes": nodes,
        "meshes": [mesh],
        "skins": [{"joints": skin_joints, "inverseBindMatrices": ibm}],
        "accessors": buffers.accessors,
        "bufferViews": buffers.views,
        "buffers": [{"byteLength": buffers.bin.len()}],
    });
    let glb = glb_container(serde_json::to_vec(&document).unwrap(), buffers.bin);
    (glb, written, inverse_binds)
}

/// Where Bevy draws each vertex: the linear blend of its joints' `GlobalTransform` × inverse
/// bind matrix applied to the position written in the file (the mesh node's own transform
/// does not take part, as glTF specifies).
fn drawn_by_bevy(
    app: &App,
    posed: &PosedSkeleton,
    rig: &SyntheticRig,
    written: &[DVec3],
    inverse_binds: &[glam::DAffine3],
) -> Vec<DVec3> {
    let skeleton = posed.model.skeleton();
    // The rig's joint k is the file's joint k; the model sorts joints: map by name.
    let entity_of: Vec<Entity> = rig
        .skeleton
        .joints()
        .iter()
        .map(|j| posed.joints[skeleton.find(&j.name).expect("a joint of the rig")])
        .collect();
    let skin: Vec<glam::DAffine3> = entity_of
        .iter()
        .zip(inverse_binds)
        .map(|(&e, ibm)| {
            let g = app.world().get::<GlobalTransform>(e).unwrap().affine();
            let g = glam::DAffine3::from_mat4(glam::Mat4::from(g).as_dmat4());
            g * *ibm
        })
        .collect();
    written
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let (ji, w) = (rig.mesh.joint_indices[i], rig.mesh.joint_weights[i]);
            (0..4)
                .map(|k| skin[ji[k] as usize].transform_point3(v) * f64::from(w[k]))
                .sum()
        })
        .collect()
}

/// Converter rigs (one with the skinned mesh node at (1.2, 1, 1) beside a ×100 armature;
/// one with both turned −90° about X, the node at (1.21, 1, 1), a second root bone chain)
/// are drawn where the rig's bind is, pose where Bevy draws them (within 1e-4 of the size),
/// keep their bones rigid (lengths within 1e-4 of the size, every joint's skin matrix a
/// rotation times the node's bind) and meet a reachable drag with the feet pinned. Set
/// `BWD_WRITE_FIXTURES=DIR` to keep the files (`character_bench --model DIR/converted_turned.glb`).
#[test]
fn a_skin_bound_by_a_converter_poses_rigidly() {
    for (name, layout) in [
        ("scaled", ConverterLayout::SCALED),
        ("turned", ConverterLayout::turned()),
    ] {
        converter_rig_poses_rigidly(name, layout);
    }
}

fn converter_rig_poses_rigidly(name: &str, layout: ConverterLayout) {
    let rig = mannequin_rig(12);
    let (glb, written, inverse_binds) = converted_glb(&rig, layout);
    let dir = ScratchDir::new("character_converted");
    let file = format!("converted_{name}.glb");
    std::fs::write(dir.join(&file), &glb).unwrap();
    if let Some(keep) = std::env::var_os("BWD_WRITE_FIXTURES") {
        std::fs::write(std::path::Path::new(&keep).join(&file), &glb).unwrap();
    }
    let (mut app, root) = common::character_app(&dir, &file, PosePlugin);
    let posed = app.world().get::<PosedSkeleton>(root).unwrap().clone();
    let size = posed.model.topology().bounding_diagonal();
    same_model_as_the_benchmark(&mut app, root, &posed, name);
    let model_drawn = |app: &App| -> Vec<DVec3> {
        let p = app.world().get::<PosedSkeleton>(root).unwrap();
        p.skinned_positions().iter().map(|v| v.as_dvec3()).collect()
    };
    let worst = |a: &[DVec3], b: &[DVec3]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.distance(*y))
            .fold(0.0, f64::max)
    };
    // The file really is bound with the node's scale: its vertices are not the rig's…
    let bind: Vec<DVec3> = rig.mesh.positions.iter().map(|p| p.as_dvec3()).collect();
    assert!(worst(&written, &bind) > 0.02 * size);
    // …but Bevy draws them there, and so does the model.
    let bevy = drawn_by_bevy(&app, &posed, &rig, &written, &inverse_binds);
    assert!(
        worst(&bevy, &bind) < 1e-4 * size,
        "{name}: {}",
        worst(&bevy, &bind)
    );
    assert_eq!(model_drawn(&app).len(), bind.len());
    assert!(worst(&model_drawn(&app), &bevy) < 1e-4 * size);
    let skeleton = posed.model.skeleton();
    let world_of =
        |app: &App, e: Entity| app.world().get::<GlobalTransform>(e).unwrap().translation();
    let bones = |app: &App| -> Vec<f64> {
        (0..skeleton.len())
            .filter_map(|j| {
                let p = skeleton.joints()[j].parent?;
                let d = world_of(app, posed.joints[j]).distance(world_of(app, posed.joints[p]));
                Some(f64::from(d))
            })
            .collect()
    };
    let bones_before = bones(&app);
    let shift = Vec3::new(0.12, -0.05, 0.0);
    let drawn: Vec<Vec3> = bind.iter().map(|p| p.as_vec3()).collect();
    let drag = drag_head_with_feet_pinned(&mut app, root, &drawn, 0.1, shift);
    // Posed where Bevy draws it.
    let now = model_drawn(&app);
    let bevy_now = drawn_by_bevy(&app, &posed, &rig, &written, &inverse_binds);
    assert!(
        worst(&now, &bevy_now) < 1e-4 * size,
        "{name}: the model and Bevy disagree by {} (size {size})",
        worst(&now, &bevy_now)
    );
    // The drag is met, the feet stay.
    assert!(
        drag.moved.distance(shift) < 0.1 * shift.length(),
        "{name}: the head moved {}, the drag was {shift}",
        drag.moved
    );
    assert!(
        f64::from(drag.foot_drift) < 1e-3 * size,
        "{name}: a pinned foot moved {} (size {size})",
        drag.foot_drift
    );
    // Rigid bones: lengths kept, and each joint's skin matrix is a rotation (and the
    // translation) applied to the node's bind — no shear from the non-uniform scale.
    for (a, b) in bones(&app).iter().zip(&bones_before) {
        assert!(
            (a - b).abs() < 1e-4 * size,
            "{name}: a bone went from {b} to {a} (size {size})"
        );
    }
    let node = layout.mesh_node();
    for (k, j) in rig.skeleton.joints().iter().enumerate() {
        let e = posed.joints[skeleton.find(&j.name).unwrap()];
        let g = app.world().get::<GlobalTransform>(e).unwrap().affine();
        let g = glam::DAffine3::from_mat4(glam::Mat4::from(g).as_dmat4());
        let motion = (g * inverse_binds[k] * node.inverse()).matrix3;
        let off = (motion.transpose() * motion - glam::DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            off < 1e-4,
            "{name}: joint {} moves its skin non-rigidly ({off})",
            j.name
        );
    }
    // The pose is not trivially the rest: something turned.
    assert!(worst(&now, &bind) > 0.05 * size);
}

/// Sharing: two characters from one asset share one model (one build, one `Arc`),
/// the second placed elsewhere, turned and scaled ×2; each poses on its own — a drag on the
/// second's head is met where that character stands (within 10 % of the drag, its pinned
/// feet within 1e-3 of its size) and leaves the first's pose as it was; moving the second
/// moves what it draws with it.
#[test]
fn two_characters_from_one_asset_share_one_model_and_pose_independently() {
    let rig = mannequin_rig(12);
    let (glb, _) = three_node_glb(&rig);
    let dir = ScratchDir::new("character_shared");
    std::fs::write(dir.join("humanoid.glb"), glb).unwrap();
    let (mut app, first) = common::character_app(&dir, "humanoid.glb", PosePlugin);
    let scene = common::loaded_scene(&app);
    let placed = Transform::from_xyz(3.0, 0.5, -2.0)
        .with_rotation(Quat::from_rotation_y(1.2))
        .with_scale(Vec3::splat(2.0));
    let second = app
        .world_mut()
        .spawn((
            bevy::world_serialization::WorldAssetRoot(scene),
            Poseable::default(),
            placed,
        ))
        .id();
    common::update_until(&mut app, "the second character's model", |a| {
        a.world().get::<PosedSkeleton>(second).is_some()
    });
    let a = app.world().get::<PosedSkeleton>(first).unwrap().clone();
    let b = app.world().get::<PosedSkeleton>(second).unwrap().clone();
    assert_eq!(app.world().resource::<PoseModels>().built(), 1, "one build");
    assert!(std::sync::Arc::ptr_eq(&a.model, &b.model), "one model");
    // The second is drawn where it stands: the first's vertices, placed.
    let (drawn_a, drawn_b) = (a.skinned_positions(), b.skinned_positions());
    let worst = drawn_a
        .iter()
        .zip(&drawn_b)
        .map(|(p, q)| placed.transform_point(*p).distance(*q))
        .fold(0.0f32, f32::max);
    assert!(
        worst < 1e-4,
        "the second is drawn {worst} off its placement"
    );
    // Drag the second's head (world space) with its feet pinned.
    let shift = Vec3::new(0.2, -0.1, 0.1);
    let drag = drag_head_with_feet_pinned(&mut app, second, &drawn_b, 0.2, shift);
    assert!(drag.head.len() > 5);
    assert!(
        drag.moved.distance(shift) < 0.1 * shift.length(),
        "the second's head moved {}, the drag was {shift}",
        drag.moved
    );
    let size = 2.0 * b.model.topology().bounding_diagonal() as f32;
    assert!(
        drag.foot_drift < 1e-3 * size,
        "a pinned foot moved {} (size {size})",
        drag.foot_drift
    );
    assert_eq!(
        app.world().get::<PosedSkeleton>(first).unwrap().pose,
        a.pose,
        "the first character did not move"
    );
    // Let go (the drag's handle is gone), then walk the second 1 m along x: what it draws
    // follows.
    app.update();
    let before = app
        .world()
        .get::<PosedSkeleton>(second)
        .unwrap()
        .skinned_positions();
    app.world_mut()
        .get_mut::<Transform>(second)
        .unwrap()
        .translation
        .x += 1.0;
    for _ in 0..3 {
        app.update();
    }
    let after = app
        .world()
        .get::<PosedSkeleton>(second)
        .unwrap()
        .skinned_positions();
    let walked = after
        .iter()
        .zip(&before)
        .map(|(p, q)| (*p - *q - Vec3::X).length())
        .fold(0.0f32, f32::max);
    assert!(
        walked < 1e-3,
        "the drawn character lags its placement by {walked}"
    );
}

/// What `character_bench --model` builds from the plugin's public reading of a character
/// (`CharacterSkin::read`, default `Poseable` settings) is the plugin's model: the same
/// joints, and the same welded vertices where the character is drawn in its pose.
fn same_model_as_the_benchmark(app: &mut App, root: Entity, posed: &PosedSkeleton, name: &str) {
    use bevy_wii_deform::ecs::CharacterSkin;
    use bevy_wii_deform::pose::{ModelSettings, SkinnedModel};
    let skin = CharacterSkin::read(app.world_mut(), root)
        .expect("a readable skin")
        .expect("loaded");
    assert_eq!(
        skin.joints, posed.joints,
        "{name}: the same joints in the same order"
    );
    let settings = ModelSettings {
        clusters: Poseable::default().clusters as usize,
        ..Default::default()
    };
    let built = SkinnedModel::new(skin.skeleton, &skin.mesh, &skin.reference, settings).unwrap();
    let ours = built.skin_welded(&skin.reference);
    let plugin = posed.model.skin_welded(&posed.pose);
    assert_eq!(ours.len(), plugin.len());
    let worst = ours
        .iter()
        .zip(&plugin)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    let size = posed.model.topology().bounding_diagonal();
    assert!(
        worst < 1e-9 * size,
        "{name}: the benchmark's model is {worst} off"
    );
}
