//! Symmetric editing ([`super::super::SymmetricEditing`]): every driver on one side of the character
//! drives its mirror image too — effectors on the partner joint, grabbed vertex sets (rigid
//! handles and position-only followers) on the vertices mirroring them.

use std::sync::Arc;

use glam::{DAffine3, DVec3};

use super::super::PosedSkeleton;
use crate::deform::Handle as CoreHandle;
use crate::pose::{CentroidEffector, Effector, Mirror};

/// What symmetric editing needs, built when it is first asked for: the left/right pairs, the
/// welded vertices where the character is symmetric (skinned in its bind pose, world space),
/// and the mirror image of each vertex set met so far (sets change only when a grab starts).
pub(super) struct Symmetry {
    mirror: Arc<Mirror>,
    frame: DAffine3,
    bind: Vec<DVec3>,
    sets: Vec<(Vec<u32>, Option<Vec<u32>>)>,
    /// For the last constraints mirrored: each mirrored effector's (original, mirror) index.
    pub(super) mirrored_effectors: Vec<(usize, usize)>,
}

impl Symmetry {
    /// Pairs and bind positions of `posed`'s model.
    pub(super) fn new(posed: &PosedSkeleton) -> Self {
        let skeleton = posed.model.skeleton();
        let bind_pose = skeleton.bind_pose();
        Self {
            mirror: Arc::new(Mirror::new(skeleton, &bind_pose)),
            frame: skeleton.joints()[0].parent_frame,
            bind: posed.model.skin_welded(&bind_pose),
            sets: Vec::new(),
            mirrored_effectors: Vec::new(),
        }
    }

    /// The mirror image of `effector` (character space), `None` for an unpaired joint.
    pub(super) fn mirror_effector(&self, effector: &Effector) -> Option<Effector> {
        self.mirror.mirror_effector(effector, &self.frame)
    }

    /// The vertices mirroring `set` (cached), `None` for a set that mirrors onto itself.
    fn mirrored_set(&mut self, set: &[u32]) -> Option<Vec<u32>> {
        if let Some((_, mirrored)) = self.sets.iter().find(|(s, _)| s == set) {
            return mirrored.clone();
        }
        let mirrored = self.mirror.mirror_vertices(&self.bind, set, &self.frame);
        if self.sets.len() > 64 {
            self.sets.clear();
        }
        self.sets.push((set.to_vec(), mirrored.clone()));
        mirrored
    }

    /// Adds the mirror image of every effector, rigid handle and follower. A mirrored vertex
    /// set that would share a vertex with any other constraint's set is left out (the solver
    /// takes each vertex in one set at most).
    pub(super) fn mirror_drivers(
        &mut self,
        effectors: &mut Vec<Effector>,
        handles: &mut Vec<CoreHandle>,
        centroids: &mut Vec<CentroidEffector>,
        fixed_vertices: &[u32],
    ) {
        // In character space (the model's): the plane is the root parent frame's x = 0.
        let originals = effectors.len();
        self.mirrored_effectors.clear();
        for i in 0..originals {
            if let Some(m) = self.mirror_effector(&effectors[i]) {
                self.mirrored_effectors.push((i, effectors.len()));
                effectors.push(m);
            }
        }
        let mut used: std::collections::HashSet<u32> = fixed_vertices
            .iter()
            .chain(handles.iter().flat_map(|h| &h.vertices))
            .chain(centroids.iter().flat_map(|c| &c.vertices))
            .copied()
            .collect();
        let mut claim = |set: Option<Vec<u32>>| {
            let set = set.filter(|s| s.iter().all(|v| !used.contains(v)))?;
            used.extend(set.iter().copied());
            Some(set)
        };
        let new_handles: Vec<CoreHandle> = handles
            .iter()
            .filter_map(|h| {
                let vertices = claim(self.mirrored_set(&h.vertices))?;
                Some(CoreHandle {
                    vertices,
                    transform: self.mirror.mirror_motion(&h.transform, &self.frame),
                })
            })
            .collect();
        let new_centroids: Vec<CentroidEffector> = centroids
            .iter()
            .filter_map(|c| {
                let vertices = claim(self.mirrored_set(&c.vertices))?;
                Some(CentroidEffector {
                    vertices,
                    target: self.mirror.reflect_point(c.target, &self.frame),
                    weight: c.weight,
                })
            })
            .collect();
        handles.extend(new_handles);
        centroids.extend(new_centroids);
    }
}
