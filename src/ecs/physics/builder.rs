//! The collider builder: one long-lived background thread that builds the colliders of bent
//! meshes and frees the ones they replace, handed its work over a channel.
//!
//! Why not the async compute pool: on a machine with few cores, a build spawned there woke a
//! pool thread that took a core from the frame's own systems, and the main thread's time in
//! the frame it started went from 0.2 to 2.5–4.8 ms (`plugin_bench --collider`). The builder
//! thread is already running (no wake of a sleeping pool), and on Linux it is in the idle
//! scheduling class (`SCHED_IDLE`; nice 19 where that is refused).
//!
//! A low priority is not enough on its own. Kernels that preempt lazily (`PREEMPT_NONE` or
//! `PREEMPT_LAZY`, as on many servers, VMs and newer distributions) let a running thread keep
//! its core until the next scheduler tick, 4 ms at 250 Hz, even when a thread of the frame
//! wakes for it; a 3 ms triangle-mesh build held the frame up for its whole length. So the
//! builder's work comes in short pieces:
//! - **a bent triangle mesh is refitted, not rebuilt**: when the collider it replaces is a
//!   triangle mesh of the same triangles over as many vertices (a bend moves vertices and keeps
//!   the topology), its copy gets the new positions and its bounding-volume tree is refitted
//!   in place (the tree keeps the structure it was built with for the first shape), a tenth of
//!   a build;
//! - the thread yields its core between the pieces of a job.
//!
//! Where threads cannot be made (the web) the build runs where it is asked for.

use avian3d::parry::shape::SharedShape;
use avian3d::prelude::*;
use bevy::mesh::Indices;
use bevy::prelude::*;
use crossbeam_channel::{Receiver, Sender};

use super::ColliderShape;

/// A bent mesh's collider, or why it could not be built.
pub(crate) type BuildResult = Result<Collider, String>;

/// What the builder thread is asked to do.
enum Job {
    /// Build a collider and send it back.
    Build {
        shape: ColliderShape,
        positions: Vec<Vec3>,
        /// The mesh's index buffer as it is (the triangles are made on the builder thread).
        indices: Option<Indices>,
        /// The collider this one will replace: a triangle mesh of the same triangles is
        /// refitted instead of built.
        previous: Option<Collider>,
        reply: Sender<BuildResult>,
    },
    /// Free a replaced collider (a large triangle mesh takes milliseconds to free).
    Free(Collider),
}

/// The handle to the builder thread ([`DeformPhysicsPlugin`](super::DeformPhysicsPlugin)'s
/// resource). The thread starts with the first job and ends when the resource is dropped.
#[derive(Resource, Default)]
pub(crate) struct ColliderBuilder {
    jobs: Option<Sender<Job>>,
}

impl ColliderBuilder {
    /// Builds a `shape` collider over the mesh (its positions and index buffer) in the
    /// background, refitting `previous`, the collider it will replace, when that is a triangle
    /// mesh of the same triangles; its result arrives on the returned channel.
    pub(crate) fn build(
        &mut self,
        shape: ColliderShape,
        positions: Vec<Vec3>,
        indices: Option<Indices>,
        previous: Option<Collider>,
    ) -> Receiver<BuildResult> {
        let (reply, result) = crossbeam_channel::bounded(1);
        self.send(Job::Build {
            shape,
            positions,
            indices,
            previous,
            reply,
        });
        result
    }

    /// Frees `collider` in the background.
    pub(crate) fn free(&mut self, collider: Collider) {
        self.send(Job::Free(collider));
    }

    /// Hands `job` to the thread (started on first use, and again if it has gone); where no
    /// thread can be started, runs it here.
    fn send(&mut self, mut job: Job) {
        for _ in 0..2 {
            if self.jobs.is_none() {
                self.jobs = spawn_thread();
            }
            let Some(jobs) = &self.jobs else {
                break;
            };
            match jobs.send(job) {
                Ok(()) => return,
                Err(returned) => {
                    job = returned.0;
                    self.jobs = None;
                }
            }
        }
        run(job);
    }
}

/// Starts the builder thread; `None` where threads cannot be started.
fn spawn_thread() -> Option<Sender<Job>> {
    if cfg!(target_arch = "wasm32") {
        return None;
    }
    let (jobs, incoming) = crossbeam_channel::unbounded::<Job>();
    std::thread::Builder::new()
        .name("collider builder".into())
        .spawn(move || {
            lower_priority();
            for job in incoming {
                run(job);
            }
        })
        .ok()?;
    Some(jobs)
}

/// The calling thread at the lowest CPU priority: on Linux the idle scheduling class
/// (`SCHED_IDLE`: it runs on a core nothing else wants), or nice 19 where that is refused.
/// Elsewhere `setpriority` would lower the whole process, so it is left alone.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: `sched_setscheduler` and `setpriority` with id 0 only change the calling
    // thread's scheduling on Linux; the parameter is a local the call only reads.
    unsafe {
        let idle = libc::sched_param { sched_priority: 0 };
        if libc::sched_setscheduler(0, libc::SCHED_IDLE, &idle) != 0 {
            libc::setpriority(libc::PRIO_PROCESS, 0, 19);
        }
    }
}

/// Does one job (a dropped reply channel — its entity gone — is no error).
fn run(job: Job) {
    match job {
        Job::Build {
            shape,
            positions,
            indices,
            previous,
            reply,
        } => {
            let triangles = indices.as_ref().map(triangles_of).unwrap_or_default();
            let _ = reply.send(build(shape, positions, triangles, previous));
        }
        Job::Free(collider) => drop(collider),
    }
}

/// The triangles of a triangle-list index buffer (a trailing partial triangle is dropped).
fn triangles_of(indices: &Indices) -> Vec<[u32; 3]> {
    match indices {
        Indices::U16(i) => i
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]].map(u32::from))
            .collect(),
        Indices::U32(i) => i.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

/// The collider of `shape` over the bent mesh (`previous` refitted when it is a triangle mesh
/// of the same triangles over as many vertices); a readable reason when it cannot be built.
/// The mesh's vertices are kept as they are (seam copies too), so that the next bend of the
/// same mesh finds the same vertex list to refit.
fn build(
    shape: ColliderShape,
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    previous: Option<Collider>,
) -> BuildResult {
    if !positions.iter().all(|p| p.is_finite()) {
        return Err("the bent mesh has non-finite positions".into());
    }
    match shape {
        ColliderShape::Trimesh => {
            if triangles.is_empty() {
                return Err("the mesh has no triangles".into());
            }
            let refittable = previous
                .as_ref()
                .and_then(|c| c.shape().as_trimesh())
                .filter(|mesh| {
                    mesh.vertices().len() == positions.len() && mesh.indices() == triangles
                });
            if let Some(mesh) = refittable {
                let mut mesh = mesh.clone();
                std::thread::yield_now();
                mesh.set_vertices(&positions);
                return Ok(Collider::from(SharedShape::new(mesh)));
            }
            Collider::try_trimesh_with_config(positions, triangles, TrimeshFlags::empty())
                .map_err(|e| format!("no triangle mesh collider: {e:?}"))
        }
        ColliderShape::ConvexHull => Collider::convex_hull(&positions)
            .ok_or_else(|| "no convex hull (the vertices are flat or too few)".to_string()),
    }
}

#[cfg(test)]
mod tests {
    use avian3d::parry::query::{Ray, RayCast};
    use avian3d::parry::shape::TriMesh;

    use super::*;

    /// The builder thread answers each build on its own channel, keeps answering after
    /// freeing a collider, and a bent mesh with a non-finite position is a readable error,
    /// not a collider. The mesh's index buffer is made into its triangles on the thread,
    /// 16-bit or 32-bit alike. (Fails with a build whose reply is never sent: the wait times
    /// out.)
    #[test]
    fn builds_arrive_on_their_channels_and_bad_meshes_are_errors() {
        let mut builder = ColliderBuilder::default();
        let wait = |r: Receiver<BuildResult>| {
            r.recv_timeout(std::time::Duration::from_secs(30))
                .expect("a reply")
        };
        let square = vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::X + Vec3::Z];
        let short = Indices::U16(vec![0, 1, 2, 1, 3, 2]);
        let first = builder.build(ColliderShape::Trimesh, square.clone(), Some(short), None);
        let collider = wait(first).expect("a collider of two triangles");
        let mesh = collider.shape().as_trimesh().expect("a triangle mesh");
        assert_eq!(mesh.indices(), &[[0, 1, 2], [1, 3, 2]]);
        builder.free(collider);
        let long = Indices::U32(vec![0, 1, 2, 1, 3, 2]);
        let again = wait(builder.build(ColliderShape::Trimesh, square.clone(), Some(long), None))
            .expect("the same square from 32-bit indices");
        assert_eq!(again.shape().as_trimesh().unwrap().num_triangles(), 2);
        let mut bent = square;
        bent[3].y = f32::NAN;
        let triangles = Some(Indices::U32(vec![0, 1, 2, 1, 3, 2]));
        let error = wait(builder.build(ColliderShape::Trimesh, bent, triangles, None))
            .expect_err("a non-finite position");
        assert!(error.contains("non-finite"), "{error}");
        let empty = wait(builder.build(ColliderShape::Trimesh, vec![Vec3::ZERO], None, None));
        assert!(empty.is_err());
        assert!(builder.jobs.is_some(), "the thread serves every job");
    }

    /// A triangle list's buffer is its triangles in order; a trailing partial triangle (a
    /// malformed buffer) is dropped, not read past.
    #[test]
    fn index_buffers_are_read_as_whole_triangles() {
        assert_eq!(
            triangles_of(&Indices::U16(vec![4, 5, 6, 7, 8])),
            vec![[4, 5, 6]]
        );
        assert_eq!(
            triangles_of(&Indices::U32(vec![70_000, 1, 2, 3, 4, 5])),
            vec![[70_000, 1, 2], [3, 4, 5]]
        );
        assert!(triangles_of(&Indices::U32(vec![1, 2])).is_empty());
    }

    /// A bent triangle mesh with the same triangles as the collider it replaces is that
    /// collider refitted: the new shape has the bent vertices, a tree that bounds them (a ray
    /// finds the moved triangle where it moved to, and no longer where it was), and the old
    /// shape is untouched. Other triangles, or another vertex count, are built anew.
    #[test]
    fn a_bend_of_the_same_triangles_is_the_previous_mesh_refitted() {
        let square = vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::X + Vec3::Z];
        let triangles = vec![[0, 1, 2], [1, 3, 2]];
        let flat = build(
            ColliderShape::Trimesh,
            square.clone(),
            triangles.clone(),
            None,
        )
        .expect("a flat square");
        let lifted: Vec<Vec3> = square.iter().map(|p| *p + Vec3::Y * 2.0).collect();
        let refitted = build(
            ColliderShape::Trimesh,
            lifted.clone(),
            triangles.clone(),
            Some(flat.clone()),
        )
        .expect("the square lifted");
        let mesh = refitted.shape().as_trimesh().expect("a triangle mesh");
        assert_eq!(mesh.vertices(), lifted.as_slice());
        assert_eq!(mesh.indices(), triangles.as_slice());
        // How far down from `from` the mesh is (a ray through its tree).
        let hit = |mesh: &TriMesh, from: Vec3| {
            mesh.cast_local_ray(&Ray::new(from, Vec3::NEG_Y), 10.0, false)
        };
        let above = Vec3::new(0.4, 5.0, 0.4);
        assert!(
            (hit(mesh, above).expect("the lifted square is under the ray") - 3.0).abs() < 1e-5,
            "the tree bounds the lifted triangles"
        );
        let between = Vec3::new(0.4, 1.0, 0.4);
        assert_eq!(
            hit(mesh, between),
            None,
            "nothing is left where the square was"
        );
        let old = flat.shape().as_trimesh().unwrap();
        assert_eq!(
            old.vertices(),
            square.as_slice(),
            "the replaced shape is untouched"
        );
        // Fewer vertices (the last one dropped, a triangle too): built, not refitted.
        let smaller = build(
            ColliderShape::Trimesh,
            lifted[..3].to_vec(),
            vec![[0, 1, 2]],
            Some(flat),
        )
        .expect("one triangle");
        assert_eq!(smaller.shape().as_trimesh().unwrap().num_triangles(), 1);
    }
}
