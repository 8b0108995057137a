#![no_main]
//! See `bevy_wii_deform_fuzz::gltf_character`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| bevy_wii_deform_fuzz::gltf_character(data));
