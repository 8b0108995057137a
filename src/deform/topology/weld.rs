//! Welding: which coincident render vertices become one solver vertex.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

use super::WeldPolicy;

/// Merges coincident vertices as `policy` says: the welded positions and, per input vertex,
/// its welded index (welded vertices are numbered in order of first appearance).
pub(super) fn weld(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    policy: WeldPolicy,
) -> (Vec<DVec3>, Vec<u32>) {
    let identity = || (positions.to_vec(), (0..positions.len() as u32).collect());
    if policy == WeldPolicy::None {
        return identity();
    }
    // Position classes by exact bit pattern (with -0.0 folded into 0.0).
    let key = |p: DVec3| {
        let f = |x: f64| if x == 0.0 { 0u64 } else { x.to_bits() };
        [f(p.x), f(p.y), f(p.z)]
    };
    let mut map: HashMap<[u64; 3], u32, BuildHasherDefault<PositionHasher>> =
        HashMap::with_capacity_and_hasher(positions.len(), Default::default());
    let class: Vec<u32> = positions
        .iter()
        .map(|&p| {
            let next = map.len() as u32;
            *map.entry(key(p)).or_insert(next)
        })
        .collect();
    let classes = map.len();
    drop(map);
    if classes == positions.len() {
        return identity();
    }
    let mergeable: Vec<bool> = match policy {
        WeldPolicy::AllCoincident => vec![true; positions.len()],
        _ => seam_vertices(&class, classes, triangles),
    };
    let mut class_to_welded = vec![u32::MAX; classes];
    let mut welded = Vec::with_capacity(classes);
    let render_to_welded = positions
        .iter()
        .enumerate()
        .map(|(v, &p)| {
            let slot = &mut class_to_welded[class[v] as usize];
            if mergeable[v] && *slot != u32::MAX {
                return *slot;
            }
            welded.push(p);
            let id = (welded.len() - 1) as u32;
            if mergeable[v] {
                *slot = id;
            }
            id
        })
        .collect();
    (welded, render_to_welded)
}

/// Vertices on a split seam: endpoints of boundary edges (used by one triangle) that have a
/// twin boundary edge between the same two position classes. Only edges with at least one end
/// sharing its position with another vertex can be seam edges (a pole fan split per triangle
/// has seam edges whose other end is unique), so only those are counted.
fn seam_vertices(class: &[u32], classes: usize, triangles: &[[u32; 3]]) -> Vec<bool> {
    let mut members = vec![0u32; classes];
    for &c in class {
        members[c as usize] += 1;
    }
    let shared = |v: u32| members[class[v as usize] as usize] > 1;
    type EdgeMap = HashMap<(u32, u32), u32, BuildHasherDefault<PositionHasher>>;
    let mut uses = EdgeMap::default();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a != b && (shared(a) || shared(b)) {
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
    }
    let boundary: Vec<(u32, u32)> = uses
        .into_iter()
        .filter(|&(_, n)| n == 1)
        .map(|(e, _)| e)
        .collect();
    let geometric = |(a, b): (u32, u32)| {
        let (ca, cb) = (class[a as usize], class[b as usize]);
        (ca.min(cb), ca.max(cb))
    };
    let mut twins = EdgeMap::default();
    for &e in &boundary {
        *twins.entry(geometric(e)).or_insert(0) += 1;
    }
    let mut seam = vec![false; class.len()];
    for &e in &boundary {
        if twins[&geometric(e)] > 1 {
            seam[e.0 as usize] = true;
            seam[e.1 as usize] = true;
        }
    }
    seam
}

/// Hasher for welding keys (three `f64` bit patterns): a multiply–rotate mix, far cheaper
/// than the default SipHash and good enough for keys no attacker chooses.
#[derive(Default)]
struct PositionHasher(u64);

impl Hasher for PositionHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(23) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }

    fn finish(&self) -> u64 {
        self.0 ^ (self.0 >> 29)
    }
}
#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::super::{Topology, WeldPolicy};

    /// An octahedron of radius `r` centred at `c`: a closed surface.
    fn octahedron(c: DVec3, r: f64) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let m = crate::deform::synth::octahedron(c, r);
        (m.positions, m.triangles)
    }

    /// Connected components of the welded adjacency.
    fn components(topo: &Topology) -> usize {
        let n = topo.vertex_count();
        let mut seen = vec![false; n];
        let mut count = 0;
        for s in 0..n {
            if seen[s] {
                continue;
            }
            count += 1;
            let mut stack = vec![s];
            seen[s] = true;
            while let Some(v) = stack.pop() {
                for &w in topo.neighbors(v) {
                    if !seen[w as usize] {
                        seen[w as usize] = true;
                        stack.push(w as usize);
                    }
                }
            }
        }
        count
    }

    #[test]
    fn touching_closed_surfaces_stay_apart_unless_asked() {
        // Two octahedra touching at one vertex: (1,0,0) of the first is (−1,0,0) of the second.
        let (mut p, mut t) = octahedron(DVec3::ZERO, 1.0);
        let (p2, t2) = octahedron(DVec3::new(2.0, 0.0, 0.0), 1.0);
        t.extend(t2.iter().map(|tri| tri.map(|i| i + 6)));
        p.extend(p2);
        let seams = Topology::new(&p, &t).unwrap();
        assert_eq!(seams.vertex_count(), 12);
        assert_eq!(components(&seams), 2);
        let all = Topology::with_weld(&p, &t, WeldPolicy::AllCoincident).unwrap();
        assert_eq!(all.vertex_count(), 11);
        assert_eq!(components(&all), 1);
        let none = Topology::with_weld(&p, &t, WeldPolicy::None).unwrap();
        assert_eq!(none.render_to_welded(), (0..12).collect::<Vec<u32>>());
    }

    #[test]
    fn a_split_seam_is_welded_and_touching_borders_are_not() {
        // The octahedron cut open along the edge 0–4: triangles [3,0,4] use copies 6 (of 0)
        // and 7 (of 4), so edges 0–4 and 6–7 are twin boundary edges.
        let (mut p, mut t) = octahedron(DVec3::ZERO, 1.0);
        p.push(p[0]);
        p.push(p[4]);
        t[3] = [3, 6, 7];
        let none = Topology::with_weld(&p, &t, WeldPolicy::None).unwrap();
        assert_eq!(none.vertex_count(), 8);
        let seams = Topology::new(&p, &t).unwrap();
        assert_eq!(seams.vertex_count(), 6);
        assert_eq!(seams.render_to_welded()[6], seams.render_to_welded()[0]);
        assert_eq!(seams.render_to_welded()[7], seams.render_to_welded()[4]);
        // Closed again: every vertex has the octahedron's four neighbours.
        assert!((0..6).all(|v| seams.neighbors(v).len() == 4));
        // Two separate squares whose corners touch at one point: a border, not a seam.
        let p = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
        ];
        let t = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let touching = Topology::new(&p, &t).unwrap();
        assert_eq!(touching.vertex_count(), 8);
        assert_eq!(components(&touching), 2);
    }
}
