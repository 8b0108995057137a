//! Scratch folders for tests: made fresh under the system's temporary folder and removed
//! when dropped, so a test run leaves nothing behind, whether its tests pass or fail.

use std::ops::Deref;
use std::path::{Path, PathBuf};

/// A fresh folder `bwd_<name>_<process id>` in the temporary folder, removed on drop.
pub struct ScratchDir {
    path: PathBuf,
}

impl ScratchDir {
    /// The folder for `name` (emptied if a killed run left one behind).
    pub fn new(name: &str) -> Self {
        let path = std::env::temp_dir().join(format!("bwd_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).unwrap();
        Self { path }
    }
}

impl Deref for ScratchDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}
