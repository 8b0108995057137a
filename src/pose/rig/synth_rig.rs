//! Rigged test characters generated in code: a skinned bar and the auto-rigged mannequin.

use glam::{DAffine3, DVec3};

use crate::deform::{TriMesh, synth};
use crate::pose::rig::model::{SkinnedMesh, SkinnedModel};
use crate::pose::rig::skeleton::{Joint, JointTransform, Skeleton, SkeletonPose};

/// A generated character: skeleton, skinned mesh and its rest pose (the bind pose).
#[derive(Debug, Clone)]
pub struct SyntheticRig {
    /// The joints.
    pub skeleton: Skeleton,
    /// The skinned mesh (bind pose).
    pub mesh: SkinnedMesh,
    /// The bind pose as local transforms.
    pub rest: SkeletonPose,
}

impl SyntheticRig {
    /// The rig's skinned model with the default settings.
    pub fn model(&self) -> Result<SkinnedModel, crate::pose::error::PoseError> {
        SkinnedModel::new(
            self.skeleton.clone(),
            &self.mesh,
            &self.rest,
            crate::pose::rig::model::ModelSettings::default(),
        )
    }

    /// Welded vertices of `model` whose bind position satisfies `keep`.
    pub fn vertices_where(&self, model: &SkinnedModel, keep: impl Fn(DVec3) -> bool) -> Vec<u32> {
        (0..model.bind_positions().len() as u32)
            .filter(|&i| keep(model.bind_positions()[i as usize]))
            .collect()
    }
}

/// Builds a rig from joint positions (bind pose, identity orientations) and parents, skinning
/// `mesh` with weights from `weights(position) → [(joint, weight)]`.
fn rig(
    names: &[String],
    positions: &[DVec3],
    parents: &[Option<usize>],
    mesh: &TriMesh,
    weights: impl Fn(DVec3) -> Vec<(usize, f64)>,
) -> SyntheticRig {
    let joints: Vec<Joint> = (0..positions.len())
        .map(|j| Joint {
            name: names[j].clone(),
            parent: parents[j],
            parent_frame: DAffine3::IDENTITY,
            inverse_bind: DAffine3::from_translation(-positions[j]),
        })
        .collect();
    let skeleton = Skeleton::new(joints).expect("generated joints are ordered");
    let rest = SkeletonPose {
        local: (0..positions.len())
            .map(|j| JointTransform {
                translation: positions[j] - parents[j].map_or(DVec3::ZERO, |p| positions[p]),
                ..JointTransform::IDENTITY
            })
            .collect(),
    };
    let mut joint_indices = Vec::with_capacity(mesh.positions.len());
    let mut joint_weights = Vec::with_capacity(mesh.positions.len());
    for p in &mesh.positions {
        let mut w = weights(*p);
        w.sort_by(|a, b| b.1.total_cmp(&a.1));
        w.truncate(4);
        let sum: f64 = w.iter().map(|e| e.1).sum();
        let mut ji = [0u16; 4];
        let mut jw = [0f32; 4];
        for (k, (j, wt)) in w.into_iter().enumerate() {
            ji[k] = j as u16;
            jw[k] = (wt / sum) as f32;
        }
        joint_indices.push(ji);
        joint_weights.push(jw);
    }
    let mesh = SkinnedMesh {
        positions: mesh.positions.iter().map(|p| p.as_vec3()).collect(),
        indices: mesh.triangles.iter().flatten().copied().collect(),
        joint_indices,
        joint_weights,
    };
    SyntheticRig {
        skeleton,
        mesh,
        rest,
    }
}

/// A bar of length 1 along +y (radius 0.1, `radial` × `rings` vertices) skinned to a chain of
/// `bones` joints at `y = k / bones`. Each vertex belongs rigidly to its bone, except within
/// a quarter bone of a joint, where it blends smoothly into the neighbour.
pub fn bar_rig(bones: usize, radial: u32, rings: u32) -> SyntheticRig {
    let bones = bones.max(1);
    let mesh = synth::bar(radial, rings, 0.1, 1.0);
    let names: Vec<String> = (0..bones).map(|k| format!("bone{k}")).collect();
    let positions: Vec<DVec3> = (0..bones)
        .map(|k| DVec3::new(0.0, k as f64 / bones as f64, 0.0))
        .collect();
    let parents: Vec<Option<usize>> = (0..bones).map(|k| k.checked_sub(1)).collect();
    let half_width = 0.25 / bones as f64;
    rig(&names, &positions, &parents, &mesh, |p| {
        let y = p.y * bones as f64;
        let k = (y.round() as usize).clamp(0, bones);
        let joint_y = k as f64 / bones as f64;
        let t = (p.y - joint_y) / half_width;
        if k == 0 || k == bones || t.abs() >= 1.0 {
            let bone = (y.floor() as usize).min(bones - 1);
            return vec![(bone, 1.0)];
        }
        // Blend from bone k−1 (t = −1) to bone k (t = 1) with a smoothstep.
        let s = 0.5 * (t + 1.0);
        let s = s * s * (3.0 - 2.0 * s);
        vec![(k - 1, 1.0 - s), (k, s)]
    })
}

/// The mannequin ([`synth::mannequin`] meshed on `cells` cells) auto-rigged to a 16-joint
/// humanoid skeleton: each vertex is weighted to the (up to four) nearest bone segments with
/// weights `∝ 1 / distance⁴`, a smooth automatic skin.
pub fn mannequin_rig(cells: u32) -> SyntheticRig {
    let mesh = synth::mannequin(cells);
    let v = DVec3::new;
    // (name, position, parent, end of the bone segment when it has no child on its axis)
    let mut spec: Vec<JointSpec> = vec![
        ("hips".into(), v(0.0, 0.92, 0.0), None, v(0.0, 1.2, 0.0)),
        ("chest".into(), v(0.0, 1.2, 0.0), Some(0), v(0.0, 1.42, 0.0)),
        ("neck".into(), v(0.0, 1.42, 0.0), Some(1), v(0.0, 1.56, 0.0)),
        ("head".into(), v(0.0, 1.56, 0.0), Some(2), v(0.0, 1.76, 0.0)),
    ];
    for (side, s) in [("l", 1.0), ("r", -1.0)] {
        let base = spec.len();
        spec.push((
            format!("shoulder_{side}"),
            v(s * 0.2, 1.4, 0.0),
            Some(1),
            v(s * 0.42, 1.14, 0.0),
        ));
        spec.push((
            format!("elbow_{side}"),
            v(s * 0.42, 1.14, 0.0),
            Some(base),
            v(s * 0.56, 0.9, 0.05),
        ));
        spec.push((
            format!("wrist_{side}"),
            v(s * 0.56, 0.9, 0.05),
            Some(base + 1),
            v(s * 0.6, 0.82, 0.07),
        ));
        spec.push((
            format!("hip_{side}"),
            v(s * 0.11, 0.85, 0.0),
            Some(0),
            v(s * 0.12, 0.48, 0.0),
        ));
        spec.push((
            format!("knee_{side}"),
            v(s * 0.12, 0.48, 0.0),
            Some(base + 3),
            v(s * 0.13, 0.1, 0.0),
        ));
        spec.push((
            format!("ankle_{side}"),
            v(s * 0.13, 0.1, 0.0),
            Some(base + 4),
            v(s * 0.13, 0.05, 0.13),
        ));
    }
    rig_from_segments(&mesh, &spec)
}

/// A joint of a generated humanoid: name, bind position, parent, and the end of its bone
/// segment (for the automatic skin).
type JointSpec = (String, DVec3, Option<usize>, DVec3);

/// Skins `mesh` to the joints of `spec`: each vertex weighted to the (up to four) nearest bone
/// segments with weights `∝ 1 / distance⁴`.
fn rig_from_segments(mesh: &TriMesh, spec: &[JointSpec]) -> SyntheticRig {
    let names: Vec<String> = spec.iter().map(|s| s.0.clone()).collect();
    let positions: Vec<DVec3> = spec.iter().map(|s| s.1).collect();
    let parents: Vec<Option<usize>> = spec.iter().map(|s| s.2).collect();
    let segments: Vec<(DVec3, DVec3)> = spec.iter().map(|s| (s.1, s.3)).collect();
    rig(&names, &positions, &parents, mesh, |p| {
        segments
            .iter()
            .enumerate()
            .map(|(j, &(a, b))| {
                let d = synth::capsule(p, a, b, 0.0).max(1e-3);
                (j, 1.0 / (d * d * d * d))
            })
            .collect()
    })
}

/// The mannequin auto-rigged to a 52-joint humanoid with Mixamo's joint names, the count of
/// game characters: a four-bone spine (`Hips`, `Spine`, `Spine1`, `Spine2`), `Neck`, `Head`,
/// and per side a clavicle, arm, forearm and hand with five three-bone fingers, and a thigh,
/// shin, foot and toe. The skin as in [`mannequin_rig`].
pub fn humanoid_rig(cells: u32) -> SyntheticRig {
    let mesh = synth::mannequin(cells);
    let v = DVec3::new;
    let mut spec: Vec<JointSpec> = vec![
        ("Hips".into(), v(0.0, 0.92, 0.0), None, v(0.0, 1.02, 0.0)),
        (
            "Spine".into(),
            v(0.0, 1.02, 0.0),
            Some(0),
            v(0.0, 1.12, 0.0),
        ),
        (
            "Spine1".into(),
            v(0.0, 1.12, 0.0),
            Some(1),
            v(0.0, 1.24, 0.0),
        ),
        (
            "Spine2".into(),
            v(0.0, 1.24, 0.0),
            Some(2),
            v(0.0, 1.42, 0.0),
        ),
        ("Neck".into(), v(0.0, 1.42, 0.0), Some(3), v(0.0, 1.56, 0.0)),
        ("Head".into(), v(0.0, 1.56, 0.0), Some(4), v(0.0, 1.76, 0.0)),
    ];
    for (side, s) in [("Left", 1.0), ("Right", -1.0)] {
        let at = |spec: &Vec<JointSpec>| spec.len();
        let clavicle = at(&spec);
        spec.push((
            format!("{side}Shoulder"),
            v(s * 0.05, 1.38, 0.0),
            Some(3),
            v(s * 0.2, 1.4, 0.0),
        ));
        let limb = [
            ("Arm", v(s * 0.2, 1.4, 0.0), v(s * 0.42, 1.14, 0.0)),
            ("ForeArm", v(s * 0.42, 1.14, 0.0), v(s * 0.56, 0.9, 0.05)),
            ("Hand", v(s * 0.56, 0.9, 0.05), v(s * 0.58, 0.86, 0.06)),
        ];
        let mut parent = clavicle;
        for (name, a, b) in limb {
            spec.push((format!("{side}{name}"), a, Some(parent), b));
            parent = at(&spec) - 1;
        }
        let hand = parent;
        let (wrist, palm) = (v(s * 0.56, 0.9, 0.05), v(s * 0.58, 0.86, 0.06));
        let along = (palm - wrist).normalize();
        for (k, finger) in ["Thumb", "Index", "Middle", "Ring", "Pinky"]
            .iter()
            .enumerate()
        {
            let spread = v(0.0, 0.0, (k as f64 - 2.0) * 0.012);
            let mut at_joint = palm + spread;
            let mut parent = hand;
            for bone in 1..=3 {
                let end = at_joint + along * 0.018;
                spec.push((
                    format!("{side}Hand{finger}{bone}"),
                    at_joint,
                    Some(parent),
                    end,
                ));
                parent = spec.len() - 1;
                at_joint = end;
            }
        }
        let leg = [
            ("UpLeg", v(s * 0.11, 0.85, 0.0), v(s * 0.12, 0.48, 0.0)),
            ("Leg", v(s * 0.12, 0.48, 0.0), v(s * 0.13, 0.1, 0.0)),
            ("Foot", v(s * 0.13, 0.1, 0.0), v(s * 0.13, 0.05, 0.1)),
            ("ToeBase", v(s * 0.13, 0.05, 0.1), v(s * 0.13, 0.04, 0.16)),
        ];
        let mut parent = 0;
        for (name, a, b) in leg {
            spec.push((format!("{side}{name}"), a, Some(parent), b));
            parent = spec.len() - 1;
        }
    }
    rig_from_segments(&mesh, &spec)
}

/// The joint names a generated figure ([`figure_rig`]) uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FigureNames {
    /// Mixamo's (`Hips`, `Spine`, `LeftArm`, `LeftUpLeg`, …), the hips the root.
    Mixamo,
    /// Unreal's mannequin (`root` at the feet, `pelvis`, `spine_01`, `upperarm_l`, `thigh_l`,
    /// `calf_l`, `ball_l`, …): the hips are not the root.
    Unreal,
}

/// What a generated figure looks like ([`figure_rig`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FigureSpec {
    /// The joints' names.
    pub names: FigureNames,
    /// How far the arms hang below horizontal at rest (0: a T-pose, 45: an A-pose).
    pub arm_down_deg: f64,
    /// Thigh length (hip to knee).
    pub thigh: f64,
    /// Shin length (knee to ankle).
    pub shin: f64,
    /// Grid cells of the skin's surface along its longest side.
    pub cells: u32,
}

impl Default for FigureSpec {
    fn default() -> Self {
        Self {
            names: FigureNames::Mixamo,
            arm_down_deg: 45.0,
            thigh: 0.42,
            shin: 0.4,
            cells: 40,
        }
    }
}

/// A 21-joint humanoid (hips, two spine joints, neck, head, and per side a clavicle, arm,
/// forearm, hand, thigh, shin, foot and toes; Unreal's names add a root at the feet) with
/// the proportions, rest pose and names of `spec`, standing on `y = 0` facing +Z, and a skin
/// of capsules along its bones, smoothly joined. Test material for retargeting: the same
/// motion on skeletons that differ the way real ones do.
pub fn figure_rig(spec: &FigureSpec) -> SyntheticRig {
    let v = DVec3::new;
    let mixamo = spec.names == FigureNames::Mixamo;
    let name = |mixamo_name: &str, unreal: &str| {
        if mixamo {
            mixamo_name.to_string()
        } else {
            unreal.to_string()
        }
    };
    let ankle_y = 0.08;
    let knee_y = ankle_y + spec.shin;
    let hip_y = knee_y + spec.thigh;
    let hips_y = hip_y + 0.06;
    // (name, position, parent, radius of the skin along the bone to its first child)
    let mut joints: Vec<(String, DVec3, Option<usize>, f64)> = Vec::new();
    let root = if mixamo {
        None
    } else {
        joints.push(("root".into(), DVec3::ZERO, None, 0.0));
        Some(0)
    };
    let hips = joints.len();
    joints.push((name("Hips", "pelvis"), v(0.0, hips_y, 0.0), root, 0.12));
    let spine = joints.len();
    joints.push((
        name("Spine", "spine_01"),
        v(0.0, hips_y + 0.14, 0.0),
        Some(hips),
        0.12,
    ));
    let chest = joints.len();
    joints.push((
        name("Spine1", "spine_02"),
        v(0.0, hips_y + 0.3, 0.0),
        Some(spine),
        0.14,
    ));
    let neck = joints.len();
    joints.push((
        name("Neck", "neck_01"),
        v(0.0, hips_y + 0.52, 0.0),
        Some(chest),
        0.05,
    ));
    joints.push((
        name("Head", "head"),
        v(0.0, hips_y + 0.62, 0.0),
        Some(neck),
        0.1,
    ));
    let down = spec.arm_down_deg.to_radians();
    for (side, s) in [("Left", 1.0), ("Right", -1.0)] {
        let suffix = if s > 0.0 { "_l" } else { "_r" };
        let n = |m: &str, u: &str| name(&format!("{side}{m}"), &format!("{u}{suffix}"));
        let shoulder_y = hips_y + 0.46;
        let clavicle = joints.len();
        joints.push((
            n("Shoulder", "clavicle"),
            v(s * 0.04, shoulder_y, 0.0),
            Some(chest),
            0.05,
        ));
        let arm_dir = v(s * down.cos(), -down.sin(), 0.0);
        let shoulder = v(s * 0.18, shoulder_y, 0.0);
        let arm = joints.len();
        joints.push((n("Arm", "upperarm"), shoulder, Some(clavicle), 0.045));
        let elbow = shoulder + arm_dir * 0.28;
        let forearm = joints.len();
        joints.push((n("ForeArm", "lowerarm"), elbow, Some(arm), 0.04));
        let wrist = elbow + arm_dir * 0.25;
        joints.push((n("Hand", "hand"), wrist, Some(forearm), 0.035));
        let thigh = joints.len();
        joints.push((
            n("UpLeg", "thigh"),
            v(s * 0.1, hip_y, 0.0),
            Some(hips),
            0.07,
        ));
        let shin = joints.len();
        joints.push((n("Leg", "calf"), v(s * 0.1, knee_y, 0.0), Some(thigh), 0.05));
        let foot = joints.len();
        joints.push((
            n("Foot", "foot"),
            v(s * 0.1, ankle_y, 0.0),
            Some(shin),
            0.045,
        ));
        joints.push((
            n("ToeBase", "ball"),
            v(s * 0.1, 0.03, 0.12),
            Some(foot),
            0.03,
        ));
    }
    // Each joint's bone runs to its first child (a leaf: a short stub onward).
    let end_of = |j: usize| -> DVec3 {
        match joints.iter().position(|c| c.2 == Some(j)) {
            Some(c) => joints[c].1,
            None => {
                let from = joints[j]
                    .2
                    .map_or(joints[j].1 - DVec3::Y * 0.1, |p| joints[p].1);
                joints[j].1 + (joints[j].1 - from).normalize_or(DVec3::Y) * 0.08
            }
        }
    };
    let bones: Vec<(DVec3, DVec3, f64)> = (0..joints.len())
        .filter(|&j| joints[j].3 > 0.0)
        .map(|j| (joints[j].1, end_of(j), joints[j].3))
        .collect();
    let surface = |p: DVec3| {
        bones
            .iter()
            .map(|&(a, b, r)| synth::capsule(p, a, b, r))
            .reduce(|a, b| synth::smooth_min(a, b, 0.03))
            .unwrap_or(f64::MAX)
    };
    let (lo, hi) = joints.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), j| (lo.min(j.1), hi.max(j.1)),
    );
    let margin = DVec3::splat(0.2);
    let mesh = synth::implicit_surface(&surface, lo - margin, hi + margin, spec.cells);
    // A joint without skin (Unreal's root) skins nothing: its segment is a point at the feet.
    let spec: Vec<JointSpec> = (0..joints.len())
        .map(|j| {
            let end = if joints[j].3 > 0.0 {
                end_of(j)
            } else {
                joints[j].1
            };
            (joints[j].0.clone(), joints[j].1, joints[j].2, end)
        })
        .collect();
    rig_from_segments(&mesh, &spec)
}
