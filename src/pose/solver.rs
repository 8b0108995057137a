//! The skinning-space ARAP solver: rigid bones as the unknowns.

use std::sync::Arc;
use std::time::Instant;

use glam::{DAffine3, DMat3, DQuat, DVec3, DVec4};

use super::PoseError;
use super::model::{SkinnedModel, add_outer4x3, mat3_from_rows};
use super::skeleton::{JointTransform, SkeletonPose};
use crate::deform::{Handle, RigidTransform, best_rotation_exact};

/// A joint driven to a rigid motion of where it was in the reference pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointHandle {
    /// Joint index in the skeleton.
    pub joint: usize,
    /// Motion applied to the joint's reference world transform (pivot usually the joint's
    /// reference position).
    pub transform: RigidTransform,
}

/// What a pose solve must respect. Vertex indices are *welded* (map render indices with
/// `model.topology().welded_set(..)`). Targets are rigid motions of where the vertices (or
/// joints) were in the reference pose given to [`PoseSolver::new`]. The *sets* fix the
/// precompute; the transforms may change every solve.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseConstraints {
    /// Vertex sets moved rigidly (grab the hand's vertices).
    pub handles: Vec<Handle>,
    /// Vertices kept where they were in the reference pose.
    pub fixed_vertices: Vec<u32>,
    /// Joints kept where they were in the reference pose, position and orientation (pin the
    /// feet).
    pub fixed_joints: Vec<usize>,
    /// Joints moved rigidly (grab the hand joint).
    pub joint_handles: Vec<JointHandle>,
}

impl PoseConstraints {
    fn same_sets(&self, other: &PoseConstraints) -> bool {
        self.fixed_vertices == other.fixed_vertices
            && self.fixed_joints == other.fixed_joints
            && self.handles.len() == other.handles.len()
            && self
                .handles
                .iter()
                .zip(&other.handles)
                .all(|(a, b)| a.vertices == b.vertices)
            && self.joint_handles.len() == other.joint_handles.len()
            && self
                .joint_handles
                .iter()
                .zip(&other.joint_handles)
                .all(|(a, b)| a.joint == b.joint)
    }
}

/// Settings of a [`PoseSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolverSettings {
    /// Stiffness of vertex constraints relative to the mesh's mean ARAP stiffness per vertex.
    /// Constraints are soft (a skeleton cannot always reach every target); at the default a
    /// reachable target is met to ~1e-4 of the model size.
    pub constraint_stiffness: f64,
    /// Stiffness of a joint constraint, in vertex constraints (a pinned joint weighs as much
    /// as this many pinned vertices).
    pub joint_stiffness: f64,
}

impl Default for PoseSolverSettings {
    fn default() -> Self {
        Self {
            constraint_stiffness: 1e4,
            joint_stiffness: 200.0,
        }
    }
}

/// Per-solve options (the same shape as [`crate::deform::SolveOptions`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolveOptions {
    /// Maximum local/global iterations.
    pub max_iterations: u32,
    /// Stop when the relative energy decrease of one iteration falls below this (0 = never).
    pub tolerance: f64,
}

impl Default for PoseSolveOptions {
    fn default() -> Self {
        Self {
            max_iterations: 10,
            tolerance: 1e-6,
        }
    }
}

/// Statistics of one pose solve.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseSolveStats {
    /// Iterations done.
    pub iterations: u32,
    /// Objective of the start pose (ARAP with the start's cluster rotations + constraint
    /// penalties), normalised by the rest energy scale `Σ w‖e‖²`.
    pub initial_energy: f64,
    /// Normalised objective after each iteration; never rises.
    pub energies: Vec<f64>,
    /// Total seconds.
    pub total_s: f64,
    /// The cancel callback stopped the iterations early (the result is the last completed
    /// iteration).
    pub cancelled: bool,
}

/// A solved pose.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseSolution {
    /// The skeleton pose: local transforms, bones at their reference lengths.
    pub pose: SkeletonPose,
    /// Best-fit rotation of each cluster (warm-start data).
    pub cluster_rotations: Vec<DQuat>,
    /// Statistics.
    pub stats: PoseSolveStats,
}

/// A vertex set's precomputed sums for a rigid target: `Σ M_iᵀ p_iᵀ`, `Σ M_iᵀ`, `Σ p_i`,
/// `Σ ‖p_i‖²` with `p_i` the reference positions.
#[derive(Debug, Clone)]
struct SetSums {
    mp: Vec<f64>,
    m: Vec<f64>,
    p: DVec3,
    pp: f64,
    count: f64,
}

/// A factorized pose problem for one skinned model and one constraint set.
///
/// **How the result stays a skeleton.** The unknowns are not free affine joint transforms
/// but rigid bones: a world-space rotation increment per joint (about the joint's origin)
/// and a translation per root joint. Non-root joints keep their local translations (and
/// scales), so every bone keeps its length and every child stays attached to its parent by
/// construction. Each iteration fits one rotation per weight cluster (local step), then
/// takes one Gauss–Newton step on the bone rotations against the reduced energy, with a
/// backtracking line search so the energy never rises (global step). Both steps cost
/// O(joints² + clusters · joints), independent of the vertex count.
#[derive(Debug, Clone)]
pub struct PoseSolver {
    model: Arc<SkinnedModel>,
    constraints: PoseConstraints,
    reference_globals: Vec<DAffine3>,
    /// `Q` plus the constraint penalties (4J × 4J).
    q: Vec<f64>,
    /// Which 4 × 4 blocks of `q` are non-zero.
    block_nonzero: Vec<bool>,
    handle_sums: Vec<SetSums>,
    fixed_b: Vec<f64>,
    fixed_c: f64,
    joint_u: Vec<[DVec4; 4]>,
    vertex_weight: f64,
    joint_weight: f64,
    length_scale: f64,
}

impl PoseSolver {
    /// Precomputes the constraint penalties for `constraints` with targets relative to
    /// `reference` (usually the pose the character is in when the grab starts).
    pub fn new(
        model: Arc<SkinnedModel>,
        constraints: &PoseConstraints,
        reference: &SkeletonPose,
        settings: PoseSolverSettings,
    ) -> Result<Self, PoseError> {
        let skeleton = model.skeleton();
        skeleton.check_pose(reference)?;
        let n = model.topology().vertex_count();
        let joints = skeleton.len();
        let dim = 4 * joints;
        let check_vertex = |v: u32| {
            if (v as usize) < n {
                Ok(())
            } else {
                Err(PoseError::VertexOutOfRange {
                    vertex: v,
                    vertex_count: n,
                })
            }
        };
        for &v in constraints
            .fixed_vertices
            .iter()
            .chain(constraints.handles.iter().flat_map(|h| &h.vertices))
        {
            check_vertex(v)?;
        }
        for &j in constraints
            .fixed_joints
            .iter()
            .chain(constraints.joint_handles.iter().map(|h| &h.joint))
        {
            if j >= joints {
                return Err(PoseError::JointOutOfRange {
                    joint: j,
                    joint_count: joints,
                });
            }
        }
        let reference_positions = model.skin_welded(reference);
        let reference_globals = skeleton.global_transforms(reference);
        let vertex_weight = settings.constraint_stiffness * model.mean_degree.max(1e-12);
        let joint_weight = vertex_weight * settings.joint_stiffness;
        let length_scale = 0.1 * model.topology().bounding_diagonal().max(1e-12);
        let mut q = model.q.clone();
        let sums = |vertices: &[u32], q: &mut [f64]| {
            let mut s = SetSums {
                mp: vec![0.0; dim * 3],
                m: vec![0.0; dim],
                p: DVec3::ZERO,
                pp: 0.0,
                count: vertices.len() as f64,
            };
            for &v in vertices {
                let p = reference_positions[v as usize];
                let row: Vec<(usize, DVec4)> = model.row(v as usize).collect();
                for &(a, ua) in &row {
                    add_outer4x3(&mut s.mp, a, ua, p);
                    for p in 0..4 {
                        s.m[4 * a + p] += ua[p];
                    }
                    for &(b, ub) in &row {
                        let base = 4 * a * dim + 4 * b;
                        for r in 0..4 {
                            for c in 0..4 {
                                q[base + r * dim + c] += vertex_weight * ua[r] * ub[c];
                            }
                        }
                    }
                }
                s.p += p;
                s.pp += p.length_squared();
            }
            s
        };
        let handle_sums: Vec<SetSums> = constraints
            .handles
            .iter()
            .map(|h| sums(&h.vertices, &mut q))
            .collect();
        let fixed = sums(&constraints.fixed_vertices, &mut q);
        let mut fixed_b = vec![0.0; dim * 3];
        let fixed_c = set_target(
            &fixed,
            &RigidTransform::IDENTITY,
            vertex_weight,
            &mut fixed_b,
        );
        // Joint constraints: ‖(S_j N_j − G*) D‖² with N_j = inverse_bind⁻¹, D = diag(ℓ,ℓ,ℓ,1).
        let joint_u: Vec<[DVec4; 4]> = (0..joints)
            .map(|j| {
                let nj = skeleton.joints()[j].inverse_bind.inverse();
                let n4 = affine_rows(&nj);
                // U = N D: column c of U scaled by ℓ for c < 3. Store rows of U.
                std::array::from_fn(|r| {
                    DVec4::new(
                        n4[r][0] * length_scale,
                        n4[r][1] * length_scale,
                        n4[r][2] * length_scale,
                        n4[r][3],
                    )
                })
            })
            .collect();
        for &j in constraints
            .fixed_joints
            .iter()
            .chain(constraints.joint_handles.iter().map(|h| &h.joint))
        {
            let u = &joint_u[j];
            for r in 0..4 {
                for c in 0..4 {
                    q[(4 * j + r) * dim + 4 * j + c] += joint_weight * u[r].dot(u[c]);
                }
            }
        }
        let block_nonzero = (0..joints * joints)
            .map(|b| {
                let (k, l) = (b / joints, b % joints);
                (0..4).any(|r| (0..4).any(|c| q[(4 * k + r) * dim + 4 * l + c] != 0.0))
            })
            .collect();
        Ok(Self {
            model,
            constraints: constraints.clone(),
            reference_globals,
            q,
            block_nonzero,
            handle_sums,
            fixed_b,
            fixed_c,
            joint_u,
            vertex_weight,
            joint_weight,
            length_scale,
        })
    }

    /// The model.
    pub fn model(&self) -> &Arc<SkinnedModel> {
        &self.model
    }

    /// The constraints the solver was built for.
    pub fn constraints(&self) -> &PoseConstraints {
        &self.constraints
    }

    /// True when `constraints` has the same sets as the ones precomputed (only transforms
    /// differ), so [`PoseSolver::solve`] accepts it.
    pub fn accepts(&self, constraints: &PoseConstraints) -> bool {
        self.constraints.same_sets(constraints)
    }

    /// Solves for the pose from `start` (the last solution for a warm start, or the pose the
    /// character is in) and the cluster rotations of a previous solution (`None`: fitted
    /// from `start`). `cancel` is polled between iterations.
    pub fn solve(
        &self,
        constraints: &PoseConstraints,
        options: &PoseSolveOptions,
        start: &SkeletonPose,
        warm_rotations: Option<&[DQuat]>,
        cancel: &dyn Fn() -> bool,
    ) -> Result<PoseSolution, PoseError> {
        let started = Instant::now();
        if !self.accepts(constraints) {
            return Err(PoseError::ConstraintSetChanged);
        }
        let valid = |t: &RigidTransform| t.is_valid();
        if !constraints.handles.iter().all(|h| valid(&h.transform))
            || !constraints
                .joint_handles
                .iter()
                .all(|h| valid(&h.transform))
        {
            return Err(PoseError::NonFiniteTarget);
        }
        let skeleton = self.model.skeleton();
        skeleton.check_pose(start)?;
        let clusters = self.model.cluster_count();
        let mut rotations: Vec<DQuat> = match warm_rotations {
            Some(r) if r.len() == clusters => r.to_vec(),
            _ => vec![DQuat::IDENTITY; clusters],
        };
        let (b_pen, c_pen) = self.penalty_terms(constraints);
        let c0 = self.model.c0.max(1e-300);
        let mut pose = start.clone();
        let mut globals = skeleton.global_transforms(&pose);
        let mut x = self.model.stack(&skinning(&globals, skeleton));
        let mut stats = PoseSolveStats::default();
        let mut b = vec![0.0; b_pen.len()];
        let mut last = f64::NAN;
        for it in 0..options.max_iterations {
            if cancel() {
                stats.cancelled = true;
                break;
            }
            self.local_step(&x, &mut rotations);
            b.copy_from_slice(&b_pen);
            self.add_rotation_terms(&rotations, &mut b);
            let constant = self.model.c0 + c_pen;
            let f0 = self.objective(&x, &b, constant);
            if it == 0 {
                stats.initial_energy = f0 / c0;
                last = f0;
            }
            let step = self.gauss_newton_step(&x, &b, &globals);
            let mut accepted = None;
            let mut t = 1.0;
            for _ in 0..12 {
                let candidate = retract(&pose, &globals, &step, t, self);
                let cg = skeleton.global_transforms(&candidate);
                let cx = self.model.stack(&skinning(&cg, skeleton));
                let f = self.objective(&cx, &b, constant);
                if f.is_finite() && f <= f0 {
                    accepted = Some((candidate, cg, cx, f));
                    break;
                }
                t *= 0.5;
            }
            let f = match accepted {
                Some((candidate, cg, cx, f)) => {
                    pose = candidate;
                    globals = cg;
                    x = cx;
                    f
                }
                None => f0,
            };
            stats.iterations += 1;
            stats.energies.push(f / c0);
            let decrease = (last - f) / last.abs().max(1e-300);
            last = f;
            if decrease < options.tolerance && it > 0 {
                break;
            }
        }
        if !pose.local.iter().all(|t| t.is_valid()) {
            return Err(PoseError::NonFiniteResult);
        }
        stats.total_s = started.elapsed().as_secs_f64();
        Ok(PoseSolution {
            pose,
            cluster_rotations: rotations,
            stats,
        })
    }

    /// The linear (`B`, 4J × 3) and constant terms of the constraint penalties for the
    /// current targets.
    fn penalty_terms(&self, constraints: &PoseConstraints) -> (Vec<f64>, f64) {
        let mut b = self.fixed_b.clone();
        let mut c = self.fixed_c;
        for (h, s) in constraints.handles.iter().zip(&self.handle_sums) {
            c += set_target(s, &h.transform, self.vertex_weight, &mut b);
        }
        let dim = self.q.len().isqrt();
        let fixed = self
            .constraints
            .fixed_joints
            .iter()
            .map(|&j| (j, RigidTransform::IDENTITY));
        let moved = constraints
            .joint_handles
            .iter()
            .map(|h| (h.joint, h.transform));
        for (j, t) in fixed.chain(moved) {
            let g = self.reference_globals[j];
            // Rigid motion p ↦ pivot + R(p − pivot) + T as an affine: R p + (pivot − R pivot + T).
            let motion = DAffine3::from_mat3_translation(
                DMat3::from_quat(t.rotation),
                t.pivot - t.rotation * t.pivot + t.translation,
            );
            let target = motion * g;
            let v = affine_rows(&target); // 3 × 4 rows of G*
            // V = G* D; B_j += λ U Vᵀ; const += λ‖V‖².
            let vd: [DVec4; 3] = std::array::from_fn(|r| {
                DVec4::new(
                    v[r][0] * self.length_scale,
                    v[r][1] * self.length_scale,
                    v[r][2] * self.length_scale,
                    v[r][3],
                )
            });
            let u = &self.joint_u[j];
            for r in 0..4 {
                for col in 0..3 {
                    b[(4 * j + r) * 3 + col] += self.joint_weight * u[r].dot(vd[col]);
                }
            }
            c += self.joint_weight * vd.iter().map(|r| r.length_squared()).sum::<f64>();
        }
        debug_assert_eq!(dim * 3, b.len());
        (b, c)
    }

    /// Fits each cluster's rotation to the current skinning matrices: `A_c = Xᵀ K_c`.
    fn local_step(&self, x: &[f64], rotations: &mut [DQuat]) {
        let dim = x.len() / 3;
        for (c, r) in rotations.iter_mut().enumerate() {
            let k = &self.model.k[c * dim * 3..][..dim * 3];
            let mut a = [0.0; 9];
            for row in 0..dim {
                let xr = &x[row * 3..row * 3 + 3];
                let kr = &k[row * 3..row * 3 + 3];
                if kr[0] == 0.0 && kr[1] == 0.0 && kr[2] == 0.0 {
                    continue;
                }
                for i in 0..3 {
                    for j in 0..3 {
                        a[i * 3 + j] += xr[i] * kr[j];
                    }
                }
            }
            *r = best_rotation_exact(&mat3_from_rows(&a));
        }
    }

    /// `B += Σ_c K_c R_cᵀ`.
    fn add_rotation_terms(&self, rotations: &[DQuat], b: &mut [f64]) {
        let dim = b.len() / 3;
        for (c, q) in rotations.iter().enumerate() {
            let r = DMat3::from_quat(*q);
            let k = &self.model.k[c * dim * 3..][..dim * 3];
            for row in 0..dim {
                let kr = DVec3::new(k[row * 3], k[row * 3 + 1], k[row * 3 + 2]);
                if kr == DVec3::ZERO {
                    continue;
                }
                // (K Rᵀ)[row][col] = Σ_m K[row][m] R[col][m] = (R kr)[col]
                let v = r * kr;
                b[row * 3] += v.x;
                b[row * 3 + 1] += v.y;
                b[row * 3 + 2] += v.z;
            }
        }
    }

    /// `Q X` using the block structure.
    fn q_times(&self, x: &[f64]) -> Vec<f64> {
        let dim = x.len() / 3;
        let joints = dim / 4;
        let mut out = vec![0.0; dim * 3];
        for k in 0..joints {
            for l in 0..joints {
                if !self.block_nonzero[k * joints + l] {
                    continue;
                }
                for r in 0..4 {
                    let row = 4 * k + r;
                    let qrow = &self.q[row * dim + 4 * l..][..4];
                    for (c, &qv) in qrow.iter().enumerate() {
                        let xr = &x[(4 * l + c) * 3..][..3];
                        out[row * 3] += qv * xr[0];
                        out[row * 3 + 1] += qv * xr[1];
                        out[row * 3 + 2] += qv * xr[2];
                    }
                }
            }
        }
        out
    }

    /// `tr(XᵀQX) − 2 tr(XᵀB) + constant`.
    fn objective(&self, x: &[f64], b: &[f64], constant: f64) -> f64 {
        let qx = self.q_times(x);
        let mut f = constant;
        for ((xv, qv), bv) in x.iter().zip(&qx).zip(b) {
            f += xv * qv - 2.0 * xv * bv;
        }
        f.max(0.0)
    }

    /// One Gauss–Newton step on the bone parameters (rotation increments, root
    /// translations), as a vector of per-parameter 3-vectors.
    fn gauss_newton_step(&self, x: &[f64], b: &[f64], globals: &[DAffine3]) -> Vec<DVec3> {
        let skeleton = self.model.skeleton();
        let joints = skeleton.len();
        let dim = 4 * joints;
        let params = parameters(self);
        // S̄_k rows (4 × 4 homogeneous) from X.
        let s_bar: Vec<[[f64; 4]; 4]> = (0..joints)
            .map(|k| {
                let mut s = [[0.0; 4]; 4];
                for (r, row) in s.iter_mut().enumerate().take(3) {
                    for (p, v) in row.iter_mut().enumerate() {
                        *v = x[(4 * k + p) * 3 + r];
                    }
                }
                s[3][3] = 1.0;
                s
            })
            .collect();
        let qx = self.q_times(x);
        // Gradient per joint: g_k[g] = 2 tr(G_g S̄_k Γ_k), Γ = QX − B.
        let mut gsum: Vec<[f64; 6]> = (0..joints)
            .map(|k| {
                let mut p = [[0.0; 3]; 4];
                for (r, pr) in p.iter_mut().enumerate() {
                    for (c, v) in pr.iter_mut().enumerate() {
                        *v = (0..4)
                            .map(|m| {
                                let row = (4 * k + m) * 3 + c;
                                s_bar[k][r][m] * (qx[row] - b[row])
                            })
                            .sum();
                    }
                }
                let mut g = [0.0; 6];
                for (gi, generator) in GENERATORS.iter().enumerate() {
                    g[gi] = 2.0
                        * generator
                            .iter()
                            .map(|&(i, p_, a)| a * p[p_][i])
                            .sum::<f64>();
                }
                g
            })
            .collect();
        for k in (0..joints).rev() {
            if let Some(p) = skeleton.joints()[k].parent {
                let gk = gsum[k];
                for (a, v) in gsum[p].iter_mut().zip(gk) {
                    *a += v;
                }
            }
        }
        // Hessian blocks M_kl[g][h] = tr(G_g N_kl G_hᵀ), N_kl = S̄_k Q_kl S̄_lᵀ, summed over
        // subtrees: Z[a][b] = Σ_{k∈sub(a), l∈sub(b)} M_kl.
        let mut z = vec![[[0.0; 6]; 6]; joints * joints];
        for k in 0..joints {
            for l in 0..joints {
                if !self.block_nonzero[k * joints + l] {
                    continue;
                }
                let mut qs = [[0.0; 4]; 4]; // Q_kl S̄_lᵀ
                for (r, row) in qs.iter_mut().enumerate() {
                    for (c, v) in row.iter_mut().enumerate() {
                        *v = (0..4)
                            .map(|m| self.q[(4 * k + r) * dim + 4 * l + m] * s_bar[l][c][m])
                            .sum();
                    }
                }
                let mut nkl = [[0.0; 4]; 4];
                for (r, row) in nkl.iter_mut().enumerate() {
                    for (c, v) in row.iter_mut().enumerate() {
                        *v = (0..4).map(|m| s_bar[k][r][m] * qs[m][c]).sum();
                    }
                }
                let m = &mut z[k * joints + l];
                for (gi, gg) in GENERATORS.iter().enumerate() {
                    for (hi, gh) in GENERATORS.iter().enumerate() {
                        let mut t = 0.0;
                        for &(i, p, a) in gg.iter() {
                            for &(i2, q, bq) in gh.iter() {
                                if i == i2 {
                                    t += a * bq * nkl[p][q];
                                }
                            }
                        }
                        m[gi][hi] += t;
                    }
                }
            }
        }
        for l in (0..joints).rev() {
            if let Some(p) = skeleton.joints()[l].parent {
                for k in 0..joints {
                    let v = z[k * joints + l];
                    add6(&mut z[k * joints + p], &v);
                }
            }
        }
        for k in (0..joints).rev() {
            if let Some(p) = skeleton.joints()[k].parent {
                for l in 0..joints {
                    let v = z[k * joints + l];
                    add6(&mut z[p * joints + l], &v);
                }
            }
        }
        // Parameter maps A (6 × 3): rotation about o: [I; [o]×]; root translation: [0; I].
        let maps: Vec<[[f64; 3]; 6]> = params
            .iter()
            .map(|&(j, kind)| {
                let mut a = [[0.0; 3]; 6];
                match kind {
                    ParamKind::Rotation => {
                        let o = globals[j].translation;
                        for (i, row) in a.iter_mut().enumerate().take(3) {
                            row[i] = 1.0;
                        }
                        // v = o × δ: rows 3..6 = [o]×
                        a[3] = [0.0, -o.z, o.y];
                        a[4] = [o.z, 0.0, -o.x];
                        a[5] = [-o.y, o.x, 0.0];
                    }
                    ParamKind::Translation => {
                        for i in 0..3 {
                            a[3 + i][i] = 1.0;
                        }
                    }
                }
                a
            })
            .collect();
        let np = params.len() * 3;
        let mut h = vec![0.0; np * np];
        let mut g = vec![0.0; np];
        for (pa, &(ja, _)) in params.iter().enumerate() {
            for r in 0..3 {
                g[pa * 3 + r] = (0..6).map(|s| maps[pa][s][r] * gsum[ja][s]).sum();
            }
            for (pb, &(jb, _)) in params.iter().enumerate() {
                let zab = &z[ja * joints + jb];
                // A_aᵀ Z A_b
                let mut za = [[0.0; 3]; 6];
                for s in 0..6 {
                    for c in 0..3 {
                        za[s][c] = (0..6).map(|t| zab[s][t] * maps[pb][t][c]).sum();
                    }
                }
                for r in 0..3 {
                    for c in 0..3 {
                        h[(pa * 3 + r) * np + pb * 3 + c] =
                            2.0 * (0..6).map(|s| maps[pa][s][r] * za[s][c]).sum::<f64>();
                    }
                }
            }
        }
        let delta = solve_damped(&mut h, &g, np);
        (0..params.len())
            .map(|p| DVec3::new(delta[3 * p], delta[3 * p + 1], delta[3 * p + 2]))
            .collect()
    }
}

/// The 6 twist generators (ω_x, ω_y, ω_z, v_x, v_y, v_z) as 3 × 4 matrices, listed as
/// (row, column, value) non-zeros: `dS = Σ ξ_g G_g S̄`.
const GENERATORS: [&[(usize, usize, f64)]; 6] = [
    &[(1, 2, -1.0), (2, 1, 1.0)],
    &[(0, 2, 1.0), (2, 0, -1.0)],
    &[(0, 1, -1.0), (1, 0, 1.0)],
    &[(0, 3, 1.0)],
    &[(1, 3, 1.0)],
    &[(2, 3, 1.0)],
];

#[derive(Debug, Clone, Copy, PartialEq)]
enum ParamKind {
    Rotation,
    Translation,
}

/// The bone parameters: a rotation per joint, a translation per root.
fn parameters(solver: &PoseSolver) -> Vec<(usize, ParamKind)> {
    let skeleton = solver.model.skeleton();
    let mut out: Vec<(usize, ParamKind)> = (0..skeleton.len())
        .map(|j| (j, ParamKind::Rotation))
        .collect();
    out.extend(
        (0..skeleton.len())
            .filter(|&j| skeleton.joints()[j].parent.is_none())
            .map(|j| (j, ParamKind::Translation)),
    );
    out
}

/// Applies `t · step` to `pose`: rotation increments (world space, about each joint) become
/// local rotation changes; root translations move the roots.
fn retract(
    pose: &SkeletonPose,
    globals: &[DAffine3],
    step: &[DVec3],
    t: f64,
    solver: &PoseSolver,
) -> SkeletonPose {
    let skeleton = solver.model.skeleton();
    let mut out = pose.clone();
    for (p, &(j, kind)) in parameters(solver).iter().enumerate() {
        let d = step[p] * t;
        let local: &mut JointTransform = &mut out.local[j];
        match kind {
            ParamKind::Rotation => {
                let qp = skeleton.parent_rotation(globals, j);
                let inc = qp.inverse() * DQuat::from_scaled_axis(d) * qp;
                local.rotation = (inc * local.rotation).normalize();
            }
            ParamKind::Translation => {
                let lin = skeleton.parent_linear(globals, j);
                if lin.determinant().abs() > 1e-300 {
                    local.translation += lin.inverse() * d;
                }
            }
        }
    }
    out
}

fn skinning(globals: &[DAffine3], skeleton: &super::Skeleton) -> Vec<DAffine3> {
    globals
        .iter()
        .zip(skeleton.joints())
        .map(|(g, j)| *g * j.inverse_bind)
        .collect()
}

fn add6(a: &mut [[f64; 6]; 6], b: &[[f64; 6]; 6]) {
    for (ra, rb) in a.iter_mut().zip(b) {
        for (x, y) in ra.iter_mut().zip(rb) {
            *x += y;
        }
    }
}

/// Rows of an affine as a 4 × 4 matrix (last row 0 0 0 1).
fn affine_rows(a: &DAffine3) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for (r, row) in m.iter_mut().enumerate().take(3) {
        for c in 0..3 {
            row[c] = a.matrix3.col(c)[r];
        }
        row[3] = a.translation[r];
    }
    m[3][3] = 1.0;
    m
}

/// Adds `λ Σ M_iᵀ t_iᵀ` for targets `t_i = motion(p_i)` to `b`; returns `λ Σ ‖t_i‖²`.
fn set_target(s: &SetSums, motion: &RigidTransform, weight: f64, b: &mut [f64]) -> f64 {
    if s.count == 0.0 {
        return 0.0;
    }
    let r = DMat3::from_quat(motion.rotation);
    let c = motion.pivot - r * motion.pivot + motion.translation;
    // Σ M_iᵀ (R p_i + c)ᵀ = (Σ M_iᵀ p_iᵀ) Rᵀ + (Σ M_iᵀ) cᵀ
    for (row, m) in s.m.iter().enumerate() {
        let mp = DVec3::new(s.mp[row * 3], s.mp[row * 3 + 1], s.mp[row * 3 + 2]);
        let v = r * mp + c * *m;
        b[row * 3] += weight * v.x;
        b[row * 3 + 1] += weight * v.y;
        b[row * 3 + 2] += weight * v.z;
    }
    weight * (s.pp + 2.0 * c.dot(r * s.p) + s.count * c.length_squared())
}

/// Solves `(H + μ I) x = −g` by Cholesky, raising `μ` until `H + μ I` is positive definite.
fn solve_damped(h: &mut [f64], g: &[f64], n: usize) -> Vec<f64> {
    let scale = (0..n)
        .map(|i| h[i * n + i])
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let mut mu = 1e-9 * scale;
    let original = h.to_vec();
    for _ in 0..12 {
        h.copy_from_slice(&original);
        for i in 0..n {
            h[i * n + i] += mu;
        }
        if cholesky_in_place(h, n) {
            let mut x: Vec<f64> = g.iter().map(|v| -v).collect();
            // L y = b, Lᵀ x = y
            for i in 0..n {
                let mut s = x[i];
                for k in 0..i {
                    s -= h[i * n + k] * x[k];
                }
                x[i] = s / h[i * n + i];
            }
            for i in (0..n).rev() {
                let mut s = x[i];
                for k in i + 1..n {
                    s -= h[k * n + i] * x[k];
                }
                x[i] = s / h[i * n + i];
            }
            if x.iter().all(|v| v.is_finite()) {
                return x;
            }
        }
        mu *= 100.0;
    }
    vec![0.0; n]
}

/// Lower Cholesky factor in place (row-major, lower triangle); false if not positive definite.
fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if !(d > 0.0) {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    true
}
