//! Where the source's feet are planted, read off the clip itself: a foot is planted in a frame
//! when its joint is near its lowest height over the clip and barely moving across the ground.
//!
//! Thresholds are shares of the source's leg length `L` (so they hold for any unit, a
//! ×100 armature included):
//!
//! * **height**: the foot joint within `0.06 L` of its planted height — the 2nd percentile of
//!   its heights over the clip (robust against a stray frame below the floor). A walking
//!   foot's ankle rises 0.1–0.2 L mid-swing; heel-strike to toe-off stays within 0.05 L.
//! * **speed**: horizontal speed at most `0.4 L` per second (central differences). A swinging
//!   foot moves at 2–5 L/s; a planted one at 0 (mocap jitter stays under 0.1 L/s).
//! * runs shorter than 2 frames are dropped (a foot passing low through its swing).
//!
//! **Clips made in place** (most game clips: the root motion taken out, so the body stays and
//! each stance foot slides back under it, as on a treadmill) have no still foot. Their ground
//! moves: its velocity, the *treadmill*, is the velocity most of the low feet share — among
//! the (foot, frame) pairs within the height threshold, the velocity with the most others
//! within the speed threshold of it, their median (axis by axis). A clip that travels over a
//! still ground has its stance feet at rest, so that velocity is zero (and one within the
//! speed threshold of zero is taken as zero). Under a clip made in place a low foot is planted
//! while it moves back with the ground at a quarter of its speed or more, and across it
//! within the speed threshold: artists' stance feet slide unevenly under the body (the
//! Fox's Walk from 0.3 to 2.5 times the mean speed), so a speed band about the mean would cut
//! stances in pieces; a low foot moving forward is landing or lifting off. The target's held
//! feet move with the ground at that one velocity, an even pace.

use glam::DVec3;

use crate::pose::rig::skeleton::{Skeleton, SkeletonPose};

/// When a source foot counts as planted (shares of the source's leg length; see the module
/// docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactThresholds {
    /// Height over its planted height, in leg lengths.
    pub height: f64,
    /// Horizontal speed, in leg lengths per second.
    pub speed: f64,
    /// Shortest run of planted frames kept.
    pub min_frames: usize,
    /// Under a clip made in place: the least share of the ground's speed a low foot moves back
    /// with to count as planted (see the module docs).
    pub in_place_share: f64,
}

impl Default for ContactThresholds {
    fn default() -> Self {
        Self {
            height: 0.06,
            speed: 0.4,
            min_frames: 2,
            in_place_share: 0.25,
        }
    }
}

/// The source's feet over a clip's frames.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceContacts {
    /// Per foot (in the map's order), per frame: planted.
    pub planted: Vec<Vec<bool>>,
    /// Per foot, its joint's height (along up) when planted.
    pub planted_height: Vec<f64>,
    /// The ground's horizontal velocity under the clip, in source units a second: zero for a
    /// clip whose body travels over a still ground, the stance feet's velocity for a clip
    /// made in place (see the module docs). A planted foot moves with it.
    pub treadmill: DVec3,
    /// Seconds between the clip's frames.
    pub frame_time: f64,
}

impl SourceContacts {
    /// The share of (foot, frame) pairs that are planted.
    pub fn planted_share(&self) -> f64 {
        let total: usize = self.planted.iter().map(Vec::len).sum();
        let planted: usize = self
            .planted
            .iter()
            .map(|f| f.iter().filter(|p| **p).count())
            .sum();
        if total == 0 {
            0.0
        } else {
            planted as f64 / total as f64
        }
    }
}

/// Finds the planted frames of each of `feet` (source joints) over `frames` (poses of
/// `skeleton`, `frame_time` seconds apart), `up` the source's world up, `leg` its leg length;
/// and the ground's velocity under a clip made in place (see the module docs).
pub fn detect_contacts(
    skeleton: &Skeleton,
    frames: &[SkeletonPose],
    frame_time: f64,
    feet: &[usize],
    up: DVec3,
    leg: f64,
    thresholds: &ContactThresholds,
) -> SourceContacts {
    let up = up.normalize_or(DVec3::Y);
    let horizontal = |p: DVec3| p - up * p.dot(up);
    let positions: Vec<Vec<DVec3>> = frames
        .iter()
        .map(|pose| {
            let g = skeleton.global_transforms(pose);
            feet.iter().map(|&f| g[f].translation).collect()
        })
        .collect();
    let n = frames.len();
    // Per foot: its planted height, and per frame whether it is that low and its horizontal
    // velocity (central differences).
    let mut planted_height = Vec::with_capacity(feet.len());
    let mut low = Vec::with_capacity(feet.len());
    let mut velocities = Vec::with_capacity(feet.len());
    for k in 0..feet.len() {
        let heights: Vec<f64> = positions.iter().map(|p| p[k].dot(up)).collect();
        let mut sorted = heights.clone();
        sorted.sort_by(f64::total_cmp);
        let lowest = sorted.get(n * 2 / 100).copied().unwrap_or(0.0);
        planted_height.push(lowest);
        low.push(
            heights
                .iter()
                .map(|h| h - lowest <= thresholds.height * leg)
                .collect::<Vec<bool>>(),
        );
        velocities.push(
            (0..n)
                .map(|f| {
                    let (a, b) = (f.saturating_sub(1), (f + 1).min(n - 1));
                    let span = (b - a) as f64 * frame_time;
                    if span > 0.0 {
                        horizontal(positions[b][k] - positions[a][k]) / span
                    } else {
                        DVec3::ZERO
                    }
                })
                .collect::<Vec<DVec3>>(),
        );
    }
    let tolerance = thresholds.speed * leg;
    let low_velocities: Vec<DVec3> = velocities
        .iter()
        .zip(&low)
        .flat_map(|(v, l)| v.iter().zip(l).filter(|(_, l)| **l).map(|(v, _)| *v))
        .collect();
    let treadmill = shared_velocity(&low_velocities, tolerance);
    let planted = velocities
        .iter()
        .zip(&low)
        .map(|(v, l)| {
            let mut flags: Vec<bool> = v
                .iter()
                .zip(l)
                .map(|(v, l)| *l && moves_with_the_ground(*v, treadmill, tolerance, thresholds))
                .collect();
            drop_short_runs(&mut flags, thresholds.min_frames);
            flags
        })
        .collect();
    SourceContacts {
        planted,
        planted_height,
        treadmill,
        frame_time,
    }
}

/// Whether a low foot moving at `velocity` (horizontal) stands on a ground moving at
/// `treadmill`: on a still ground, within `tolerance` of still; on a moving one (a clip made
/// in place), moving back with it at least [`ContactThresholds::in_place_share`] of its speed
/// (an artist's stance foot slides unevenly under the body: the Fox's Walk from 0.3 to 2.5
/// times the mean) and across it within `tolerance`. A low foot moving forward under a body
/// made in place is landing or lifting off.
fn moves_with_the_ground(
    velocity: DVec3,
    treadmill: DVec3,
    tolerance: f64,
    thresholds: &ContactThresholds,
) -> bool {
    let speed = treadmill.length();
    if speed == 0.0 {
        return velocity.length() <= tolerance;
    }
    let along = treadmill / speed;
    let with = velocity.dot(along);
    with >= thresholds.in_place_share * speed && (velocity - along * with).length() <= tolerance
}

/// Most candidates a shared velocity is searched among (evenly spaced through the samples):
/// the search is quadratic in them, and a long capture has tens of thousands of low frames.
const MOST_CANDIDATES: usize = 256;

/// The velocity most of `velocities` share: the one (of up to [`MOST_CANDIDATES`] of them)
/// with the most others within `tolerance`, their median; zero when that is within
/// `tolerance` of zero, or there are none.
fn shared_velocity(velocities: &[DVec3], tolerance: f64) -> DVec3 {
    let stride = velocities.len().div_ceil(MOST_CANDIDATES).max(1);
    let near = |c: DVec3| {
        velocities
            .iter()
            .filter(move |v| (**v - c).length() <= tolerance)
    };
    let best = velocities
        .iter()
        .step_by(stride)
        .map(|&c| (near(c).count(), c))
        .max_by(|a, b| a.0.cmp(&b.0).then(b.1.length().total_cmp(&a.1.length())));
    let Some((_, candidate)) = best.filter(|(count, _)| *count > 0) else {
        return DVec3::ZERO;
    };
    // Their median, axis by axis: the frames where a foot starts to lift or land are near the
    // band's edge and would pull a mean off the stance's speed.
    let inliers: Vec<DVec3> = near(candidate).copied().collect();
    let median = |axis: fn(&DVec3) -> f64| {
        let mut values: Vec<f64> = inliers.iter().map(axis).collect();
        let middle = values.len() / 2;
        *values.select_nth_unstable_by(middle, f64::total_cmp).1
    };
    let shared = DVec3::new(median(|v| v.x), median(|v| v.y), median(|v| v.z));
    if shared.length() <= tolerance || !shared.is_finite() {
        DVec3::ZERO
    } else {
        shared
    }
}

/// Clears the runs of `true` in `flags` shorter than `min_frames`.
fn drop_short_runs(flags: &mut [bool], min_frames: usize) {
    let n = flags.len();
    let mut f = 0;
    while f < n {
        if flags[f] {
            let start = f;
            while f < n && flags[f] {
                f += 1;
            }
            if f - start < min_frames {
                flags[start..f].iter_mut().for_each(|p| *p = false);
            }
        } else {
            f += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stance feet sliding back at one speed, swinging feet faster forward: the stance
    /// speed is found, and a still majority reads as a still ground.
    #[test]
    fn the_velocity_the_low_feet_share_is_the_ground_s() {
        let back = DVec3::new(0.0, 0.0, -1.2);
        let mut samples: Vec<DVec3> = (0..30)
            .map(|i| back + DVec3::new(0.01 * (i % 3) as f64, 0.0, 0.02 * (i % 5) as f64))
            .collect();
        samples.extend((0..12).map(|i| DVec3::new(0.0, 0.0, 2.0 + 0.1 * i as f64)));
        let found = shared_velocity(&samples, 0.3);
        assert!((found - back).length() < 0.05, "found {found}");
        let still: Vec<DVec3> = (0..30)
            .map(|i| DVec3::new(0.0, 0.0, 0.01 * (i % 4) as f64))
            .chain((0..20).map(|_| back))
            .collect();
        assert_eq!(shared_velocity(&still, 0.3), DVec3::ZERO);
        assert_eq!(shared_velocity(&[], 0.3), DVec3::ZERO);
    }

    /// Runs shorter than the minimum are cleared, longer ones kept.
    #[test]
    fn short_runs_are_dropped() {
        let mut flags = [true, false, true, true, false, true, true, true];
        drop_short_runs(&mut flags, 3);
        assert_eq!(flags, [false, false, false, false, false, true, true, true]);
    }
}
