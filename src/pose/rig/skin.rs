//! Weighted sums of skinned vertices as per-joint sums: a centroid (or one vertex) of the
//! skin is `Σ_j S_j m_j` in the skinning matrices `S_j`, with `m_j` summed once per solve.

use crate::pose::rig::skeleton::VertexInfluences;

use glam::{DAffine3, DVec3, DVec4};

/// Per joint, `Σ_v m_v w_vj (b_v, 1)` over `(vertex, m_v)`: a weighted centroid of skinned
/// vertices as `Σ_j S_j m_j` ([`centroid_of`]); joints with no share left out.
pub(crate) fn joint_sums(
    joints: usize,
    (bind, influences): (&[DVec3], &[VertexInfluences]),
    vertices: impl Iterator<Item = (u32, f64)>,
) -> Vec<(usize, DVec4)> {
    let mut per_joint: Vec<DVec4> = vec![DVec4::ZERO; joints];
    for (v, m) in vertices {
        let b = bind[v as usize];
        for &(j, w) in &influences[v as usize] {
            if w != 0.0 {
                per_joint[j as usize] += DVec4::new(b.x, b.y, b.z, 1.0) * (w * m);
            }
        }
    }
    per_joint
        .into_iter()
        .enumerate()
        .filter(|(_, m)| *m != DVec4::ZERO)
        .collect()
}

/// The centre of mass of the skin as per-joint sums ([`joint_sums`] of each welded vertex at
/// its share of `masses`); empty when the masses do not add up to anything. The same for
/// every solve of a model with the same masses: the solver keeps the area masses' ones.
pub(crate) fn mass_sums(
    joints: usize,
    skin: (&[DVec3], &[VertexInfluences]),
    masses: &[f64],
) -> Vec<(usize, DVec4)> {
    let total: f64 = masses.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let shares = masses
        .iter()
        .enumerate()
        .map(|(v, m)| (v as u32, m / total));
    joint_sums(joints, skin, shares)
}

/// [`joint_sums`] of one vertex at weight 1 (its influences, each joint once), without the
/// dense per-joint pass and in at most four entries: one per welded vertex ([`vertex_skins`]).
fn vertex_sums(b: DVec3, influences: &VertexInfluences) -> VertexSums {
    let mut sums = VertexSums {
        entries: [(0, DVec4::ZERO); 4],
        len: 0,
    };
    for &(j, w) in influences {
        if w == 0.0 {
            continue;
        }
        let m = DVec4::new(b.x, b.y, b.z, 1.0) * w;
        let len = sums.len;
        match sums.entries[..len]
            .iter_mut()
            .find(|(k, _)| *k == j as usize)
        {
            Some((_, sum)) => *sum += m,
            None => {
                sums.entries[len] = (j as usize, m);
                sums.len += 1;
            }
        }
    }
    let mut kept = 0;
    for k in 0..sums.len {
        if sums.entries[k].1 != DVec4::ZERO {
            sums.entries[kept] = sums.entries[k];
            kept += 1;
        }
    }
    sums.len = kept;
    sums.entries[..kept].sort_unstable_by_key(|(j, _)| *j);
    sums
}

/// What the terms keeping a vertex above its ground read of its skin: its [`VertexSums`] and,
/// per joint of them, its bind position's distance from the joint's (how far the joint's turn
/// can move it, per unit of turn). The same in every solve of a model: the model keeps them
/// ([`vertex_skins`]), and a solve's terms point at them instead of building them again in
/// every solve (`docs/design/ground.md`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct VertexSkin {
    pub(crate) sums: VertexSums,
    pub(crate) reach: [f64; 4],
}

/// How many vertices a [`SkinGroup`] holds at most: few enough that its vertices stay near
/// each other, enough that a test of the whole group is rare.
pub(crate) const SKIN_GROUP: usize = 16;

/// Vertices carried most by the same joint, [`SKIN_GROUP`] at a time in the model's vertex
/// order, with what bounds how far any of them moves when their joints move: the floor's
/// terms are grouped by them (`solver/terms/floor_groups.rs`), so a group far above its
/// ground passes in one test.
#[derive(Debug, Clone, Default)]
pub(crate) struct SkinGroup {
    /// Every joint carrying a vertex of it, with the farthest such vertex's distance from
    /// the joint's bind position.
    pub(crate) reach: Vec<(usize, f64)>,
    /// The largest sum of absolute skin weights of a vertex of it.
    pub(crate) weight_sum: f64,
}

/// Every welded vertex's [`VertexSkin`], with the vertices in [`SkinGroup`]s: made once per
/// model ([`vertex_skins`]); derefs to the vertices' skins.
#[derive(Debug, Clone, Default)]
pub(crate) struct VertexSkins {
    skins: Vec<VertexSkin>,
    groups: Vec<SkinGroup>,
    /// Each vertex's group (apart from its skin: a solve's floor reads only this of most
    /// of its vertices while grouping them).
    group_of: Vec<u32>,
}

impl VertexSkins {
    /// No vertices (a solve that keeps none above a ground).
    pub(crate) const NONE: &'static VertexSkins = &VertexSkins {
        skins: Vec::new(),
        groups: Vec::new(),
        group_of: Vec::new(),
    };

    /// The model's groups of vertices.
    pub(crate) fn groups(&self) -> &[SkinGroup] {
        &self.groups
    }

    /// Vertex `v`'s group among [`VertexSkins::groups`] (`None` past the last vertex).
    pub(crate) fn group_of(&self, v: usize) -> Option<usize> {
        self.group_of.get(v).map(|&g| g as usize)
    }
}

impl std::ops::Deref for VertexSkins {
    type Target = [VertexSkin];

    fn deref(&self) -> &[VertexSkin] {
        &self.skins
    }
}

impl VertexSkin {
    /// The vertex skinned by the joints' skinning matrices `skinning`.
    pub(crate) fn skinned(&self, skinning: &[DAffine3]) -> DVec3 {
        centroid_of(&self.sums, skinning)
    }
}

/// Each vertex's [`VertexSkin`], in their [`SkinGroup`]s: bind positions `bind` with their
/// `influences`, the joints' bind positions `bind_origins`.
pub(crate) fn vertex_skins(
    bind: &[DVec3],
    influences: &[VertexInfluences],
    bind_origins: &[DVec3],
) -> VertexSkins {
    let skins: Vec<VertexSkin> = bind
        .iter()
        .zip(influences)
        .map(|(&b, influences)| {
            let sums = vertex_sums(b, influences);
            let mut reach = [0.0; 4];
            for (r, &(j, _)) in reach.iter_mut().zip(sums.iter()) {
                *r = bind_origins.get(j).map_or(0.0, |o| b.distance(*o));
            }
            VertexSkin { sums, reach }
        })
        .collect();
    let (groups, group_of) = group_skins(&skins, bind_origins.len());
    VertexSkins {
        skins,
        groups,
        group_of,
    }
}

/// Puts each vertex of `skins` in a [`SkinGroup`] of vertices with its carrier, [`SKIN_GROUP`]
/// at a time in vertex order (`joints`: the skeleton's count): the groups, and each vertex's.
fn group_skins(skins: &[VertexSkin], joints: usize) -> (Vec<SkinGroup>, Vec<u32>) {
    let mut groups: Vec<SkinGroup> = Vec::new();
    // Per carrier, its open group with how many vertices it holds.
    let mut open: Vec<Option<(u32, usize)>> = vec![None; joints + 1];
    let mut group_of = Vec::with_capacity(skins.len());
    for skin in skins {
        let slot = &mut open[carrier_of(&skin.sums, joints)];
        let index = match slot {
            Some((g, len)) if *len < SKIN_GROUP => {
                *len += 1;
                *g
            }
            _ => {
                let g = groups.len() as u32;
                groups.push(SkinGroup::default());
                *slot = Some((g, 1));
                g
            }
        };
        group_of.push(index);
        let group = &mut groups[index as usize];
        group.weight_sum = group.weight_sum.max(weight_sum_of(&skin.sums));
        for (&(j, _), &r) in skin.sums.iter().zip(skin.reach.iter()) {
            match group.reach.iter_mut().find(|(k, _)| *k == j) {
                Some((_, far)) => *far = far.max(r),
                None => group.reach.push((j, r)),
            }
        }
    }
    (groups, group_of)
}

/// The joint with the largest share of a vertex skinned by `sums` (`joints`, the skeleton's
/// count, for a vertex with none): the model groups its vertices by it ([`SkinGroup`]).
fn carrier_of(sums: &JointSums, joints: usize) -> usize {
    sums.iter()
        .max_by(|a, b| a.1.w.abs().total_cmp(&b.1.w.abs()))
        .map_or(joints, |s| s.0.min(joints))
}

/// The sum of a vertex's absolute skin weights (1 for a normalised skin).
fn weight_sum_of(sums: &JointSums) -> f64 {
    sums.iter().map(|s| s.1.w.abs()).sum()
}

/// One vertex's [`JointSums`] (at most four joints), kept in its term.
#[derive(Debug, Clone, Copy)]
pub(crate) struct VertexSums {
    entries: [(usize, DVec4); 4],
    len: usize,
}

impl std::ops::Deref for VertexSums {
    type Target = JointSums;

    fn deref(&self) -> &JointSums {
        &self.entries[..self.len]
    }
}

/// `Σ_j S_j m_j` (homogeneous weighted sums).
pub(crate) fn centroid_of(sums: &[(usize, DVec4)], skinning: &[DAffine3]) -> DVec3 {
    sums.iter().map(|&(j, m)| apply(&skinning[j], m)).sum()
}

/// An affine applied to a homogeneous point `(x, y, z, w)`.
pub(crate) fn apply(a: &DAffine3, m: DVec4) -> DVec3 {
    a.matrix3 * m.truncate() + a.translation * m.w
}

/// A weighted sum of skinned points as per-joint sums `(joint, Σ m w (b, 1))`
/// ([`centroid_of`]).
pub(crate) type JointSums = [(usize, DVec4)];

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::{SKIN_GROUP, carrier_of, vertex_skins, weight_sum_of};

    /// Each group holds at most [`SKIN_GROUP`] vertices, all with one carrier, and bounds
    /// every vertex of it: each of the vertex's joints is in the group's reach at least as
    /// far, its weight sum at most the group's. Vertices alternate between two carriers, so
    /// a group opened per carrier is what keeps them apart. (Fails when a vertex joins the
    /// last group opened whatever its carrier.)
    #[test]
    fn a_skin_group_bounds_each_of_its_vertices() {
        let origins = [DVec3::ZERO, DVec3::Y, DVec3::Y * 2.0];
        let bind: Vec<DVec3> = (0..70)
            .map(|i| DVec3::new(0.1 * (i % 5) as f64, 0.03 * i as f64, 0.0))
            .collect();
        let influences: Vec<_> = (0..bind.len() as u32)
            .map(|i| {
                let (most, other) = if i % 2 == 0 { (0, 1) } else { (2, 1) };
                [(most, 0.7), (other, 0.3), (0, 0.0), (0, 0.0)]
            })
            .collect();
        let skins = vertex_skins(&bind, &influences, &origins);
        let groups = skins.groups();
        assert_eq!(groups.len(), 2 * 35usize.div_ceil(SKIN_GROUP));
        let mut count = vec![0; groups.len()];
        let mut carrier = vec![None; groups.len()];
        for (v, skin) in skins.iter().enumerate() {
            let g = skins.group_of(v).unwrap();
            count[g] += 1;
            let own = carrier_of(&skin.sums, origins.len());
            assert_eq!(*carrier[g].get_or_insert(own), own);
            let group = &groups[g];
            assert!(weight_sum_of(&skin.sums) <= group.weight_sum);
            for (&(j, _), &r) in skin.sums.iter().zip(skin.reach.iter()) {
                let far = group.reach.iter().find(|(k, _)| *k == j).map(|(_, r)| *r);
                assert!(far.is_some_and(|far| far >= r), "joint {j}: {far:?} < {r}");
            }
        }
        assert!(count.iter().all(|&c| (1..=SKIN_GROUP).contains(&c)));
    }
}
