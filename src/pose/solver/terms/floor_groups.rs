//! The floor's vertices in groups that share one bound on how far their joints moved them:
//! a group certainly well above its ground passes its vertices in one test.
//!
//! A rig's floor keeps thousands of vertices above the ground (every vertex within 30 % of
//! the size of it: a mannequin's legs to the knees), and nine in ten of them are certainly
//! well above it in every trial pose of a solve — their height at the start less how far
//! their joints moved ([`ExtraTerms::certainly_above`](crate::pose::solver::terms::ExtraTerms)).
//! Grouped as the model groups its vertices (by the joint that carries them most,
//! [`SKIN_GROUP`](crate::pose::rig::skin::SKIN_GROUP) at a time in vertex order:
//! [`SkinGroup`]), a group's bound is its lowest start height less the most any of its
//! joints moved a vertex of the model's group: `min h₀ − W max_j (‖ΔA_j‖ R_j + |Δo_j|)`,
//! `R_j` the farthest vertex of the model's group from joint `j`'s bind position, `W` its
//! largest sum of skin weights (1 for normalised skins). It is below each vertex's own
//! bound, so a group that passes holds only vertices that would each have passed. The
//! floor's terms are made group by group, side by side, so a group that passes is skipped
//! in one step (made in the floor's order, the groups of the several joints a floor passes
//! through interleaved, and every term was visited to find its group's answer: 7 % of the
//! mannequin's grounded solve).

use std::ops::Range;

use crate::pose::ground::GroundPlane;
use crate::pose::rig::skin::{SkinGroup, VertexSkins};

/// The floor's terms in groups ([`plan_groups`]), each group's terms side by side.
pub(super) struct FloorGroups<'a> {
    /// Where the floor's terms are among the solve's.
    terms: Range<usize>,
    /// Each floor term's group.
    group_of: Vec<u32>,
    groups: Vec<FloorGroup<'a>>,
}

/// One group's bound: the floor's vertices of one of the model's [`SkinGroup`]s.
struct FloorGroup<'a> {
    /// Where its terms start, counted from the floor's first.
    start: u32,
    /// How many terms it holds.
    len: u32,
    /// The lowest start height of its vertices.
    min_start_gap: f64,
    /// The model's group its vertices are of: every joint carrying one of them with its
    /// reach, the largest sum of skin weights (over the model's group, so over these).
    skin: &'a SkinGroup,
}

impl FloorGroups<'_> {
    /// Each group's lower bound of its vertices' heights above their ground's skin when it
    /// is above `near` (else `None`), from how far each joint's skinning matrix `drift`ed
    /// since the start ([`crate::pose::solver::terms::ExtraTerms::drift`]).
    pub(super) fn passing(&self, drift: &[(f64, f64)], near: f64) -> Vec<Option<f64>> {
        self.groups
            .iter()
            .map(|g| {
                let moved = g
                    .skin
                    .reach
                    .iter()
                    .map(|&(j, r)| {
                        let (turn, origin) = drift.get(j).copied().unwrap_or((f64::INFINITY, 0.0));
                        turn * r + origin
                    })
                    // (A NaN motion stays NaN, and the group is then tested vertex by vertex.)
                    .fold(
                        0.0f64,
                        |most, m| if m > most || m.is_nan() { m } else { most },
                    );
                let bound = g.min_start_gap - g.skin.weight_sum * moved;
                (bound > near).then_some(bound)
            })
            .collect()
    }

    /// Term `i`'s start height is now `start_gap` (it was made, or its plane was raised,
    /// `raised_floor.rs`): its group's bound is lowered to it if it is below.
    pub(super) fn lower_bound(&mut self, i: usize, start_gap: f64) {
        if let Some(g) = self.group_of(i) {
            let bound = &mut self.groups[g].min_start_gap;
            *bound = bound.min(start_gap);
        }
    }

    /// The group of term `i` (`None` outside the floor's groups).
    pub(super) fn group_of(&self, i: usize) -> Option<usize> {
        let k = i.checked_sub(self.terms.start)?;
        self.group_of.get(k).map(|&g| g as usize)
    }

    /// The group whose first term is term `i`, with how many terms it holds (`None` for a
    /// term that does not start one): a group that passes is skipped whole.
    pub(super) fn starting_at(&self, i: usize) -> Option<(usize, usize)> {
        let g = self.group_of(i)?;
        let group = &self.groups[g];
        (group.start as usize + self.terms.start == i).then_some((g, group.len as usize))
    }
}

/// Groups the floor's vertices (`floor`, each with its plane; but not those `left_out`) by
/// the model's [`SkinGroup`] each is in (`skins`: every vertex's, with the groups), for
/// terms made from `first_term` on. Returns the order to make them in (indices into
/// `floor`: each group's side by side, the groups in the model's order) and the groups,
/// whose bounds start at infinity: each term made lowers its group's
/// ([`FloorGroups::lower_bound`]).
///
/// (The model's groups are made once: grouping the floor anew in every solve, each vertex's
/// joints merged into its group's, was 5–7 % of a grounded solve.)
pub(super) fn plan_groups<'a>(
    floor: &[(u32, GroundPlane)],
    skins: &'a VertexSkins,
    first_term: usize,
    left_out: impl Fn(usize) -> bool,
) -> (Vec<u32>, FloorGroups<'a>) {
    let skin_groups = skins.groups();
    // Per model group, how many floor vertices it holds; then, for those holding any, its
    // index among the solve's groups.
    let mut at: Vec<u32> = vec![0; skin_groups.len()];
    let group_of_vertex = |k: usize| {
        let v = floor[k].0 as usize;
        (!left_out(k)).then(|| skins.group_of(v)).flatten()
    };
    for k in 0..floor.len() {
        if let Some(g) = group_of_vertex(k) {
            at[g] += 1;
        }
    }
    // The groups that hold any, in the model's order; `at` becomes each one's index.
    let mut groups: Vec<FloorGroup> = Vec::new();
    let mut next = 0;
    for (g, count) in at.iter_mut().enumerate() {
        if *count == 0 {
            continue;
        }
        groups.push(FloorGroup {
            start: next,
            len: *count,
            min_start_gap: f64::INFINITY,
            skin: &skin_groups[g],
        });
        next += *count;
        *count = groups.len() as u32 - 1;
    }
    let mut filled = vec![0u32; groups.len()];
    let mut order = vec![0u32; next as usize];
    let mut group_of = vec![0u32; next as usize];
    for k in 0..floor.len() {
        let Some(g) = group_of_vertex(k) else {
            continue;
        };
        let index = at[g] as usize;
        let slot = (groups[index].start + filled[index]) as usize;
        filled[index] += 1;
        order[slot] = k as u32;
        group_of[slot] = index as u32;
    }
    let out = FloorGroups {
        terms: first_term..first_term + next as usize,
        group_of,
        groups,
    };
    (order, out)
}

#[cfg(test)]
mod tests {
    use glam::{DAffine3, DQuat, DVec3};

    use crate::pose::ground::GroundPlane;
    use crate::pose::rig::skeleton::{Joint, Skeleton, VertexInfluences};
    use crate::pose::solver::terms::Term;

    /// A chain of three joints up the y axis (bind origins at y = 0, 1, 2).
    fn chain() -> Skeleton {
        let joint = |name: &str, parent: Option<usize>, y: f64| Joint {
            name: name.into(),
            parent,
            parent_frame: DAffine3::from_translation(
                DVec3::Y * if parent.is_some() { 1.0 } else { 0.0 },
            ),
            inverse_bind: DAffine3::from_translation(-DVec3::Y * y),
        };
        Skeleton::new(vec![
            joint("hips", None, 0.0),
            joint("knee", Some(0), 1.0),
            joint("ankle", Some(1), 2.0),
        ])
        .unwrap()
    }

    /// The skinning matrices with the knee turned by `turn` about z (the ankle following) and
    /// the ankle by `ankle` more.
    fn bent(turn: f64, ankle: f64) -> Vec<DAffine3> {
        let about = |y: f64, a: f64| {
            let o = DVec3::Y * y;
            DAffine3::from_translation(o)
                * DAffine3::from_quat(DQuat::from_rotation_z(a))
                * DAffine3::from_translation(-o)
        };
        let knee = about(1.0, turn);
        vec![DAffine3::IDENTITY, knee, knee * about(2.0, ankle)]
    }

    /// A floor group's bound is below the exact height and the own bound of every vertex in
    /// it, whatever the joints did; small motions pass most groups, a large one fails some.
    /// (Fails with half the joints' motion subtracted.)
    #[test]
    fn a_group_bound_is_below_each_of_its_vertices() {
        let skeleton = chain();
        let movers: Vec<Vec<u32>> = (0..3).map(|j| (0..=j as u32).collect()).collect();
        let origins = [DVec3::ZERO, DVec3::Y, DVec3::Y * 2.0];
        // 90 vertices up the chain, a little off it, each blended between the two joints
        // it lies between.
        let bind: Vec<DVec3> = (0..90)
            .map(|i| DVec3::new(0.2 * ((i % 7) as f64 - 3.0), 2.7 * i as f64 / 89.0, 0.1))
            .collect();
        let influences: Vec<VertexInfluences> = bind
            .iter()
            .map(|p| {
                let t = p.y.clamp(0.0, 2.0);
                let j = (t.floor() as u32).min(1);
                let f = t - j as f64;
                [(j, 1.0 - f), (j + 1, f), (0, 0.0), (0, 0.0)]
            })
            .collect();
        let ground = GroundPlane::new(DVec3::Y * -0.3, DVec3::Y).unwrap();
        let under: Vec<(u32, GroundPlane)> = (0..bind.len() as u32).map(|v| (v, ground)).collect();
        let skins = crate::pose::rig::skin::vertex_skins(&bind, &influences, &origins);
        let terms =
            crate::pose::solver::terms::floor_only((&skeleton, &movers, &origins), &skins, &under);
        let mut passed = 0;
        let mut failed = 0;
        for (turn, ankle) in [(0.01, 0.0), (0.05, -0.1), (-0.2, 0.3), (1.4, 1.2)] {
            let skinning = bent(turn, ankle);
            let drift = terms.drift(&skinning);
            let passing = terms.floor_groups.passing(&drift, -f64::INFINITY);
            for (i, term) in terms.terms.iter().enumerate() {
                let Term::Above {
                    sums,
                    plane,
                    start_gap,
                    reach,
                    ..
                } = term
                else {
                    continue;
                };
                let group = terms.floor_groups.group_of(i).unwrap();
                let bound = passing[group].unwrap();
                let exact = terms.gap_above(sums, plane, &skinning);
                assert!(
                    bound <= exact + 1e-12,
                    "turn {turn}: vertex {i} is {exact} above, its group's bound {bound}"
                );
                if let Some(own) = terms.certainly_above(sums, (*start_gap, reach), &drift) {
                    assert!(
                        bound <= own + 1e-12,
                        "its own bound {own} is lower: {bound}"
                    );
                }
            }
            // The energy's heights: one per vertex in term order, a group that passes read
            // whole at its bound, every one at or below the vertex's height.
            let mut gaps = Vec::new();
            terms.energy(&skinning, &skinning, &mut gaps);
            let exact: Vec<f64> = terms
                .terms
                .iter()
                .filter_map(|t| match t {
                    Term::Above { sums, plane, .. } => {
                        Some(terms.gap_above(sums, plane, &skinning))
                    }
                    _ => None,
                })
                .collect();
            assert_eq!(gaps.len(), exact.len());
            for (k, (gap, exact)) in gaps.iter().zip(&exact).enumerate() {
                assert!(*gap <= exact + 1e-12, "vertex {k}: {gap} over {exact}");
            }
            let near = 0.05;
            let groups = terms.floor_groups.passing(&drift, near);
            passed += groups.iter().filter(|g| g.is_some()).count();
            failed += groups.iter().filter(|g| g.is_none()).count();
        }
        assert!(passed > 0 && failed > 0, "passed {passed}, failed {failed}");
        // Each group's terms are side by side, so one that passes is skipped whole.
        let mut seen = vec![false; terms.floor_groups.groups.len()];
        let mut last = None;
        for i in 0..terms.terms.len() {
            let g = terms.floor_groups.group_of(i).unwrap();
            if last != Some(g) {
                assert!(!seen[g], "group {g} is split");
                seen[g] = true;
                assert_eq!(terms.floor_groups.starting_at(i).map(|s| s.0), Some(g));
            } else {
                assert_eq!(terms.floor_groups.starting_at(i), None);
            }
            last = Some(g);
        }
        // A joint whose motion is not a number passes none of the groups it carries.
        let drift = vec![(0.0, 0.0), (f64::NAN, 0.0), (0.0, 0.0)];
        let nan = terms.floor_groups.passing(&drift, f64::NEG_INFINITY);
        for (g, group) in terms.floor_groups.groups.iter().enumerate() {
            let carried = group.skin.reach.iter().any(|(j, _)| *j == 1);
            assert_eq!(nan[g].is_none(), carried, "group {g}");
        }
    }
}
