//! The effector and stiffness energies of a pose solve, with their Jacobians in the bone
//! parameters: position, orientation and aim effectors, centroid effectors (a vertex set's
//! centroid to a point) and reference stiffness (each joint pulled towards a reference pose's
//! rotation). Each is a weighted least-squares term; see [`crate::pose::constraints::effectors`] for what
//! the weights mean.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `floor_groups.rs` | The floor's vertices in groups that share one bound on how far their joints moved them: a group certainly well above its ground passes its vertices in one test. |
//! | `ground.rs` | The ground's terms of a pose solve: contacts (patch vertices kept above their ground, a planted contact's joint's up turned to the ground's normal; the weight of its holds, which `holds.rs` folds into the solve's `Q`), the floor, and balance — built from [`PoseConstraints`], one-sided where they are inequalities. |
//! | `moments.rs` | The one-number terms (a vertex under or near its ground, along the ground's normal `n`) summed by their moments instead of pair by pair of parameters. |
//! | `raised_floor.rs` | Non-penetration as an augmented Lagrangian: a vertex the ground's penalty cannot get out of the ground is kept above a plane raised by its depth. |
//! | `system.rs` | The Gauss–Newton system of the extra terms: each active term's Jacobian blocks (for the parameters that move it only), summed as `2 w JᵀJ` and `2 w Jᵀr` into the solver's system. |

use glam::{DAffine3, DMat3, DVec3, DVec4};

use crate::pose::ground::GroundPlane;
use crate::pose::ground::balance::{AllowedRegion, Balance, SupportPolygon};
use crate::pose::ground::contact::Contact;
use crate::pose::solver::params::Param;

mod floor_groups;
mod ground;
mod moments;
mod raised_floor;
mod system;
use crate::pose::constraints::effectors::{
    CentroidEffector, Effector, EffectorGoal, ReferenceStiffness, StiffnessWeighting,
};
use crate::pose::error::PoseError;
use crate::pose::rig::skeleton::rotation_of;
use crate::pose::rig::skeleton::{Skeleton, VertexInfluences};
pub(crate) use crate::pose::rig::skin::VertexSkin;
use crate::pose::rig::skin::{VertexSums, apply, centroid_of, joint_sums};
pub(crate) use crate::pose::solver::terms::ground::{
    contact_hold_weight, contact_skin, validate_ground,
};

/// An effector of weight 1 weighs this many joint pins.
const EFFECTOR_STRENGTH: f64 = 100.0;

/// Strength of a weighted term: fades in over w ∈ [0, ¼].
fn strength(weight: f64) -> f64 {
    (4.0 * weight).clamp(0.0, 1.0)
}

/// One residual block `r` (stacked 3-vectors) with its weight.
enum Term<'a> {
    Position {
        joint: usize,
        target: DVec3,
        weight: f64,
    },
    Orientation {
        joint: usize,
        target: DMat3,
        weight: f64,
    },
    Aim {
        joint: usize,
        axis: DVec3,
        target: DVec3,
        up: Option<(DVec3, DVec3)>,
        weight: f64,
    },
    Centroid {
        sums: Vec<(usize, DVec4)>,
        target: DVec3,
        weight: f64,
    },
    Stiffness {
        joint: usize,
        reference: DMat3,
        root_translation: Option<DVec3>,
        weight: f64,
    },
    /// A skinned vertex (`sums`) not below `plane`; one-sided. `start_gap`: its height above
    /// the ground's skin in the pose the solve starts from; `reach`: per joint of `sums`, its
    /// bind position's distance from the joint's (how far the joint's turn can move it, per
    /// unit of turn). Both read from the model's [`VertexSkin`]s.
    Above {
        sums: &'a VertexSums,
        plane: GroundPlane,
        weight: f64,
        start_gap: f64,
        reach: &'a [f64; 4],
    },
    /// The centre of mass (`sums`: mass-weighted, normalised) in its allowed region (at least
    /// the margin inside the support polygon); one-sided.
    Balance {
        sums: Vec<(usize, DVec4)>,
        /// (Boxed, as `allowed`: a term is as large as its largest kind, and a solve holds
        /// hundreds of floor terms and one balance.)
        polygon: Box<SupportPolygon>,
        /// Where the centre of mass may be: the polygon shrunk by the margin asked (or grown
        /// by a lean).
        allowed: Box<AllowedRegion>,
        weight: f64,
    },
}

impl Term<'_> {
    /// Calls `each` with every joint whose transform the term reads (a joint may repeat).
    fn for_each_joint(&self, mut each: impl FnMut(usize)) {
        match self {
            Term::Position { joint, .. }
            | Term::Orientation { joint, .. }
            | Term::Aim { joint, .. }
            | Term::Stiffness { joint, .. } => each(*joint),
            Term::Centroid { sums, .. } | Term::Balance { sums, .. } => {
                sums.iter().for_each(|(j, _)| each(*j))
            }
            Term::Above { sums, .. } => sums.iter().for_each(|(j, _)| each(*j)),
        }
    }
}

/// The extra terms of one solve, with the skeleton they refer to.
pub(crate) struct ExtraTerms<'a> {
    skeleton: &'a Skeleton,
    terms: Vec<Term<'a>>,
    /// The skinning matrices of the pose the solve starts from (where the vertices kept
    /// above the ground had their `start_gap`).
    start_skinning: Vec<DAffine3>,
    /// Each joint's position in the bind pose.
    bind_origins: &'a [DVec3],
    /// Per joint, the solver's parameters that move it: a term's Jacobian has blocks for
    /// those of its joints only.
    joint_movers: &'a [Vec<u32>],
    length_scale: f64,
    /// The floor's terms in groups with one bound each (`floor_groups.rs`).
    floor_groups: crate::pose::solver::terms::floor_groups::FloorGroups,
}

/// The inputs a solve needs to build its extra terms.
pub(crate) struct ExtraInputs<'a> {
    /// Balance with its centre of mass as per-joint sums ([`mass_sums`]).
    pub balance: Option<(&'a Balance, &'a [(usize, DVec4)])>,
    /// How much further inside its polygon than [`Balance::required_inside`] the centre of
    /// mass is asked to be this solve ([`crate::pose::solver::PoseSolution::balance_boost`], world units).
    pub balance_boost: f64,
    /// Ground contacts.
    pub contacts: &'a [Contact],
    /// The vertices kept above the floor in this solve, each with its plane of the ground.
    pub floor: &'a [(u32, GroundPlane)],
    pub effectors: &'a [Effector],
    pub centroids: &'a [CentroidEffector],
    pub stiffness: Option<&'a ReferenceStiffness>,
    pub reference_globals: &'a [DAffine3],
    pub reference_skinning: &'a [DAffine3],
    /// The skinning matrices of the pose the solve starts from.
    pub start_skinning: &'a [DAffine3],
    pub influences: &'a [VertexInfluences],
    pub relative_inertia: &'a [f64],
    pub bind: &'a [DVec3],
    pub joint_weight: f64,
    pub vertex_weight: f64,
    pub length_scale: f64,
}

/// Checks effectors against the skeleton and model (indices, weights, finite goals).
pub(crate) fn validate(
    skeleton: &Skeleton,
    vertex_count: usize,
    effectors: &[Effector],
    centroids: &[CentroidEffector],
    stiffness: Option<&ReferenceStiffness>,
) -> Result<(), PoseError> {
    let joints = skeleton.len();
    let weight_ok = |w: f64| w.is_finite() && (0.0..=1.0).contains(&w);
    for e in effectors {
        if e.joint >= joints {
            return Err(PoseError::JointOutOfRange {
                joint: e.joint,
                joint_count: joints,
            });
        }
        let finite = match e.goal {
            EffectorGoal::Position(p) => p.is_finite(),
            EffectorGoal::Orientation(q) => q.is_finite() && q.length_squared() > 1e-12,
            EffectorGoal::Aim { axis, target, up } => {
                axis.is_finite()
                    && axis.length_squared() > 1e-18
                    && target.is_finite()
                    && up.is_none_or(|(a, b)| a.is_finite() && b.is_finite())
            }
        };
        if !finite {
            return Err(PoseError::NonFiniteTarget);
        }
        if !weight_ok(e.weight) {
            return Err(PoseError::InvalidConstraintWeight { weight: e.weight });
        }
    }
    for c in centroids {
        if let Some(&v) = c.vertices.iter().find(|&&v| v as usize >= vertex_count) {
            return Err(PoseError::VertexOutOfRange {
                vertex: v,
                vertex_count,
            });
        }
        if !c.target.is_finite() {
            return Err(PoseError::NonFiniteTarget);
        }
        if !weight_ok(c.weight) {
            return Err(PoseError::InvalidConstraintWeight { weight: c.weight });
        }
    }
    if let Some(s) = stiffness {
        skeleton.check_pose(&s.pose)?;
        if s.per_joint.len() != joints {
            return Err(PoseError::PoseLength {
                expected: joints,
                got: s.per_joint.len(),
            });
        }
        if let Some(&w) = s.per_joint.iter().find(|w| !weight_ok(**w)) {
            return Err(PoseError::InvalidConstraintWeight { weight: w });
        }
    }
    Ok(())
}

impl<'a> ExtraTerms<'a> {
    /// The weighted terms for these inputs (targets blended from the reference pose).
    /// (`joint_movers`: per joint, the solver's parameters that move it; `bind_origins`: each
    /// joint's position in the bind pose; `vertex_skins`: each vertex's skin for the ground's
    /// terms, [`vertex_skins`], may be empty without contacts and floor.)
    pub(crate) fn new(
        (skeleton, joint_movers, bind_origins): (&'a Skeleton, &'a [Vec<u32>], &'a [DVec3]),
        vertex_skins: &'a [VertexSkin],
        input: &ExtraInputs<'_>,
    ) -> Self {
        let mut terms = Vec::new();
        // A hundred pinned joints' worth: a reachable goal is met to well under 1e-3 of the
        // model's size against the shape energy of the bends it takes.
        let lw = EFFECTOR_STRENGTH * input.joint_weight;
        let ref_rot = |j: usize| rotation_of(&input.reference_globals[j].matrix3);
        for e in input.effectors.iter().filter(|e| e.weight > 0.0) {
            let weight = lw * strength(e.weight);
            let j = e.joint;
            match e.goal {
                EffectorGoal::Position(p) => terms.push(Term::Position {
                    joint: j,
                    target: input.reference_globals[j].translation.lerp(p, e.weight),
                    weight,
                }),
                EffectorGoal::Orientation(q) => terms.push(Term::Orientation {
                    joint: j,
                    target: DMat3::from_quat(ref_rot(j).slerp(q.normalize(), e.weight)),
                    weight,
                }),
                EffectorGoal::Aim { axis, target, up } => {
                    // Blend the aim point from the one the joint aims at in the reference.
                    let origin = input.reference_globals[j].translation;
                    let reach = (target - origin).length().max(1e-9);
                    let now = origin + ref_rot(j) * axis.normalize() * reach;
                    let blended = origin + (now - origin).lerp(target - origin, e.weight);
                    terms.push(Term::Aim {
                        joint: j,
                        axis: axis.normalize(),
                        target: blended,
                        up: up.map(|(a, b)| (a.normalize_or_zero(), b.normalize_or_zero())),
                        weight,
                    });
                }
            }
        }
        for c in input
            .centroids
            .iter()
            .filter(|c| c.weight > 0.0 && !c.vertices.is_empty())
        {
            let n = c.vertices.len() as f64;
            let sums = joint_sums(
                skeleton.len(),
                (input.bind, input.influences),
                c.vertices.iter().map(|&v| (v, 1.0 / n)),
            );
            let at_reference = centroid_of(&sums, input.reference_skinning);
            terms.push(Term::Centroid {
                sums,
                target: at_reference.lerp(c.target, c.weight),
                weight: lw * strength(c.weight),
            });
        }
        let floor_groups = crate::pose::solver::terms::ground::push_terms(
            &mut terms,
            vertex_skins,
            input,
            (lw, skeleton.len()),
        );
        if let Some(s) = input.stiffness {
            let scale = |j: usize| match s.weighting {
                StiffnessWeighting::Uniform => 1.0,
                StiffnessWeighting::Inertia => {
                    input.relative_inertia.get(j).copied().unwrap_or(1.0)
                }
            };
            for (j, &k) in s.per_joint.iter().enumerate().filter(|(_, k)| **k > 0.0) {
                let joint = &skeleton.joints()[j];
                let root_translation = joint.parent.is_none().then(|| {
                    joint
                        .parent_frame
                        .transform_point3(s.pose.local[j].translation)
                });
                terms.push(Term::Stiffness {
                    joint: j,
                    reference: DMat3::from_quat(s.pose.local[j].rotation),
                    root_translation,
                    weight: input.vertex_weight * k * scale(j),
                });
            }
        }
        Self {
            skeleton,
            terms,
            start_skinning: input.start_skinning.to_vec(),
            bind_origins,
            joint_movers,
            length_scale: input.length_scale,
            floor_groups,
        }
    }

    /// Whether there is anything to add.
    pub(crate) fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// World rotation of a joint (scale divided out).
    fn rotation(globals: &[DAffine3], j: usize) -> DMat3 {
        DMat3::from_quat(rotation_of(&globals[j].matrix3))
    }

    /// The rotation a joint's local rotation is relative to, in the world.
    fn parent_rotation(&self, globals: &[DAffine3], j: usize) -> DMat3 {
        let joint = &self.skeleton.joints()[j];
        let m = joint
            .parent
            .map_or(joint.parent_frame.matrix3, |p| globals[p].matrix3);
        DMat3::from_quat(rotation_of(&m))
    }

    /// True when `a` is `j` or one of its ancestors.
    fn moves(&self, a: usize, j: usize) -> bool {
        self.skeleton.descends_from(j, a)
    }

    /// The deepest joint that moves every one of `joints` (their deepest common ancestor,
    /// or their one joint); `None` for no joints or joints of different roots.
    fn common_carrier(&self, joints: &[usize]) -> Option<usize> {
        let (&first, others) = joints.split_first()?;
        let mut carrier = first;
        for &j in others {
            while !self.moves(carrier, j) {
                carrier = self.skeleton.joints()[carrier].parent?;
            }
        }
        Some(carrier)
    }

    /// Calls `each` with every term's weight and residual (stacked 3-vectors, at most four)
    /// at `globals` / `skinning`, in term order, and for a vertex kept above the ground its
    /// height above the ground's skin (`None` for other terms) — but `certain` with a lower
    /// bound of that height and how many terms it holds for a floor group certainly well
    /// above its ground (`floor_groups.rs`: their residuals are zero; the group's terms are
    /// side by side and skipped whole); no allocation but the rotation cache and the groups'
    /// bounds.
    fn for_each_residual(
        &self,
        globals: &[DAffine3],
        skinning: &[DAffine3],
        mut each: impl FnMut(&Term, f64, &Rows<DVec3>, Option<f64>),
        mut certain: impl FnMut(f64, usize),
    ) {
        let l = self.length_scale;
        // Each joint's world rotation once (a stiffness term reads its joint's and its
        // parent's, which is the next term's joint).
        let mut cache: Vec<Option<DMat3>> = vec![None; globals.len()];
        let mut rotation = |j: usize| *cache[j].get_or_insert_with(|| Self::rotation(globals, j));
        // How far each skinning matrix moved since the start: a vertex certainly well above
        // its ground is not skinned.
        let drift = self.drift(skinning);
        // Floor groups certainly well above their ground: their vertices are not skinned.
        let passing = self
            .floor_groups
            .passing(&drift, crate::pose::solver::terms::ground::NEAR_CONTACT * l);
        let mut i = 0;
        while let Some(term) = self.terms.get(i) {
            if let Some((g, len)) = self.floor_groups.starting_at(i)
                && let Some(bound) = passing[g]
            {
                certain(bound, len);
                i += len;
                continue;
            }
            i += 1;
            let mut gap = None;
            let (weight, rows) = match term {
                Term::Position {
                    joint,
                    target,
                    weight,
                } => (*weight, Rows::of(&[globals[*joint].translation - *target])),
                Term::Orientation {
                    joint,
                    target,
                    weight,
                } => {
                    let r = rotation(*joint);
                    (*weight, columns(&((r - *target) * l)))
                }
                Term::Aim {
                    joint,
                    axis,
                    target,
                    up,
                    weight,
                } => {
                    let r = rotation(*joint);
                    let d = r * *axis;
                    let u = (*target - globals[*joint].translation).normalize_or(d);
                    let mut out = Rows::of(&[(d - u) * l]);
                    if let Some((local_up, world_up)) = up {
                        let e = r * *local_up;
                        let f = (*world_up - u * world_up.dot(u)).normalize_or(e);
                        out.push((e - f) * l);
                    }
                    (*weight, out)
                }
                Term::Centroid {
                    sums,
                    target,
                    weight,
                } => (*weight, Rows::of(&[centroid_of(sums, skinning) - *target])),
                Term::Above {
                    sums,
                    plane,
                    weight,
                    start_gap,
                    reach,
                } => {
                    let height = self
                        .certainly_above(sums, (*start_gap, reach), &drift)
                        .unwrap_or_else(|| self.gap_above(sums, plane, skinning));
                    gap = Some(height);
                    (*weight, Rows::of(&[plane.normal * height.min(0.0)]))
                }
                Term::Balance { weight, .. } => {
                    (*weight, Rows::of(&[self.balance_residual(term, skinning)]))
                }
                Term::Stiffness {
                    joint,
                    reference,
                    root_translation,
                    weight,
                } => {
                    let r = rotation(*joint);
                    let parent = match self.skeleton.joints()[*joint].parent {
                        Some(p) => rotation(p),
                        None => self.parent_rotation(globals, *joint),
                    };
                    let goal = parent * *reference;
                    let mut out = columns(&((r - goal) * l));
                    if let Some(t) = root_translation {
                        out.push(globals[*joint].translation - *t);
                    }
                    (*weight, out)
                }
            };
            each(term, weight, &rows, gap);
        }
    }

    /// `Σ w ‖r‖²`; `gaps` gets each vertex's height above its ground's skin, in term order
    /// (what [`ExtraTerms::first_contact`] compares between two poses) — for a vertex
    /// certainly well above it, a lower bound ([`ExtraTerms::certainly_above`]).
    pub(crate) fn energy(
        &self,
        globals: &[DAffine3],
        skinning: &[DAffine3],
        gaps: &mut Vec<f64>,
    ) -> f64 {
        gaps.clear();
        let mut sum = 0.0;
        let gaps = std::cell::RefCell::new(gaps);
        self.for_each_residual(
            globals,
            skinning,
            |_, w, r, gap| {
                sum += w * r.iter().map(|v| v.length_squared()).sum::<f64>();
                gaps.borrow_mut().extend(gap);
            },
            |bound, count| gaps.borrow_mut().extend(std::iter::repeat_n(bound, count)),
        );
        sum
    }

    /// The Jacobian blocks (one 3 × 3 per residual 3-vector) of a two-sided term for one
    /// parameter.
    fn jacobian(
        &self,
        term: &Term,
        param: Param,
        globals: &[DAffine3],
        skinning: &[DAffine3],
    ) -> Option<Rows<DMat3>> {
        let l = self.length_scale;
        let (a, rotation) = match param {
            Param::Rotation(a) => (a, true),
            Param::Translation(a) => (a, false),
        };
        let origin = globals[a].translation;
        // d(point) for a point moved rigidly with joint `a`'s subtree.
        let point = |p: DVec3| {
            if rotation {
                -skew(p - origin)
            } else {
                DMat3::IDENTITY
            }
        };
        // d(direction) for a direction turned with the subtree.
        let direction = |d: DVec3| if rotation { -skew(d) } else { DMat3::ZERO };
        match term {
            Term::Position { joint, .. } => self
                .moves(a, *joint)
                .then(|| Rows::of(&[point(globals[*joint].translation)])),
            Term::Orientation { joint, .. } => self.moves(a, *joint).then(|| {
                let r = Self::rotation(globals, *joint);
                Rows::of(&[r.x_axis, r.y_axis, r.z_axis].map(|c| direction(c) * l))
            }),
            Term::Aim {
                joint,
                axis,
                target,
                up,
                ..
            } => self.moves(a, *joint).then(|| {
                let r = Self::rotation(globals, *joint);
                let d = r * *axis;
                let to = *target - globals[*joint].translation;
                let dist = to.length().max(1e-9);
                let u = to / dist;
                let project = DMat3::IDENTITY - outer(u, u);
                // r = d − u; du = −P dp / dist.
                let change =
                    (direction(d) + project * point(globals[*joint].translation) / dist) * l;
                let mut out = Rows::of(&[change]);
                if up.is_some() {
                    let e = r * up.map_or(DVec3::Y, |u| u.0);
                    out.push(direction(e) * l);
                }
                out
            }),
            Term::Centroid { sums, .. } => self
                .centroid_jacobian(sums, a, rotation, origin, skinning)
                .map(|b| Rows::of(&[b])),
            // Summed elsewhere: a vertex along its ground's normal (`moments.rs`), balance as
            // rank-one parts (`system.rs`).
            Term::Above { .. } | Term::Balance { .. } => None,
            Term::Stiffness {
                joint,
                root_translation,
                ..
            } => {
                // Only the joint's own parameters: an ancestor turns the joint and its goal
                // together, so the residual turns rigidly and its length does not change — no
                // gradient and no curvature (the Gauss–Newton blocks `JᵀJ` it would add are
                // spurious stiffness on the ancestors). A translation is a root's own, and
                // counts only where the term holds the root's position.
                if a != *joint || (!rotation && root_translation.is_none()) {
                    return None;
                }
                let mut out = if rotation {
                    let r = Self::rotation(globals, *joint);
                    Rows::of(&[r.x_axis, r.y_axis, r.z_axis].map(|c| direction(c) * l))
                } else {
                    Rows::of(&[DMat3::ZERO; 3])
                };
                if root_translation.is_some() {
                    out.push(point(globals[*joint].translation));
                }
                Some(out)
            }
        }
    }

    /// The change of the weighted centroid `Σ_j S_j m_j` under parameter `a` (a rotation about
    /// `origin`, or a root's translation); `None` when no joint it moves has a share.
    fn centroid_jacobian(
        &self,
        sums: &[(usize, DVec4)],
        a: usize,
        rotation: bool,
        origin: DVec3,
        skinning: &[DAffine3],
    ) -> Option<DMat3> {
        let mut moved = DVec3::ZERO;
        let mut mass = 0.0;
        for &(j, m) in sums.iter().filter(|(j, _)| self.moves(a, *j)) {
            moved += apply(&skinning[j], m);
            mass += m.w;
        }
        carried_change((moved, mass), rotation, origin)
    }
}

/// The change of the part of a weighted centroid a parameter carries — its skinned sum
/// `moved` and its weight `mass` — under the parameter: a turn about `origin`, or a root's
/// translation; `None` when it carries none of it.
fn carried_change((moved, mass): (DVec3, f64), rotation: bool, origin: DVec3) -> Option<DMat3> {
    (mass != 0.0).then(|| match rotation {
        true => -skew(moved - origin * mass),
        false => DMat3::IDENTITY * mass,
    })
}

/// Test terms: only a floor — every vertex of `skins` kept above its plane in `under`, the
/// joints at rest (identity skinning), size 1.
/// (`skins`: the vertices' [`vertex_skins`].)
#[cfg(test)]
fn floor_only<'a>(
    rig: (&'a Skeleton, &'a [Vec<u32>], &'a [DVec3]),
    skins: &'a [VertexSkin],
    under: &[(u32, GroundPlane)],
) -> ExtraTerms<'a> {
    floor_and_contacts(rig, skins, under, &[])
}

/// Test terms: a floor as [`floor_only`] and `contacts`.
#[cfg(test)]
fn floor_and_contacts<'a>(
    (skeleton, movers, bind_origins): (&'a Skeleton, &'a [Vec<u32>], &'a [DVec3]),
    skins: &'a [VertexSkin],
    under: &[(u32, GroundPlane)],
    contacts: &[Contact],
) -> ExtraTerms<'a> {
    let rest = vec![DAffine3::IDENTITY; skeleton.len()];
    ExtraTerms::new(
        (skeleton, movers, bind_origins),
        skins,
        &ExtraInputs {
            balance: None,
            balance_boost: 0.0,
            contacts,
            floor: under,
            effectors: &[],
            centroids: &[],
            stiffness: None,
            reference_globals: &rest,
            reference_skinning: &rest,
            start_skinning: &rest,
            influences: &[],
            relative_inertia: &vec![1.0; skeleton.len()],
            bind: &[],
            joint_weight: 1.0,
            vertex_weight: 1.0,
            length_scale: 1.0,
        },
    )
}

fn columns(m: &DMat3) -> Rows<DVec3> {
    Rows::of(&[m.x_axis, m.y_axis, m.z_axis])
}

/// Up to four rows of a residual or its Jacobian, on the stack (a term has at most four:
/// a stiffness term's three rotation columns and its root's position).
#[derive(Clone, Copy)]
struct Rows<T: Copy> {
    items: [T; 4],
    len: usize,
}

impl<T: Copy + Default> Rows<T> {
    /// The rows `items` (at most four).
    fn of(items: &[T]) -> Self {
        let mut rows = Self {
            items: [T::default(); 4],
            len: 0,
        };
        for &item in items {
            rows.push(item);
        }
        rows
    }

    /// Appends a row (a fifth is a bug: debug builds stop, release builds drop it).
    fn push(&mut self, item: T) {
        debug_assert!(self.len < 4, "a term has at most four rows");
        if let Some(slot) = self.items.get_mut(self.len) {
            *slot = item;
            self.len += 1;
        }
    }

    fn iter(&self) -> std::slice::Iter<'_, T> {
        self.items[..self.len].iter()
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The cross-product matrix `[o]×` (`[o]× v = o × v`).
pub(crate) fn skew(o: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, o.z, -o.y),
        DVec3::new(-o.z, 0.0, o.x),
        DVec3::new(o.y, -o.x, 0.0),
    )
}
