//! The unknowns of a pose solve: a world-space rotation increment per joint (about the
//! joint's origin, moving its subtree) and a translation per root joint — the one parameter
//! type every part of the solver (the system, the effector terms, the hinges, the step) uses.

use crate::pose::rig::skeleton::Skeleton;

/// One bone parameter (three unknowns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Param {
    /// A world rotation increment about the joint's origin (moves its subtree).
    Rotation(usize),
    /// A root translation (moves its subtree).
    Translation(usize),
}

impl Param {
    /// The joint it moves.
    pub(crate) fn joint(self) -> usize {
        match self {
            Param::Rotation(j) | Param::Translation(j) => j,
        }
    }
}

/// The bone parameters: a rotation per joint, a translation per root — only for joints whose
/// subtree moves something (a weighted vertex or a constrained joint); the others would be
/// zero rows of the system.
pub(super) fn parameters_for(skeleton: &Skeleton, block_nonzero: &[bool]) -> Vec<Param> {
    let n = skeleton.len();
    let mut active: Vec<bool> = (0..n).map(|j| block_nonzero[j * n + j]).collect();
    for j in (0..n).rev() {
        if let Some(p) = skeleton.joints()[j].parent {
            active[p] |= active[j];
        }
    }
    // Children before parents, root translations last: the order the block Cholesky
    // eliminates in, so that a joint's elimination fills in only among its ancestors.
    let mut out: Vec<Param> = (0..n)
        .rev()
        .filter(|&j| active[j])
        .map(Param::Rotation)
        .collect();
    out.extend(
        (0..n)
            .filter(|&j| active[j] && skeleton.joints()[j].parent.is_none())
            .map(Param::Translation),
    );
    out
}

/// Per joint, the indices into `params` of the parameters that move it (its own and its
/// ancestors'): the only ones a term on that joint has a Jacobian block for.
pub(super) fn movers_of_joints(skeleton: &Skeleton, params: &[Param]) -> Vec<Vec<u32>> {
    (0..skeleton.len())
        .map(|j| {
            (0..params.len() as u32)
                .filter(|&p| skeleton.descends_from(j, params[p as usize].joint()))
                .collect()
        })
        .collect()
}
