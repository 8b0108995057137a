//! In-frame solves ([`PoseInFrame`]): the targets a frame's `Update` set are solved in
//! `PostUpdate`, after animation and before transform propagation, for every such character
//! in parallel on Bevy's compute pool; the pose is then written to the joints by `apply.rs`
//! in the same frame.

use bevy::prelude::*;

use super::super::blend::BlendMemory;
use super::super::convert::{affine, composed_global};
use super::super::{
    PoseBalance, PoseBlend, PoseBlendMode, PoseFailed, PoseGround, PoseInFrame, PoseSolved,
    PoseStatus, Poseable, PosedSkeleton,
};
use super::constraints::core_effector;
use super::ground_contacts::{FloorRecast, Standing, StartPose, stand_on};
use super::solve::{SolveJob, SolveResult, store_landed};
use super::state::{CharacterSpace, GroundContacts, LastSolve, PoseDrivers, PoseSolves};
use crate::ecs::SceneGround;
use crate::pose::constraints::frame::similarity;
use crate::pose::{EffectorGoal, SkeletonPose, blend_pose};

/// What an in-frame solve reads and writes of a character.
type InFrameCharacter = (
    (Entity, Has<CharacterSpace>),
    (&'static Poseable, &'static PoseInFrame),
    &'static mut PosedSkeleton,
    (
        &'static PoseDrivers,
        &'static mut GroundContacts,
        &'static mut PoseSolves,
        &'static mut LastSolve,
        &'static BlendMemory,
    ),
    &'static mut PoseStatus,
    (
        Option<&'static PoseBlend>,
        Option<&'static PoseGround>,
        Option<&'static PoseBalance>,
    ),
);

/// The local transforms and parents of every entity: effector targets are composed from them
/// after animation, before propagation.
type Locals<'w, 's> = Query<'w, 's, (&'static Transform, Option<&'static ChildOf>)>;

/// Solves the pending targets of every in-frame character (in parallel) and stores the poses.
pub(super) fn solve_in_frame(
    mut characters: Query<InFrameCharacter>,
    locals: Locals,
    ground: Option<Res<SceneGround>>,
    mut solved: MessageWriter<PoseSolved>,
    mut failed: MessageWriter<PoseFailed>,
) {
    let ground = ground.as_deref();
    characters.par_iter_mut().for_each(
        |((entity, character_space), settings, mut posed, parts, mut status, extras)| {
            let (blend, standing, balance) = extras;
            let (drivers, mut contacts, mut solves, mut last, memory) = parts;
            if character_space && solves.pending.is_some() {
                place_where_it_is_now(posed.bypass_change_detection(), entity, &locals);
            }
            let solves = solves.bypass_change_detection();
            let last = last.bypass_change_detection();
            refresh_goals(drivers, solves, &posed, &locals);
            let animated = blend
                .filter(|b| b.mode == PoseBlendMode::Additive)
                .and_then(|b| start_from_this_frame(solves, &posed, (b, memory), &locals));
            if let (Some(settings), Some(ground)) = (standing, ground) {
                let balance = balance.filter(|b| b.enabled);
                if let Some(found) = stand_here(
                    (solves, contacts.bypass_change_detection(), last),
                    &posed,
                    (settings, balance),
                    ground,
                ) {
                    found.report(status.bypass_change_detection(), &posed);
                }
            }
            let ground = standing.zip(ground);
            let Some(outcome) = solve_pending(solves, drivers, last, &posed, settings, ground)
            else {
                return;
            };
            solves.in_frame_outcome = Some(match outcome {
                Ok(landed) => {
                    let ms = landed.ms;
                    let more = solves.pending.is_some();
                    let blending = (blend, memory, animated);
                    store_landed(&mut posed, last, &mut status, blending, landed, more);
                    Ok(ms)
                }
                Err(error) => {
                    status.error = Some(error.clone());
                    Err(error)
                }
            });
        },
    );
    for ((entity, _), _, _, (_, _, mut solves, ..), status, _) in &mut characters {
        match solves.bypass_change_detection().in_frame_outcome.take() {
            Some(Ok(ms)) => {
                solved.write(PoseSolved {
                    entity,
                    iterations: status.iterations,
                    energy: status.energy,
                    solve_ms: ms,
                });
            }
            Some(Err(error)) => {
                // The last good pose is kept.
                warn!("Poseable {entity}: {error}");
                failed.write(PoseFailed { entity, error });
            }
            None => {}
        }
    }
}

/// An additive layer solved inside the frame starts from this frame's animation with the
/// layer so far added — what the blend would show without a solve — and keeps this frame's
/// animation as its shape and stiffness reference; returns that animation (the new layer is
/// taken over it, so the blend shows the solved pose itself: planted feet stay planted). The
/// request was made in `Update`, from the frame before's animation. `None`: nothing pending.
fn start_from_this_frame(
    solves: &mut PoseSolves,
    posed: &PosedSkeleton,
    (blend, memory): (&PoseBlend, &BlendMemory),
    locals: &Locals,
) -> Option<SkeletonPose> {
    let pending = solves.pending.as_mut()?;
    let current: Vec<Option<Transform>> = posed
        .joints
        .iter()
        .map(|&j| locals.get(j).ok().map(|(t, _)| *t))
        .collect();
    let animated = memory.peek_animation(&current);
    if animated.local.len() != posed.pose.local.len() {
        return None;
    }
    let skeleton = posed.model.skeleton();
    let reference = memory
        .reference
        .clone()
        .unwrap_or_else(|| blend.reference_pose(skeleton));
    solves.start = Some(blend_pose(
        &animated,
        &posed.pose,
        &reference,
        blend.mode.into(),
        f64::from(blend.weight),
        memory.mask.as_deref(),
    ));
    if pending.shape_rest.is_some() {
        pending.shape_rest = Some(animated.clone());
    }
    if let Some(stiffness) = &mut pending.stiffness {
        stiffness.pose = animated.clone();
    }
    Some(animated)
}

/// Stands a character on the ground in the frame: its contacts, floor and balance, cast from
/// the pose its solve starts from (this frame's animation under an additive layer), added to
/// the pending constraints. `None`: nothing pending.
fn stand_here(
    (solves, contacts, last): (&mut PoseSolves, &mut GroundContacts, &LastSolve),
    posed: &PosedSkeleton,
    settings: (&PoseGround, Option<&PoseBalance>),
    ground: &SceneGround,
) -> Option<Standing> {
    let pending = solves.pending.as_mut()?;
    let pose = match solves.start.as_mut() {
        Some(pose) => StartPose::Given {
            pose,
            last: last.solved_pose(),
        },
        None => StartPose::Held(&posed.pose),
    };
    let standee = (&mut *contacts, posed, pose);
    Some(stand_on(pending, standee, settings, ground))
}

/// Puts a character-space model about to be solved where its entity is now (moved after the
/// request, by animation or a late system): a solve placed elsewhere would stand on the
/// ground, and hold its planted feet, that far from where it is drawn. With nothing to solve
/// the placement waits for the next request, which sees the move.
fn place_where_it_is_now(posed: &mut PosedSkeleton, entity: Entity, locals: &Locals) {
    if let Some(now) = current_global(entity, locals).and_then(|g| similarity(&affine(&g))) {
        posed.placement = now;
    }
}

/// `entity`'s world transform as its hierarchy's local transforms are now.
fn current_global(entity: Entity, locals: &Locals) -> Option<GlobalTransform> {
    composed_global(entity, |e| {
        let (t, parent) = locals.get(e).ok()?;
        Some((*t, parent.map(ChildOf::parent)))
    })
}

/// Reads the effectors' goals again from their entities as they are now (after this frame's
/// animation), in character space: into the pending constraints, or — when nothing was asked
/// in `Update` but a target moved since (an animated carrier) — into a new request made from
/// the last solved constraints.
fn refresh_goals(
    drivers: &PoseDrivers,
    solves: &mut PoseSolves,
    posed: &PosedSkeleton,
    locals: &Locals,
) {
    if drivers.effector_sources.is_empty() {
        return;
    }
    let Some(base) = solves.pending.as_ref().or(solves.solved.as_ref()) else {
        return;
    };
    // The goals that changed, read without touching (or copying) the constraints: most frames
    // of a character whose targets stand still change nothing.
    let to_character = posed.placement.inverse();
    let changed: Vec<(usize, EffectorGoal)> = drivers
        .effector_sources
        .iter()
        .filter_map(|(index, entity, effector)| {
            let global = current_global(*entity, locals)?;
            let fresh = core_effector(posed, effector, &global)?.transformed(&to_character);
            (base.effectors.get(*index)?.goal != fresh.goal).then_some((*index, fresh.goal))
        })
        .collect();
    if changed.is_empty() {
        return;
    }
    let Some(mut constraints) = solves.pending.take().or_else(|| solves.solved.clone()) else {
        return;
    };
    for (index, goal) in changed {
        constraints.effectors[index].goal = goal;
    }
    // Mirrored effectors (symmetric editing) follow their originals.
    if let Some(symmetry) = &drivers.symmetry {
        for &(original, mirrored) in &symmetry.mirrored_effectors {
            let image = constraints
                .effectors
                .get(original)
                .and_then(|e| symmetry.mirror_effector(e));
            if let (Some(image), Some(slot)) = (image, constraints.effectors.get_mut(mirrored)) {
                slot.goal = image.goal;
            }
        }
    }
    solves.pending = Some(constraints);
}

/// Solves the pending constraints within the frame's iteration budget (`None`: nothing
/// pending), warm-started from the last solve when its solver still fits.
fn solve_pending(
    solves: &mut PoseSolves,
    drivers: &PoseDrivers,
    last: &LastSolve,
    posed: &PosedSkeleton,
    (poseable, in_frame): (&Poseable, &PoseInFrame),
    ground: Option<(&PoseGround, &SceneGround)>,
) -> Option<SolveResult> {
    let budget = in_frame.iterations.max(1);
    let recast = ground.map(|(settings, ground)| FloorRecast::new(settings, ground, posed));
    let options = poseable.options_with(budget);
    let job = SolveJob::take(solves, drivers, last, posed, (options, recast))?;
    let outcome = job.run(&|| false);
    let constraints = job.constraints;
    // The whole budget used and still improving: the same targets go on next frame
    // (warm-started), so a pose whose targets stop moving settles over a few frames.
    let again = matches!(&outcome, Ok(landed) if landed.solution.stats.iterations >= budget)
        && solves.pending.is_none();
    // Kept (with effectors) so that a target moved after `Update` can ask again.
    let keep = !drivers.effector_sources.is_empty();
    match (again, keep) {
        (true, true) => {
            solves.solved = Some(constraints.clone());
            solves.pending = Some(constraints);
        }
        (true, false) => solves.pending = Some(constraints),
        (false, true) => solves.solved = Some(constraints),
        (false, false) => {}
    }
    Some(outcome)
}
