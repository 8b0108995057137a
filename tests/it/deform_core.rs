//! Integration tests of the deformation core against independent references.

use crate::common::shared;

use std::sync::Arc;

use bevy_wii_deform::deform::*;
use glam::{DMat3, DQuat, DVec3};

fn topo(mesh: &TriMesh) -> Arc<Topology> {
    Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap())
}

fn bend_problem(topology: &Topology, angle: f64) -> Constraints {
    synth::bend_problem(topology.positions(), angle, DVec3::new(0.3, -0.1, 0.05))
}

const NEVER: &dyn Fn() -> bool = &|| false;

/// The largest distance between corresponding points of `a` and `b`.
fn max_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f64::max)
}

#[test]
fn one_rigid_transform_everywhere_reproduces_it() {
    let mesh = synth::icosphere(3, 1.0);
    let t = topo(&mesh);
    let motion = RigidTransform::new(
        DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.1),
        DVec3::new(0.5, -2.0, 1.0),
        DVec3::new(0.1, 0.2, 0.3),
    );
    // Two handles and a target, all from the same rigid motion; nothing fixed at rest.
    let n = t.vertex_count() as u32;
    let constraints = Constraints {
        fixed: vec![],
        handles: vec![
            Handle {
                vertices: (0..10).collect(),
                transform: motion,
            },
            Handle {
                vertices: (n - 10..n).collect(),
                transform: motion,
            },
        ],
        targets: vec![(300, motion.apply(t.positions()[300]))],
    };
    let solver =
        ArapSolver::precompute(t.clone(), &constraints, SolverSettings::default()).unwrap();
    let options = SolveOptions {
        max_iterations: 200,
        tolerance: 0.0,
        ..Default::default()
    };
    let sol = solver
        .solve(&constraints, &options, InitialGuess::Laplacian, NEVER)
        .unwrap();
    let err = sol
        .positions
        .iter()
        .zip(t.positions())
        .map(|(p, r)| (*p - motion.apply(*r)).length())
        .fold(0.0, f64::max);
    assert!(err < 1e-6, "max deviation from the rigid motion {err}");
    assert!(arap_energy(&t, &sol.positions) < 1e-12);
    // Cell rotations equal the motion's rotation.
    let q = sol.rotations[42];
    assert!(q.dot(motion.rotation).abs() > 1.0 - 1e-9);
}

#[test]
fn energy_never_increases_across_iterations() {
    for mesh in [synth::bar(24, 60, 0.1, 1.0), synth::icosphere(3, 1.0)] {
        let t = topo(&mesh);
        let c = bend_problem(&t, 1.2);
        let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
        for init in [InitialGuess::Laplacian, InitialGuess::Rest] {
            let sol = solver
                .solve(
                    &c,
                    &SolveOptions {
                        max_iterations: 30,
                        tolerance: 0.0,
                        ..Default::default()
                    },
                    init,
                    NEVER,
                )
                .unwrap();
            let mut prev = sol.stats.initial_energy.unwrap_or(f64::INFINITY);
            for &e in &sol.stats.energies {
                assert!(
                    e <= prev * (1.0 + 1e-9) + 1e-15,
                    "energy rose {prev} -> {e}"
                );
                prev = e;
            }
            // The solver's bookkeeping agrees with the public exact energy.
            let exact = arap_energy(&t, &sol.positions);
            assert!((exact - sol.stats.final_energy()).abs() <= 1e-9 * exact.max(1e-12));
        }
    }
}

#[allow(clippy::needless_range_loop)] // dense matrix indices read as the math
/// Dense reference: full Laplacian with constrained rows eliminated, Gaussian elimination,
/// exact rotations. Independent of faer and of the warm rotation fit.
fn dense_reference(t: &Topology, c: &Constraints, iterations: usize) -> Vec<DVec3> {
    let n = t.vertex_count();
    let rest = t.positions();
    let w = t.weights(WeightMode::ClampedCotangent);
    let mut known = vec![None; n];
    for &v in &c.fixed {
        known[v as usize] = Some(rest[v as usize]);
    }
    for h in &c.handles {
        for &v in &h.vertices {
            known[v as usize] = Some(h.transform.apply(rest[v as usize]));
        }
    }
    let free: Vec<usize> = (0..n).filter(|&i| known[i].is_none()).collect();
    let fidx: Vec<Option<usize>> = {
        let mut m = vec![None; n];
        for (f, &i) in free.iter().enumerate() {
            m[i] = Some(f);
        }
        m
    };
    let nf = free.len();
    let mut a = vec![vec![0.0f64; nf]; nf];
    for (f, &i) in free.iter().enumerate() {
        for (e, &j) in t.neighbors(i).iter().enumerate() {
            let we = w[t.offsets()[i] as usize + e];
            a[f][f] += we;
            if let Some(g) = fidx[j as usize] {
                a[f][g] -= we;
            }
        }
    }
    let mut x: Vec<DVec3> = (0..n).map(|i| known[i].unwrap_or(rest[i])).collect();
    let mut rots = vec![DMat3::IDENTITY; n];
    for it in 0..=iterations {
        if it > 0 {
            for i in 0..n {
                let mut cov = DMat3::ZERO;
                for (e, &j) in t.neighbors(i).iter().enumerate() {
                    let we = w[t.offsets()[i] as usize + e];
                    let d = x[i] - x[j as usize];
                    let r = rest[i] - rest[j as usize];
                    cov += DMat3::from_cols(d * r.x, d * r.y, d * r.z) * we;
                }
                rots[i] = DMat3::from_quat(best_rotation_exact(&cov));
            }
        }
        if it == iterations {
            break;
        }
        let mut m = a.clone();
        let mut b: Vec<DVec3> = free
            .iter()
            .map(|&i| {
                let mut b = DVec3::ZERO;
                for (e, &j) in t.neighbors(i).iter().enumerate() {
                    let we = w[t.offsets()[i] as usize + e];
                    let j = j as usize;
                    b += 0.5 * we * ((rots[i] + rots[j]) * (rest[i] - rest[j]));
                    if fidx[j].is_none() {
                        b += we * x[j];
                    }
                }
                b
            })
            .collect();
        // Gaussian elimination with partial pivoting.
        for k in 0..nf {
            let p = (k..nf)
                .max_by(|&r, &s| m[r][k].abs().total_cmp(&m[s][k].abs()))
                .unwrap();
            m.swap(k, p);
            b.swap(k, p);
            for r in k + 1..nf {
                let f = m[r][k] / m[k][k];
                if f != 0.0 {
                    for col in k..nf {
                        m[r][col] -= f * m[k][col];
                    }
                    b[r] = b[r] - f * b[k];
                }
            }
        }
        for k in (0..nf).rev() {
            let mut s = b[k];
            for col in k + 1..nf {
                s -= m[k][col] * b[col];
            }
            b[k] = s / m[k][k];
        }
        for (f, &i) in free.iter().enumerate() {
            x[i] = b[f];
        }
    }
    x
}

/// The bar with its vertices stored in a scrambled order (so the solver renumbers them for
/// locality instead of keeping the file order).
fn scrambled(mesh: &TriMesh) -> TriMesh {
    let n = mesh.positions.len();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut seed = 12345u64;
    for i in (1..n).rev() {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        order.swap(i, (seed >> 33) as usize % (i + 1));
    }
    let mut slot = vec![0u32; n];
    for (k, &v) in order.iter().enumerate() {
        slot[v as usize] = k as u32;
    }
    TriMesh {
        positions: order.iter().map(|&v| mesh.positions[v as usize]).collect(),
        triangles: mesh
            .triangles
            .iter()
            .map(|t| t.map(|v| slot[v as usize]))
            .collect(),
    }
}

#[test]
fn matches_dense_reference_solve() {
    let bar = synth::bar(10, 12, 0.1, 1.0);
    for mesh in [bar.clone(), scrambled(&bar)] {
        matches_dense_reference_on(&mesh);
    }
}

fn matches_dense_reference_on(mesh: &TriMesh) {
    let t = topo(mesh);
    let c = bend_problem(&t, 0.9);
    let iterations = 6;
    let reference = dense_reference(&t, &c, iterations);
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    let sol = solver
        .solve(
            &c,
            &SolveOptions {
                max_iterations: iterations as u32,
                tolerance: 0.0,
                // The reference is the plain local/global map.
                acceleration: Acceleration::None,
            },
            InitialGuess::Rest,
            NEVER,
        )
        .unwrap();
    assert_eq!(sol.stats.iterations, iterations as u32);
    let scale = t.bounding_diagonal();
    let err = max_distance(&sol.positions, &reference);
    assert!(
        err <= 1e-8 * scale,
        "max deviation {err} vs dense reference"
    );
}

#[test]
fn split_cube_deforms_without_gaps() {
    // A cube with 4 vertices per face (24 render vertices, split at every edge).
    let faces: [(DVec3, DVec3, DVec3); 6] = [
        (DVec3::X, DVec3::Y, DVec3::Z),
        (-DVec3::X, DVec3::Z, DVec3::Y),
        (DVec3::Y, DVec3::Z, DVec3::X),
        (-DVec3::Y, DVec3::X, DVec3::Z),
        (DVec3::Z, DVec3::X, DVec3::Y),
        (-DVec3::Z, DVec3::Y, DVec3::X),
    ];
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (n, u, v) in faces {
        let base = positions.len() as u32;
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            positions.push((n + u * a + v * b).as_vec3());
        }
        indices.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    let t = Arc::new(Topology::from_render_mesh(&positions, &indices).unwrap());
    assert_eq!(t.vertex_count(), 8);
    let bottom: Vec<u32> = (0..8)
        .filter(|&i| t.positions()[i as usize].y < 0.0)
        .collect();
    let top: Vec<u32> = (0..8)
        .filter(|&i| t.positions()[i as usize].y > 0.0)
        .collect();
    let c = Constraints {
        fixed: bottom[..2].to_vec(),
        handles: vec![Handle {
            vertices: top[..2].to_vec(),
            transform: RigidTransform::new(DQuat::IDENTITY, DVec3::new(0.5, 0.5, 0.0), DVec3::ZERO),
        }],
        targets: vec![],
    };
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    let sol = solver
        .solve(&c, &SolveOptions::default(), InitialGuess::Laplacian, NEVER)
        .unwrap();
    let render = t.to_render(&sol.positions);
    let mut moved = false;
    for a in 0..positions.len() {
        for b in 0..positions.len() {
            if positions[a] == positions[b] {
                assert_eq!(
                    render[a], render[b],
                    "gap between render vertices {a} and {b}"
                );
            }
        }
        moved |= (render[a] - positions[a].as_dvec3()).length() > 1e-3;
    }
    assert!(moved);
}

#[test]
fn disconnected_and_isolated_parts_keep_rest_pose() {
    let mut a = synth::icosphere(2, 1.0);
    let b = synth::icosphere(1, 0.5);
    let off = a.positions.len() as u32;
    a.positions
        .extend(b.positions.iter().map(|p| *p + DVec3::new(5.0, 0.0, 0.0)));
    a.triangles
        .extend(b.triangles.iter().map(|t| t.map(|i| i + off)));
    a.positions.push(DVec3::splat(9.0)); // isolated vertex
    let t = topo(&a);
    let c = Constraints::with_handle(
        vec![0, 1],
        vec![50, 51],
        RigidTransform::new(DQuat::IDENTITY, DVec3::Y, DVec3::ZERO),
    );
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    assert_eq!(
        solver.precompute_stats().unconstrained_component_vertices,
        b.positions.len() + 1
    );
    let sol = solver
        .solve(&c, &SolveOptions::default(), InitialGuess::Laplacian, NEVER)
        .unwrap();
    for i in off as usize..t.vertex_count() {
        assert_eq!(sol.positions[i], t.positions()[i]);
    }
    assert!(sol.positions[100].distance(t.positions()[100]) > 1e-3);
}

#[test]
fn empty_constraints_return_the_rest_pose() {
    let t = topo(&synth::icosphere(1, 1.0));
    let c = Constraints::default();
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    let sol = solver
        .solve(&c, &SolveOptions::default(), InitialGuess::Laplacian, NEVER)
        .unwrap();
    assert_eq!(sol.positions, t.positions());
}

#[test]
fn bad_constraints_are_typed_errors() {
    let t = topo(&synth::icosphere(1, 1.0));
    let overlap = Constraints::with_handle(vec![1, 2], vec![2, 3], RigidTransform::IDENTITY);
    assert!(matches!(
        ArapSolver::precompute(t.clone(), &overlap, SolverSettings::default()),
        Err(SolveError::Constraint(ConstraintError::Overlap {
            vertex: 2
        }))
    ));
    let out = Constraints::with_handle(vec![1], vec![9999], RigidTransform::IDENTITY);
    assert!(matches!(
        ArapSolver::precompute(t.clone(), &out, SolverSettings::default()),
        Err(SolveError::Constraint(ConstraintError::OutOfRange { .. }))
    ));
    let good = Constraints::with_handle(vec![1], vec![30], RigidTransform::IDENTITY);
    let solver = ArapSolver::precompute(t.clone(), &good, SolverSettings::default()).unwrap();
    let mut nan = good.clone();
    nan.handles[0].transform.translation.y = f64::NAN;
    assert!(matches!(
        solver.solve(
            &nan,
            &SolveOptions::default(),
            InitialGuess::Laplacian,
            NEVER
        ),
        Err(SolveError::Constraint(ConstraintError::NonFinite))
    ));
    let other = Constraints::with_handle(vec![1], vec![31], RigidTransform::IDENTITY);
    assert_eq!(
        solver
            .solve(
                &other,
                &SolveOptions::default(),
                InitialGuess::Laplacian,
                NEVER
            )
            .unwrap_err(),
        SolveError::ConstraintSetChanged
    );
    assert_eq!(
        solver
            .solve(
                &good,
                &SolveOptions::default(),
                InitialGuess::Laplacian,
                &|| true
            )
            .unwrap_err(),
        SolveError::Cancelled
    );
    let wrong = Solution::rest(&Topology::new(&[DVec3::ZERO], &[]).unwrap());
    assert!(matches!(
        solver.solve(
            &good,
            &SolveOptions::default(),
            InitialGuess::Warm(&wrong),
            NEVER
        ),
        Err(SolveError::WarmStartMismatch { .. })
    ));
}

#[test]
fn degenerate_triangles_never_produce_nan() {
    let mut mesh = synth::bar(12, 10, 0.1, 1.0);
    // Collapse a ring: many zero-area triangles.
    for k in 0..12 {
        mesh.positions[5 * 12 + k] = mesh.positions[5 * 12];
    }
    let t = topo(&mesh);
    let c = bend_problem(&t, 0.5);
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    let sol = solver
        .solve(&c, &SolveOptions::default(), InitialGuess::Laplacian, NEVER)
        .unwrap();
    assert!(sol.positions.iter().all(|p| p.is_finite()));
    assert!(sol.rotations.iter().all(|q| q.is_finite()));
}

#[test]
fn warm_start_reuses_factorization_and_converges_closer() {
    let t = topo(&synth::bar(16, 40, 0.1, 1.0));
    let c0 = bend_problem(&t, 0.0);
    let solver = ArapSolver::precompute(t.clone(), &c0, SolverSettings::default()).unwrap();
    // A 30-frame drag, 3 iterations a frame, warm-started, with and without acceleration.
    let drag = |anderson_depth| {
        let opts = SolveOptions {
            max_iterations: 3,
            tolerance: 0.0,
            acceleration: Acceleration::anderson(anderson_depth),
        };
        let mut c = c0.clone();
        let mut warm = solver
            .solve(&c, &opts, InitialGuess::Laplacian, NEVER)
            .unwrap();
        for k in 1..=30 {
            c.handles[0].transform.rotation = DQuat::from_rotation_z(0.04 * k as f64);
            warm = solver
                .solve(&c, &opts, InitialGuess::Warm(&warm), NEVER)
                .unwrap();
        }
        (c, arap_energy(&t, &warm.positions))
    };
    let (c, warm_plain) = drag(0);
    let (_, warm_accelerated) = drag(3);
    let plain = SolveOptions {
        max_iterations: 3,
        tolerance: 0.0,
        acceleration: Acceleration::None,
    };
    let cold = solver
        .solve(&c, &plain, InitialGuess::Laplacian, NEVER)
        .unwrap();
    let converged = solver
        .solve(
            &c,
            &SolveOptions {
                max_iterations: 500,
                tolerance: 1e-10,
                ..Default::default()
            },
            InitialGuess::Laplacian,
            NEVER,
        )
        .unwrap();
    let (ec, e0) = (
        arap_energy(&t, &cold.positions),
        arap_energy(&t, &converged.positions),
    );
    assert!(
        warm_plain < ec,
        "warm {warm_plain} should beat cold {ec} (converged {e0})"
    );
    // Three iterations a frame leave acceleration little history to work with: it must at
    // least never make the drag worse.
    assert!(
        warm_accelerated <= warm_plain * (1.0 + 1e-9),
        "acceleration {warm_accelerated} worse than plain {warm_plain} in a drag"
    );
}

#[test]
fn anderson_acceleration_lowers_the_energy_at_equal_iterations() {
    let t = topo(&synth::bar(16, 60, 0.1, 1.0));
    let c = bend_problem(&t, 1.2);
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    let run = |anderson_depth| {
        let s = solver
            .solve(
                &c,
                &SolveOptions {
                    max_iterations: 10,
                    tolerance: 0.0,
                    acceleration: Acceleration::anderson(anderson_depth),
                },
                InitialGuess::Laplacian,
                NEVER,
            )
            .unwrap();
        for w in s.stats.energies.windows(2) {
            assert!(w[1] <= w[0] * (1.0 + 1e-12), "energy rose {w:?}");
        }
        arap_energy(&t, &s.positions)
    };
    let (plain, accelerated) = (run(0), run(3));
    assert!(
        accelerated < 0.99 * plain,
        "accelerated {accelerated} vs plain {plain}"
    );
}

#[test]
fn region_of_interest_keeps_outside_at_rest() {
    let t = topo(&synth::bar(16, 40, 0.1, 1.0));
    let c = bend_problem(&t, 0.4);
    let roi: Vec<bool> = t.positions().iter().map(|p| p.y > 0.5).collect();
    let settings = SolverSettings {
        region_of_interest: Some(roi.clone()),
        ..Default::default()
    };
    let solver = ArapSolver::precompute(t.clone(), &c, settings).unwrap();
    assert!(solver.precompute_stats().free_vertices < t.vertex_count() / 2);
    let sol = solver
        .solve(&c, &SolveOptions::default(), InitialGuess::Laplacian, NEVER)
        .unwrap();
    for (i, inside) in roi.iter().enumerate() {
        if !inside {
            assert_eq!(sol.positions[i], t.positions()[i]);
        }
    }
    // The same problem with the outside stated as fixed vertices, solved by the dense
    // reference (which fits every cell, also those the solver knows are at rest). The solve is
    // warm-started from the rest pose with wrong rotations in the cells wholly outside (which
    // nothing reads): they must come back as the identity, not as the warm start's.
    let mut stated = c.clone();
    stated
        .fixed
        .extend((0..t.vertex_count() as u32).filter(|&i| !roi[i as usize]));
    stated.fixed.sort_unstable();
    stated.fixed.dedup();
    let iterations = 5;
    let reference = dense_reference(&t, &stated, iterations);
    let deep_outside = (0..t.vertex_count())
        .filter(|&i| !roi[i] && t.neighbors(i).iter().all(|&j| !roi[j as usize]))
        .collect::<Vec<_>>();
    assert!(!deep_outside.is_empty());
    let mut twisted = Solution::rest(&t);
    for &i in &deep_outside {
        twisted.rotations[i] = DQuat::from_rotation_z(0.3);
    }
    let plain = SolveOptions {
        max_iterations: iterations as u32,
        tolerance: 0.0,
        acceleration: Acceleration::None,
    };
    let from_rest = solver
        .solve(&c, &plain, InitialGuess::Warm(&twisted), NEVER)
        .unwrap();
    let err = max_distance(&from_rest.positions, &reference);
    assert!(
        err <= 1e-8 * t.bounding_diagonal(),
        "{err} from the reference"
    );
    for i in deep_outside {
        assert_eq!(from_rest.rotations[i], DQuat::IDENTITY, "cell {i}");
    }
    let bad = SolverSettings {
        region_of_interest: Some(vec![true; 3]),
        ..Default::default()
    };
    assert!(matches!(
        ArapSolver::precompute(t.clone(), &c, bad),
        Err(SolveError::Constraint(ConstraintError::RegionLength { .. }))
    ));
}

#[test]
fn factorization_variants_and_orderings_agree() {
    let t = topo(&synth::bar(20, 50, 0.1, 1.0));
    let c = bend_problem(&t, 0.7);
    let opts = SolveOptions {
        max_iterations: 4,
        tolerance: 0.0,
        ..Default::default()
    };
    let run = |factorization, ordering| {
        let s = SolverSettings {
            factorization,
            ordering,
            ..Default::default()
        };
        let solver = ArapSolver::precompute(t.clone(), &c, s).unwrap();
        let parallel = solver.precompute_stats().parallel_solves;
        let positions = solver
            .solve(&c, &opts, InitialGuess::Laplacian, NEVER)
            .unwrap()
            .positions;
        (positions, parallel)
    };
    let (a, split) = run(Factorization::Simplicial, FillOrdering::Halves);
    assert!(split, "a 1000-vertex bar is cut into two halves");
    for (f, o) in [
        (Factorization::Supernodal, FillOrdering::Halves),
        (Factorization::Simplicial, FillOrdering::MinimumDegree),
        (Factorization::Supernodal, FillOrdering::MinimumDegree),
    ] {
        let (b, parallel) = run(f, o);
        assert_eq!(parallel, o == FillOrdering::Halves);
        let d = max_distance(&a, &b);
        assert!(d < 1e-9, "{f:?} {o:?}: {d}");
    }
}

#[test]
fn raw_weights_are_an_option_and_clamped_are_default() {
    let t = topo(&synth::icosphere(2, 1.0));
    assert_eq!(
        SolverSettings::default().weights,
        WeightMode::ClampedCotangent
    );
    let c = Constraints::with_handle(vec![0], vec![5], RigidTransform::IDENTITY);
    for weights in [WeightMode::RawCotangent, WeightMode::Uniform] {
        let s = SolverSettings {
            weights,
            ..Default::default()
        };
        // On a well-shaped icosphere every cotangent weight is positive: both modes must
        // factor and solve to finite positions (a mode that fails is a bug, not an option).
        let solver = ArapSolver::precompute(t.clone(), &c, s)
            .unwrap_or_else(|e| panic!("{weights:?} does not factor: {e}"));
        let sol = solver
            .solve(&c, &SolveOptions::default(), InitialGuess::Laplacian, NEVER)
            .unwrap_or_else(|e| panic!("{weights:?} does not solve: {e}"));
        assert!(sol.positions.iter().all(|p| p.is_finite()), "{weights:?}");
    }
}

#[test]
fn shared_meshes_load_when_present() {
    let Some(dir) = shared::shared_asset("meshes") else {
        return;
    };
    for name in ["armadillo.off", "camel.off", "dino.off", "cactus.off"] {
        let m = TriMesh::read(dir.join(name)).unwrap();
        let t = Topology::new(&m.positions, &m.triangles).unwrap();
        assert!(t.vertex_count() > 500, "{name}");
        let neg = t.negative_weight_fraction();
        assert!((0.0..0.5).contains(&neg), "{name}: {neg}");
    }
}

/// Positions and triangles of every triangle primitive of a glTF file (node transforms
/// ignored: the test assets used here are single meshes at the origin).
/// `None` when the asset is absent outside CI; a file that is present but does not parse fails.
fn gltf_triangles(relative: &str) -> Option<(Vec<DVec3>, Vec<[u32; 3]>)> {
    let path = shared::shared_asset(relative)?;
    let (doc, buffers, _) =
        gltf::import(&path).unwrap_or_else(|e| panic!("{} does not import: {e}", path.display()));
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for mesh in doc.meshes() {
        for prim in mesh.primitives() {
            let reader = prim.reader(|b| Some(&buffers[b.index()]));
            let base = positions.len() as u32;
            positions.extend(
                reader
                    .read_positions()
                    .expect("a primitive without positions")
                    .map(|p| DVec3::from(p.map(f64::from))),
            );
            let idx: Vec<u32> = reader
                .read_indices()
                .expect("a primitive without indices")
                .into_u32()
                .collect();
            triangles.extend(
                idx.chunks_exact(3)
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
        }
    }
    Some((positions, triangles))
}

/// Number of triangles using each undirected edge.
fn edge_uses(triangles: &[[u32; 3]]) -> std::collections::HashMap<(u32, u32), u32> {
    let mut uses = std::collections::HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    uses
}

#[test]
fn a_gltf_sphere_split_at_its_uv_seam_welds_to_one_closed_surface() {
    let Some((positions, triangles)) = gltf_triangles("models/sphere.gltf") else {
        return;
    };
    let none = Topology::with_weld(&positions, &triangles, WeldPolicy::None).unwrap();
    let open = edge_uses(none.triangles())
        .values()
        .filter(|&&n| n == 1)
        .count();
    assert!(open > 0, "the asset is split at a seam");
    let seams = Topology::new(&positions, &triangles).unwrap();
    assert!(
        seams.vertex_count() < positions.len(),
        "{} of {}",
        seams.vertex_count(),
        positions.len()
    );
    let uses = edge_uses(seams.triangles());
    assert!(
        uses.values().all(|&n| n == 2),
        "a boundary or non-manifold edge remains after welding"
    );
    // Closed genus-0 surface: V − E + F = 2.
    let (v, e, f) = (
        seams.vertex_count() as i64,
        uses.len() as i64,
        seams.triangles().len() as i64,
    );
    assert_eq!(v - e + f, 2);
    // Seams-only welding agrees with welding everything here (no touching parts).
    let all = Topology::with_weld(&positions, &triangles, WeldPolicy::AllCoincident).unwrap();
    assert_eq!(all.vertex_count(), seams.vertex_count());
}

/// The peer CLI's path (`arap_peer`): mesh's own topology (no welding), constraints in input
/// order mapped through the weld map, output in input order.
fn solve_in_input_order(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    input: &Constraints,
) -> Vec<DVec3> {
    let topology = Arc::new(Topology::with_weld(positions, triangles, WeldPolicy::None).unwrap());
    let c = input.from_render(&topology).unwrap();
    let solver = ArapSolver::precompute(topology.clone(), &c, SolverSettings::default()).unwrap();
    let options = SolveOptions {
        max_iterations: 10,
        tolerance: 0.0,
        ..Default::default()
    };
    let s = solver
        .solve(&c, &options, InitialGuess::Laplacian, NEVER)
        .unwrap();
    topology.to_render(&s.positions)
}

#[test]
fn coincident_vertices_solve_like_vertices_a_hair_apart() {
    // Two bars side by side whose facing corners touch: bar B's first vertex is moved onto a
    // vertex of bar A, so the mesh has a coincident pair that is not a seam.
    let a = synth::bar(8, 12, 0.1, 1.0);
    let mut b = synth::bar(8, 12, 0.1, 1.0);
    let shift = a.positions[3] - b.positions[7];
    for p in &mut b.positions {
        *p += shift;
    }
    let n = a.positions.len() as u32;
    let mut positions = a.positions.clone();
    positions.extend(&b.positions);
    let mut triangles = a.triangles.clone();
    triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + n)));
    // Make the pair bit-identical (the shift above leaves a rounding difference).
    positions[(n + 7) as usize] = positions[3];
    // Fix the bottom of both bars, move the tops (input indices after the coincident pair).
    let (fixed_a, handle_a) = synth::slab_regions(&a.positions, 1, 0.1, 0.1);
    let input = Constraints {
        fixed: fixed_a
            .iter()
            .copied()
            .chain(fixed_a.iter().map(|i| i + n))
            .collect(),
        handles: vec![Handle {
            vertices: handle_a
                .iter()
                .copied()
                .chain(handle_a.iter().map(|i| i + n))
                .collect(),
            transform: RigidTransform::new(
                DQuat::from_rotation_z(0.5),
                DVec3::new(0.2, 0.0, 0.0),
                DVec3::Y,
            ),
        }],
        targets: vec![],
    };
    let together = solve_in_input_order(&positions, &triangles, &input);
    let mut apart = positions.clone();
    apart[(n + 7) as usize] += DVec3::splat(1e-9);
    let separated = solve_in_input_order(&apart, &triangles, &input);
    let diag = Topology::new(&positions, &triangles)
        .unwrap()
        .bounding_diagonal();
    let worst = max_distance(&together, &separated);
    assert!(worst < 1e-6 * diag, "worst {worst} vs diagonal {diag}");
    // The moved tops really moved (the problem is not trivial).
    let moved = handle_a
        .iter()
        .map(|&i| together[i as usize].distance(positions[i as usize]))
        .fold(0.0, f64::max);
    assert!(moved > 0.05, "{moved}");
}

#[test]
fn render_constraints_out_of_range_are_rejected() {
    let mesh = synth::bar(6, 6, 0.1, 1.0);
    let t = Topology::new(&mesh.positions, &mesh.triangles).unwrap();
    let c = Constraints {
        fixed: vec![0, mesh.positions.len() as u32],
        ..Default::default()
    };
    assert!(matches!(
        c.from_render(&t),
        Err(ConstraintError::OutOfRange { .. })
    ));
}

/// L-BFGS and truncated Newton reach the converged pose of plain local/global (to 1e-8 of the
/// diagonal), never raise the energy, and settle (the benchmark's criterion: within 1 % energy
/// and 5e-4 × the diagonal of converged) in a fraction of the plain iterations; Newton in
/// fewer iterations than L-BFGS.
#[test]
fn accelerations_reach_the_plain_converged_pose_in_fewer_iterations() {
    let t = topo(&synth::bar(8, 40, 0.1, 1.0));
    let c = bend_problem(&t, 1.0);
    let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
    let diagonal = t.bounding_diagonal();
    let solve = |iterations, acceleration| {
        let options = SolveOptions {
            max_iterations: iterations,
            tolerance: 0.0,
            acceleration,
        };
        let s = solver
            .solve(&c, &options, InitialGuess::Laplacian, NEVER)
            .unwrap();
        for w in s.stats.energies.windows(2) {
            assert!(w[1] <= w[0] * (1.0 + 1e-12), "energy rose {w:?}");
        }
        s
    };
    let lbfgs = Acceleration::Lbfgs { depth: 8 };
    let newton = Acceleration::Newton { max_cg: 30 };
    let plain_star = solve(20_000, Acceleration::None);
    let worst = |a: &Solution, b: &Solution| max_distance(&a.positions, &b.positions);
    for (name, acceleration, iterations) in [("L-BFGS", lbfgs, 2_000), ("Newton", newton, 100)] {
        let gap = worst(&plain_star, &solve(iterations, acceleration));
        assert!(
            gap <= 1e-8 * diagonal,
            "{name}: converged poses differ by {gap}"
        );
    }
    let e_star = arap_energy(&t, &plain_star.positions);
    let settled = |s: &Solution| {
        arap_energy(&t, &s.positions) <= 1.01 * e_star && worst(s, &plain_star) <= 5e-4 * diagonal
    };
    let first = |acceleration| {
        (1..=4000)
            .find(|&k| settled(&solve(k, acceleration)))
            .unwrap_or(u32::MAX)
    };
    let (plain_k, lbfgs_k, newton_k) = (first(Acceleration::None), first(lbfgs), first(newton));
    eprintln!("settled: plain {plain_k}, L-BFGS {lbfgs_k}, Newton {newton_k} iterations");
    assert!(
        lbfgs_k * 3 <= plain_k,
        "L-BFGS settles in {lbfgs_k} iterations, plain in {plain_k}"
    );
    assert!(
        newton_k * 2 <= lbfgs_k,
        "Newton settles in {newton_k} iterations, L-BFGS in {lbfgs_k}"
    );
}

/// A new constraint set on a topology that already served another (cached layout, the whole
/// mesh's elimination order restricted to the new free set) gives the result of a fresh
/// precompute: bit for bit when the fresh topology made the same whole-mesh order, within
/// 1e-10 of the diagonal when it ordered the new set on its own.
#[test]
fn a_set_change_matches_a_fresh_precompute() {
    let mesh = synth::bar(16, 40, 0.1, 1.0);
    let opts = SolveOptions {
        max_iterations: 8,
        tolerance: 0.0,
        acceleration: Acceleration::None,
    };
    // The second set frees a region of a quarter of the bar (less than half the vertices).
    let second = |t: &Topology| {
        let mut c = bend_problem(t, 0.5);
        let free_region: Vec<bool> = t.positions().iter().map(|p| p.y > 0.6).collect();
        let settings = SolverSettings {
            region_of_interest: Some(free_region),
            ..Default::default()
        };
        c.fixed.retain(|&v| t.positions()[v as usize].y > 0.55);
        (c, settings)
    };
    let solve = |t: &Arc<Topology>| {
        let (c, settings) = second(t);
        let solver = ArapSolver::precompute(t.clone(), &c, settings).unwrap();
        solver
            .solve(&c, &opts, InitialGuess::Laplacian, NEVER)
            .unwrap()
    };
    // Reused: the topology first served the whole-bar set (most vertices free).
    let reused = topo(&mesh);
    ArapSolver::precompute(
        reused.clone(),
        &bend_problem(&reused, 0.0),
        SolverSettings::default(),
    )
    .unwrap();
    let a = solve(&reused);
    // Fresh, with the same whole-mesh order made first: identical.
    let prepared = topo(&mesh);
    prepared.prepare_elimination_order();
    let b = solve(&prepared);
    assert_eq!(a.positions, b.positions);
    assert_eq!(a.rotations, b.rotations);
    // Fresh, ordering the region on its own: the same solution up to rounding.
    let own = solve(&topo(&mesh));
    let diagonal = reused.bounding_diagonal();
    let worst = max_distance(&a.positions, &own.positions);
    assert!(worst < 1e-10 * diagonal, "{worst:e}");
    // And the region really moved (the comparison is not of two rest poses).
    let moved = max_distance(&a.positions, reused.positions());
    assert!(moved > 0.01 * diagonal, "{moved}");
}

/// The paper's initial guess — the uniform-Laplacian solve with the fixed and handle vertices
/// held — against the same system built and solved independently here: the combinatorial
/// Laplacian from the triangles, its free rows and columns solved densely by faer's LU. The
/// two agree to 1e-9 (a wrong right-hand side, a wrong neighbour set or a cotangent Laplacian
/// in its place would not).
#[test]
fn the_laplacian_initial_guess_matches_an_independent_dense_solve() {
    use faer::linalg::solvers::Solve;
    for mesh in [synth::icosphere(2, 1.0), synth::bar(4, 12, 0.2, 1.0)] {
        let t = topo(&mesh);
        let rest = t.positions().to_vec();
        let c = bend_problem(&t, 0.9);
        let solver = ArapSolver::precompute(t.clone(), &c, SolverSettings::default()).unwrap();
        let options = SolveOptions {
            max_iterations: 0,
            tolerance: 0.0,
            ..Default::default()
        };
        let guess = solver
            .solve(&c, &options, InitialGuess::Laplacian, NEVER)
            .unwrap()
            .positions;
        // Independently: neighbours, the held positions, L x = L rest on the free rows.
        let n = rest.len();
        let mut neighbours = vec![std::collections::BTreeSet::new(); n];
        for tri in t.triangles() {
            for k in 0..3 {
                let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
                neighbours[a].insert(b);
                neighbours[b].insert(a);
            }
        }
        let mut held: Vec<Option<DVec3>> = vec![None; n];
        for &v in &c.fixed {
            held[v as usize] = Some(rest[v as usize]);
        }
        for h in &c.handles {
            for &v in &h.vertices {
                held[v as usize] = Some(h.transform.apply(rest[v as usize]));
            }
        }
        let free: Vec<usize> = (0..n).filter(|&v| held[v].is_none()).collect();
        let column: std::collections::HashMap<usize, usize> =
            free.iter().enumerate().map(|(k, &v)| (v, k)).collect();
        let laplacian = |v: usize, of: &dyn Fn(usize) -> DVec3| {
            of(v) * neighbours[v].len() as f64 - neighbours[v].iter().map(|&u| of(u)).sum::<DVec3>()
        };
        let a = faer::Mat::<f64>::from_fn(free.len(), free.len(), |r, k| {
            let (v, u) = (free[r], free[k]);
            if v == u {
                neighbours[v].len() as f64
            } else if neighbours[v].contains(&u) {
                -1.0
            } else {
                0.0
            }
        });
        let b = faer::Mat::<f64>::from_fn(free.len(), 3, |r, axis| {
            let v = free[r];
            let delta = laplacian(v, &|u| rest[u]);
            // Move the held neighbours' terms to the right-hand side.
            let held_terms: DVec3 = neighbours[v].iter().filter_map(|&u| held[u]).sum();
            (delta + held_terms)[axis]
        });
        let x = a.partial_piv_lu().solve(&b);
        let mut worst = 0.0f64;
        for v in 0..n {
            let expected = match held[v] {
                Some(p) => p,
                None => {
                    let r = column[&v];
                    DVec3::new(x[(r, 0)], x[(r, 1)], x[(r, 2)])
                }
            };
            worst = worst.max(guess[v].distance(expected));
        }
        assert!(
            worst < 1e-9,
            "the initial guess is {worst} from the dense solve"
        );
        // And the guess is not the rest pose (the handle moved the free vertices).
        assert!(max_distance(&guess, &rest) > 0.05);
    }
}

/// Two bars side by side as one mesh (two components, each with fixed and handle vertices).
fn two_bars() -> TriMesh {
    let a = synth::bar(16, 40, 0.1, 1.0);
    let mut mesh = a.clone();
    let base = mesh.positions.len() as u32;
    mesh.positions
        .extend(a.positions.iter().map(|p| *p + DVec3::new(0.5, 0.0, 0.0)));
    mesh.triangles
        .extend(a.triangles.iter().map(|t| t.map(|v| v + base)));
    mesh
}

/// A small mesh solves on the calling thread ([`Threading::Auto`] below
/// [`SERIAL_BELOW`] free vertices) and gives the positions the pool's path gives, for every
/// acceleration, from the Laplacian start and warm.
#[test]
fn small_meshes_solve_alike_on_the_calling_thread_and_on_the_pool() {
    let mut meshes = vec![
        ("bar 2k", synth::bar_with_vertices(2000)),
        ("two bars", two_bars()),
    ];
    if let Some((positions, triangles)) = gltf_triangles("models/sphere.gltf") {
        meshes.push((
            "sphere.gltf (split at its seam)",
            TriMesh {
                positions,
                triangles,
            },
        ));
    }
    if let Some(path) = shared::shared_asset("meshes/dino.off") {
        meshes.push(("dino", TriMesh::read(&path).unwrap()));
    }
    let accelerations = [
        Acceleration::None,
        Acceleration::Anderson { depth: 3 },
        Acceleration::Lbfgs { depth: 4 },
        Acceleration::Newton { max_cg: 6 },
    ];
    for (name, mesh) in &meshes {
        let t = topo(mesh);
        let diagonal = t.bounding_diagonal();
        let shift = DVec3::new(0.15 * diagonal, 0.0, 0.0);
        let mut c = synth::bend_problem(t.positions(), 0.6, shift);
        let solver = |threading| {
            let settings = SolverSettings {
                threading,
                ..Default::default()
            };
            ArapSolver::precompute(t.clone(), &c, settings).unwrap()
        };
        let (serial, pooled) = (solver(Threading::Serial), solver(Threading::Parallel));
        let auto = solver(Threading::Auto);
        assert!(!serial.precompute_stats().parallel_iterations, "{name}");
        assert!(pooled.precompute_stats().parallel_iterations, "{name}");
        assert_eq!(
            auto.precompute_stats().parallel_iterations,
            auto.precompute_stats().free_vertices >= SERIAL_BELOW,
            "{name}"
        );
        assert!(
            auto.precompute_stats().free_vertices < SERIAL_BELOW,
            "{name}: a small mesh"
        );
        for acceleration in accelerations {
            let opts = SolveOptions {
                max_iterations: 6,
                tolerance: 0.0,
                acceleration,
            };
            let a = serial
                .solve(&c, &opts, InitialGuess::Laplacian, NEVER)
                .unwrap();
            let b = pooled
                .solve(&c, &opts, InitialGuess::Laplacian, NEVER)
                .unwrap();
            let d = max_distance(&a.positions, &b.positions);
            assert!(d <= 1e-12 * diagonal, "{name} {acceleration:?}: {d}");
            assert!(
                max_distance(&a.positions, t.positions()) > 0.05 * diagonal,
                "{name}: the bend moved the mesh"
            );
            c.handles[0].transform.translation += DVec3::new(0.0, 0.02 * diagonal, 0.0);
            let a2 = serial
                .solve(&c, &opts, InitialGuess::Warm(&a), NEVER)
                .unwrap();
            let b2 = pooled
                .solve(&c, &opts, InitialGuess::Warm(&b), NEVER)
                .unwrap();
            let d = max_distance(&a2.positions, &b2.positions);
            assert!(d <= 1e-12 * diagonal, "{name} {acceleration:?}, warm: {d}");
            let (ea, eb) = (a2.stats.final_energy(), b2.stats.final_energy());
            assert!(
                (ea - eb).abs() <= 1e-9 * ea.max(1e-300),
                "{name}: {ea} vs {eb}"
            );
        }
    }
}

/// The cactus test case as the deformation benchmark ships it: its selection and handle
/// transform read from the real `.sel`/`.def` files, solved. The fixed vertices stay, the handle
/// lands where the file's transform puts it, and the free region follows without tearing.
#[test]
fn cactus_selection_and_handle_transform_drive_a_solve() {
    use bevy_wii_deform::deform::{VertexRole, VertexSelection, read_handle_transform};
    let Some(dir) = shared::shared_asset("meshes") else {
        return;
    };
    let mesh = TriMesh::read(dir.join("cactus.off")).unwrap();
    let selection = VertexSelection::read(dir.join("cactus.sel"), mesh.positions.len()).unwrap();
    let affine = read_handle_transform(dir.join("cactus.def")).unwrap();
    let fixed = selection.vertices(VertexRole::Fixed);
    let handle = selection.vertices(VertexRole::Handle);
    assert!(
        fixed.len() > 10 && handle.len() > 10,
        "{} fixed, {} handle",
        fixed.len(),
        handle.len()
    );
    // The benchmark's handle transforms are rigid: an orthonormal block with determinant 1.
    let gram = affine.matrix3.transpose() * affine.matrix3;
    let off_identity = (gram - glam::DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        off_identity < 1e-4 && (affine.matrix3.determinant() - 1.0).abs() < 1e-4,
        "{affine:?}"
    );
    let transform = RigidTransform::new(
        glam::DQuat::from_mat3(&affine.matrix3),
        affine.translation,
        DVec3::ZERO,
    );
    let topology = Arc::new(Topology::new(&mesh.positions, &mesh.triangles).unwrap());
    let constraints = Constraints::with_handle(fixed.clone(), handle.clone(), transform);
    let solver = ArapSolver::precompute(topology, &constraints, SolverSettings::default()).unwrap();
    let solved = solver
        .solve(
            &constraints,
            &SolveOptions::default(),
            InitialGuess::Laplacian,
            NEVER,
        )
        .unwrap();
    let size = {
        let (lo, hi) = mesh.bounds();
        (hi - lo).length()
    };
    for &v in &fixed {
        assert!((solved.positions[v as usize] - mesh.positions[v as usize]).length() < 1e-9 * size);
    }
    for &v in &handle {
        let target = affine.transform_point3(mesh.positions[v as usize]);
        assert!(
            (solved.positions[v as usize] - target).length() < 1e-6 * size,
            "handle vertex {v}"
        );
    }
    // The handle turns by ~70° and rises (the file's transform): the free region bends, and
    // its edges stretch by a few per cent on average (0.04 mean, 0.18 p95 with the default
    // settings) — a free region left at rest would tear at the handle's border instead.
    let mut stretch: Vec<f64> = mesh
        .triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| {
            let rest = (mesh.positions[a as usize] - mesh.positions[b as usize]).length();
            let now = (solved.positions[a as usize] - solved.positions[b as usize]).length();
            (now / rest - 1.0).abs()
        })
        .collect();
    stretch.sort_by(f64::total_cmp);
    let p95 = stretch[stretch.len() * 95 / 100];
    let mean = stretch.iter().sum::<f64>() / stretch.len() as f64;
    eprintln!(
        "edge stretch: mean {mean:.4}, p95 {p95:.4}, max {:.4}",
        stretch[stretch.len() - 1]
    );
    assert!(
        p95 < 0.25 && mean < 0.06,
        "edge stretch mean {mean}, p95 {p95}"
    );
}
