//! A live source retargeted frame by frame (a motion-capture stream, another character's
//! pose as it plays): each frame carried over and solved as a bake's frame is, with the
//! source's contacts read from the frames seen so far.
//!
//! A bake sees the whole clip; a live source does not, so its contacts are read differently:
//!
//! * **ground**: the source's ground is its rest pose's lowest foot (the clip's lowest would
//!   need the clip); [`LiveRetarget::set_source_ground`] sets it when the stream knows better;
//! * **speed**: the backward difference from the previous frame (no frame to come);
//! * **no shortest run**: a foot plants in the first frame it is low and slow, so a hold
//!   never lags the source; a frame whose time does not advance keeps each low foot's last
//!   state;
//! * **a still ground**: a live source travels (a stream made in place would need its
//!   ground's speed, which a bake finds over the clip).

use glam::DVec3;

use crate::pose::ground::Ground;
use crate::pose::retarget::RetargetError;
use crate::pose::retarget::bake::{Retargeter, source_leg};
use crate::pose::retarget::transfer::PoseTransfer;
use crate::pose::rig::skeleton::SkeletonPose;
use crate::pose::solver::PoseSolution;

/// One live frame retargeted.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveFrame {
    /// The target's pose.
    pub pose: SkeletonPose,
    /// Per foot of the map: whether the source's foot is planted in this frame.
    pub planted: Vec<bool>,
}

/// The state of a live retarget: the feet's holds, the source's feet in the last frame and
/// the last solve (the next one's warm start). Made by [`Retargeter::live`].
pub struct LiveRetarget<'a> {
    retargeter: &'a Retargeter,
    transfer: PoseTransfer,
    up: DVec3,
    leg: f64,
    previous: Option<(f64, Vec<DVec3>)>,
    planted: Vec<bool>,
    holds: Vec<Option<DVec3>>,
    last: Option<PoseSolution>,
}

impl Retargeter {
    /// Starts retargeting a live source frame by frame ([`LiveRetarget::frame`]).
    pub fn live(&self) -> LiveRetarget<'_> {
        let transfer = self.transfer().clone();
        let map = transfer.map();
        let up = map.axes[0].0.normalize_or(DVec3::Y);
        let feet = map.feet.len();
        LiveRetarget {
            leg: source_leg(transfer.source(), self.source_rest(), map),
            up,
            transfer,
            previous: None,
            planted: vec![false; feet],
            holds: vec![None; feet],
            last: None,
            retargeter: self,
        }
    }
}

impl LiveRetarget<'_> {
    /// Sets the height (along the source's up) of the source's ground: its feet's joints when
    /// planted. The target's feet stand on its ground when the source's are this high.
    pub fn set_source_ground(&mut self, height: f64) {
        self.transfer.set_source_foot_height(height);
    }

    /// Forgets the holds, the previous frame and the last solve (a cut in the stream).
    pub fn reset(&mut self) {
        self.previous = None;
        self.planted.iter_mut().for_each(|p| *p = false);
        self.holds.iter_mut().for_each(|h| *h = None);
        self.last = None;
    }

    /// Retargets the source's pose at `time` (seconds) onto the target standing on `ground`.
    /// A source pose of the wrong length or with a non-finite joint is a typed error, as is a
    /// solve that does not give a finite pose; either way the state is left as it was, so the
    /// caller keeps showing the last good pose and the next good frame goes on from it.
    pub fn frame(
        &mut self,
        source_pose: &SkeletonPose,
        time: f64,
        ground: &dyn Ground,
    ) -> Result<LiveFrame, RetargetError> {
        let source = self.transfer.source();
        source.check_pose(source_pose)?;
        let g = source.global_transforms(source_pose);
        let up = self.up;
        let feet: Vec<DVec3> = self
            .transfer
            .map()
            .feet
            .iter()
            .map(|f| g[f.0].translation)
            .collect();
        let thresholds = self.retargeter.settings().thresholds;
        // The rest's lowest foot unless set (the transfer stands the target's feet on its
        // ground when the source's are this high).
        let ground_height = self.transfer.source_foot_height();
        let dt = self
            .previous
            .as_ref()
            .map(|(t, _)| time - t)
            .filter(|dt| dt.is_finite() && *dt > 0.0);
        let planted: Vec<bool> = feet
            .iter()
            .enumerate()
            .map(|(k, &at)| {
                let low = at.dot(up) - ground_height <= thresholds.height * self.leg;
                let slow = match (dt, &self.previous) {
                    (Some(dt), Some((_, before))) => {
                        let moved = at - before[k];
                        (moved - up * moved.dot(up)).length() / dt <= thresholds.speed * self.leg
                    }
                    // The first frame: nothing to tell the speed by.
                    (None, None) => true,
                    // A frame whose time does not advance: as it was.
                    (None, Some(_)) => self.planted[k],
                    (Some(_), None) => true,
                };
                low && slow
            })
            .collect();
        let carried = self.transfer.transfer(source_pose);
        let pose = if self.retargeter.settings().contacts {
            let mut holds = self.holds.clone();
            let solution = self.retargeter.solve_frame(
                &carried,
                &planted,
                &mut holds,
                ground,
                self.last.as_ref(),
            )?;
            self.holds = holds;
            let pose = solution.pose.clone();
            self.last = Some(solution);
            pose
        } else {
            carried
        };
        self.previous = Some((time, feet));
        self.planted.clone_from(&planted);
        Ok(LiveFrame { pose, planted })
    }
}
