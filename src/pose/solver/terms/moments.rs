//! The one-number terms (a vertex under or near its ground, along the ground's normal `n`)
//! summed by their moments instead of pair by pair of parameters.
//!
//! A term's row for a parameter that moves every joint carrying its vertex — the joints'
//! deepest common ancestor `L` and every joint above it, the root's translation — depends on
//! the parameter only through the joint's origin `o`: with `x` the vertex's skinned position
//! times its weights' sum `M`, a turn about `o` moves it by `(x − M o) × n = c − o × m`
//! along `n` (`c = x × n`, `m = M n`), a root translation by `m`. Their Gauss–Newton block
//! `Σ s u_a u_bᵀ` over every vertex carried whole by `L` is then
//! `α_a α_b C_cc + α_a C_cm B_bᵀ + α_b B_a C_cmᵀ + B_a C_mm B_bᵀ` (a turn: `α = 1`,
//! `B = −[o]×`; a translation: `α = 0`, `B = I`) in the moments `C_cc = Σ s c cᵀ`,
//! `C_cm = Σ s c mᵀ`, `C_mm = Σ s m mᵀ` — summed once per vertex, expanded once per pair of
//! parameters per `L` (a foot's), not once per pair per vertex. The expansion is `G_a M G_bᵀ`
//! with `G = [α I, B]` and `M` the moments: `G_a M` is made once per parameter, which leaves
//! one 3 × 3 product a pair instead of four (the Fox's grounded drag 6 % faster).
//!
//! A parameter below `L` moves part of a vertex (a toe's share of a vertex the foot and the
//! toe carry; with weights on both legs, every joint of a leg): its row is `α c_K + B m_K`
//! with `c_K`, `m_K` summed over the part `K` it moves. Every vertex skinned by the same
//! joints has the same parameters, parts and carrier, so its rows' products are summed as
//! the moments of the stacked `(c_K, m_K)` per such joint set ([`PartialGroup`]) and expanded
//! once per set: an automatic skin weighting each foot vertex to both legs had 7 such
//! parameters a vertex, 45 pairs of them, summed vertex by vertex (a third of a humanoid's
//! solve). The sums are the same as pair by pair, up to rounding.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::{DAffine3, DMat3, DVec3};

use crate::pose::rig::skin::{VertexSums, apply};
use crate::pose::solver::params::Param;
use crate::pose::solver::terms::system::{System, split};
use crate::pose::solver::terms::{ExtraTerms, outer, skew};

/// The moments of the terms carried whole by one joint (see the module docs).
#[derive(Debug, Clone, Copy)]
struct Moments {
    cc: DMat3,
    cm: DMat3,
    mm: DMat3,
    /// `Σ s d c` and `Σ s d m` (`d`: the term's depth).
    gc: DVec3,
    gm: DVec3,
    used: bool,
}

/// One-number terms being summed into a system (see the module docs).
pub(super) struct RankOneSums {
    /// Per joint, the moments of the terms it is the deepest common carrier of.
    per_joint: Vec<Moments>,
    /// Per parameter, the stamp of the last joint set that took it (as moving the set whole,
    /// or in part).
    whole: Vec<u32>,
    stamp: u32,
    /// The terms with parameters that move part of their vertex, per joint set.
    partial: Vec<PartialGroup>,
    /// What each joint set (its joints, then `usize::MAX`) met so far is to the sums: its
    /// carrier and its group in `partial` — found once a system, not once a term (the
    /// carrier is a walk up the skeleton per joint).
    sets: HashMap<[usize; 4], JointSet, BuildHasherDefault<JointSetHasher>>,
    /// A term's per-joint `(c_i, m_i)`, stacked (reused term after term).
    stacked: Vec<f64>,
}

/// A joint set's carrier and group (see [`RankOneSums`]).
#[derive(Debug, Clone, Copy)]
struct JointSet {
    carrier: Option<usize>,
    group: Option<usize>,
}

/// Hashes a joint set (four small numbers) by multiplying and rotating: the sets are few
/// and looked up once a term.
#[derive(Default)]
struct JointSetHasher(u64);

impl Hasher for JointSetHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        // (An array of `usize` arrives here as its bytes, eight at a time.)
        let mut chunks = bytes.chunks_exact(8);
        for chunk in &mut chunks {
            let mut word = [0; 8];
            word.copy_from_slice(chunk);
            self.write_u64(u64::from_ne_bytes(word));
        }
        for &b in chunks.remainder() {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn write_usize(&mut self, n: usize) {
        self.write_u64(n as u64);
    }
}

/// The terms of one joint set that parameters below its carrier move in part (see the module
/// docs). A part's `(c_K, m_K)` is the sum of its joints' `(c_i, m_i)` (joint `i`'s share
/// of the vertex: `c_i = x_i × n`, `m_i = w_i n`), so the terms are summed per joint —
/// `Σ s u uᵀ`, `Σ s d u` of the stacked `u = (c_1, m_1, c_2, m_2, …)`, at most 24 long — and
/// the parts' moments read off them once, when the group is expanded.
struct PartialGroup {
    /// The joint carrying the whole vertex (`None`: joints of different roots).
    carrier: Option<usize>,
    /// The parameters that move part of the vertex, each with its part.
    params: Vec<(u32, usize)>,
    /// Per part, which of the set's joints it carries (bit `i`: joint `i`); part 0 is the
    /// whole vertex.
    masks: Vec<u8>,
    /// `Σ s u uᵀ` (upper triangle, row-major, `6 × joints` square).
    moments: Vec<f64>,
    /// `Σ s d u`.
    gradient: Vec<f64>,
}

/// A parameter's row coefficients: `u = α c + B m` (see the module docs), with `Bᵀ`.
#[derive(Debug, Clone, Copy)]
struct RowCoefficients {
    alpha: f64,
    b: DMat3,
    b_transposed: DMat3,
}

impl RowCoefficients {
    /// The coefficients of `param`'s row at `globals`: a turn `(1, −[o]×)` about its joint's
    /// origin `o`, a root's translation `(0, I)`.
    fn of(param: Param, globals: &[DAffine3]) -> Self {
        let (alpha, b) = match param {
            Param::Rotation(a) => (1.0, -skew(globals[a].translation)),
            Param::Translation(_) => (0.0, DMat3::IDENTITY),
        };
        Self {
            alpha,
            b,
            b_transposed: b.transpose(),
        }
    }

    /// The first half of every block `Σ s u_a u_bᵀ = G_a M G_bᵀ` of this parameter's row
    /// (`G = [α I, B]`) against the moments `M = [cc, cm; mc, mm]` (`cc = Σ s c_a c_bᵀ`,
    /// `cm = Σ s c_a m_bᵀ`, `mc = Σ s m_a c_bᵀ`, `mm = Σ s m_a m_bᵀ`): `G_a M`, as its two
    /// 3 × 3 halves. Made once per parameter, it leaves one product per pair
    /// ([`RowCoefficients::pair_block`]) instead of four.
    fn times_moments(&self, [cc, cm, mc, mm]: [DMat3; 4]) -> [DMat3; 2] {
        [cc * self.alpha + self.b * mc, cm * self.alpha + self.b * mm]
    }

    /// `Σ s u_a u_bᵀ` from parameter `a`'s half ([`RowCoefficients::times_moments`]) and
    /// this parameter's row (`b`): `α_b L + R B_bᵀ`.
    fn pair_block(&self, [left, right]: [DMat3; 2]) -> DMat3 {
        left * self.alpha + right * self.b_transposed
    }
}

impl Moments {
    /// No terms (glam's default matrix is the identity, not zero).
    const NONE: Self = Self {
        cc: DMat3::ZERO,
        cm: DMat3::ZERO,
        mm: DMat3::ZERO,
        gc: DVec3::ZERO,
        gm: DVec3::ZERO,
        used: false,
    };
}

impl RankOneSums {
    /// Empty sums for a skeleton of `joints` and `params` parameters.
    pub(super) fn new(joints: usize, params: usize) -> Self {
        Self {
            per_joint: vec![Moments::NONE; joints],
            whole: vec![0; params],
            stamp: 0,
            partial: Vec::new(),
            sets: HashMap::default(),
            stacked: Vec::new(),
        }
    }

    /// Adds `s uuᵀ` and `s d u` of the term whose vertex is `sums`, along `along` at depth
    /// `d`.
    pub(super) fn add(
        &mut self,
        terms: &ExtraTerms,
        (sums, along, depth): (&VertexSums, DVec3, f64),
        s: f64,
        (params, skinning): (&[Param], &[DAffine3]),
    ) {
        // A vertex has at most four joints (`VertexSums`).
        let mut joints = [usize::MAX; 4];
        for (slot, (j, _)) in joints.iter_mut().zip(sums.iter()) {
            *slot = *j;
        }
        let set = match self.sets.get(&joints) {
            Some(&set) => set,
            None => self.new_set(terms, joints, &joints[..sums.len()], params),
        };
        // Each joint's share of the vertex, skinned once for the carrier and the group.
        let mut shares = [DVec3::ZERO; 4];
        for (x, (j, m)) in shares.iter_mut().zip(sums.iter()) {
            *x = apply(&skinning[*j], *m);
        }
        let shares = &shares[..sums.len()];
        if let Some(l) = set.carrier {
            let x: DVec3 = shares.iter().sum();
            let mass: f64 = sums.iter().map(|(_, m)| m.w).sum();
            let (c, m) = (x.cross(along), along * mass);
            let moments = &mut self.per_joint[l];
            moments.cc += outer(c, c) * s;
            moments.cm += outer(c, m) * s;
            moments.mm += outer(m, m) * s;
            moments.gc += c * (s * depth);
            moments.gm += m * (s * depth);
            moments.used = true;
        }
        let Some(k) = set.group else {
            return;
        };
        let v = &mut self.stacked;
        v.clear();
        for (x, (_, m)) in shares.iter().zip(sums.iter()) {
            v.extend(x.cross(along).to_array());
            v.extend((along * m.w).to_array());
        }
        self.partial[k].add(v, s, depth);
    }

    /// The carrier of the vertices skinned by `joints` (`key`: as looked up) and, when
    /// parameters below it move them in part, their new group.
    fn new_set(
        &mut self,
        terms: &ExtraTerms,
        key: [usize; 4],
        joints: &[usize],
        params: &[Param],
    ) -> JointSet {
        self.stamp += 1;
        let carrier = terms.common_carrier(joints);
        if let Some(l) = carrier {
            for &p in &terms.joint_movers[l] {
                self.whole[p as usize] = self.stamp;
            }
        }
        // The parameters that move a joint of the set but not the carrier, each once.
        let mut in_part = Vec::new();
        for &j in joints {
            for &p in &terms.joint_movers[j] {
                if self.whole[p as usize] != self.stamp {
                    self.whole[p as usize] = self.stamp;
                    in_part.push(p);
                }
            }
        }
        let group = (!in_part.is_empty()).then(|| {
            let group = PartialGroup::new(terms, joints, carrier, &in_part, params);
            self.partial.push(group);
            self.partial.len() - 1
        });
        let set = JointSet { carrier, group };
        self.sets.insert(key, set);
        set
    }

    /// Adds the moments' blocks and gradients to `system`.
    pub(super) fn finish(
        &self,
        terms: &ExtraTerms,
        system: &mut System,
        (params, globals): (&[Param], &[DAffine3]),
    ) {
        for (l, moments) in self.per_joint.iter().enumerate() {
            if !moments.used {
                continue;
            }
            let whole: Vec<(usize, RowCoefficients)> = terms.joint_movers[l]
                .iter()
                .map(|&p| (p as usize, RowCoefficients::of(params[p as usize], globals)))
                .collect();
            let blocks = [moments.cc, moments.cm, moments.cm.transpose(), moments.mm];
            for (i, &(pa, a)) in whole.iter().enumerate() {
                let g = moments.gc * a.alpha + a.b * moments.gm;
                for k in 0..3 {
                    system.g[pa * 3 + k] += g[k];
                }
                let half = a.times_moments(blocks);
                for &(pb, b) in &whole[i..] {
                    system.add_pair((pa, pb), b.pair_block(half), 1.0);
                }
            }
        }
        for group in &self.partial {
            group.finish(terms, system, (params, globals));
        }
    }
}

impl PartialGroup {
    /// The group of the vertices skinned by `joints` (at most four), carried whole by
    /// `carrier`, with the parameters `in_part` moving part of them.
    fn new(
        terms: &ExtraTerms,
        joints: &[usize],
        carrier: Option<usize>,
        in_part: &[u32],
        params: &[Param],
    ) -> Self {
        let mut masks = vec![((1u16 << joints.len()) - 1) as u8];
        let params_in_part = in_part
            .iter()
            .map(|&p| {
                let (a, _) = split(params[p as usize]);
                let mask = joints
                    .iter()
                    .enumerate()
                    .filter(|(_, j)| terms.moves(a, **j))
                    .fold(0u8, |mask, (i, _)| mask | (1 << i));
                let part = match masks[1..].iter().position(|&m| m == mask) {
                    Some(k) => k + 1,
                    None => {
                        masks.push(mask);
                        masks.len() - 1
                    }
                };
                (p, part)
            })
            .collect();
        let n = 6 * joints.len();
        Self {
            carrier,
            params: params_in_part,
            masks,
            moments: vec![0.0; n * n],
            gradient: vec![0.0; n],
        }
    }

    /// Adds a term's stacked per-joint `u` at weight `s` and depth `depth`.
    fn add(&mut self, u: &[f64], s: f64, depth: f64) {
        let n = u.len();
        for (i, ui) in u.iter().enumerate() {
            self.gradient[i] += s * depth * ui;
            let (row, su) = (&mut self.moments[i * n + i..(i + 1) * n], s * ui);
            for (h, uj) in row.iter_mut().zip(&u[i..]) {
                *h += su * uj;
            }
        }
    }

    /// The parts' moments `Σ s v vᵀ` (full, row-major, `6 × parts` square) and `Σ s d v`,
    /// summed from the joints' (see [`PartialGroup`]): each part's rows first (`6 × parts`
    /// by `6 × joints`), then their columns, so a pair of parts costs the joints of one, not
    /// the product of both's.
    fn parts(&self) -> (Vec<f64>, Vec<f64>) {
        let (n, k) = (self.gradient.len(), 6 * self.masks.len());
        let at = |i: usize, j: usize| self.moments[i.min(j) * n + i.max(j)];
        let joints_of = |mask: u8| (0..n / 6).filter(move |i| mask & (1 << i) != 0);
        let mut gradient = vec![0.0; k];
        // Per part's row, the sum of its joints' rows of the moments.
        let mut rows = vec![0.0; k * n];
        for (a, &mask) in self.masks.iter().enumerate() {
            for i in joints_of(mask) {
                for r in 0..6 {
                    gradient[6 * a + r] += self.gradient[6 * i + r];
                    let row = &mut rows[(6 * a + r) * n..(6 * a + r + 1) * n];
                    for (c, v) in row.iter_mut().enumerate() {
                        *v += at(6 * i + r, c);
                    }
                }
            }
        }
        let mut moments = vec![0.0; k * k];
        for (row, out) in rows.chunks_exact(n).zip(moments.chunks_exact_mut(k)) {
            for (b, &mask) in self.masks.iter().enumerate() {
                for j in joints_of(mask) {
                    for c in 0..6 {
                        out[6 * b + c] += row[6 * j + c];
                    }
                }
            }
        }
        (moments, gradient)
    }

    /// Adds the group's pairs of a part-moving parameter with every parameter after it and
    /// with the carrier's, and its gradient, to `system`.
    fn finish(
        &self,
        terms: &ExtraTerms,
        system: &mut System,
        (params, globals): (&[Param], &[DAffine3]),
    ) {
        let (moments, gradient) = self.parts();
        let k = gradient.len();
        let block = |r: usize, c: usize| {
            let at = |i: usize, j: usize| moments[i * k + j];
            DMat3::from_cols_array_2d(&[
                [at(r, c), at(r + 1, c), at(r + 2, c)],
                [at(r, c + 1), at(r + 1, c + 1), at(r + 2, c + 1)],
                [at(r, c + 2), at(r + 1, c + 2), at(r + 2, c + 2)],
            ])
        };
        // Per pair of parts `(ka, kb)`, the moments of rows `u = α c_K + B m_K`.
        let parts = k / 6;
        let pair_moments: Vec<[DMat3; 4]> = (0..parts * parts)
            .map(|ab| {
                let (ra, rb) = (6 * (ab / parts), 6 * (ab % parts));
                [
                    block(ra, rb),
                    block(ra, rb + 3),
                    block(ra + 3, rb),
                    block(ra + 3, rb + 3),
                ]
            })
            .collect();
        // Each parameter with its part and row coefficients, once.
        let with = |p: u32, k: usize| {
            (
                p as usize,
                k,
                RowCoefficients::of(params[p as usize], globals),
            )
        };
        let in_part: Vec<_> = self.params.iter().map(|&(p, k)| with(p, k)).collect();
        let whole: Vec<_> = self
            .carrier
            .map_or(&[][..], |l| &terms.joint_movers[l][..])
            .iter()
            .map(|&p| with(p, 0))
            .collect();
        let mut halves = vec![[DMat3::ZERO; 2]; parts];
        for (i, &(pa, ka, a)) in in_part.iter().enumerate() {
            let r = 6 * ka;
            let gc = DVec3::from_slice(&gradient[r..r + 3]);
            let gm = DVec3::from_slice(&gradient[r + 3..r + 6]);
            let g = gc * a.alpha + a.b * gm;
            for k in 0..3 {
                system.g[pa * 3 + k] += g[k];
            }
            // `G_a M` against each part, once for every parameter paired with this one.
            for (kb, half) in halves.iter_mut().enumerate() {
                *half = a.times_moments(pair_moments[ka * parts + kb]);
            }
            for &(pb, kb, b) in in_part[i..].iter().chain(&whole) {
                system.add_pair((pa, pb), b.pair_block(halves[kb]), 1.0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{DAffine3, DQuat, DVec3};

    use crate::pose::ground::GroundPlane;
    use crate::pose::rig::skeleton::{Joint, Skeleton, VertexInfluences};
    use crate::pose::solver::params::{Param, movers_of_joints};
    use crate::pose::solver::terms::system::split;
    use crate::pose::solver::terms::{ExtraTerms, floor_only, ground, outer};

    /// A chain of four joints (0 → 1 → 2 → 3) with a branch (4) off joint 1, each half a unit
    /// from its parent, and a second root (5: a skin with two root joints).
    fn branching() -> Skeleton {
        let parents = [None, Some(0), Some(1), Some(2), Some(1), None];
        let offsets = [
            DVec3::ZERO,
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(0.5, 0.1, 0.0),
            DVec3::new(0.4, -0.1, 0.1),
            DVec3::new(0.0, -0.5, 0.2),
            DVec3::new(0.9, -0.4, -0.1),
        ];
        let mut globals = Vec::new();
        let joints = parents
            .iter()
            .zip(offsets)
            .enumerate()
            .map(|(j, (parent, offset))| {
                let frame = DAffine3::from_translation(offset);
                let global = parent.map_or(frame, |p: usize| globals[p] * frame);
                globals.push(global);
                Joint {
                    name: format!("j{j}"),
                    parent: *parent,
                    parent_frame: frame,
                    inverse_bind: global.inverse(),
                }
            })
            .collect();
        Skeleton::new(joints).unwrap()
    }

    /// What the moments sum, term by term and pair by pair of parameters: each one-number
    /// term's row for every parameter that moves it, from its Jacobian.
    fn pairwise(
        terms: &ExtraTerms,
        params: &[Param],
        (globals, skinning): (&[DAffine3], &[DAffine3]),
    ) -> (Vec<f64>, Vec<f64>) {
        let n = 3 * params.len();
        let (mut h, mut g) = (vec![0.0; n * n], vec![0.0; n]);
        terms.for_each_residual(
            globals,
            skinning,
            |term, w, r, gap| {
                let near = terms.near_contact(term, gap);
                let w = near.map_or(w, |(_, scale)| w * scale);
                let Some((sums, along, depth)) = near
                    .map(|(along, _)| along)
                    .or_else(|| ground::along_the_normal(term, r))
                else {
                    return;
                };
                let mut rows = Vec::new();
                for (p, param) in params.iter().enumerate() {
                    let (a, rotation) = split(*param);
                    let origin = globals[a].translation;
                    if let Some(b) = terms.centroid_jacobian(sums, a, rotation, origin, skinning) {
                        rows.push((p, b.transpose() * along));
                    }
                }
                for &(pa, ua) in &rows {
                    for k in 0..3 {
                        g[pa * 3 + k] += 2.0 * w * ua[k] * depth;
                    }
                    for &(pb, ub) in &rows {
                        let block = outer(ua, ub);
                        for r in 0..3 {
                            for c in 0..3 {
                                h[(pa * 3 + r) * n + pb * 3 + c] += 2.0 * w * block.col(c)[r];
                            }
                        }
                    }
                }
            },
            |_, _| {},
        );
        (h, g)
    }

    /// Vertices carried by one joint, by a joint and its child, by two branches (their
    /// common carrier above both), by the root and a tip, by joints under two roots (no
    /// carrier), under and just above a tilted floor, in a bent pose: the system summed by
    /// moments is the one summed pair by pair.
    #[test]
    fn the_moments_sum_what_the_pairs_sum() {
        let skeleton = branching();
        let mut params = vec![Param::Translation(0), Param::Translation(5)];
        params.extend((0..skeleton.len()).map(Param::Rotation));
        let movers = movers_of_joints(&skeleton, &params);
        let origins = skeleton.bind_origins();
        let mixes: [&[(u32, f64)]; 8] = [
            &[(3, 1.0)],
            &[(2, 0.6), (3, 0.4)],
            &[(3, 0.5), (4, 0.5)],
            &[(0, 0.3), (3, 0.7)],
            &[(4, 0.8), (1, 0.2)],
            &[(1, 0.2), (2, 0.3), (4, 0.5)],
            &[(3, 0.4), (5, 0.6)],
            &[(2, 0.1), (3, 0.2), (4, 0.3), (5, 0.4)],
        ];
        let mut bind = Vec::new();
        let mut influences: Vec<VertexInfluences> = Vec::new();
        for k in 0..60 {
            let t = k as f64;
            bind.push(DVec3::new(
                1.4 * (0.37 * t).sin().abs(),
                -0.4 + 0.3 * (0.71 * t).cos(),
                0.3 * (1.3 * t).sin(),
            ));
            let mut inf = [(0, 0.0); 4];
            for (slot, &(j, w)) in inf.iter_mut().zip(mixes[k % mixes.len()]) {
                *slot = (j, w);
            }
            influences.push(inf);
        }
        let floor =
            GroundPlane::new(DVec3::new(0.0, -0.3, 0.0), DVec3::new(0.2, 1.0, -0.1)).unwrap();
        let under: Vec<(u32, GroundPlane)> = (0..bind.len() as u32).map(|v| (v, floor)).collect();
        let skins = crate::pose::rig::skin::vertex_skins(&bind, &influences, &origins);
        let terms = floor_only((&skeleton, &movers, &origins), &skins, &under);
        // A bent pose: every joint turned a little, the root moved.
        let mut globals = Vec::new();
        for (j, joint) in skeleton.joints().iter().enumerate() {
            let turn = DQuat::from_euler(
                glam::EulerRot::XYZ,
                0.2 * (j as f64 + 1.0).sin(),
                0.15 * j as f64,
                -0.1 * (j as f64).cos(),
            );
            let local = joint.parent_frame * DAffine3::from_quat(turn);
            let global = match joint.parent {
                Some(p) => globals[p] * local,
                None => DAffine3::from_translation(DVec3::new(0.05, -0.1, 0.02)) * local,
            };
            globals.push(global);
        }
        let skinning: Vec<DAffine3> = globals
            .iter()
            .zip(skeleton.joints())
            .map(|(g, j)| *g * j.inverse_bind)
            .collect();
        let n = 3 * params.len();
        let (mut h, mut g) = (vec![0.0; n * n], vec![0.0; n]);
        terms.add_system_at(
            (&globals, &skinning),
            &params,
            (&mut h, &mut Vec::new()),
            &mut g,
        );
        let (h_ref, g_ref) = pairwise(&terms, &params, (&globals, &skinning));
        let largest = h_ref
            .iter()
            .chain(&g_ref)
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(largest > 1.0, "the floor acts: {largest}");
        for (k, (a, b)) in h.iter().zip(&h_ref).chain(g.iter().zip(&g_ref)).enumerate() {
            assert!(
                (a - b).abs() <= 1e-10 * largest,
                "entry {k}: {a} against {b}"
            );
        }
    }
}
