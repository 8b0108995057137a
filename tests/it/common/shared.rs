//! The shared test assets beside the project root (`../shared`): meshes, glTF models and
//! Wii Remote captures. A test that needs them says so when they are absent and skips — except
//! in CI (`CI` set), which always has them, where their absence fails the test.

use std::path::PathBuf;

/// The path of `relative` under `../shared`, or `None` (after saying so) when it is absent
/// outside CI. Panics in CI when it is absent.
pub fn shared_asset(relative: &str) -> Option<PathBuf> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared")
        .join(relative);
    if path.exists() {
        return Some(path);
    }
    if std::env::var_os("CI").is_some() {
        panic!(
            "{} is absent, and CI always has ../shared: this test must not skip there",
            path.display()
        );
    }
    eprintln!(
        "SKIPPED: {} is absent (the shared test assets sit beside the project root)",
        path.display()
    );
    None
}
