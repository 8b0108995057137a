//! A skinned mesh prepared for posing: welded, clustered, and its ARAP energy reduced to the
//! joint transforms.

use std::sync::Arc;

use glam::{DAffine3, DMat3, DVec3, DVec4, Vec3};
use rayon::prelude::*;

use crate::deform::{Topology, WeightMode, WeldPolicy};
use crate::pose::error::PoseError;
use crate::pose::rig::skeleton::{Skeleton, SkeletonPose, VertexInfluences, skin_positions};
use crate::pose::rig::skin::{VertexSkins, vertex_skins};

/// A skinned triangle mesh as a glTF primitive (or a Bevy `Mesh`) stores it, in render order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SkinnedMesh {
    /// Bind-pose positions (mesh space).
    pub positions: Vec<Vec3>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Up to four joint indices per vertex (`JOINTS_0`), into the skeleton's joint list.
    pub joint_indices: Vec<[u16; 4]>,
    /// The matching weights (`WEIGHTS_0`).
    pub joint_weights: Vec<[f32; 4]>,
}

impl SkinnedMesh {
    /// Checks the skin and returns each vertex' influences with the weights normalised to sum
    /// to 1 (the glTF rule; exporters often leave small rounding errors, and a GPU skins with
    /// the weights as given, so the normalisation is what the artist meant).
    ///
    /// Errors: attribute lengths differ ([`PoseError::AttributeLength`]); a weight is negative
    /// or not finite ([`PoseError::InvalidWeight`]); a joint with a non-zero weight is out of
    /// range ([`PoseError::JointIndexOutOfRange`]; one with weight 0 is ignored, as glTF
    /// allows); all weights of a vertex are zero ([`PoseError::UnweightedVertex`]).
    pub fn influences(&self, joint_count: usize) -> Result<Vec<VertexInfluences>, PoseError> {
        let n = self.positions.len();
        if self.joint_indices.len() != n || self.joint_weights.len() != n {
            return Err(PoseError::AttributeLength {
                positions: n,
                joints: self.joint_indices.len(),
                weights: self.joint_weights.len(),
            });
        }
        (0..n)
            .map(|vertex| {
                let mut inf: VertexInfluences = [(0, 0.0); 4];
                let mut sum = 0.0;
                for (k, (&j, &w)) in self.joint_indices[vertex]
                    .iter()
                    .zip(&self.joint_weights[vertex])
                    .enumerate()
                {
                    if !w.is_finite() || w < 0.0 {
                        return Err(PoseError::InvalidWeight { vertex });
                    }
                    if w == 0.0 {
                        continue;
                    }
                    if j as usize >= joint_count {
                        return Err(PoseError::JointIndexOutOfRange {
                            vertex,
                            joint: j as usize,
                            joint_count,
                        });
                    }
                    inf[k] = (j as u32, w as f64);
                    sum += w as f64;
                }
                if sum <= 0.0 {
                    return Err(PoseError::UnweightedVertex { vertex });
                }
                for e in &mut inf {
                    e.1 /= sum;
                }
                Ok(inf)
            })
            .collect()
    }
}

/// How a [`SkinnedModel`] is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelSettings {
    /// Number of rotation clusters (k-means in weight space); capped by the vertex count.
    pub clusters: usize,
    /// Which coincident vertices are welded (seams, as the static solver does, by default).
    pub weld: WeldPolicy,
    /// Lloyd iterations of the clustering.
    pub cluster_iterations: u32,
}

impl Default for ModelSettings {
    fn default() -> Self {
        Self {
            clusters: 100,
            weld: WeldPolicy::Seams,
            cluster_iterations: 8,
        }
    }
}

/// A skinned mesh ready for [`crate::pose::solver::PoseSolver`]: the welded topology, each welded vertex'
/// skin, the rotation clusters, and the ARAP energy reduced to the skinning matrices.
///
/// With the skinning matrices `S_k` stacked transposed into `X` (4·joints × 3), every skinned
/// vertex is linear in `X`, `p'_i = M_i X`, so the ARAP energy with one rotation `R_c` per
/// cluster is `E = tr(XᵀQX) − 2 Σ_c tr(R_cᵀ Xᵀ K_c) + c₀`: `Q` (4J × 4J) and `K_c` (4J × 3)
/// are summed over the mesh once, here, and a solver iteration never touches a vertex.
#[derive(Debug, Clone)]
pub struct SkinnedModel {
    skeleton: Skeleton,
    topology: Arc<Topology>,
    render_influences: Vec<VertexInfluences>,
    render_bind: Vec<DVec3>,
    bind: Vec<DVec3>,
    influences: Vec<VertexInfluences>,
    cluster_of: Vec<u32>,
    cluster_count: usize,
    rest_scale: f64,
    /// Per joint, the share of the body its rotation carries ([`crate::pose::rig::inertia`]).
    relative_inertia: Vec<f64>,
    /// Mass per welded vertex by area ([`crate::pose::rig::mass::vertex_masses`]), made by the first
    /// balance that needs it.
    area_masses: std::sync::OnceLock<Vec<f64>>,
    /// What the solver's ground terms read of each welded vertex's skin, made by the first
    /// solve with contacts or a floor and shared by every solver of the model (a crowd's).
    vertex_skins: std::sync::OnceLock<VertexSkins>,
    pub(crate) q: Vec<f64>,
    pub(crate) k: Vec<f64>,
    pub(crate) c0: f64,
    pub(crate) mean_degree: f64,
}

impl SkinnedModel {
    /// Welds, clusters and reduces `mesh` skinned to `skeleton`.
    ///
    /// `reference` is a pose the character is in (its current or bind pose); it fixes the
    /// *scale* of the rest shape: the solver compares edges in the space the skeleton is posed
    /// in (world space in Bevy), so the bind-pose positions are scaled by the skinning
    /// matrices' uniform scale at `reference`.
    pub fn new(
        skeleton: Skeleton,
        mesh: &SkinnedMesh,
        reference: &SkeletonPose,
        settings: ModelSettings,
    ) -> Result<Self, PoseError> {
        skeleton.check_pose(reference)?;
        let render_influences = mesh.influences(skeleton.len())?;
        let render_bind: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        let rest_scale = uniform_scale(&skeleton, reference, &render_influences)?;
        let scaled: Vec<DVec3> = render_bind.iter().map(|p| *p * rest_scale).collect();
        if !mesh.indices.len().is_multiple_of(3) {
            return Err(
                crate::deform::MeshError::IndexCountNotTriangles(mesh.indices.len()).into(),
            );
        }
        let triangles: Vec<[u32; 3]> = mesh
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        let topology = Arc::new(Topology::with_weld(&scaled, &triangles, settings.weld)?);
        let mut first = vec![u32::MAX; topology.vertex_count()];
        for (r, &w) in topology.render_to_welded().iter().enumerate().rev() {
            first[w as usize] = r as u32;
        }
        let influences: Vec<VertexInfluences> = first
            .iter()
            .map(|&r| render_influences[r as usize])
            .collect();
        let bind: Vec<DVec3> = first.iter().map(|&r| render_bind[r as usize]).collect();
        let (cluster_of, cluster_count) = cluster_weights(
            &influences,
            skeleton.len(),
            settings.clusters,
            settings.cluster_iterations,
        );
        let relative_inertia =
            crate::pose::rig::inertia::relative_inertia(&skeleton, &bind, &influences);
        let mut model = Self {
            relative_inertia,
            area_masses: std::sync::OnceLock::new(),
            vertex_skins: std::sync::OnceLock::new(),
            skeleton,
            topology,
            render_influences,
            render_bind,
            bind,
            influences,
            cluster_of,
            cluster_count,
            rest_scale,
            q: Vec::new(),
            k: Vec::new(),
            c0: 0.0,
            mean_degree: 0.0,
        };
        model.reduce();
        Ok(model)
    }

    /// Per joint, the moment of inertia of what its rotation carries (its subtree's skinned
    /// vertices about it, bind pose) relative to the mean over the joints: ≫ 1 for the hips,
    /// ≪ 1 for a finger tip ([`crate::pose::constraints::effectors::StiffnessWeighting::Inertia`]).
    pub fn relative_inertia(&self) -> &[f64] {
        &self.relative_inertia
    }

    /// The skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// The welded topology (rest positions: bind pose × [`SkinnedModel::rest_scale`]).
    pub fn topology(&self) -> &Arc<Topology> {
        &self.topology
    }

    /// Number of rotation clusters.
    pub fn cluster_count(&self) -> usize {
        self.cluster_count
    }

    /// Cluster of each welded vertex.
    pub fn clusters(&self) -> &[u32] {
        &self.cluster_of
    }

    /// Uniform scale from bind space to the skeleton's space, measured at the reference pose.
    pub fn rest_scale(&self) -> f64 {
        self.rest_scale
    }

    /// Normalised skin of each welded vertex.
    pub fn influences(&self) -> &[VertexInfluences] {
        &self.influences
    }

    /// The joints a vertex set does not reach: no vertex of `welded` is weighted (more than
    /// `min_weight`) to the joint or to any joint below it. Pinning them holds everything a
    /// grab of `welded` should not carry along (the legs and tail when the head is grabbed),
    /// while the chain from the root to the grabbed part stays free to bend.
    pub fn joints_not_reaching(&self, welded: &[u32], min_weight: f64) -> Vec<usize> {
        let n = self.skeleton.len();
        let mut reached = vec![false; n];
        for &v in welded {
            if let Some(influences) = self.influences.get(v as usize) {
                for &(j, w) in influences {
                    if w > min_weight && (j as usize) < n {
                        reached[j as usize] = true;
                    }
                }
            }
        }
        // Parents come before children: propagate from the leaves up.
        for j in (0..n).rev() {
            if let Some(p) = self.skeleton.joints()[j].parent
                && reached[j]
            {
                reached[p] = true;
            }
        }
        (0..n).filter(|&j| !reached[j]).collect()
    }

    /// Mass per welded vertex, a third of the bind-pose area of each triangle around it
    /// ([`crate::pose::ground::balance`]'s mass model), computed once.
    pub fn area_masses(&self) -> &[f64] {
        self.area_masses
            .get_or_init(|| crate::pose::rig::mass::vertex_masses(self))
    }

    /// Each welded vertex's skin as the solver's ground terms read it (see
    /// [`VertexSkins`]); made once.
    pub(crate) fn vertex_skins(&self) -> &VertexSkins {
        self.vertex_skins.get_or_init(|| {
            vertex_skins(&self.bind, &self.influences, &self.skeleton.bind_origins())
        })
    }

    /// Bind-pose position of each welded vertex (mesh space).
    pub fn bind_positions(&self) -> &[DVec3] {
        &self.bind
    }

    /// Skinned positions of the welded vertices in `pose` (CPU linear-blend skinning).
    pub fn skin_welded(&self, pose: &SkeletonPose) -> Vec<DVec3> {
        let m = self.skeleton.skinning_matrices(pose);
        skin_positions(&m, &self.bind, &self.influences)
    }

    /// The centroid of the welded vertices `welded` skinned in `pose` (only those vertices are
    /// skinned); the origin for an empty set.
    pub fn skinned_centroid(&self, pose: &SkeletonPose, welded: &[u32]) -> DVec3 {
        if welded.is_empty() {
            return DVec3::ZERO;
        }
        self.skin_vertices(pose, welded).iter().sum::<DVec3>() / welded.len() as f64
    }

    /// Skinned positions of the welded vertices `welded` in `pose`, in that order (only those
    /// vertices are skinned: the same numbers [`SkinnedModel::skin_welded`] gives them).
    pub fn skin_vertices(&self, pose: &SkeletonPose, welded: &[u32]) -> Vec<DVec3> {
        let m = self.skeleton.skinning_matrices(pose);
        let bind: Vec<DVec3> = welded.iter().map(|&v| self.bind[v as usize]).collect();
        let influences: Vec<VertexInfluences> = welded
            .iter()
            .map(|&v| self.influences[v as usize])
            .collect();
        skin_positions(&m, &bind, &influences)
    }

    /// Skinned positions of the render vertices in `pose` (what the GPU draws; ray-cast these
    /// to pick the posed mesh).
    pub fn skin_render(&self, pose: &SkeletonPose) -> Vec<DVec3> {
        let m = self.skeleton.skinning_matrices(pose);
        skin_positions(&m, &self.render_bind, &self.render_influences)
    }

    /// The full-mesh normalised ARAP energy ([`crate::deform::arap_energy`]) of `pose`'s
    /// skinned mesh against the rest shape: per-vertex best rotations, so it is comparable
    /// with the full-mesh solver.
    pub fn full_arap_energy(&self, pose: &SkeletonPose) -> f64 {
        crate::deform::arap_energy(&self.topology, &self.skin_welded(pose))
    }

    /// Sums `Q`, `K_c` and `c₀` over the mesh (in parallel over vertex chunks).
    fn reduce(&mut self) {
        let dim = 4 * self.skeleton.len();
        let clusters = self.cluster_count;
        let w = self.topology.weights(WeightMode::ClampedCotangent);
        let offsets = self.topology.offsets();
        let nbrs = self.topology.neighbor_list();
        let rest = self.topology.positions();
        let n = self.topology.vertex_count();
        let hom = |i: usize| self.bind[i].extend(1.0);
        // Partial sums over fixed chunks of vertices, in parallel, then added in chunk order:
        // the same sums on every run and any thread count (a work-stealing reduction adds in
        // whatever order the threads finish, and a balance held at the edge of its polygon
        // flipped between runs on the last bits). At most 16 chunks of at least 2 048
        // vertices: the partial sums (J² and clusters × J numbers each) are all held at once.
        let chunk_len = n.div_ceil(16).max(2048);
        let partial = |chunk: usize| {
            let (mut q, mut k, mut c0, mut degree) = (
                vec![0.0; dim * dim],
                vec![0.0; clusters * dim * 3],
                0.0,
                0.0,
            );
            for i in chunk * chunk_len..((chunk + 1) * chunk_len).min(n) {
                let range = offsets[i] as usize..offsets[i + 1] as usize;
                let vi = hom(i);
                // r_i = d_i M_i − Σ_j w_ij M_j, as joint → 4-vector.
                let mut r: Vec<(u32, DVec4)> = Vec::with_capacity(16);
                let mut add = |j: u32, v: DVec4| match r.iter_mut().find(|e| e.0 == j) {
                    Some(e) => e.1 += v,
                    None => r.push((j, v)),
                };
                let d: f64 = w[range.clone()].iter().sum();
                degree += d;
                for &(a, wa) in self.influences[i].iter().filter(|e| e.1 != 0.0) {
                    add(a, vi * (d * wa));
                }
                let kc = &mut k[self.cluster_of[i] as usize * dim * 3..][..dim * 3];
                let mut s = DVec3::ZERO;
                for e in range {
                    let j = nbrs[e] as usize;
                    let vj = hom(j);
                    let eij = rest[i] - rest[j];
                    s += eij * w[e];
                    c0 += w[e] * eij.length_squared();
                    for &(b, wb) in self.influences[j].iter().filter(|e| e.1 != 0.0) {
                        add(b, vj * (-w[e] * wb));
                        add_outer4x3(kc, b as usize, vj * (-w[e] * wb), eij);
                    }
                }
                for &(a, wa) in self.influences[i].iter().filter(|e| e.1 != 0.0) {
                    add_outer4x3(kc, a as usize, vi * wa, s);
                    let left = vi * (2.0 * wa);
                    for &(b, rb) in &r {
                        let base = (4 * a as usize) * dim + 4 * b as usize;
                        for p in 0..4 {
                            for c in 0..4 {
                                q[base + p * dim + c] += left[p] * rb[c];
                            }
                        }
                    }
                }
            }
            (q, k, c0, degree)
        };
        let chunks: Vec<_> = (0..n.div_ceil(chunk_len))
            .into_par_iter()
            .map(partial)
            .collect();
        let mut q = vec![0.0; dim * dim];
        let mut k = vec![0.0; clusters * dim * 3];
        let (mut c0, mut degree) = (0.0, 0.0);
        for (pq, pk, pc, pd) in chunks {
            q.iter_mut().zip(&pq).for_each(|(x, y)| *x += y);
            k.iter_mut().zip(&pk).for_each(|(x, y)| *x += y);
            c0 += pc;
            degree += pd;
        }
        self.q = q;
        self.k = k;
        self.c0 = c0;
        self.mean_degree = degree / n.max(1) as f64;
    }

    /// The stacked transposed skinning matrices `X` (4J × 3, row-major) of `pose`.
    /// (`x` is resized; its allocation is reused.)
    pub(crate) fn stack_into(&self, matrices: &[DAffine3], x: &mut Vec<f64>) {
        x.clear();
        x.resize(matrices.len() * 12, 0.0);
        for (k, m) in matrices.iter().enumerate() {
            for c in 0..3 {
                for p in 0..3 {
                    x[(4 * k + p) * 3 + c] = m.matrix3.col(p)[c];
                }
                x[(4 * k + 3) * 3 + c] = m.translation[c];
            }
        }
    }

    /// Row `M_i` of vertex `i` as (joint, weight · homogeneous bind position) entries.
    pub(crate) fn row(&self, i: usize) -> impl Iterator<Item = (usize, DVec4)> + '_ {
        let v = self.bind[i].extend(1.0);
        self.influences[i]
            .iter()
            .filter(|e| e.1 != 0.0)
            .map(move |&(j, w)| (j as usize, v * w))
    }
}

/// Adds `u vᵀ` (4 × 3) to block `joint` of a (4J × 3, row-major) matrix.
pub(crate) fn add_outer4x3(m: &mut [f64], joint: usize, u: DVec4, v: DVec3) {
    for p in 0..4 {
        for c in 0..3 {
            m[(4 * joint + p) * 3 + c] += u[p] * v[c];
        }
    }
}

/// Median uniform scale (cube root of |det|) of the skinning matrices of the joints that move
/// vertices.
fn uniform_scale(
    skeleton: &Skeleton,
    pose: &SkeletonPose,
    influences: &[VertexInfluences],
) -> Result<f64, PoseError> {
    let m = skeleton.skinning_matrices(pose);
    let mut used = vec![false; skeleton.len()];
    for inf in influences {
        for &(j, w) in inf {
            if w != 0.0 {
                used[j as usize] = true;
            }
        }
    }
    let mut scales: Vec<f64> = (0..skeleton.len())
        .filter(|&j| used[j])
        .map(|j| m[j].matrix3.determinant().abs().cbrt())
        .collect();
    scales.sort_by(f64::total_cmp);
    let s = scales.get(scales.len() / 2).copied().unwrap_or(1.0);
    if s.is_finite() && s > 0.0 {
        Ok(s)
    } else {
        Err(PoseError::DegenerateSkinning)
    }
}

/// Weighted k-means of the vertices' weight vectors (Lloyd's iterations from a farthest-point
/// start). Returns each vertex' cluster and the number of (non-empty) clusters.
fn cluster_weights(
    influences: &[VertexInfluences],
    joints: usize,
    wanted: usize,
    iterations: u32,
) -> (Vec<u32>, usize) {
    let n = influences.len();
    let wanted = wanted.clamp(1, n.max(1));
    let norm2 = |inf: &VertexInfluences| inf.iter().map(|e| e.1 * e.1).sum::<f64>();
    let dist = |inf: &VertexInfluences, c: &[f64], c_norm2: f64| {
        c_norm2 + norm2(inf) - 2.0 * inf.iter().map(|&(j, w)| w * c[j as usize]).sum::<f64>()
    };
    let dense = |inf: &VertexInfluences| {
        let mut c = vec![0.0; joints];
        for &(j, w) in inf {
            c[j as usize] += w;
        }
        c
    };
    // Farthest-point seeding.
    let mut centres: Vec<Vec<f64>> = vec![dense(&influences[0])];
    let mut nearest: Vec<f64> = {
        let c = &centres[0];
        let cn = c.iter().map(|x| x * x).sum();
        influences.par_iter().map(|inf| dist(inf, c, cn)).collect()
    };
    while centres.len() < wanted {
        let (far, d) = nearest
            .iter()
            .enumerate()
            .fold((0, -1.0), |b, (i, &d)| if d > b.1 { (i, d) } else { b });
        if d <= 1e-12 {
            break;
        }
        let c = dense(&influences[far]);
        let cn = c.iter().map(|x| x * x).sum();
        nearest
            .par_iter_mut()
            .zip(influences.par_iter())
            .for_each(|(m, inf)| *m = m.min(dist(inf, &c, cn)));
        centres.push(c);
    }
    let mut assign = vec![0u32; n];
    for _ in 0..iterations.max(1) {
        let norms: Vec<f64> = centres
            .iter()
            .map(|c| c.iter().map(|x| x * x).sum())
            .collect();
        let next: Vec<u32> = influences
            .par_iter()
            .map(|inf| {
                let mut best = (0u32, f64::MAX);
                for (ci, c) in centres.iter().enumerate() {
                    let d = dist(inf, c, norms[ci]);
                    if d < best.1 {
                        best = (ci as u32, d);
                    }
                }
                best.0
            })
            .collect();
        let changed = next != assign;
        assign = next;
        let mut sums = vec![vec![0.0; joints]; centres.len()];
        let mut counts = vec![0usize; centres.len()];
        for (inf, &c) in influences.iter().zip(&assign) {
            counts[c as usize] += 1;
            for &(j, w) in inf {
                sums[c as usize][j as usize] += w;
            }
        }
        for ((c, s), &count) in centres.iter_mut().zip(sums).zip(&counts) {
            if count > 0 {
                *c = s.into_iter().map(|x| x / count as f64).collect();
            }
        }
        if !changed {
            break;
        }
    }
    // Renumber without empty clusters.
    let mut renumber = vec![u32::MAX; centres.len()];
    let mut count = 0u32;
    for a in &mut assign {
        if renumber[*a as usize] == u32::MAX {
            renumber[*a as usize] = count;
            count += 1;
        }
        *a = renumber[*a as usize];
    }
    (assign, count as usize)
}

/// `DMat3` from a row-major 3 × 3 slice.
pub(crate) fn mat3_from_rows(m: &[f64]) -> DMat3 {
    DMat3::from_cols_array(&[m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]])
}
