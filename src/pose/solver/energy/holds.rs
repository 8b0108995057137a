//! A planted contact's holds as part of the solve's quadratic energy.
//!
//! A planted patch vertex is held where it touched: `w ‖Σ_j S_j m_j − t‖²`, with `m_j` its
//! skinning weight for joint `j` times its homogeneous bind position. That is a quadratic in
//! the stacked skinning matrices `X`, exactly like a handle's penalty: it adds `w m_j m_kᵀ` to
//! the 4 × 4 block `(j, k)` of `Q`, `w m_j tᵀ` to block `j` of `B` and `w ‖t‖²` to the
//! constant. Folded into `Q` once a solve, a hold costs nothing per iteration beyond the
//! blocks it adds to (those of the few joints that skin a sole, already coupled by the shape
//! energy) — as a per-vertex effector term it cost a Jacobian block per joint above it, for
//! every vertex and every iteration (a walking crowd's largest single cost).
//!
//! The held point is where the vertex touched, lifted along the ground's normal by the
//! contact skin ([`contact_skin`]): the one-sided term that keeps the patch above its ground
//! acts from that skin, so a hold at the touching point itself pulled every patch vertex into
//! the skin against that term — two stiff terms at odds in every planted frame, the patch
//! resting 0.9 skins above its point (just under [`OFF_THE_HOLD`](crate::pose::solver::OFF_THE_HOLD)'s
//! extra iterations), its soles turned by the fight.

use std::borrow::Cow;
use std::sync::Mutex;

use glam::{DAffine3, DMat4, DVec3};

use crate::pose::ground::contact::Contact;
use crate::pose::rig::model::add_outer4x3;
use crate::pose::solver::PoseSolver;
use crate::pose::solver::terms::{contact_hold_weight, contact_skin};

/// The 4 × 4 blocks `(k, l, Q_kl)` of a solve's `Q`.
pub(crate) type QBlocks = [(usize, usize, DMat4)];

/// The `Q` blocks of the last planted patches a solver held (`blocks_with_holds`), kept for
/// its next solves: a planted foot's patch stays the same from frame to frame while only
/// where it is held moves, and summing its vertices' outer products was a sixth of a
/// grounded solve's setup. A clone of the solver starts without them.
#[derive(Default)]
pub(crate) struct HeldBlocks(Mutex<Option<KeptBlocks>>);

/// The patches last held (their vertices) and the `Q` blocks with their holds.
type KeptBlocks = (Vec<Vec<u32>>, Vec<(usize, usize, DMat4)>);

impl HeldBlocks {
    /// The blocks for `patches` (called again for each comparison): the kept ones when they
    /// are of the same patches, else `make`'s, kept. (A solver used from two threads at once
    /// makes them for one of them without keeping them.)
    fn get<'p, I: Iterator<Item = &'p [u32]>>(
        &self,
        patches: impl Fn() -> I,
        make: impl FnOnce() -> Vec<(usize, usize, DMat4)>,
    ) -> Vec<(usize, usize, DMat4)> {
        let Ok(mut kept) = self.0.try_lock() else {
            return make();
        };
        if let Some((held, blocks)) = kept.as_ref()
            && held.len() == patches().count()
            && held.iter().zip(patches()).all(|(a, b)| a[..] == *b)
        {
            return blocks.clone();
        }
        let blocks = make();
        *kept = Some((patches().map(<[u32]>::to_vec).collect(), blocks.clone()));
        blocks
    }
}

impl Clone for HeldBlocks {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for HeldBlocks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("HeldBlocks")
    }
}

impl PoseSolver {
    /// This solve's `Q` blocks: the solver's with the holds of every planted contact added,
    /// whose linear and constant parts go to `b` (4J × 3) and `constant`. Borrowed when
    /// nothing is planted.
    pub(crate) fn with_holds<'a>(
        &'a self,
        contacts: &[Contact],
        b: &mut [f64],
        constant: &mut f64,
    ) -> Cow<'a, QBlocks> {
        let planted: Vec<_> = self.held_points(contacts).collect();
        if planted.is_empty() {
            return Cow::Borrowed(&self.q_blocks);
        }
        let weight = contact_hold_weight(self.joint_weight);
        for &(patch, at, lift) in &planted {
            for (&v, &touched) in patch.iter().zip(at) {
                let target = touched + lift;
                for (j, mj) in self.model.row(v as usize) {
                    add_outer4x3(b, j, mj * weight, target);
                }
                *constant += weight * target.length_squared();
            }
        }
        let patches = || planted.iter().map(|(patch, _, _)| *patch);
        Cow::Owned(
            self.held_blocks
                .get(patches, || self.blocks_with_holds(patches(), weight)),
        )
    }

    /// The solver's `Q` blocks with `w m_j m_kᵀ` added for every vertex of `patches` (their
    /// holds' quadratic part: the same while the same patches are planted).
    fn blocks_with_holds<'p>(
        &self,
        patches: impl Iterator<Item = &'p [u32]>,
        weight: f64,
    ) -> Vec<(usize, usize, DMat4)> {
        let joints = self.model.skeleton().len();
        // Where each (k, l) block is in the list.
        let mut index: Vec<Option<usize>> = vec![None; joints * joints];
        for (i, &(k, l, _)) in self.q_blocks.iter().enumerate() {
            index[k * joints + l] = Some(i);
        }
        let mut list = self.q_blocks.clone();
        for &v in patches.flatten() {
            for (j, mj) in self.model.row(v as usize) {
                for (k, mk) in self.model.row(v as usize) {
                    let slot = *index[j * joints + k].get_or_insert_with(|| {
                        list.push((j, k, DMat4::ZERO));
                        list.len() - 1
                    });
                    let q = &mut list[slot].2;
                    // Q_jk[r][c] += w m_j[r] m_k[c]: column c gains m_j · w m_k[c].
                    for c in 0..4 {
                        *q.col_mut(c) += mj * (weight * mk[c]);
                    }
                }
            }
        }
        list
    }

    /// How far the planted patch vertex farthest from its held point is from it, with the
    /// joints' skinning transforms `skin` (0 with nothing planted).
    pub(crate) fn farthest_off_hold(&self, contacts: &[Contact], skin: &[DAffine3]) -> f64 {
        let skins = self.model.vertex_skins();
        let skinned = |v: u32| skins[v as usize].skinned(skin);
        self.held_points(contacts)
            .flat_map(|(patch, at, lift)| patch.iter().zip(at).map(move |(&v, &t)| (v, t + lift)))
            .map(|(v, target)| skinned(v).distance(target))
            .fold(0.0, f64::max)
    }

    /// Each planted contact's patch, the points its vertices touched, and the lift of its
    /// holds above them (the contact skin along its ground's normal).
    fn held_points<'c>(
        &self,
        contacts: &'c [Contact],
    ) -> impl Iterator<Item = (&'c [u32], &'c [DVec3], DVec3)> + 'c {
        let skin = contact_skin(self.length_scale);
        contacts.iter().filter_map(move |c| {
            c.planted
                .as_ref()
                .map(|at| (&c.patch[..], &at[..], c.ground.normal * skin))
        })
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{DQuat, DVec3};

    use crate::pose::constraints::PoseConstraints;
    use crate::pose::ground::GroundPlane;
    use crate::pose::ground::contact::Contact;
    use crate::pose::rig::synth_rig::mannequin_rig;
    use crate::pose::solver::energy::arap::q_times_into;
    use crate::pose::solver::{PoseSolver, PoseSolverSettings};

    /// What the holds of `contacts` folded into `Q`, `B` and the constant weigh at a pose
    /// away from the rest, and what the per-vertex terms `w ‖skinned vertex − held point‖²`
    /// of the planted ones weigh there.
    fn folded_and_direct(
        solver: &PoseSolver,
        rest: &crate::pose::rig::skeleton::SkeletonPose,
        contacts: &[Contact],
    ) -> (f64, f64) {
        let model = &solver.model;
        let dim = model.skeleton().len() * 12;
        let (mut b, mut constant) = (vec![0.0; dim], 0.0);
        let blocks = solver.with_holds(contacts, &mut b, &mut constant);
        let mut pose = rest.clone();
        for (j, t) in pose.local.iter_mut().enumerate() {
            t.rotation = DQuat::from_euler(glam::EulerRot::XYZ, 0.1 * j as f64, -0.2, 0.05);
            t.translation += DVec3::splat(0.01 * j as f64);
        }
        let posed = solver.posed(pose.clone(), &blocks);
        let plain = solver.posed(pose.clone(), &solver.q_blocks);
        let mut qx = Vec::new();
        q_times_into(&blocks, &posed.x, &mut qx);
        let quadratic = |qx: &[f64], b: &[f64], c: f64| {
            posed
                .x
                .iter()
                .zip(qx)
                .zip(b)
                .map(|((x, q), b)| x * q - 2.0 * x * b)
                .sum::<f64>()
                + c
        };
        let folded = quadratic(&qx, &b, constant) - quadratic(&plain.qx, &vec![0.0; dim], 0.0);
        let skinned = model.skin_welded(&pose);
        let weight = crate::pose::solver::terms::contact_hold_weight(solver.joint_weight);
        // Each hold is lifted off the touching point by the contact skin, along the normal.
        let lift = DVec3::Y * crate::pose::solver::terms::contact_skin(solver.length_scale);
        let direct: f64 = contacts
            .iter()
            .filter_map(|c| c.planted.as_ref().map(|held| (&c.patch, held)))
            .flat_map(|(patch, held)| patch.iter().zip(held))
            .map(|(&v, t)| weight * (skinned[v as usize] - (*t + lift)).length_squared())
            .sum();
        (folded, direct)
    }

    /// The holds folded into `Q`, `B` and the constant weigh, at any pose, exactly what the
    /// per-vertex terms `w ‖skinned vertex − held point‖²` weigh (a hold on the wrong
    /// block, side or weight changes the sum) — also in the next solves of the same solver,
    /// which keeps the blocks of the patches it held last: with another patch planted, and
    /// with the same patch held elsewhere. (Fails with the kept blocks reused for another
    /// patch.)
    #[test]
    fn folded_holds_weigh_what_each_held_vertex_does() {
        let rig = mannequin_rig(12);
        let model = Arc::new(rig.model().unwrap());
        let solver = PoseSolver::new(
            model.clone(),
            &PoseConstraints::default(),
            &rig.rest,
            PoseSolverSettings::default(),
        )
        .unwrap();
        let ground = GroundPlane::new(DVec3::ZERO, DVec3::Y).unwrap();
        // Patches held at points away from where any pose puts them, one planted at a time.
        let planted = |patch: Vec<u32>, shift: f64| {
            let held: Vec<DVec3> = (0..patch.len())
                .map(|i| DVec3::new(0.1 * i as f64 + shift, -0.05, 0.3 - 0.02 * i as f64))
                .collect();
            let mut contact = Contact::new(1, patch, ground);
            contact.planted = Some(held);
            contact
        };
        let free = Contact::new(2, (50..60).collect(), ground);
        let first = [planted((0..40).step_by(3).collect(), 0.0), free.clone()];
        let other = [planted((100..160).step_by(2).collect(), 0.0), free.clone()];
        let moved = [planted((100..160).step_by(2).collect(), 0.2), free];
        for contacts in [&first, &other, &moved, &first] {
            let (folded, direct) = folded_and_direct(&solver, &rig.rest, contacts);
            assert!(direct > 0.0);
            assert!(
                (folded - direct).abs() < 1e-9 * direct,
                "folded {folded} vs per vertex {direct}"
            );
        }
    }
}
