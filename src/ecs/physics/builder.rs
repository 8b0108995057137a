//! The collider builder: one long-lived background thread that builds the colliders of bent
//! meshes and frees the ones they replace, handed its work over a channel.
//!
//! Why not the async compute pool: on a machine with few cores, a build spawned there woke a
//! pool thread that took a core from the frame's own systems, and the main thread's time in
//! the frame it started went from 0.2 to 2.5–4.8 ms (`plugin_bench --collider`). The builder
//! thread is already running (no wake of a sleeping pool), and on Linux it runs at the
//! lowest CPU priority (nice 19), so the frame's threads preempt it rather than the other
//! way round. Where threads cannot be made (the web) the build runs where it is asked for.

use avian3d::prelude::*;
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
        triangles: Vec<[u32; 3]>,
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
    /// Builds a `shape` collider over the mesh in the background; its result arrives on the
    /// returned channel.
    pub(crate) fn build(
        &mut self,
        shape: ColliderShape,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
    ) -> Receiver<BuildResult> {
        let (reply, result) = crossbeam_channel::bounded(1);
        self.send(Job::Build {
            shape,
            positions,
            triangles,
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

/// The calling thread at the lowest CPU priority (Linux, where a thread has its own nice
/// value; elsewhere `setpriority` would lower the whole process, so it is left alone).
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: `setpriority` with `PRIO_PROCESS` and id 0 only changes the calling thread's
    // nice value on Linux; it reads and writes no memory of ours.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 19);
    }
}

/// Does one job (a dropped reply channel — its entity gone — is no error).
fn run(job: Job) {
    match job {
        Job::Build {
            shape,
            positions,
            triangles,
            reply,
        } => {
            let _ = reply.send(build(shape, positions, triangles));
        }
        Job::Free(collider) => drop(collider),
    }
}

/// The collider of `shape` over the bent mesh; a readable reason when it cannot be built.
fn build(shape: ColliderShape, positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> BuildResult {
    if !positions.iter().all(|p| p.is_finite()) {
        return Err("the bent mesh has non-finite positions".into());
    }
    match shape {
        ColliderShape::Trimesh => {
            if triangles.is_empty() {
                return Err("the mesh has no triangles".into());
            }
            Collider::try_trimesh_with_config(
                positions,
                triangles,
                TrimeshFlags::MERGE_DUPLICATE_VERTICES,
            )
            .map_err(|e| format!("no triangle mesh collider: {e:?}"))
        }
        ColliderShape::ConvexHull => Collider::convex_hull(&positions)
            .ok_or_else(|| "no convex hull (the vertices are flat or too few)".to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The builder thread answers each build on its own channel, keeps answering after
    /// freeing a collider, and a bent mesh with a non-finite position is a readable error,
    /// not a collider. (Fails with a build whose reply is never sent: the wait times out.)
    #[test]
    fn builds_arrive_on_their_channels_and_bad_meshes_are_errors() {
        let mut builder = ColliderBuilder::default();
        let wait = |r: Receiver<BuildResult>| {
            r.recv_timeout(std::time::Duration::from_secs(30))
                .expect("a reply")
        };
        let square = vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::X + Vec3::Z];
        let triangles = vec![[0, 1, 2], [1, 3, 2]];
        let first = builder.build(ColliderShape::Trimesh, square.clone(), triangles.clone());
        let collider = wait(first).expect("a collider of two triangles");
        builder.free(collider);
        let mut bent = square;
        bent[3].y = f32::NAN;
        let error = wait(builder.build(ColliderShape::Trimesh, bent, triangles))
            .expect_err("a non-finite position");
        assert!(error.contains("non-finite"), "{error}");
        let empty = wait(builder.build(ColliderShape::Trimesh, vec![Vec3::ZERO], Vec::new()));
        assert!(empty.is_err());
        assert!(builder.jobs.is_some(), "the thread serves every job");
    }
}
