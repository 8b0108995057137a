#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod deform;
pub mod ecs;
pub mod wiimote;

/// Everything most apps need.
pub mod prelude {
    pub use crate::deform::{
        ArapSolver, Constraints, InitialGuess, RigidTransform, SolveOptions, SolverSettings,
        Topology, TriMesh, arap_energy,
    };
    pub use crate::ecs::*;
    pub use crate::wiimote::{EmulatorConfig, EmulatorControls, FilterKind};
}
