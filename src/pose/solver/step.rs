//! The Levenberg–Marquardt step of an iteration: solve the damped system, shorten or damp a
//! step that would raise the energy, project it into the joint limits, and retract it onto
//! the skeleton (rigid bones).

use glam::{DAffine3, DQuat, DVec3};

use crate::pose::constraints::limits::JointLimits;
use crate::pose::rig::skeleton::{JointTransform, SkeletonPose};
use crate::pose::solver::damped_step::{DampedStep, solve_damped};
use crate::pose::solver::energy::holds::QBlocks;
use crate::pose::solver::linalg::block_cholesky::BlockPattern;
use crate::pose::solver::linalg::low_rank::RankOne;
use crate::pose::solver::params::Param;
use crate::pose::solver::solve::Posed;
use crate::pose::solver::terms::ExtraTerms;
use crate::pose::solver::{PoseSolveStats, PoseSolver};

/// A rejected step is shortened to where it first takes a vertex through the ground only when
/// that is at least this share of it (a vertex already at the ground would make it a crawl:
/// then half, and more damping).
const SHORTEST_TO_CONTACT: f64 = 0.1;
/// How much of the way to that first contact the shortened step goes: the heights are
/// interpolated linearly along a rotation, so stop a little short of the ground.
const BEFORE_CONTACT: f64 = 0.9;

/// A rejected full step that rose by more than this many times the decrease its model
/// promised is not tried at half its length (unless a vertex it took through the ground
/// shortens it): the damping is raised at once. The model's error grows about as the cube of
/// the step's length (the retraction's turns), so half the step keeps 3/4 of the promise
/// and an eighth of the error, and can only fall for a rise under ~5 times the promise.
/// Measured on the mannequin's drag on the slope (`character_bench --ground slope
/// --balance`): half steps after a rise of 1–2 / 2–4 / 4–8 / over 8 times fell in 19 of 36 /
/// 5 of 21 / 2 of 20 / 2 of 166 trials.
const HOPELESS_RISE: f64 = 4.0;

/// What an iteration's energy is made of besides the pose: its quadratic form, the linear
/// term of the rotation fit and penalties, its constant, and the effector, limit and
/// stiffness terms.
pub(super) struct Objective<'a> {
    /// The 4 × 4 blocks of this solve's `Q` (the shape energy's, the penalties' and the
    /// planted contacts' holds).
    pub(super) q_blocks: &'a QBlocks,
    pub(super) b: &'a [f64],
    pub(super) constant: f64,
    pub(super) extras: &'a ExtraTerms<'a>,
}

/// An iteration's Gauss–Newton system and the energy it starts from.
pub(super) struct DampedSystem<'a> {
    /// The block-sparse part of the matrix.
    pub(super) h: &'a [f64],
    /// Its rank-one parts (`low_rank.rs`: balance).
    pub(super) low_rank: &'a [RankOne],
    pub(super) g: &'a [f64],
    pub(super) f0: f64,
    /// A predicted decrease of the energy below this is no progress: the solve has converged
    /// (a step is not tried; without this a solve at its minimum, where the one-sided terms'
    /// kinks make every step rise, would raise the damping through all its trials).
    pub(super) no_progress: f64,
    /// Where `h`'s Cholesky factor has non-zero blocks.
    pub(super) pattern: &'a BlockPattern,
    /// Each coordinate's damping weight ([`crate::pose::solver::damped_step::damping_weights`]).
    pub(super) weights: &'a [f64],
}

impl PoseSolver {
    /// One Levenberg–Marquardt step from `current`: a rejected step is first shortened along
    /// its direction (cheap: no new factorization) unless it rose far past its model
    /// ([`shorter_trial`]), then re-solved with more damping. The accepted pose and its
    /// energy, or `None` after twelve rejections.
    pub(super) fn damped_step(
        &self,
        (current, spare): (&Posed, &mut Option<Posed>),
        system: &DampedSystem,
        objective: &Objective,
        limits: Option<&JointLimits>,
        damping: &mut f64,
        stats: &mut PoseSolveStats,
    ) -> Option<(Posed, f64)> {
        // Each rejection raises the damping faster than the last (Nielsen's rule): a solve at
        // its minimum, where every step rises, gives up in a few trials, not a dozen.
        let mut raise = 4.0;
        for _ in 0..12 {
            let DampedStep {
                step,
                predicted_decrease,
            } = solve_damped(
                (system.h, system.low_rank),
                system.g,
                *damping,
                system.pattern,
                system.weights,
            );
            if system.no_progress > 0.0 && predicted_decrease < system.no_progress {
                return None;
            }
            // The full step, then a shorter one: most of the way to the first vertex that the
            // full step took through the ground (the one-sided terms are not in the model
            // until they act, so a step that plunges a vertex in rises), else half of it.
            let mut length = 1.0;
            for k in 0..2 {
                let mut candidate = match spare.take() {
                    Some(mut buffers) => {
                        retract_into(
                            &current.pose,
                            &current.globals,
                            &step,
                            length,
                            self,
                            &mut buffers.pose,
                        );
                        buffers
                    }
                    None => {
                        let pose = retract(&current.pose, &current.globals, &step, length, self);
                        self.posed_unrefreshed(pose)
                    }
                };
                if let Some(limits) = limits {
                    limits.project(&mut candidate.pose);
                }
                self.refresh(&mut candidate, objective.q_blocks);
                let f = self.energy(&mut candidate, objective);
                if f.is_finite() && f <= system.f0 {
                    *damping = if k == 0 {
                        (*damping / 2.0).max(1e-9)
                    } else {
                        *damping * 2.0
                    };
                    return Some((candidate, f));
                }
                let contact = objective
                    .extras
                    .first_contact(&current.gaps, &candidate.gaps, &current.skin)
                    .filter(|t| (SHORTEST_TO_CONTACT..1.0).contains(t));
                *spare = Some(candidate);
                stats.rejected_steps += 1;
                match shorter_trial(length, contact, f - system.f0, predicted_decrease) {
                    Some(shorter) => length = shorter,
                    None => break,
                }
            }
            *damping *= raise;
            raise *= 2.0;
        }
        None
    }
}

/// The length of the next trial along a step whose trial at `length` was rejected, having
/// risen by `rise` where its model promised a decrease of `promised`: most of the way to
/// `contact` (the share of it at which it first took a vertex through the ground), else half
/// the step — or `None` when the rise says a half step would rise as well
/// ([`HOPELESS_RISE`]; a rise that is not a number too): then the damping is raised.
fn shorter_trial(length: f64, contact: Option<f64>, rise: f64, promised: f64) -> Option<f64> {
    match contact {
        Some(t) => Some(BEFORE_CONTACT * t * length),
        None if rise <= HOPELESS_RISE * promised => Some(0.5),
        None => None,
    }
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
    let mut out = SkeletonPose { local: Vec::new() };
    retract_into(pose, globals, step, t, solver, &mut out);
    out
}

/// [`retract`] into `out` (its allocation reused).
fn retract_into(
    pose: &SkeletonPose,
    globals: &[DAffine3],
    step: &[DVec3],
    t: f64,
    solver: &PoseSolver,
    out: &mut SkeletonPose,
) {
    let skeleton = solver.model.skeleton();
    out.local.clear();
    out.local.extend_from_slice(&pose.local);
    for (p, &param) in solver.params.iter().enumerate() {
        let d = step[p] * t;
        let j = param.joint();
        let local: &mut JointTransform = &mut out.local[j];
        match param {
            Param::Rotation(_) => {
                let qp = skeleton.parent_rotation(globals, j);
                let inc = qp.inverse() * DQuat::from_scaled_axis(d) * qp;
                local.rotation = (inc * local.rotation).normalize();
            }
            Param::Translation(_) => {
                let lin = skeleton.parent_linear(globals, j);
                if lin.determinant().abs() > 1e-300 {
                    local.translation += lin.inverse() * d;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{BEFORE_CONTACT, HOPELESS_RISE, shorter_trial};

    /// A rejected step goes most of the way to the vertex it first took through the ground
    /// whatever it rose by; without one it is halved after a rise within
    /// [`HOPELESS_RISE`] times its promise, and not tried shorter past that or when its
    /// energy was not a number. (Fails with the halving kept for every rise.)
    #[test]
    fn a_step_far_past_its_model_is_not_halved() {
        let promised = 2.0;
        let within = 0.9 * HOPELESS_RISE * promised;
        let past = 1.1 * HOPELESS_RISE * promised;
        assert_eq!(
            shorter_trial(0.8, Some(0.5), past, promised),
            Some(BEFORE_CONTACT * 0.5 * 0.8)
        );
        assert_eq!(shorter_trial(1.0, None, within, promised), Some(0.5));
        assert_eq!(shorter_trial(1.0, None, past, promised), None);
        assert_eq!(shorter_trial(1.0, None, f64::NAN, promised), None);
        assert_eq!(shorter_trial(1.0, None, f64::INFINITY, promised), None);
    }
}
