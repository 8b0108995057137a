//! What the examples, the benchmark programs and the tests of `bevy_wii_deform` share, in one
//! place instead of copies: the apps' command lines and unattended runs, glTF loading without
//! a window, built-in models, the remote cursor, springy tails, the terrain, undo keys, broken
//! glTF files made for tests, and the orientation-drift evaluation. A dev-dependency of the
//! crate; not published.
//!
//! | question | module |
//! |---|---|
//! | how an example reads its command line (`--help`, unknown flags refused, model paths) | [`cli`] |
//! | how an app saves frame N and exits (`--screenshot PATH --frames N`) | [`screenshot`] |
//! | how glTF scenes load in a headless app, with or without materials | [`headless_gltf`] |
//! | what an app does when a model's textures are missing | [`missing_textures`] |
//! | which models are built in (bar, cactus, mannequin) | [`models`] |
//! | how a Wii Remote or pad drives an on-screen cursor | [`remote_cursor`] |
//! | how the Fox's tail gets spring bones | [`springy_tails`] |
//! | the crowd's hilly, terraced terrain | [`terrain`] |
//! | Ctrl+Z / Ctrl+Y as history commands | [`undo_keys`] |
//! | broken glTF files for the loading tests | [`broken_gltf`] |
//! | the orientation filters' drift evaluation (scripted sessions, scores) | [`drift`] |

#![warn(missing_docs)]

pub mod broken_gltf;
pub mod cli;
pub mod drift;
// Headless apps (tests, benchmarks) run natively only.
#[cfg(not(target_arch = "wasm32"))]
pub mod headless_gltf;
pub mod missing_textures;
pub mod models;
pub mod remote_cursor;
pub mod screenshot;
pub mod springy_tails;
pub mod terrain;
pub mod undo_keys;
