//! The deformation core: As-Rigid-As-Possible surface modelling (Sorkine & Alexa 2007) with the
//! paper's uniform-Laplacian initial guess. Pure math on `glam` + `faer`; no Bevy.
//!
//! | file | what it answers |
//! |---|---|
//! | `mod.rs` | the types and docs of this folder (above) |
//! | `anderson.rs` | Anderson acceleration (type II) of the local/global fixed-point map `y ↦ G(y)` on the free positions, after Peng et al. 2018. |
//! | `constraints.rs` | Positional constraints: fixed vertices, rigid handles and free-form targets. |
//! | `dynamics.rs` | Bends that wobble: the ARAP energy given inertia, stepped in time as projective dynamics does (Bouaziz et al. 2014). |
//! | `energy.rs` | The normalised ARAP energy used to compare solvers. |
//! | `factor.rs` | The Cholesky factor in the form the iterations use: compressed columns with 32-bit row indices, the inverted diagonal kept apart, and the three coordinates of a right-hand side interleaved, so one pass over `L` (and one over `Lᵀ`) solves for x, y and z together. |
//! | `io.rs` | Reading OFF and OBJ triangle meshes (for tools, tests and benchmarks). |
//! | `lbfgs.rs` | Limited-memory BFGS directions for the ARAP energy, with the factored cotangent Laplacian as the initial inverse Hessian, after Liu, Bouaziz & Kavan 2017, "Quasi-Newton Methods for Real-Time Simulation of Hyperelastic Materials". |
//! | `obstacle.rs` | Surfaces a bend may not pass through (the game's ground under a [`Deformable`] mesh). |
//! | `ordering.rs` | Fill-reducing elimination order for the Cholesky factor: geometric dissection on top, approximate minimum degree below. |
//! | `parallel.rs` | The solver's data-parallel loops, run on rayon's pool for large meshes and on the calling thread for small ones. |
//! | `preview.rs` | A first pose for a new constraint set without waiting for the whole mesh's factorization. |
//! | `rotation.rs` | Best-fit rotations of 3×3 covariance matrices. |
//! | `selection_io.rs` | Reading the vertex selections (`.sel`) and handle transforms (`.def`) of the deformation benchmark of Botsch and Sorkine ("On Linear Variational Surface Deformation Methods", 2008), the format the ARAP literature's test cases (the cactus, the bar) come in. |
//! | `solver/` | The ARAP solver: precompute (weights, elimination, Cholesky factorization) and warm-startable local/global iterations. |
//! | `synth.rs` | Synthetic meshes generated in code (for tests, benchmarks and the sandbox's assets). |
//! | `topology/` | Welded mesh topology and cotangent edge weights. |
//!
//! ```
//! use std::sync::Arc;
//! use bevy_wii_deform::deform::*;
//! use glam::{DQuat, DVec3};
//!
//! let bar = synth::bar(16, 20, 0.1, 1.0);
//! let topology = Arc::new(Topology::new(&bar.positions, &bar.triangles).unwrap());
//! // Fix the bottom ring, move the top ring sideways.
//! let fixed: Vec<u32> = (0..16).collect();
//! let handle: Vec<u32> = (19 * 16..20 * 16).collect();
//! let mut constraints = Constraints::with_handle(fixed, handle, RigidTransform::IDENTITY);
//! let solver = ArapSolver::precompute(topology.clone(), &constraints, SolverSettings::default()).unwrap();
//! constraints.handles[0].transform.translation = DVec3::new(0.3, 0.0, 0.0);
//! let first = solver.solve(&constraints, &SolveOptions::default(), InitialGuess::Laplacian, &|| false).unwrap();
//! // Next frame: move a little further, warm-started from the last solution.
//! constraints.handles[0].transform.translation.x = 0.35;
//! let next = solver.solve(&constraints, &SolveOptions::default(), InitialGuess::Warm(&first), &|| false).unwrap();
//! assert!(next.positions.iter().all(|p| p.is_finite()));
//! ```

mod anderson;
pub(crate) mod constraints;
pub mod dynamics;
mod energy;
mod factor;
mod io;
mod lbfgs;
pub mod obstacle;
mod ordering;
mod parallel;
mod preview;
mod rotation;
mod selection_io;
mod solver;
pub mod synth;
mod topology;

pub use constraints::{ConstraintError, Constraints, Handle, RigidTransform};
pub use dynamics::{DynamicsSettings, MeshMotion};
pub use energy::arap_energy;
pub use io::{MeshIoError, TriMesh, bounding_box, centroid, glb_container};
pub use obstacle::{HeightField, HeightFieldError, Obstacle, PlaneObstacle, SurfaceSample};
pub use parallel::{SERIAL_BELOW, Threading};
pub use preview::{Preview, PreviewRegion};
pub use rotation::{best_rotation_exact, fit_rotation_warm};
pub use selection_io::{
    VertexRole, VertexSelection, parse_handle_transform, read_handle_transform,
};
pub use solver::{
    Acceleration, ArapSolver, Factorization, FillOrdering, InitialGuess, PrecomputeStats,
    SliceProgress, SlicedSolve, Solution, SolveError, SolveOptions, SolveStats, SolverSettings,
};
pub use topology::{MeshError, Topology, WeightMode, WeldPolicy};
