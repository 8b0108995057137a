//! Which target joints follow which source joints: chains of joints on each side, found for
//! humanoids by their roles ([`SkeletonMap::humanoid`]) or named in a RON file
//! ([`SkeletonMap::from_ron`]) for anything else.

use glam::DVec3;
use serde::Deserialize;

use crate::pose::retarget::RetargetError;
use crate::pose::rig::humanoid::{HumanoidRole, Side, humanoid_role_and_side};
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};

/// Which side of a retarget a joint or chain belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// The skeleton the clip was made for.
    Source,
    /// The skeleton the clip is played on.
    Target,
}

/// A chain of source joints and the chain of target joints that follows it, both listed from
/// the chain's root outwards. Chains of different lengths map by normalised length: a target
/// joint a third of the way along its chain follows the source chain a third of the way along.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainPair {
    /// The chain's name (`left_arm`, `spine`, …).
    pub name: String,
    /// Source joints, root outwards.
    pub source: Vec<usize>,
    /// Target joints, root outwards.
    pub target: Vec<usize>,
}

/// How a source skeleton's motion maps onto a target skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct SkeletonMap {
    /// The source's and the target's body root (the hips): its translation carries the root
    /// motion.
    pub root: (usize, usize),
    /// The mapped chains.
    pub chains: Vec<ChainPair>,
    /// The feet (or paws): (source joint, target joint), whose contacts are kept.
    pub feet: Vec<(usize, usize)>,
    /// Target joints nothing maps to: they keep their rest pose (relative to their parent).
    pub unmapped: Vec<usize>,
    /// Per skeleton, the world "up" and "forward" of its rest pose (for the frame the
    /// rotations are carried over in).
    pub axes: [(DVec3, DVec3); 2],
}

impl SkeletonMap {
    /// The names of the mapped chains (the hips as `hips`).
    pub fn roles_mapped(&self) -> Vec<String> {
        std::iter::once("hips".to_string())
            .chain(self.chains.iter().map(|c| c.name.clone()))
            .collect()
    }

    /// The number of target joints that follow a source joint (the hips included).
    pub fn joints_mapped(&self) -> usize {
        let mut mapped: Vec<usize> = self
            .chains
            .iter()
            .flat_map(|c| c.target.iter().copied())
            .chain([self.root.1])
            .collect();
        mapped.sort_unstable();
        mapped.dedup();
        mapped.len()
    }

    fn finish(
        root: (usize, usize),
        chains: Vec<ChainPair>,
        feet: Vec<(usize, usize)>,
        target: &Skeleton,
        axes: [(DVec3, DVec3); 2],
    ) -> Self {
        let mut mapped = vec![false; target.len()];
        mapped[root.1] = true;
        for c in &chains {
            for &j in &c.target {
                mapped[j] = true;
            }
        }
        let unmapped = (0..target.len()).filter(|&j| !mapped[j]).collect();
        Self {
            root,
            chains,
            feet,
            unmapped,
            axes,
        }
    }

    /// The map between two humanoids, found by their joints' names ([`humanoid_role_and_side`]):
    /// the hips (the joint both thighs hang from), the spine (the joints between the hips and
    /// the neck), the neck and head, and per side the clavicle, the arm (upper arm, forearm,
    /// hand), the leg (thigh, shin, foot) and the toes — each where both skeletons have it.
    /// The feet are the ankles. Errors: a skeleton without two thighs (no hips), or without a
    /// neck or head ([`RetargetError::MissingRole`]).
    pub fn humanoid(
        source: (&Skeleton, &SkeletonPose),
        target: (&Skeleton, &SkeletonPose),
    ) -> Result<Self, RetargetError> {
        let s = HumanoidChains::find(source.0, Which::Source)?;
        let t = HumanoidChains::find(target.0, Which::Target)?;
        let mut chains = Vec::new();
        for (name, a, b) in s
            .named()
            .into_iter()
            .zip(t.named())
            .map(|((n, a), (_, b))| (n, a, b))
        {
            if !a.is_empty() && !b.is_empty() {
                chains.push(ChainPair {
                    name: name.to_string(),
                    source: a,
                    target: b,
                });
            }
        }
        let feet = [s.left_leg.last(), s.right_leg.last()]
            .into_iter()
            .zip([t.left_leg.last(), t.right_leg.last()])
            .filter_map(|(a, b)| Some((*a?, *b?)))
            .collect();
        let axes = [s.axes(source), t.axes(target)];
        Ok(Self::finish((s.hips, t.hips), chains, feet, target.0, axes))
    }

    /// The map a RON file names (see [`ChainMapFile`]): joints by name on each side. Errors: a
    /// joint the skeleton does not have, an empty chain ([`RetargetError::ChainJoint`],
    /// [`RetargetError::EmptyChain`]), a file that does not parse ([`RetargetError::MapFile`]).
    pub fn from_ron(
        text: &str,
        source: (&Skeleton, &SkeletonPose),
        target: (&Skeleton, &SkeletonPose),
    ) -> Result<Self, RetargetError> {
        let file: ChainMapFile =
            ron::from_str(text).map_err(|e| RetargetError::MapFile(e.to_string()))?;
        Self::from_file(&file, source, target)
    }

    /// The map of an already parsed [`ChainMapFile`].
    pub fn from_file(
        file: &ChainMapFile,
        source: (&Skeleton, &SkeletonPose),
        target: (&Skeleton, &SkeletonPose),
    ) -> Result<Self, RetargetError> {
        let find = |skeleton: &Skeleton, which: Which, chain: &str, name: &str| {
            skeleton
                .find(name)
                .ok_or_else(|| RetargetError::ChainJoint {
                    chain: chain.to_string(),
                    joint: name.to_string(),
                    which,
                })
        };
        let root = (
            find(source.0, Which::Source, "root", &file.root.0)?,
            find(target.0, Which::Target, "root", &file.root.1)?,
        );
        let mut chains = Vec::new();
        let mut feet = Vec::new();
        for chain in &file.chains {
            if chain.source.is_empty() || chain.target.is_empty() {
                return Err(RetargetError::EmptyChain(chain.name.clone()));
            }
            let pair = ChainPair {
                name: chain.name.clone(),
                source: chain
                    .source
                    .iter()
                    .map(|n| find(source.0, Which::Source, &chain.name, n))
                    .collect::<Result<_, _>>()?,
                target: chain
                    .target
                    .iter()
                    .map(|n| find(target.0, Which::Target, &chain.name, n))
                    .collect::<Result<_, _>>()?,
            };
            if chain.foot
                && let (Some(&a), Some(&b)) = (pair.source.last(), pair.target.last())
            {
                feet.push((a, b));
            }
            chains.push(pair);
        }
        let axes = [
            (file.source_up, file.source_forward),
            (file.target_up, file.target_forward),
        ];
        Ok(Self::finish(root, chains, feet, target.0, axes))
    }
}

/// A chain map in RON:
///
/// ```ron
/// (
///     root: ("b_Hip_01", "pelvis"),
///     chains: [
///         (name: "spine", source: ["b_Spine01_02", "b_Spine02_03"], target: ["spine1", "spine2", "chest"]),
///         (name: "left_front_leg", source: ["b_LeftUpperArm_09", "b_LeftForeArm_010", "b_LeftHand_011"],
///          target: ["front_thigh_l", "front_shin_l", "front_paw_l"], foot: true),
///     ],
/// )
/// ```
///
/// `foot: true` marks a chain whose last joint touches the ground (its contacts are kept).
/// Each skeleton's world up and forward default to glTF's (+Y, +Z); give `source_up` and
/// `source_forward` (or the target's) for a skeleton exported with other axes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ChainMapFile {
    /// (source joint, target joint) of the body root.
    pub root: (String, String),
    /// The chains.
    pub chains: Vec<ChainFile>,
    /// The source's world up.
    #[serde(default = "up")]
    pub source_up: DVec3,
    /// The source's world forward.
    #[serde(default = "forward")]
    pub source_forward: DVec3,
    /// The target's world up.
    #[serde(default = "up")]
    pub target_up: DVec3,
    /// The target's world forward.
    #[serde(default = "forward")]
    pub target_forward: DVec3,
}

fn up() -> DVec3 {
    DVec3::Y
}

fn forward() -> DVec3 {
    DVec3::Z
}

/// One chain of a [`ChainMapFile`].
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ChainFile {
    /// The chain's name.
    pub name: String,
    /// Source joint names, root outwards.
    pub source: Vec<String>,
    /// Target joint names, root outwards.
    pub target: Vec<String>,
    /// Whether the chain's last joint is a foot.
    #[serde(default)]
    pub foot: bool,
}

/// A humanoid's chains as its names give them.
struct HumanoidChains {
    hips: usize,
    left_thigh: usize,
    right_thigh: usize,
    spine: Vec<usize>,
    neck: Vec<usize>,
    head: Vec<usize>,
    left_clavicle: Vec<usize>,
    right_clavicle: Vec<usize>,
    left_arm: Vec<usize>,
    right_arm: Vec<usize>,
    left_leg: Vec<usize>,
    right_leg: Vec<usize>,
    left_toes: Vec<usize>,
    right_toes: Vec<usize>,
}

fn depth(skeleton: &Skeleton, mut j: usize) -> usize {
    let mut d = 0;
    while let Some(p) = skeleton.joints()[j].parent {
        d += 1;
        j = p;
    }
    d
}

fn is_ancestor(skeleton: &Skeleton, ancestor: usize, mut j: usize) -> bool {
    while let Some(p) = skeleton.joints()[j].parent {
        if p == ancestor {
            return true;
        }
        j = p;
    }
    false
}

/// The joints from `from` (exclusive) down to `to` (exclusive), top-down.
fn between(skeleton: &Skeleton, from: usize, to: usize) -> Vec<usize> {
    let mut path = Vec::new();
    let mut j = skeleton.joints()[to].parent;
    while let Some(p) = j {
        if p == from {
            path.reverse();
            return path;
        }
        path.push(p);
        j = skeleton.joints()[p].parent;
    }
    Vec::new()
}

impl HumanoidChains {
    fn find(skeleton: &Skeleton, which: Which) -> Result<Self, RetargetError> {
        let roles: Vec<Option<(HumanoidRole, Option<Side>)>> = skeleton
            .joints()
            .iter()
            .map(|j| humanoid_role_and_side(&j.name))
            .collect();
        let missing = |role: &'static str| RetargetError::MissingRole { role, which };
        // The topmost joint of a role (and side), optionally below `under`.
        let top = |role: HumanoidRole, side: Option<Side>, under: Option<usize>| {
            (0..skeleton.len())
                .filter(|&j| roles[j] == Some((role, side)))
                .filter(|&j| under.is_none_or(|u| is_ancestor(skeleton, u, j)))
                .min_by_key(|&j| depth(skeleton, j))
        };
        let left_thigh =
            top(HumanoidRole::Hip, Some(Side::Left), None).ok_or(missing("left thigh"))?;
        let right_thigh =
            top(HumanoidRole::Hip, Some(Side::Right), None).ok_or(missing("right thigh"))?;
        // The hips: the lowest common ancestor of the thighs.
        let hips = {
            let mut a = left_thigh;
            let mut found = None;
            while let Some(p) = skeleton.joints()[a].parent {
                if is_ancestor(skeleton, p, right_thigh) {
                    found = Some(p);
                    break;
                }
                a = p;
            }
            found.ok_or(missing("hips"))?
        };
        let neck_top = top(HumanoidRole::Neck, None, Some(hips));
        let head = top(HumanoidRole::Head, None, Some(hips)).ok_or(missing("head"))?;
        let spine_end = neck_top.unwrap_or(head);
        let spine = between(skeleton, hips, spine_end);
        let neck = match neck_top {
            Some(n) => std::iter::once(n)
                .chain(between(skeleton, n, head))
                .collect(),
            None => Vec::new(),
        };
        // Down a limb: each role the first descendant of the previous joint with it.
        let limb = |first: Option<usize>, rest: &[HumanoidRole], side: Side| -> Vec<usize> {
            let Some(mut at) = first else {
                return Vec::new();
            };
            let mut chain = vec![at];
            for &role in rest {
                match top(role, Some(side), Some(at)) {
                    Some(next) => {
                        chain.push(next);
                        at = next;
                    }
                    None => break,
                }
            }
            chain
        };
        let arm = |side| {
            limb(
                top(HumanoidRole::UpperArm, Some(side), Some(hips)),
                &[HumanoidRole::Elbow, HumanoidRole::Wrist],
                side,
            )
        };
        let leg = |thigh, side| {
            limb(
                Some(thigh),
                &[HumanoidRole::Knee, HumanoidRole::Ankle],
                side,
            )
        };
        let (left_arm, right_arm) = (arm(Side::Left), arm(Side::Right));
        let clavicle = |side, arm: &[usize]| -> Vec<usize> {
            top(HumanoidRole::Clavicle, Some(side), Some(hips))
                .filter(|&c| arm.first().is_some_and(|&a| is_ancestor(skeleton, c, a)))
                .into_iter()
                .collect()
        };
        let toes = |side, leg: &[usize]| -> Vec<usize> {
            leg.get(2)
                .and_then(|&ankle| top(HumanoidRole::Toes, Some(side), Some(ankle)))
                .into_iter()
                .collect()
        };
        let (left_leg, right_leg) = (leg(left_thigh, Side::Left), leg(right_thigh, Side::Right));
        Ok(Self {
            hips,
            left_thigh,
            right_thigh,
            spine,
            neck,
            head: vec![head],
            left_clavicle: clavicle(Side::Left, &left_arm),
            right_clavicle: clavicle(Side::Right, &right_arm),
            left_toes: toes(Side::Left, &left_leg),
            right_toes: toes(Side::Right, &right_leg),
            left_arm,
            right_arm,
            left_leg,
            right_leg,
        })
    }

    /// The chains by name, in one fixed order.
    fn named(&self) -> Vec<(&'static str, Vec<usize>)> {
        vec![
            ("spine", self.spine.clone()),
            ("neck", self.neck.clone()),
            ("head", self.head.clone()),
            ("left_clavicle", self.left_clavicle.clone()),
            ("right_clavicle", self.right_clavicle.clone()),
            ("left_arm", self.left_arm.clone()),
            ("right_arm", self.right_arm.clone()),
            ("left_leg", self.left_leg.clone()),
            ("right_leg", self.right_leg.clone()),
            ("left_toes", self.left_toes.clone()),
            ("right_toes", self.right_toes.clone()),
        ]
    }

    /// The rest pose's world up (hips to head) and forward (the body's left × up).
    fn axes(&self, (skeleton, rest): (&Skeleton, &SkeletonPose)) -> (DVec3, DVec3) {
        let g = skeleton.global_transforms(rest);
        let at = |j: usize| g[j].translation;
        let up = (at(self.head[0]) - at(self.hips)).normalize_or(DVec3::Y);
        let left = at(self.left_thigh) - at(self.right_thigh);
        let left = (left - up * left.dot(up)).normalize_or(DVec3::X);
        (up, left.cross(up).normalize_or(DVec3::Z))
    }
}
