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
}

impl Default for ContactThresholds {
    fn default() -> Self {
        Self {
            height: 0.06,
            speed: 0.4,
            min_frames: 2,
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
/// `skeleton`, `frame_time` seconds apart), `up` the source's world up, `leg` its leg length.
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
    let positions: Vec<Vec<DVec3>> = frames
        .iter()
        .map(|pose| {
            let g = skeleton.global_transforms(pose);
            feet.iter().map(|&f| g[f].translation).collect()
        })
        .collect();
    let n = frames.len();
    let mut planted = Vec::with_capacity(feet.len());
    let mut planted_height = Vec::with_capacity(feet.len());
    for k in 0..feet.len() {
        let heights: Vec<f64> = positions.iter().map(|p| p[k].dot(up)).collect();
        let mut sorted = heights.clone();
        sorted.sort_by(f64::total_cmp);
        let low = sorted.get(n * 2 / 100).copied().unwrap_or(0.0);
        let horizontal = |p: DVec3| p - up * p.dot(up);
        let mut flags: Vec<bool> = (0..n)
            .map(|f| {
                let (a, b) = (f.saturating_sub(1), (f + 1).min(n - 1));
                let span = (b - a) as f64 * frame_time;
                let speed = if span > 0.0 {
                    horizontal(positions[b][k] - positions[a][k]).length() / span
                } else {
                    0.0
                };
                heights[f] - low <= thresholds.height * leg && speed <= thresholds.speed * leg
            })
            .collect();
        // Drop runs shorter than the minimum.
        let mut f = 0;
        while f < n {
            if flags[f] {
                let start = f;
                while f < n && flags[f] {
                    f += 1;
                }
                if f - start < thresholds.min_frames {
                    flags[start..f].iter_mut().for_each(|p| *p = false);
                }
            } else {
                f += 1;
            }
        }
        planted.push(flags);
        planted_height.push(low);
    }
    SourceContacts {
        planted,
        planted_height,
    }
}
