//! The Gauss–Newton system of the extra terms: each active term's Jacobian blocks (for the
//! parameters that move it only), summed as `2 w JᵀJ` and `2 w Jᵀr` into the solver's system.

use glam::{DAffine3, DMat3, DVec3};

use crate::pose::rig::skin::apply;
use crate::pose::rig::skin::centroid_of;
use crate::pose::solver::linalg::low_rank::RankOne;
use crate::pose::solver::params::Param;
use crate::pose::solver::terms::moments::RankOneSums;
use crate::pose::solver::terms::{ExtraTerms, Rows, Term, carried_change, ground};

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
    /// `3P × 3P` row-major, `g` `3P`) at the pose of `globals` / `skinning`, whose vertices'
    /// heights above their ground are `gaps` ([`ExtraTerms::energy`] at that pose). A term
    /// has Jacobian blocks only for the parameters that move it; a vertex under its ground is
    /// a single number along the ground's normal, whose `JᵀJ` is an outer product of
    /// 3-vectors.
    ///
    /// Balance reads every joint (the centre of mass): its `JᵀJ` goes to `low_rank` as
    /// rank-one parts ([`ExtraTerms::balance_parts`]), not into `h`, which stays as sparse as
    /// the skeleton.
    pub(crate) fn add_system(
        &self,
        (globals, skinning, gaps): (&[DAffine3], &[DAffine3], &[f64]),
        params: &[Param],
        (h, low_rank): (&mut [f64], &mut Vec<RankOne>),
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
            if let Term::Balance { .. } = term {
                self.balance_parts(
                    (term, w, r),
                    (params, globals, skinning),
                    system.g,
                    low_rank,
                );
                return;
            }
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
            let w = near.map_or(w, |(_, scale)| w * scale);
            if let Some((sums, along, depth)) = near
                .map(|(along, _)| along)
                .or_else(|| ground::along_the_normal(term, r))
            {
                rank_one.add(self, (sums, along, depth), 2.0 * w, (params, skinning));
                return;
            }
            stamp += 1;
            self.movers_of(term, (&mut seen, stamp), &mut movers);
            blocks.clear();
            blocks.extend(movers.iter().filter_map(|&p| {
                self.jacobian(term, params[p as usize], globals, skinning)
                    .map(|j| (p as usize, j))
            }));
            system.add_blocks(&blocks, 2.0 * w, r);
        };
        // (A vertex well above its ground adds nothing.)
        self.for_each_acting((globals, skinning, gaps), each);
        rank_one.finish(self, &mut system, (params, globals));
    }

    /// A balance term's `2 w JᵀJ` as rank-one parts `2 w u uᵀ` into `low_rank` and its
    /// `2 w Jᵀr` into `g`, one per direction its residual `r` is measured along
    /// ([`ExtraTerms::balance_directions`]): `u` per parameter is the centre of mass's
    /// change under it seen along that direction. While balance holds, one part with a bound
    /// (no pull): along the way out of the region, active only for a step that would take
    /// the centre of mass further than that ([`RankOne::bound`]).
    fn balance_parts(
        &self,
        (term, w, r): (&Term, f64, &Rows<DVec3>),
        (params, globals, skinning): (&[Param], &[DAffine3], &[DAffine3]),
        g: &mut [f64],
        low_rank: &mut Vec<RankOne>,
    ) {
        let Term::Balance { sums, allowed, .. } = term else {
            return;
        };
        let r = r.iter().next().copied().unwrap_or(DVec3::ZERO);
        let mut directions = self.balance_directions(term, skinning);
        let mut bound = None;
        if directions.is_empty() {
            let Some((out, slack)) = allowed.way_out(centroid_of(sums, skinning)) else {
                return;
            };
            directions.push((out, 1.0));
            bound = Some(slack);
        }
        // The centre of mass's change under each parameter, once for every direction: from
        // each joint's subtree's share of the mass and its skinned moment, summed children to
        // parents (what `centroid_jacobian` sums per parameter, walking the skeleton for each
        // of its joints, in one pass).
        let joints = self.skeleton.joints();
        let mut moved = vec![DVec3::ZERO; joints.len()];
        let mut mass = vec![0.0; joints.len()];
        for &(j, m) in sums.iter() {
            moved[j] += apply(&skinning[j], m);
            mass[j] += m.w;
        }
        for j in (0..joints.len()).rev() {
            if let Some(p) = joints[j].parent {
                let (child, share) = (moved[j], mass[j]);
                moved[p] += child;
                mass[p] += share;
            }
        }
        let changes: Vec<Option<DMat3>> = params
            .iter()
            .map(|&param| {
                let (a, rotation) = split(param);
                carried_change((moved[a], mass[a]), rotation, globals[a].translation)
            })
            .collect();
        for (along, scale) in directions {
            let s = 2.0 * w * scale;
            let mut u = vec![0.0; params.len() * 3];
            for (p, change) in changes.iter().enumerate() {
                if let Some(b) = change {
                    let row = b.transpose() * along;
                    u[3 * p..3 * p + 3].copy_from_slice(&row.to_array());
                }
            }
            let depth = along.dot(r);
            for (gi, ui) in g.iter_mut().zip(&u) {
                *gi += s * depth * ui;
            }
            low_rank.push(RankOne { scale: s, u, bound });
        }
    }
}

#[cfg(test)]
impl ExtraTerms<'_> {
    /// [`ExtraTerms::add_system`] at a pose whose heights are taken here first, as a solve's
    /// energy takes them before its system (tests).
    pub(super) fn add_system_at(
        &self,
        (globals, skinning): (&[DAffine3], &[DAffine3]),
        params: &[Param],
        (h, low_rank): (&mut [f64], &mut Vec<RankOne>),
        g: &mut [f64],
    ) {
        let mut gaps = Vec::new();
        self.energy(globals, skinning, &mut gaps);
        self.add_system((globals, skinning, &gaps), params, (h, low_rank), g);
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

#[cfg(test)]
mod tests {
    use glam::{DAffine3, DQuat, DVec3, DVec4};

    use super::split;
    use crate::pose::ground::balance::Balance;
    use crate::pose::rig::skeleton::{
        Joint, JointTransform, Skeleton, SkeletonPose, VertexInfluences,
    };
    use crate::pose::rig::skin::mass_sums;
    use crate::pose::solver::linalg::low_rank::RankOne;
    use crate::pose::solver::params::{Param, movers_of_joints};
    use crate::pose::solver::solve;
    use crate::pose::solver::terms::{ExtraInputs, ExtraTerms, Term};

    /// A two-joint chain standing on the origin, its child a unit up.
    fn chain() -> Skeleton {
        let frames = [DAffine3::IDENTITY, DAffine3::from_translation(DVec3::Y)];
        Skeleton::new(vec![
            Joint {
                name: "hips".into(),
                parent: None,
                parent_frame: DAffine3::IDENTITY,
                inverse_bind: frames[0].inverse(),
            },
            Joint {
                name: "chest".into(),
                parent: Some(0),
                parent_frame: DAffine3::IDENTITY,
                inverse_bind: frames[1].inverse(),
            },
        ])
        .unwrap()
    }

    /// The chain with its chest leaning `lean` radians towards +x, and its skinning.
    fn leaning(skeleton: &Skeleton, lean: f64) -> (Vec<DAffine3>, Vec<DAffine3>) {
        let pose = SkeletonPose {
            local: vec![
                JointTransform::IDENTITY,
                JointTransform {
                    translation: DVec3::Y,
                    rotation: DQuat::from_rotation_z(-lean),
                    scale: DVec3::ONE,
                },
            ],
        };
        let globals = skeleton.global_transforms(&pose);
        let skinning = solve::skinning(&globals, skeleton);
        (globals, skinning)
    }

    /// What balance adds at a lean: the system (`h`, `g`, the rank-one parts), the term's
    /// weight, its residual and the residual's Jacobian by central differences (a column per
    /// coordinate: turns about each joint, the root's shift).
    struct AtLean {
        h: Vec<f64>,
        g: Vec<f64>,
        parts: Vec<RankOne>,
        weight: f64,
        residual: DVec3,
        jacobian: Vec<DVec3>,
    }

    fn balance_at(lean: f64) -> AtLean {
        let skeleton = chain();
        let params = vec![
            Param::Rotation(1),
            Param::Rotation(0),
            Param::Translation(0),
        ];
        let movers = movers_of_joints(&skeleton, &params);
        let origins = skeleton.bind_origins();
        // A mass low on the hips, one high on the chest.
        let bind = [DVec3::new(0.0, 0.5, 0.0), DVec3::new(0.1, 1.6, 0.05)];
        let influences: [VertexInfluences; 2] = [
            [(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
            [(1, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
        ];
        let sums: Vec<(usize, DVec4)> = mass_sums(2, (&bind, &influences), &[1.0, 1.0]);
        let square = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(x, z)| DVec3::new(0.15 * x, 0.0, 0.15 * z));
        let balance = Balance {
            margin: 0.02,
            ..Balance::over(square.to_vec())
        };
        let rest = vec![DAffine3::IDENTITY; 2];
        let (globals, skinning) = leaning(&skeleton, lean);
        let terms = ExtraTerms::new(
            (&skeleton, &movers, &origins),
            crate::pose::rig::skin::VertexSkins::NONE,
            &ExtraInputs {
                balance: Some((&balance, &sums)),
                balance_boost: 0.0,
                contacts: &[],
                floor: &[],
                effectors: &[],
                centroids: &[],
                stiffness: None,
                reference_globals: &rest,
                reference_skinning: &rest,
                start_skinning: &skinning,
                influences: &influences,
                relative_inertia: &[1.0, 1.0],
                bind: &bind,
                joint_weight: 1.0,
                vertex_weight: 1.0,
                length_scale: 1.0,
            },
        );
        let n = 3 * params.len();
        let (mut h, mut g, mut parts) = (vec![0.0; n * n], vec![0.0; n], Vec::new());
        terms.add_system_at((&globals, &skinning), &params, (&mut h, &mut parts), &mut g);
        let term = terms
            .terms
            .iter()
            .find(|t| matches!(t, Term::Balance { .. }))
            .expect("a balance term");
        let Term::Balance { weight, .. } = term else {
            unreachable!()
        };
        let residual = |globals: &[DAffine3]| {
            terms.balance_residual(term, &solve::skinning(globals, &skeleton))
        };
        let moved = |(a, rotation): (usize, bool), d: DVec3| -> Vec<DAffine3> {
            let o = globals[a].translation;
            let motion = match rotation {
                true => {
                    DAffine3::from_translation(o)
                        * DAffine3::from_quat(DQuat::from_scaled_axis(d))
                        * DAffine3::from_translation(-o)
                }
                false => DAffine3::from_translation(d),
            };
            (0..2)
                .map(|j| match skeleton.descends_from(j, a) {
                    true => motion * globals[j],
                    false => globals[j],
                })
                .collect()
        };
        let eps = 1e-6;
        let mut jacobian = Vec::new();
        for &param in &params {
            for axis in DVec3::AXES {
                let d = axis * eps;
                let (plus, minus) = (moved(split(param), d), moved(split(param), -d));
                jacobian.push((residual(&plus) - residual(&minus)) / (2.0 * eps));
            }
        }
        AtLean {
            h,
            g,
            parts,
            weight: *weight,
            residual: residual(&globals),
            jacobian,
        }
    }

    /// Out of its polygon, balance adds nothing to the sparse matrix and one rank-one part
    /// whose `s u uᵀ` and gradient are `2 w JᵀJ` and `2 w Jᵀr` of its residual's finite
    /// differences (turns about each joint, the root's shift).
    #[test]
    fn balance_is_a_rank_one_part_of_its_gauss_newton_system() {
        let at = balance_at(0.5);
        assert!(at.h.iter().all(|v| *v == 0.0), "balance left h alone");
        assert_eq!(at.parts.len(), 1);
        assert!(
            at.residual.length() > 0.05,
            "the chain leans out: {}",
            at.residual
        );
        let scale = 2.0 * at.weight;
        let (part, jac) = (&at.parts[0], &at.jacobian);
        for a in 0..9 {
            let expected_g = scale * jac[a].dot(at.residual);
            assert!(
                (at.g[a] - expected_g).abs() < 1e-5 * scale,
                "g[{a}] {} vs {expected_g}",
                at.g[a]
            );
            for b in 0..9 {
                let expected = scale * jac[a].dot(jac[b]);
                let got = part.scale * part.u[a] * part.u[b];
                assert!(
                    (got - expected).abs() < 1e-5 * scale,
                    "H[{a}][{b}] {got} vs {expected}"
                );
            }
        }
    }

    /// Inside its margin, balance adds no pull and no curvature, only a part with a bound
    /// (for a step that would cross the margin); just past it, its part in the matrix (found
    /// by bisection on the residual's onset: the part acts with the residual, not before).
    #[test]
    fn balance_acts_only_past_its_margin() {
        let (mut inside, mut outside) = (0.0, 0.5);
        for _ in 0..50 {
            let mid = 0.5 * (inside + outside);
            match balance_at(mid).residual == DVec3::ZERO {
                true => inside = mid,
                false => outside = mid,
            }
        }
        let before = balance_at(inside - 1e-3);
        assert!(before.g.iter().all(|v| *v == 0.0));
        assert!(
            before.parts.len() == 1 && before.parts[0].bound.is_some_and(|slack| slack > 0.0),
            "{:?}",
            before.parts.iter().map(|p| p.bound).collect::<Vec<_>>()
        );
        let past = balance_at(outside + 1e-3);
        assert_eq!(past.parts.len(), 1);
        assert_eq!(past.parts[0].bound, None);
        assert!(past.g.iter().any(|v| *v != 0.0));
        let upright = balance_at(0.0);
        assert!(
            upright.parts.iter().all(|p| p.bound.is_some()) && upright.g.iter().all(|v| *v == 0.0),
            "upright, balance adds nothing to the matrix"
        );
    }
}
