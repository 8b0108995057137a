#![no_main]
//! See `bevy_wii_deform_fuzz::bvh_files`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| bevy_wii_deform_fuzz::bvh_files(data));
