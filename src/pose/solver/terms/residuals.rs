//! Each extra term's residual at a pose and their weighted sum, the energy: a floor group
//! certainly above its ground is passed whole, a vertex certainly above it is bounded
//! instead of skinned; where the heights are already known (an iteration's system), a
//! vertex well above its ground is passed.

use glam::{DAffine3, DMat3, DVec3};

use crate::pose::rig::skin::centroid_of;
use crate::pose::solver::terms::ground::NEAR_CONTACT;
use crate::pose::solver::terms::{ExtraTerms, Rows, Term, columns};

impl ExtraTerms<'_> {
    /// Calls `each` with every term's weight and residual (stacked 3-vectors, at most four)
    /// at `globals` / `skinning`, in term order, and for a vertex kept above the ground its
    /// height above the ground's skin (`None` for other terms) — but `certain` with a lower
    /// bound of that height and how many terms it holds for a floor group certainly well
    /// above its ground (`floor_groups.rs`: their residuals are zero; the group's terms are
    /// side by side and skipped whole); no allocation but the rotation cache and the groups'
    /// bounds.
    pub(super) fn for_each_residual(
        &self,
        globals: &[DAffine3],
        skinning: &[DAffine3],
        each: impl FnMut(&Term, f64, &Rows<DVec3>, Option<f64>),
        certain: impl FnMut(f64, usize),
    ) {
        self.residuals_with((globals, skinning, None), each, certain);
    }

    /// Calls `each` as [`ExtraTerms::for_each_residual`] does, but for a pose whose vertices'
    /// heights above their ground's skin are known (`gaps`, as [`ExtraTerms::energy`] gave
    /// them at this pose: exact below [`NEAR_CONTACT`], a lower bound above it), and not for
    /// a vertex at least that far above its ground, which adds nothing to a Gauss–Newton
    /// system (no residual, no near-contact curvature). The heights are read, not skinned
    /// or bounded again: an iteration's system is built at the pose whose energy was just
    /// taken.
    pub(super) fn for_each_acting(
        &self,
        (globals, skinning, gaps): (&[DAffine3], &[DAffine3], &[f64]),
        each: impl FnMut(&Term, f64, &Rows<DVec3>, Option<f64>),
    ) {
        self.residuals_with((globals, skinning, Some(gaps)), each, |_, _| {});
    }

    /// [`ExtraTerms::for_each_residual`], or with `known` heights
    /// [`ExtraTerms::for_each_acting`].
    fn residuals_with(
        &self,
        (globals, skinning, known): (&[DAffine3], &[DAffine3], Option<&[f64]>),
        mut each: impl FnMut(&Term, f64, &Rows<DVec3>, Option<f64>),
        mut certain: impl FnMut(f64, usize),
    ) {
        let l = self.length_scale;
        let near = NEAR_CONTACT * l;
        // Each joint's world rotation once (a stiffness term reads its joint's and its
        // parent's, which is the next term's joint).
        let mut cache: Vec<Option<DMat3>> = vec![None; globals.len()];
        let mut rotation = |j: usize| *cache[j].get_or_insert_with(|| Self::rotation(globals, j));
        // How far each skinning matrix moved since the start: a vertex certainly well above
        // its ground is not skinned. Floor groups certainly well above their ground: their
        // vertices are not skinned. (Neither is needed where the heights are known.)
        let (drift, passing) = match known {
            None => {
                let drift = self.drift(skinning);
                let passing = self.floor_groups.passing(&drift, near);
                (drift, passing)
            }
            Some(_) => (Vec::new(), Vec::new()),
        };
        // How many vertices kept above the ground came before (the index into `known`).
        let mut above = 0;
        let mut i = 0;
        while let Some(term) = self.terms.get(i) {
            if let Some((g, len)) = self.floor_groups.starting_at(i) {
                if let Some(&Some(bound)) = passing.get(g) {
                    certain(bound, len);
                    i += len;
                    above += len;
                    continue;
                }
                // Known heights: a group whose every vertex is well above its ground adds
                // nothing to a system, and its terms are not read.
                if let Some(heights) = known.and_then(|k| k.get(above..above + len))
                    && heights.iter().all(|h| *h >= near)
                {
                    i += len;
                    above += len;
                    continue;
                }
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
                    let known = known.and_then(|k| k.get(above).copied());
                    above += 1;
                    let height = match known {
                        // Nothing to add to a system.
                        Some(h) if h >= near => continue,
                        Some(h) => h,
                        None => self
                            .certainly_above(sums, (*start_gap, reach), &drift)
                            .unwrap_or_else(|| self.gap_above(sums, plane, skinning)),
                    };
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
}
