#![no_main]
//! See `bevy_wii_deform_fuzz::vrm_springs`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| bevy_wii_deform_fuzz::vrm_springs(data));
