//! `character_bench --ground slope|steps [--balance]`: the model stood on a 25° slope or on
//! steps by automatic contacts (`ContactTracker`: its lowest joints, cast down, planted when
//! they touch), its handle dragged sideways far enough to topple it, with and without balance.
//! Gravity is −Y (glTF's up is +Y; the reader folds a converter's turn into the pose).
//!
//! `GROUND_DEBUG=1` in the environment prints each frame's solve: iterations, rejected trial
//! steps and the solve's own timers (total, cluster rotations, systems, steps), and each
//! planted patch's slide and the centre of mass against its support polygon; the setup is
//! the total less the rotations and the steps.

use std::sync::Arc;
use std::time::Instant;

use bevy_wii_deform::deform::{Handle, RigidTransform, centroid};
use bevy_wii_deform::pose::*;
use glam::{DQuat, DVec3};

/// Iterations a drag frame's solve may add while skin is through the ground (the default
/// of `PoseSolveOptions` and `Poseable`); `GROUND_ITERATIONS=0` in the environment: none, as
/// before they existed.
static GROUND_ITERATIONS: std::sync::LazyLock<u32> = std::sync::LazyLock::new(|| {
    std::env::var("GROUND_ITERATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(PoseSolveOptions::default().ground_iterations)
});

/// Which ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GroundKind {
    /// A plane 25° steep, rising along +X.
    Slope,
    /// Two levels, the step between the feet, 10 % of the leg's length high.
    Steps,
}

/// What a drag stands the character on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Standing {
    /// Nothing: the handle's drag alone (no ground, contacts, floor or balance), the price
    /// the grounded drag is compared with.
    Bare,
    /// The ground by contacts, with or without the floor (every skin vertex near the ground
    /// kept above it) and balance: without the floor, the price of the rest on its own.
    Ground { balance: bool, floor: bool },
}

/// What one drag measured.
struct Run {
    ms: Vec<f64>,
    penetration_max: f64,
    sole_errors_deg: Vec<f64>,
    slide_max: f64,
    supported: usize,
    with_support: usize,
    com_margin_min: f64,
    replants: usize,
}

/// The ground under a character standing in `rest` (welded positions) with its lowest point
/// at `lowest`: a slope through it, or steps whose edge runs between the feet.
fn ground_for(kind: GroundKind, rest: &[DVec3], feet_centre: DVec3, size: f64) -> Box<dyn Ground> {
    let lowest = rest.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let at = DVec3::new(feet_centre.x, lowest, feet_centre.z);
    match kind {
        GroundKind::Slope => {
            let normal = DQuat::from_rotation_z(25f64.to_radians()) * DVec3::Y;
            Box::new(GroundPlane::new(at, normal).expect("a plane"))
        }
        GroundKind::Steps => {
            let (w, h) = (10.0 * size, 0.05 * size);
            let p = |x: f64, y: f64, z: f64| at + DVec3::new(x, y, z);
            let positions = vec![
                p(-w, -h, -w),
                p(0.0, -h, -w),
                p(0.0, -h, w),
                p(-w, -h, w),
                p(0.0, 0.0, -w),
                p(w, 0.0, -w),
                p(w, 0.0, w),
                p(0.0, 0.0, w),
            ];
            let triangles = vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]];
            Box::new(TriangleGround::new(positions, triangles, DVec3::NEG_Y))
        }
    }
}

/// The ground's height under `p` (by a cast), and its normal there.
fn under(ground: &dyn Ground, p: DVec3, size: f64) -> Option<GroundPlane> {
    ground.cast_down(p + DVec3::Y * 10.0 * size, DVec3::NEG_Y, 20.0 * size)
}

/// How far the handle is dragged, as shares of the size: the first that topples the
/// character without balance (in either direction) is the drag measured.
const REACHES: [f64; 3] = [0.3, 0.45, 0.6];

/// The horizontal direction across the feet (joint positions `feet`): square to the line
/// they spread along most — a biped's left to right, a quadruped's nose to tail — so that a
/// drag along it leaves the support polygon where it is narrowest. +X for one foot or feet
/// spread evenly every way; the sign puts it on the +X (else +Z) side.
fn across_the_feet(feet: &[DVec3]) -> DVec3 {
    let n = feet.len().max(1) as f64;
    let mean = feet.iter().sum::<DVec3>() / n;
    // The horizontal (x, z) covariance and its principal axis.
    let (mut xx, mut xz, mut zz) = (0.0, 0.0, 0.0);
    for p in feet {
        let d = *p - mean;
        xx += d.x * d.x;
        xz += d.x * d.z;
        zz += d.z * d.z;
    }
    let spread = ((xx - zz) * (xx - zz) + 4.0 * xz * xz).sqrt();
    if feet.len() < 2 || spread <= 1e-9 * (xx + zz) {
        return DVec3::X;
    }
    // The larger eigenvalue's eigenvector of [[xx, xz], [xz, zz]].
    let along = if xz.abs() > 1e-12 * (xx + zz) {
        DVec3::new(xz, 0.0, (zz - xx + spread) / 2.0)
    } else if xx >= zz {
        DVec3::X
    } else {
        DVec3::Z
    };
    let across = DVec3::Y.cross(along).normalize();
    if across.x < -1e-9 || (across.x.abs() <= 1e-9 && across.z < 0.0) {
        -across
    } else {
        across
    }
}

/// The drag as `standing` says; `handle` dragged `reach` `along` a direction and a little
/// down over 30 frames of 3 warm iterations, contacts tracked every frame, after a frame
/// that stands the character on the ground; with the floor, every skin vertex near the
/// ground kept above it.
fn drag(
    model: &Arc<SkinnedModel>,
    pose: &SkeletonPose,
    handle: &[u32],
    ground: &dyn Ground,
    (along, reach, standing): (DVec3, f64, Standing),
) -> Run {
    let (grounded, balance, floor) = match standing {
        Standing::Bare => (false, false, false),
        Standing::Ground { balance, floor } => (true, balance, floor),
    };
    let size = model.topology().bounding_diagonal();
    let down = DVec3::NEG_Y;
    let feet = lowest_joints(model, pose, down, 0.04 * size);
    let mut tracker = ContactTracker::new(model, pose, &feet, down);
    // Every skin vertex within 30 % of the size of the ground under it at the start of a solve
    // is kept above it (10 % let a paw that started further up pass through within one solve).
    let sampling = FloorSampling::for_size(size, 0.3, down);
    let rest = model.skin_welded(pose);
    let pivot = centroid(&rest, handle);
    let mut run = Run {
        ms: Vec::new(),
        penetration_max: 0.0,
        sole_errors_deg: Vec::new(),
        slide_max: 0.0,
        supported: 0,
        with_support: 0,
        com_margin_min: f64::INFINITY,
        replants: 0,
    };
    let mut last: Option<PoseSolution> = None;
    let mut previous: Option<Vec<Option<Vec<DVec3>>>> = None;
    let drag_to = |reach: f64| Handle {
        vertices: handle.to_vec(),
        transform: RigidTransform::new(
            DQuat::IDENTITY,
            along * reach - DVec3::Y * 0.2 * reach,
            pivot,
        ),
    };
    // Contacts and balance change every frame; the handle's set does not: one solver.
    let solver = PoseSolver::new(
        model.clone(),
        &PoseConstraints {
            handles: vec![drag_to(0.0)],
            ..Default::default()
        },
        pose,
        PoseSolverSettings::default(),
    )
    .expect("solver");
    for frame in 0..=30 {
        let now = last.as_ref().map_or(pose, |l| &l.pose);
        let events = tracker.update(model, now, ground);
        if frame > 0 {
            run.replants += events
                .iter()
                .filter(|e| **e == ContactEvent::Planted)
                .count();
        }
        let support = tracker.support();
        let reached = reach * frame as f64 / 30.0;
        let constraints = if grounded {
            PoseConstraints {
                handles: vec![drag_to(reached)],
                contacts: tracker.active(),
                floor: floor.then(|| Floor::cast(&model.skin_welded(now), ground, &sampling).0),
                balance: (balance && !support.is_empty()).then(|| Balance {
                    margin: 0.01 * size,
                    ..Balance::over(support.clone())
                }),
                ..Default::default()
            }
        } else {
            PoseConstraints {
                handles: vec![drag_to(reached)],
                ..Default::default()
            }
        };
        // Frame 0 stands the character on the ground (its contacts just planted) to
        // convergence, as a game settles a character it places; the drag frames get 3.
        let options = PoseSolveOptions {
            max_iterations: if frame == 0 { 40 } else { 3 },
            tolerance: 0.0,
            ground_iterations: *GROUND_ITERATIONS,
        };
        let start = match &last {
            Some(l) => PoseStart::Warm(l),
            None => PoseStart::Pose(pose),
        };
        let t = Instant::now();
        let solved = solver
            .solve(&constraints, &options, start, &|| false)
            .expect("a solve");
        if std::env::var("GROUND_DEBUG").is_ok() {
            eprintln!(
                "frame {frame} {standing:?}: {} its, boost {:.5}, {} rejected steps, ms total {:.3} local {:.3} system {:.3} global {:.3} energies {:?}",
                solved.stats.iterations,
                solved.balance_boost / size,
                solved.stats.rejected_steps,
                solved.stats.total_s * 1e3,
                solved.stats.local_s * 1e3,
                solved.stats.system_s * 1e3,
                solved.stats.global_s * 1e3,
                solved.stats.energies
            );
        }
        if frame > 0 {
            run.ms.push(t.elapsed().as_secs_f64() * 1e3);
            measure(&mut run, model, &solved.pose, &tracker, ground);
        }
        // Planted patches: how far each moved since the last frame, while planted in both.
        let skinned = model.skin_welded(&solved.pose);
        let now_planted: Vec<Option<Vec<DVec3>>> = tracker
            .contacts
            .iter()
            .map(|c| {
                c.planted
                    .as_ref()
                    .map(|_| c.patch.iter().map(|&v| skinned[v as usize]).collect())
            })
            .collect();
        if let Some(before) = &previous {
            for ((a, b), c) in before.iter().zip(&now_planted).zip(&tracker.contacts) {
                if let (Some(a), Some(b)) = (a, b) {
                    let n = c.ground.normal;
                    let slide = a
                        .iter()
                        .zip(b)
                        .map(|(p, q)| {
                            let d = *q - *p;
                            (d - n * d.dot(n)).length()
                        })
                        .fold(0.0, f64::max);
                    run.slide_max = run.slide_max.max(slide / size);
                    if std::env::var("GROUND_DEBUG").is_ok() {
                        eprintln!("  slide {:.5}", slide / size);
                    }
                }
            }
        }
        previous = Some(now_planted);
        last = Some(solved);
    }
    run
}

/// Penetration of every skin vertex, the planted soles' turn to their ground, and where the
/// centre of mass is against the support polygon.
fn measure(
    run: &mut Run,
    model: &SkinnedModel,
    pose: &SkeletonPose,
    tracker: &ContactTracker,
    ground: &dyn Ground,
) {
    let size = model.topology().bounding_diagonal();
    let skinned = model.skin_welded(pose);
    for p in &skinned {
        if let Some(g) = under(ground, *p, size) {
            run.penetration_max = run.penetration_max.max(-g.height(*p) / size);
        }
    }
    let globals = model.skeleton().global_transforms(pose);
    for c in tracker.contacts.iter().filter(|c| c.planted.is_some()) {
        let up = (globals[c.joint].matrix3 * c.up.unwrap_or(DVec3::Y)).normalize_or(DVec3::Y);
        run.sole_errors_deg
            .push(up.angle_between(c.ground.normal).to_degrees());
    }
    let support = tracker.support();
    if !support.is_empty()
        && let Some(com) = centre_of_mass(model, pose, None)
    {
        let polygon = SupportPolygon::new(&support, DVec3::NEG_Y);
        let d = polygon.signed_distance(com) / size;
        if std::env::var("GROUND_DEBUG").is_ok() {
            eprintln!(
                "com {com:.3} d {d:.4} corners {:.3?}",
                polygon.corners_at(com)
            );
        }
        run.with_support += 1;
        run.supported += usize::from(d >= 0.0);
        run.com_margin_min = run.com_margin_min.min(d);
    }
}

/// Runs the ground drag and returns its JSON fields.
pub fn run(
    model: &Arc<SkinnedModel>,
    pose: &SkeletonPose,
    handle: &[u32],
    kind: GroundKind,
    balance: bool,
) -> serde_json::Value {
    let size = model.topology().bounding_diagonal();
    let rest = model.skin_welded(pose);
    let feet = lowest_joints(model, pose, DVec3::NEG_Y, 0.04 * size);
    let globals = model.skeleton().global_transforms(pose);
    let feet_centre =
        feet.iter().map(|&j| globals[j].translation).sum::<DVec3>() / feet.len().max(1) as f64;
    let ground = ground_for(kind, &rest, feet_centre, size);
    let feet_at: Vec<DVec3> = feet.iter().map(|&j| globals[j].translation).collect();
    // The drag that topples the character without balance: across the feet, outwards from
    // them through the handle, or back across them, the shortest reach first (a biped's
    // T-posed hand pulled forward turns the torso and keeps the centre of mass over the feet;
    // the mannequin on steps topples only backwards).
    let outwards = (centroid(&rest, handle) - feet_centre) * DVec3::new(1.0, 0.0, 1.0);
    let across = across_the_feet(&feet_at);
    let directions = [
        across,
        outwards.try_normalize().unwrap_or(DVec3::X),
        -across,
    ];
    let drags = REACHES
        .iter()
        .flat_map(|&r| directions.iter().map(move |&d| (d, r * size)));
    let mut tried = None;
    for (along, reach) in drags {
        let without = drag(
            model,
            pose,
            handle,
            ground.as_ref(),
            (
                along,
                reach,
                Standing::Ground {
                    balance: false,
                    floor: true,
                },
            ),
        );
        let topples = without.supported < without.with_support;
        tried = Some((along, reach, without));
        if topples {
            break;
        }
    }
    let (along, reach, without) = tried.expect("a drag");
    let with = drag(
        model,
        pose,
        handle,
        ground.as_ref(),
        (
            along,
            reach,
            Standing::Ground {
                balance,
                floor: true,
            },
        ),
    );
    // The same drag with nothing under it, side by side in this process, and with the
    // contacts alone and (with balance) the contacts and balance: the price of all but the
    // floor, which a floor of any cost cannot go under.
    let standing_ms = |standing: Standing| {
        let mut ms = drag(
            model,
            pose,
            handle,
            ground.as_ref(),
            (along, reach, standing),
        )
        .ms;
        ms.sort_by(f64::total_cmp);
        ms
    };
    let bare_ms = standing_ms(Standing::Bare);
    let contacts_ms = standing_ms(Standing::Ground {
        balance: false,
        floor: false,
    });
    let without_floor_ms = balance.then(|| {
        standing_ms(Standing::Ground {
            balance: true,
            floor: false,
        })
    });
    let mut ms = with.ms.clone();
    ms.sort_by(f64::total_cmp);
    let mut errors = with.sole_errors_deg.clone();
    errors.sort_by(f64::total_cmp);
    let pick = |v: &[f64], p: f64| {
        v.get(((v.len().max(1) - 1) as f64 * p).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    let share = |r: &Run| r.supported as f64 / r.with_support.max(1) as f64;
    serde_json::json!({
        "ground": format!("{kind:?}").to_lowercase(),
        "balance": balance,
        "feet": feet.len(),
        "drag_direction": [along.x, along.y, along.z],
        "drag_reach": reach / size,
        "constrained_ms_per_solve": pick(&ms, 0.5),
        "bare_ms_per_solve": pick(&bare_ms, 0.5),
        "ground_cost_ratio": pick(&ms, 0.5) / pick(&bare_ms, 0.5),
        "contacts_ms_per_solve": pick(&contacts_ms, 0.5),
        "contacts_cost_ratio": pick(&contacts_ms, 0.5) / pick(&bare_ms, 0.5),
        "without_floor_ms_per_solve": without_floor_ms.as_deref().map(|ms| pick(ms, 0.5)),
        "without_floor_cost_ratio": without_floor_ms
            .as_deref()
            .map(|ms| pick(ms, 0.5) / pick(&bare_ms, 0.5)),
        "penetration_max": with.penetration_max,
        "sole_normal_error_deg_p95": pick(&errors, 0.95),
        "soles_at_limit_share": errors.iter().filter(|e| **e > 3.0).count() as f64
            / errors.len().max(1) as f64,
        "planted_slide_max": with.slide_max,
        "com_supported_share": share(&with),
        "com_margin_min": with.com_margin_min,
        "com_supported_share_without_balance": share(&without),
        "replants": with.replants,
    })
}
