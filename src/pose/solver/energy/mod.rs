//! The solver's quadratic energies: the ARAP shape energy and the penalties folded into its
//! quadratic form.
//!
//! | question | file |
//! |---|---|
//! | the shape energy: the cluster rotations' fit, `Q·X`, the objective | `arap.rs` |
//! | handles, fixed vertices, pinned joints and joint handles (quadratic penalties) | `penalties.rs` |
//! | planted contacts' holds, folded into a solve's `Q` | `holds.rs` |
//! | the shape-rest tilt (a given pose at rest) | `shape_rest.rs` |

pub(crate) mod arap;
pub(crate) mod holds;
pub(crate) mod penalties;
pub(crate) mod shape_rest;
