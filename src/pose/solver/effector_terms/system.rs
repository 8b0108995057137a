//! The Gauss–Newton system of the extra terms: each active term's Jacobian blocks (for the
//! parameters that move it only), summed as `2 w JᵀJ` and `2 w Jᵀr` into the solver's system.

use glam::{DAffine3, DMat3, DVec3};

use super::super::params::Param;
use super::moments::RankOneSums;
use super::{ExtraTerms, Rows, Term, ground};

impl ExtraTerms<'_> {
    /// Into `movers`, the parameters that move `term` (indices into the solver's, each once:
    /// `seen` holds a stamp per parameter, `stamp` this term's).
    fn movers_of(&self, term: &Term, (seen, stamp): (&mut [u32], u32), movers: &mut Vec<u32>) {
        movers.clear();
        term.for_each_joint(|j| {
            for &p in &self.joint_movers[j] {
                if seen[p as usize] != stamp {
                    seen[p as usize] = stamp;
                    movers.push(p);
                }
            }
        });
    }

    /// Adds the Gauss–Newton terms `2 w JᵀJ` and `2 w Jᵀr` to the solver's system (`h` is
    /// `3P × 3P` row-major, `g` `3P`). A term has Jacobian blocks only for the parameters
    /// that move it; a vertex under its ground is a single number along the ground's normal,
    /// whose `JᵀJ` is an outer product of 3-vectors.
    pub(crate) fn add_system(
        &self,
        globals: &[DAffine3],
        skinning: &[DAffine3],
        params: &[Param],
        h: &mut [f64],
        g: &mut [f64],
    ) {
        let mut system = System {
            n: params.len() * 3,
            h,
            g,
        };
        // A term's Jacobian blocks (or rows), reused term after term.
        let mut blocks: Vec<(usize, Rows<DMat3>)> = Vec::with_capacity(params.len());
        let mut movers = Vec::with_capacity(params.len());
        let mut seen = vec![0; params.len()];
        let mut stamp = 0;
        let mut rank_one = RankOneSums::new(self.skeleton.len(), params.len());
        let each = |term: &Term, w: f64, r: &Rows<DVec3>, gap: Option<f64>| {
            // A vertex just above its ground is in the step's model with curvature and no
            // pull ([`ExtraTerms::near_contact`]).
            let near = self.near_contact(term, gap);
            // A one-sided term that holds (a vertex above its ground, the centre of mass inside
            // its polygon) adds neither gradient nor curvature: skip its Jacobian.
            if near.is_none()
                && matches!(term, Term::Above { .. } | Term::Balance { .. })
                && r.iter().all(|v| *v == DVec3::ZERO)
            {
                return;
            }
            stamp += 1;
            self.movers_of(term, (&mut seen, stamp), &mut movers);
            let w = near.map_or(w, |(_, scale)| w * scale);
            if let Some((sums, along, depth)) = near
                .map(|(along, _)| along)
                .or_else(|| ground::along_the_normal(term, r))
            {
                rank_one.add(
                    self,
                    &mut system,
                    (sums, along, depth),
                    (2.0 * w, &movers),
                    (params, globals, skinning),
                );
                return;
            }
            blocks.clear();
            blocks.extend(movers.iter().filter_map(|&p| {
                self.jacobian((term, r), params[p as usize], globals, skinning)
                    .map(|j| (p as usize, j))
            }));
            system.add_blocks(&blocks, 2.0 * w, r);
        };
        // (A group of vertices certainly above their ground adds nothing.)
        self.for_each_residual(globals, skinning, each, |_| {});
        rank_one.finish(self, &mut system, (params, globals));
    }
}

/// A parameter's joint, and whether it is a rotation (else a root's translation).
pub(super) fn split(param: Param) -> (usize, bool) {
    match param {
        Param::Rotation(a) => (a, true),
        Param::Translation(a) => (a, false),
    }
}

/// The Gauss–Newton system being summed into (`h`: `n × n` row-major).
pub(super) struct System<'s> {
    n: usize,
    h: &'s mut [f64],
    pub(super) g: &'s mut [f64],
}

impl System<'_> {
    /// Adds `s` times the block at parameters `(a, b)`, and its transpose at `(b, a)`.
    pub(super) fn add_pair(&mut self, (a, b): (usize, usize), m: DMat3, s: f64) {
        let n = self.n;
        for r in 0..3 {
            for c in 0..3 {
                let v = s * m.col(c)[r];
                self.h[(a * 3 + r) * n + b * 3 + c] += v;
                if a != b {
                    self.h[(b * 3 + c) * n + a * 3 + r] += v;
                }
            }
        }
    }

    /// `s JᵀJ` and `s Jᵀr` for a term's Jacobian `blocks` (per parameter) and residual `r`.
    fn add_blocks(&mut self, blocks: &[(usize, Rows<DMat3>)], s: f64, r: &Rows<DVec3>) {
        for (i, (pa, ja)) in blocks.iter().enumerate() {
            let mut ga = DVec3::ZERO;
            for (jb, rv) in ja.iter().zip(r.iter()) {
                ga += jb.transpose() * *rv;
            }
            for k in 0..3 {
                self.g[pa * 3 + k] += s * ga[k];
            }
            for (pb, jbk) in &blocks[i..] {
                let mut m = DMat3::ZERO;
                for (x, y) in ja.iter().zip(jbk.iter()) {
                    m += x.transpose() * *y;
                }
                self.add_pair((*pa, *pb), m, s);
            }
        }
    }
}
