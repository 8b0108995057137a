//! The ground's terms of a pose solve: contacts (patch vertices kept above their ground, a
//! planted contact's joint's up turned to the ground's normal; the weight of its holds, which
//! `holds.rs` folds into the solve's `Q`), the floor, and balance — built from
//! [`PoseConstraints`], one-sided where they are inequalities.

use glam::DVec3;

use crate::pose::constraints::PoseConstraints;
use crate::pose::error::PoseError;
use crate::pose::ground::GroundPlane;
use crate::pose::ground::balance::SupportPolygon;
use crate::pose::ground::floor::Floor;
use crate::pose::rig::skin::{JointSums, VertexSkin, VertexSkins, VertexSums, centroid_of};
use crate::pose::solver::CONTACT_SKIN;
use crate::pose::solver::terms::floor_groups::{FloorGroups, plan_groups};
use crate::pose::solver::terms::{EFFECTOR_STRENGTH, ExtraInputs, ExtraTerms, Term, strength};

/// Balance at weight 1 against a position effector at weight 1: the body leans out only where
/// an effector is a thousand times stronger. (At a hundred, a Fox standing across a 25° slope
/// stayed 2.7 % of its size out of its polygon: the penalty's give was the whole lean.)
const BALANCE_STRENGTH: f64 = 1000.0;
/// A planted contact's hold against a position effector at weight 1.
const CONTACT_STRENGTH: f64 = 100.0;
/// Non-penetration against a planted contact's hold: ten times stiffer, so where the hold and
/// the ground disagree (a curved sole laid on a slope, a patch whose skin bends) the ground
/// wins and the hold gives.
const ABOVE_OVER_HOLD: f64 = 10.0;
/// A planted sole's turn to the ground's normal against a position effector at weight 1.
const SOLE_TURN: f64 = 3.0;
/// A vertex less than this share of the model's size above its ground's skin is near contact
/// ([`ExtraTerms::near_contact`]).
pub(super) const NEAR_CONTACT: f64 = 5e-3;
/// A near-contact vertex's curvature in the step's model against its non-penetration weight:
/// a position effector's worth (a thousandth of the ground's push).
const NEAR_CURVATURE: f64 = 1e-3;

/// Two planes closer than this share of the model's size (normals and offsets) are the same
/// plane: a floor vertex a contact keeps above one is kept by that one term at the two
/// terms' weight — the same energy, gradient and curvature, summed once.
const SAME_PLANE: f64 = 1e-12;

/// Whether `a` and `b` are the same plane: unit normals within [`SAME_PLANE`] of each other
/// and `b`'s point within `tolerance` (world units) of `a`.
fn same_plane(a: &GroundPlane, b: &GroundPlane, tolerance: f64) -> bool {
    (a.normal - b.normal).abs().max_element() <= SAME_PLANE
        && a.normal.dot(b.point - a.point).abs() <= tolerance
}

/// For each floor vertex (`floor`), the contact's term that keeps it above the same plane
/// ([`same_plane`], to within `tolerance`), if any (`patch_terms`: each contact patch
/// vertex's term, `terms` the solve's so far; `vertex_count`: the model's). Empty when no
/// contact has a patch.
fn kept_by_a_contact(
    floor: &[(u32, GroundPlane)],
    mut patch_terms: Vec<(u32, usize)>,
    terms: &[Term],
    (tolerance, vertex_count): (f64, usize),
) -> Vec<Option<usize>> {
    if patch_terms.is_empty() {
        return Vec::new();
    }
    patch_terms.sort_unstable();
    // One bit a vertex: most floor vertices are in no patch and need no search.
    let mut in_a_patch = vec![0u64; vertex_count.div_ceil(64)];
    for &(v, _) in &patch_terms {
        in_a_patch[v as usize / 64] |= 1 << (v % 64);
    }
    floor
        .iter()
        .map(|&(v, plane)| {
            if in_a_patch[v as usize / 64] & (1 << (v % 64)) == 0 {
                return None;
            }
            let first = patch_terms.partition_point(|&(u, _)| u < v);
            patch_terms[first..]
                .iter()
                .take_while(|&&(u, _)| u == v)
                .map(|&(_, i)| i)
                .find(|&i| match &terms[i] {
                    Term::Above { plane: held, .. } => same_plane(held, &plane, tolerance),
                    _ => false,
                })
        })
        .collect()
}

/// Checks the balance, contacts and floor of `constraints` against a model of `joint_count`
/// joints and `vertex_count` welded vertices.
pub(crate) fn validate_ground(
    constraints: &PoseConstraints,
    joint_count: usize,
    vertex_count: usize,
) -> Result<(), PoseError> {
    if let Some(b) = &constraints.balance {
        if !b.is_valid(vertex_count) {
            return Err(PoseError::InvalidBalance(
                "support points, gravity, margin or masses are not usable",
            ));
        }
        if !(b.weight.is_finite() && (0.0..=1.0).contains(&b.weight)) {
            return Err(PoseError::InvalidConstraintWeight { weight: b.weight });
        }
    }
    for c in &constraints.contacts {
        if c.joint >= joint_count {
            return Err(PoseError::JointOutOfRange {
                joint: c.joint,
                joint_count,
            });
        }
        if let Some(&v) = c.patch.iter().find(|&&v| v as usize >= vertex_count) {
            return Err(PoseError::VertexOutOfRange {
                vertex: v,
                vertex_count,
            });
        }
        if !c.is_valid() {
            return Err(PoseError::InvalidContact(
                "ground, planted points or up axis are not usable",
            ));
        }
    }
    if let Some(f) = &constraints.floor {
        if !f.is_valid() {
            return Err(PoseError::InvalidContact(
                "the floor's plane or band is not usable",
            ));
        }
        if let Floor::Under(under) = f
            && let Some(&(v, _)) = under.iter().find(|(v, _)| *v as usize >= vertex_count)
        {
            return Err(PoseError::VertexOutOfRange {
                vertex: v,
                vertex_count,
            });
        }
    }
    Ok(())
}

/// [`CONTACT_SKIN`] in world units for a model of size `length_scale`
/// ([`ExtraTerms::skin`]; a planted vertex's hold is lifted by it).
pub(crate) fn contact_skin(length_scale: f64) -> f64 {
    CONTACT_SKIN * length_scale
}

/// A planted contact's hold on each of its patch vertices (`joint_weight`: a pinned joint's
/// weight): [`CONTACT_STRENGTH`] position effectors at weight 1.
pub(crate) fn contact_hold_weight(joint_weight: f64) -> f64 {
    CONTACT_STRENGTH * EFFECTOR_STRENGTH * joint_weight
}

/// Appends the contacts', the floor's and balance's terms of `input` (`lw`: a position
/// effector's weight at weight 1); returns the floor's groups. (`vertex_skins`: each
/// vertex's, which its terms point at.)
pub(super) fn push_terms<'a>(
    terms: &mut Vec<Term<'a>>,
    vertex_skins: &'a VertexSkins,
    input: &ExtraInputs<'_>,
    lw: f64,
) -> FloorGroups<'a> {
    // Contacts: every patch vertex above its ground; a planted one held where it touched,
    // its joint's up turned to the ground's normal.
    let above = ABOVE_OVER_HOLD * CONTACT_STRENGTH * lw;
    let contact_skin = CONTACT_SKIN * input.length_scale;
    let above_term = |v: u32, plane: GroundPlane| {
        let VertexSkin { sums, reach, .. } = &vertex_skins[v as usize];
        Term::Above {
            start_gap: plane.height(centroid_of(sums, input.start_skinning)) - contact_skin,
            reach,
            sums,
            plane,
            weight: above,
        }
    };
    // Each patch vertex's term, by vertex: a floor vertex a contact already keeps above the
    // same plane is not given a second term (see `same_plane`).
    let mut patch_terms: Vec<(u32, usize)> = Vec::new();
    // (The holds themselves are quadratic in the skinning matrices: `holds.rs` adds them to
    // the solve's `Q`.)
    for c in input.contacts {
        for &v in &c.patch {
            patch_terms.push((v, terms.len()));
            terms.push(above_term(v, c.ground));
        }
        // (A patch still rolling onto the ground turns with its holds.)
        if let (Some(_), Some(up), None) = (&c.planted, c.up, c.rolling) {
            let origin = input.reference_globals[c.joint].translation;
            terms.push(Term::Aim {
                joint: c.joint,
                axis: up.normalize(),
                target: origin + c.ground.normal * (1e3 * input.length_scale),
                up: None,
                weight: SOLE_TURN * lw,
            });
        }
    }
    // A floor vertex kept above the same plane by a contact's term: its weight is added to
    // that term instead.
    let tolerance = SAME_PLANE * input.length_scale;
    let merged = kept_by_a_contact(
        input.floor,
        patch_terms,
        terms,
        (tolerance, vertex_skins.len()),
    );
    for i in merged.iter().flatten() {
        if let Term::Above { weight, .. } = &mut terms[*i] {
            *weight += above;
        }
    }
    let is_merged = |k: usize| merged.get(k).is_some_and(Option::is_some);
    // The floor's other vertices, each group's side by side (`floor_groups.rs`).
    let (order, mut groups) = plan_groups(input.floor, vertex_skins, terms.len(), is_merged);
    for &k in &order {
        let (v, plane) = input.floor[k as usize];
        let term = above_term(v, plane);
        if let Term::Above { start_gap, .. } = term {
            groups.lower_bound(terms.len(), start_gap);
        }
        terms.push(term);
    }
    if let Some((b, sums)) = input.balance
        && !sums.is_empty()
    {
        let polygon = SupportPolygon::new(&b.support, b.gravity);
        terms.push(Term::Balance {
            sums: sums.to_vec(),
            allowed: Box::new(polygon.allowed(b.required_inside() + input.balance_boost)),
            polygon: Box::new(polygon),
            weight: BALANCE_STRENGTH * lw * strength(b.weight),
        });
    }
    groups
}

impl ExtraTerms<'_> {
    /// How far above its ground a vertex is held by a one-sided contact term: the penalty
    /// balances a push at a depth proportional to it, so the term acts from a thin skin above
    /// the surface and a pushed vertex comes to rest on the surface, not under it.
    fn skin(&self) -> f64 {
        contact_skin(self.length_scale)
    }

    /// How far inside its support polygon (of three corners or more) the centre of mass is
    /// in the pose of `skinning`, world units, negative outside; `None` without balance or
    /// over a point or a segment.
    pub(crate) fn balance_inside(&self, skinning: &[glam::DAffine3]) -> Option<f64> {
        self.terms.iter().find_map(|term| match term {
            Term::Balance { sums, polygon, .. } if polygon.corners().len() >= 3 => {
                Some(polygon.signed_distance(centroid_of(sums, skinning)))
            }
            _ => None,
        })
    }

    /// The share of the way between two poses at which the first vertex above its ground's
    /// skin in the first reaches it, by its heights at both ends (`from` and `to`: the `gaps`
    /// of [`ExtraTerms::energy`] at each, linear in between); `None` when none goes under.
    /// A height far above the ground may be a lower bound in `gaps`: a vertex that goes under
    /// has its height in the first pose (`from_skinning`) computed.
    pub(crate) fn first_contact(
        &self,
        from: &[f64],
        to: &[f64],
        from_skinning: &[glam::DAffine3],
    ) -> Option<f64> {
        let above = self.terms.iter().filter_map(|t| match t {
            Term::Above { sums, plane, .. } => Some((sums, plane)),
            _ => None,
        });
        from.iter()
            .zip(to)
            .zip(above)
            .filter(|&((&before, &after), _)| before > 0.0 && after < 0.0)
            .map(|((_, after), (sums, plane))| {
                let before = self.gap_above(sums, plane, from_skinning);
                before / (before - after)
            })
            .filter(|t| t.is_finite() && *t > 0.0)
            .min_by(f64::total_cmp)
    }

    /// A vertex kept above its ground that is above it by less than [`NEAR_CONTACT`] of the
    /// size (`gap`: its height above the ground's skin) enters the Gauss–Newton model as if
    /// its term were active, with no residual — curvature along the normal, no pull — at
    /// [`NEAR_CURVATURE`] of its weight: its sums, its normal and a depth of zero, and that
    /// weight's scale. `None` for other terms and vertices.
    ///
    /// The model of a step sees only the vertices already under their ground; a vertex just
    /// above it is free in the model, and a full step that swung a paw or a tail tip down
    /// took it deep into the ground, rose and was shortened or damped (a walking crowd on
    /// terrain: four rejected steps a solve, a tenth of its solves a dozen). With the
    /// curvature the step's model knows what going down there would cost, as the one-sided
    /// term would once it acts; rising stays nearly free.
    pub(super) fn near_contact<'t>(
        &self,
        term: &'t Term,
        gap: Option<f64>,
    ) -> Option<((&'t VertexSums, DVec3, f64), f64)> {
        match (term, gap) {
            (Term::Above { sums, plane, .. }, Some(gap))
                if (0.0..NEAR_CONTACT * self.length_scale).contains(&gap) =>
            {
                Some(((sums, plane.normal, 0.0), NEAR_CURVATURE))
            }
            _ => None,
        }
    }

    /// The directions a balance term's residual is measured along in the pose of `skinning`,
    /// each with its share of the term's weight ([`crate::pose::ground::balance::AllowedRegion::directions`]): across the
    /// nearest edge of the allowed region while the centre of mass is out of it, towards and
    /// across a corner past one; none while it holds.
    ///
    /// (The region is the polygon shrunk by the margin. Measured from the polygon's own edges
    /// instead, the residual inside the margin's band jumped from one edge's normal to the
    /// next where their distances were equal: a kink in the energy at the rounded front of the
    /// feet's outline, where the humanoid's centre of mass rested, and a third of its solves
    /// rejected 10–22 steps that went round it.)
    ///
    /// (Tried: near the edge, the outward direction at 1e-3 to 1e-1 of the weight with no
    /// pull, as the floor does for a vertex near its ground. The mannequin dragged on the slope
    /// solved in 0.92 ms instead of 1.10, but the walking crowd's centre of mass was held back:
    /// supported 0.57 instead of 0.61, penetration p99 3.4e-3 instead of 2.5e-3. And: the
    /// polygon as the intersection of its edges' half-planes shrunk by the margin, each edge
    /// a rank-one part of its own, so a corner is two in the model. The mannequin's solve
    /// fell to 0.72 ms, but the centre of mass then rested exactly on the edge and every other
    /// solve of the humanoid overshot it: 1.36–1.54 ms; smoothed over 5e-3 of the size, all
    /// as here within 3 %.)
    pub(super) fn balance_directions(
        &self,
        term: &Term,
        skinning: &[glam::DAffine3],
    ) -> Vec<(DVec3, f64)> {
        let Term::Balance { sums, allowed, .. } = term else {
            return Vec::new();
        };
        allowed.directions(centroid_of(sums, skinning))
    }

    /// Per joint, how far its skinning matrix is from the start's: the Frobenius norm of the
    /// linear part's change and how far it moved the joint's bind position (empty without
    /// vertices kept above the ground).
    pub(super) fn drift(&self, skinning: &[glam::DAffine3]) -> Vec<(f64, f64)> {
        if !self.terms.iter().any(|t| matches!(t, Term::Above { .. })) {
            return Vec::new();
        }
        skinning
            .iter()
            .zip(&self.start_skinning)
            .zip(self.bind_origins)
            .map(|((s, s0), &origin)| {
                let d = s.matrix3 - s0.matrix3;
                let linear = d.x_axis.length_squared()
                    + d.y_axis.length_squared()
                    + d.z_axis.length_squared();
                let moved = d * origin + (s.translation - s0.translation);
                (linear.sqrt(), moved.length())
            })
            .collect()
    }

    /// A lower bound of a vertex's height above its ground's skin, from its height at the
    /// start and how far its joints' skinning matrices `drift`ed since (a vertex moves at
    /// most `Σ_j w_j (‖ΔA_j‖ |b − c_j| + |Δo_j|)`, `c_j` the joint's bind position, `Δo_j`
    /// how far it moved), when that bound is above [`NEAR_CONTACT`]; `None` when the vertex
    /// may be near or in its ground (then it is skinned).
    pub(super) fn certainly_above(
        &self,
        sums: &JointSums,
        (start_gap, reach): (f64, &[f64; 4]),
        drift: &[(f64, f64)],
    ) -> Option<f64> {
        let near = NEAR_CONTACT * self.length_scale;
        // (A vertex that started near its ground, a planted sole's, cannot be bounded above
        // it: no need to add up its joints' motion.)
        if start_gap.is_nan() || start_gap <= near {
            return None;
        }
        let moved: f64 = sums
            .iter()
            .zip(reach)
            .map(|(&(j, m), reach)| {
                let (turn, origin) = drift.get(j).copied().unwrap_or((f64::INFINITY, 0.0));
                m.w.abs() * (turn * reach + origin)
            })
            .sum();
        let lower = start_gap - moved;
        (lower > near).then_some(lower)
    }

    /// A vertex's height above its ground's skin (negative: in it).
    pub(super) fn gap_above(
        &self,
        sums: &[(usize, glam::DVec4)],
        plane: &GroundPlane,
        skinning: &[glam::DAffine3],
    ) -> f64 {
        plane.height(centroid_of(sums, skinning)) - self.skin()
    }

    /// The residual of a balance term (zero while it holds): the centre of mass's way out of
    /// its allowed region. (A vertex's is its depth along its ground's normal, from its gap:
    /// [`ExtraTerms::energy`].)
    pub(super) fn balance_residual(&self, term: &Term, skinning: &[glam::DAffine3]) -> DVec3 {
        match term {
            Term::Balance { sums, allowed, .. } => allowed
                .violation(centroid_of(sums, skinning))
                .unwrap_or(DVec3::ZERO),
            _ => DVec3::ZERO,
        }
    }
}

/// An active non-penetration term: its vertex's skinning sums, its ground's normal and its
/// residual's length along it (`r = normal · depth`). Its Jacobian is projected on the normal
/// (`J = n nᵀ B` for the vertex's change `B`), so `JᵀJ` and `Jᵀr` need only `Bᵀ n`. `None`
/// for other terms and a vertex above its ground. (Balance's are rank-one parts of their own:
/// [`ExtraTerms::balance_directions`].)
pub(super) fn along_the_normal<'t>(
    term: &'t Term,
    r: &crate::pose::solver::terms::Rows<DVec3>,
) -> Option<(&'t VertexSums, DVec3, f64)> {
    let r = *r.iter().next()?;
    match term {
        Term::Above { sums, plane, .. } if r != DVec3::ZERO => {
            Some((sums, plane.normal, r.dot(plane.normal)))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use glam::{DAffine3, DVec3};

    use crate::pose::ground::GroundPlane;
    use crate::pose::rig::skeleton::{Joint, Skeleton};
    use crate::pose::rig::skin::{VertexSkins, vertex_skins};
    use crate::pose::solver::params::Param;
    use crate::pose::solver::terms::{EFFECTOR_STRENGTH, ExtraTerms};

    /// A one-joint bar (its joint at the origin).
    fn bar() -> Skeleton {
        Skeleton::new(vec![Joint {
            name: "bar".into(),
            parent: None,
            parent_frame: DAffine3::IDENTITY,
            inverse_bind: DAffine3::IDENTITY,
        }])
        .unwrap()
    }

    /// The skins of vertices at bind positions `bind`, all on the bar's joint.
    fn bar_skins(bind: &[DVec3]) -> VertexSkins {
        let one = [(0u32, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)];
        vertex_skins(bind, &vec![one; bind.len()], &[DVec3::ZERO])
    }

    /// The terms keeping the bar's vertices (their `skins`: [`bar_skins`]) above `floor`
    /// (pinned joints of weight 1, size 1).
    fn floor_terms<'a>(
        skeleton: &'a Skeleton,
        movers: &'a [Vec<u32>],
        skins: &'a VertexSkins,
        floor: GroundPlane,
    ) -> ExtraTerms<'a> {
        let under: Vec<(u32, GroundPlane)> = (0..skins.len() as u32).map(|v| (v, floor)).collect();
        crate::pose::solver::terms::floor_only((skeleton, movers, &[DVec3::ZERO]), skins, &under)
    }

    /// A step that takes a vertex 1 above the floor to 2 below it first touches the floor's
    /// skin a third of the way; one that keeps every vertex above touches nothing; a vertex
    /// that starts below does not count (it is already in the model).
    #[test]
    fn a_step_first_touches_the_floor_where_its_lowest_vertex_crosses_it() {
        let skeleton = bar();
        let floor = GroundPlane::new(DVec3::ZERO, DVec3::Y).unwrap();
        let bind = [DVec3::new(0.0, 1.0, 0.0), DVec3::new(2.0, -0.5, 0.0)];
        let movers = [vec![0]];
        let skins = bar_skins(&bind);
        let terms = floor_terms(&skeleton, &movers, &skins, floor);
        let gaps = |skinning: DAffine3| {
            let mut gaps = Vec::new();
            terms.energy(&[skinning], &[skinning], &mut gaps);
            gaps
        };
        let from = gaps(DAffine3::IDENTITY);
        let down = gaps(DAffine3::from_translation(DVec3::new(0.0, -3.0, 0.0)));
        let skin = super::CONTACT_SKIN;
        let t = terms
            .first_contact(&from, &down, &[DAffine3::IDENTITY])
            .unwrap();
        assert!((t - (1.0 - skin) / 3.0).abs() < 1e-12, "{t}");
        let up = gaps(DAffine3::from_translation(DVec3::new(0.0, 0.5, 0.0)));
        let at_start = [DAffine3::IDENTITY];
        assert_eq!(terms.first_contact(&from, &up, &at_start), None);
    }

    /// A vertex just above the floor adds the floor's normal curvature at a thousandth of its
    /// weight, and no gradient; one further up adds nothing (the model of a step sees the
    /// ground a paw swings down to, without being pulled to it).
    #[test]
    fn a_vertex_near_the_floor_adds_curvature_and_no_pull() {
        let skeleton = bar();
        let floor = GroundPlane::new(DVec3::ZERO, DVec3::Y).unwrap();
        let movers = [vec![0]];
        let params = [Param::Translation(0)];
        let system = |height: f64| {
            let y = super::CONTACT_SKIN + height * super::NEAR_CONTACT;
            let skins = bar_skins(&[DVec3::new(0.3, y, 0.0)]);
            let terms = floor_terms(&skeleton, &movers, &skins, floor);
            let (mut h, mut g) = (vec![0.0; 9], vec![0.0; 3]);
            let at = [DAffine3::IDENTITY];
            terms.add_system_at((&at, &at), &params, (&mut h, &mut Vec::new()), &mut g);
            (h, g)
        };
        let above = super::ABOVE_OVER_HOLD * super::CONTACT_STRENGTH * EFFECTOR_STRENGTH;
        let (h, g) = system(0.5);
        let expected = 2.0 * above * super::NEAR_CURVATURE;
        assert!((h[4] - expected).abs() < 1e-9 * expected, "{h:?}");
        assert!(
            h.iter().enumerate().all(|(k, v)| k == 4 || *v == 0.0),
            "{h:?}"
        );
        assert!(g.iter().all(|v| *v == 0.0), "{g:?}");
        let (h, g) = system(2.0);
        assert!(h.iter().chain(&g).all(|v| *v == 0.0), "{h:?} {g:?}");
    }

    /// A floor vertex a contact keeps above the same plane is one term at both terms'
    /// weight: the energy and the Gauss–Newton system are the two terms' (against the same
    /// floor a billionth of the size lower, where each vertex keeps two terms), under
    /// motions that take vertices under, near and far above the ground. (Fails with the
    /// floor's weight not added to the contact's term.)
    #[test]
    fn a_floor_vertex_kept_by_a_contact_on_the_same_plane_is_summed_once() {
        let skeleton = bar();
        let movers = [vec![0, 1]];
        let params = [Param::Rotation(0), Param::Translation(0)];
        let ground =
            GroundPlane::new(DVec3::new(0.1, -0.2, 0.3), DVec3::new(0.2, 1.0, -0.1)).unwrap();
        let bind: Vec<DVec3> = (0..8)
            .map(|k| DVec3::new(0.2 * (k % 3) as f64 - 0.2, -0.21 + 0.004 * k as f64, 0.1))
            .collect();
        let skins = bar_skins(&bind);
        let contact = crate::pose::ground::contact::Contact::new(0, (0..5).collect(), ground);
        let lower = GroundPlane::new(ground.point - ground.normal * 1e-9, ground.normal).unwrap();
        let with_floor = |floor: GroundPlane| {
            let under: Vec<(u32, GroundPlane)> = (0..8).map(|v| (v, floor)).collect();
            crate::pose::solver::terms::floor_and_contacts(
                (&skeleton, &movers, &[DVec3::ZERO]),
                &skins,
                &under,
                std::slice::from_ref(&contact),
            )
        };
        let (merged, apart) = (with_floor(ground), with_floor(lower));
        assert_eq!(merged.terms.len() + 5, apart.terms.len());
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-6 * scale;
        for k in 0..6 {
            let t = k as f64 * 0.4;
            let motion = [DAffine3::from_rotation_translation(
                glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.05 * t.sin(), 0.1 * t, -0.03 * t),
                DVec3::new(0.01 * t.cos(), 0.004 - 0.003 * t, 0.0),
            )];
            let (e1, e2) = (
                merged.energy(&motion, &motion, &mut Vec::new()),
                apart.energy(&motion, &motion, &mut Vec::new()),
            );
            assert!(
                close(e1, e2, e2.abs().max(1e-300)),
                "motion {k}: {e1} vs {e2}"
            );
            let system = |terms: &ExtraTerms| {
                let (mut h, mut g) = (vec![0.0; 36], vec![0.0; 6]);
                terms.add_system_at(
                    (&motion, &motion),
                    &params,
                    (&mut h, &mut Vec::new()),
                    &mut g,
                );
                (h, g)
            };
            let ((h1, g1), (h2, g2)) = (system(&merged), system(&apart));
            let scale = h2.iter().chain(&g2).fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0, "motion {k}: no system");
            for (a, b) in h1.iter().chain(&g1).zip(h2.iter().chain(&g2)) {
                assert!(close(*a, *b, scale), "motion {k}: {a} vs {b}");
            }
        }
    }

    /// The lower bound that spares skinning a vertex far above its ground is one: under any
    /// turn and shift of the bar it is at most the vertex's height, and a small motion
    /// leaves the far vertices bounded (not skinned) and the near one skinned.
    #[test]
    fn a_vertex_far_above_is_bounded_below_its_height() {
        let skeleton = bar();
        let floor = GroundPlane::new(DVec3::new(0.0, -0.5, 0.0), DVec3::Y).unwrap();
        let bind: Vec<DVec3> = (0..12)
            .map(|k| {
                DVec3::new(
                    0.3 * (k % 4) as f64 - 0.4,
                    0.25 * (k / 4) as f64 - 0.49,
                    0.1,
                )
            })
            .collect();
        let movers = [vec![0]];
        let skins = bar_skins(&bind);
        let terms = floor_terms(&skeleton, &movers, &skins, floor);
        let bounded = |motion: DAffine3| {
            let drift = terms.drift(&[motion]);
            let mut out = Vec::new();
            for term in &terms.terms {
                if let crate::pose::solver::terms::Term::Above {
                    sums,
                    plane,
                    start_gap,
                    reach,
                    ..
                } = term
                {
                    let exact = terms.gap_above(sums, plane, &[motion]);
                    let bound = terms.certainly_above(sums, (*start_gap, reach), &drift);
                    out.push((bound, exact));
                }
            }
            out
        };
        for k in 0..20 {
            let t = k as f64 * 0.37;
            let motion = DAffine3::from_rotation_translation(
                glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3 * t.sin(), t.cos(), 0.2 * t),
                DVec3::new(0.1 * t.cos(), -0.05 * t, 0.02),
            );
            for (bound, exact) in bounded(motion) {
                assert!(
                    bound.is_none_or(|b| b <= exact + 1e-12),
                    "{bound:?} > {exact}"
                );
            }
        }
        let small = bounded(DAffine3::from_translation(DVec3::new(0.0, -0.02, 0.0)));
        assert!(small[0].0.is_none(), "the vertex near the floor is skinned");
        assert!(small[4..].iter().all(|(b, _)| b.is_some()), "{small:?}");
    }
}
