//! Distances along the mesh surface (edge paths): grab patches and regions of interest.

use std::collections::BinaryHeap;

use super::Topology;

impl Topology {
    /// Distances along mesh edges from the nearest of `seeds` (welded indices) to every welded
    /// vertex within `limit` (Dijkstra; seeds at 0), nearest first, at most `max_vertices`
    /// of them (the search stops there): a region of interest around a handle, a grabbed
    /// patch.
    pub fn geodesic_distances(
        &self,
        seeds: &[u32],
        limit: f64,
        max_vertices: usize,
    ) -> Vec<(u32, f64)> {
        #[derive(PartialEq)]
        struct Item(f64, u32);
        impl Eq for Item {}
        impl PartialOrd for Item {
            fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
                Some(self.cmp(other))
            }
        }
        impl Ord for Item {
            fn cmp(&self, other: &Self) -> std::cmp::Ordering {
                // Min-heap; ties by vertex, so the order never depends on the heap's history.
                other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
            }
        }
        let positions = &self.positions;
        // Dense tentative distances: a region is a sizeable part of the mesh, and a hash map
        // of it cost more than the whole search.
        let mut best = vec![f64::INFINITY; positions.len()];
        let mut settled = Vec::new();
        let mut heap = BinaryHeap::new();
        let mut done = vec![false; positions.len()];
        let relax = |v: u32, d: f64, best: &mut [f64], heap: &mut BinaryHeap<Item>| {
            for &w in self.neighbors(v as usize) {
                let nd = d + positions[v as usize].distance(positions[w as usize]);
                if nd <= limit && nd < best[w as usize] {
                    best[w as usize] = nd;
                    heap.push(Item(nd, w));
                }
            }
        };
        // The seeds are settled at 0 in vertex order (what the heap would pop first), without
        // passing through it: a handle can hold thousands of vertices.
        let mut sorted: Vec<u32> = seeds
            .iter()
            .copied()
            .filter(|&s| (s as usize) < positions.len())
            .collect();
        sorted.sort_unstable();
        sorted.dedup();
        sorted.truncate(max_vertices);
        for &seed in &sorted {
            best[seed as usize] = 0.0;
            done[seed as usize] = true;
            settled.push((seed, 0.0));
        }
        for &seed in &sorted {
            relax(seed, 0.0, &mut best, &mut heap);
        }
        while let Some(Item(d, v)) = heap.pop() {
            if settled.len() >= max_vertices {
                break;
            }
            if std::mem::replace(&mut done[v as usize], true) {
                continue; // an entry superseded by a shorter path
            }
            settled.push((v, d));
            relax(v, d, &mut best, &mut heap);
        }
        settled
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geodesic_distances_are_shortest_edge_paths_nearest_first() {
        let mesh = crate::deform::synth::icosphere(3, 1.0);
        let topo = Topology::new(&mesh.positions, &mesh.triangles).unwrap();
        let n = topo.vertex_count();
        // Reference: Bellman–Ford relaxation to a fixed point over every edge.
        let mut reference = vec![f64::INFINITY; n];
        reference[0] = 0.0;
        reference[7] = 0.0;
        loop {
            let mut changed = false;
            for i in 0..n {
                for &j in topo.neighbors(i) {
                    let d =
                        reference[i] + topo.positions()[i].distance(topo.positions()[j as usize]);
                    if d < reference[j as usize] {
                        reference[j as usize] = d;
                        changed = true;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        let limit = 0.8;
        // A repeated seed changes nothing.
        let found = topo.geodesic_distances(&[0, 7, 7], limit, usize::MAX);
        let inside = reference.iter().filter(|&&d| d <= limit).count();
        assert!(
            inside > 20 && inside < n,
            "the limit cuts the sphere: {inside} of {n}"
        );
        assert_eq!(found.len(), inside, "every vertex within the limit, once");
        for pair in found.windows(2) {
            assert!(pair[0].1 <= pair[1].1, "nearest first");
        }
        for &(v, d) in &found {
            assert!(
                (d - reference[v as usize]).abs() < 1e-12,
                "vertex {v}: {d} vs {}",
                reference[v as usize]
            );
        }
        // A cap keeps the nearest.
        let capped = topo.geodesic_distances(&[0, 7], limit, 10);
        assert_eq!(capped[..], found[..10]);
    }
}
