//! Build script: keeps the examples' debug builds small.
//!
//! The dependencies are built at `opt-level = 3` with their debug info (Cargo.toml), and every
//! debug example links all of it: 1.5–1.9 GB a binary, ~25 GB for the examples `cargo test`
//! builds, enough to fill a CI machine's disk. Debug examples are linked without debug info
//! (`--strip-debug`: symbols stay, so a panic's backtrace still names its functions), ~170 MB
//! each. Tests keep theirs. Set `BEVY_WII_DEFORM_EXAMPLE_DEBUGINFO=1` to keep it in the
//! examples too (to step through one in a debugger).

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=BEVY_WII_DEFORM_EXAMPLE_DEBUGINFO");
    let keep = std::env::var_os("BEVY_WII_DEFORM_EXAMPLE_DEBUGINFO").is_some_and(|v| v != "0");
    let linux = std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "linux");
    let debug = std::env::var("PROFILE").is_ok_and(|p| p == "debug");
    if linux && debug && !keep {
        println!("cargo:rustc-link-arg-examples=-Wl,--strip-debug");
    }
}
