//! The integration tests, one module per behaviour, in one test binary: Bevy is linked once
//! instead of once per file (each link is ~1.7 GB with debug info and half a minute on two
//! cores). Run one module with `cargo test --test it pose_clip::`.

mod common;
mod fixtures;

mod character_grab;
mod character_nodes;
mod deform_core;
mod deform_dynamics;
mod deform_ecs;
mod deform_obstacle;
mod fuzz_regressions;
mod gltf_character;
mod grab_ecs;
mod grab_picking;
mod input_turns;
mod layering;
mod malformed_gltf;
mod missing_texture;
mod motion_pads;
mod mouse_control;
mod pads_ecs;
#[cfg(feature = "avian")]
mod physics_avian;
mod pose_balance;
mod pose_blend;
mod pose_clip;
mod pose_constraints;
mod pose_contacts;
mod pose_core;
mod pose_ecs;
mod pose_effectors_ecs;
mod pose_ground_ecs;
mod pose_planted_start;
mod pose_springs;
mod retarget;
mod retarget_ecs;
mod scene_roundtrip;
mod springs_ecs;
mod wiimote_device;
mod wiimote_ecs;
mod wiimote_ir;
