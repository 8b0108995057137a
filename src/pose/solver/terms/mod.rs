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
//! | `jacobians.rs` | The Jacobians of the two-sided terms (effectors, centroids, stiffness) in the bone parameters, for the parameters that move each term. |
//! | `moments.rs` | The one-number terms (a vertex under or near its ground, along the ground's normal `n`) summed by their moments instead of pair by pair of parameters. |
//! | `raised_floor.rs` | Non-penetration as an augmented Lagrangian: a vertex the ground's penalty cannot get out of the ground is kept above a plane raised by its depth. |
//! | `residuals.rs` | Each term's residual at a pose and their weighted sum, the energy (floor groups certainly above their ground passed whole). |
//! | `system.rs` | The Gauss–Newton system of the extra terms: each active term's Jacobian blocks (for the parameters that move it only), summed as `2 w JᵀJ` and `2 w Jᵀr` into the solver's system. |

use glam::{DAffine3, DMat3, DVec3, DVec4};

use crate::pose::ground::GroundPlane;
use crate::pose::ground::balance::{AllowedRegion, Balance, SupportPolygon};
use crate::pose::ground::contact::Contact;

mod floor_groups;
mod ground;
mod jacobians;
mod moments;
mod raised_floor;
mod residuals;
mod system;
use crate::pose::constraints::effectors::{
    CentroidEffector, Effector, EffectorGoal, ReferenceStiffness, StiffnessWeighting,
};
use crate::pose::error::PoseError;
use crate::pose::rig::skeleton::rotation_of;
use crate::pose::rig::skeleton::{Skeleton, VertexInfluences};
pub(crate) use crate::pose::rig::skin::VertexSkins;
use crate::pose::rig::skin::{VertexSums, centroid_of, joint_sums};
pub(crate) use crate::pose::solver::terms::ground::{
    contact_hold_weight, contact_skin, validate_ground,
};
use crate::pose::solver::terms::jacobians::carried_change;

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
    /// unit of turn). Both read from the model's
    /// [`VertexSkin`](crate::pose::rig::skin::VertexSkin)s.
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
    floor_groups: crate::pose::solver::terms::floor_groups::FloorGroups<'a>,
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
        vertex_skins: &'a VertexSkins,
        input: &ExtraInputs<'_>,
    ) -> Self {
        // Room for every term at once: a grounded solve makes thousands.
        let patches: usize = input.contacts.iter().map(|c| c.patch.len() + 1).sum();
        let stiff = input.stiffness.map_or(0, |s| s.per_joint.len());
        let mut terms = Vec::with_capacity(
            input.effectors.len() + input.centroids.len() + patches + input.floor.len() + stiff + 1,
        );
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
        let floor_groups =
            crate::pose::solver::terms::ground::push_terms(&mut terms, vertex_skins, input, lw);
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
}

/// Test terms: only a floor — every vertex of `skins` kept above its plane in `under`, the
/// joints at rest (identity skinning), size 1.
/// (`skins`: the vertices' [`vertex_skins`].)
#[cfg(test)]
fn floor_only<'a>(
    rig: (&'a Skeleton, &'a [Vec<u32>], &'a [DVec3]),
    skins: &'a VertexSkins,
    under: &[(u32, GroundPlane)],
) -> ExtraTerms<'a> {
    floor_and_contacts(rig, skins, under, &[])
}

/// Test terms: a floor as [`floor_only`] and `contacts`.
#[cfg(test)]
fn floor_and_contacts<'a>(
    (skeleton, movers, bind_origins): (&'a Skeleton, &'a [Vec<u32>], &'a [DVec3]),
    skins: &'a VertexSkins,
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
