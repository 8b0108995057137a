//! The deformation core: As-Rigid-As-Possible surface modelling (Sorkine & Alexa 2007) with the
//! paper's uniform-Laplacian initial guess. Pure math on `glam` + `faer`; no Bevy.
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
pub use dynamics::{DynamicsSettings, Motion};
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
