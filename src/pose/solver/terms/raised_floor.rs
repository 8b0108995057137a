//! Non-penetration as an augmented Lagrangian: a vertex the ground's penalty cannot get out
//! of the ground is kept above a plane raised by its depth.
//!
//! A vertex kept above its ground weighs `w · min(h, 0)²` (`h`: its height above the ground's
//! skin). Against a force `F` that pushes it in (a leg's shape and stiffness holding a paw
//! where its walk clip swings it, into a rise of the terrain), the penalty settles where
//! `2 w h = −F`: under the ground by `F / 2w`. Raising the weight shrinks that but makes the
//! system stiff (measured on the walking crowd: worse everywhere). The method of multipliers
//! keeps the weight and moves the target instead: the term becomes `w · min(h − s, 0)²` with
//! `s ← max(0, s − h)` after a settled round (`λ = 2 w s`, the constraint's multiplier). From
//! `s = 0` a vertex settled at `h = −F / 2w` gets `s = F / 2w` and the next round settles it
//! on the ground: `h − s = −F / 2w`, `h = 0`. A vertex the raised plane no longer pushes
//! (above it, `h − s ≥ 0`) gets its shift back to 0.
//!
//! The shift is applied by raising the term's plane along its normal, so everything that
//! reads the term (its residual, the near-contact curvature, the first contact along a step,
//! the bounds that skip vertices certainly above their ground) reads the shifted height.

use crate::pose::solver::terms::{ExtraTerms, Term};

/// The most a plane is raised, as a share of the model's size: a vertex pressed in by more
/// than this is a pose the ground cannot hold (a drag through the floor), not a penalty's
/// give.
const MOST_RAISED: f64 = 0.05;

impl ExtraTerms<'_> {
    /// One multiplier update: each vertex kept above the ground whose height above its
    /// (raised) plane is `gaps[k]` (the `k`th such term, as [`ExtraTerms::energy`] lists
    /// them) has its plane raised by its depth below it, or lowered back to where its ground
    /// is when it is above; `raised[k]` keeps how far each plane is raised (grown as needed).
    /// Returns whether any plane moved.
    pub(crate) fn raise_floor(&mut self, gaps: &[f64], raised: &mut Vec<f64>) -> bool {
        let most = MOST_RAISED * self.length_scale;
        let mut moved = false;
        let mut k = 0;
        for i in 0..self.terms.len() {
            let Term::Above {
                plane, start_gap, ..
            } = &mut self.terms[i]
            else {
                continue;
            };
            let Some(&gap) = gaps.get(k) else {
                break;
            };
            if raised.len() <= k {
                raised.resize(k + 1, 0.0);
            }
            let wanted = match gap.is_finite() {
                true => (-gap).clamp(0.0, most),
                false => raised[k],
            };
            let change = wanted - raised[k];
            if change != 0.0 {
                plane.point += plane.normal * change;
                *start_gap -= change;
                self.floor_groups.lower_bound(i, *start_gap);
                raised[k] = wanted;
                moved = true;
            }
            k += 1;
        }
        moved
    }
}
