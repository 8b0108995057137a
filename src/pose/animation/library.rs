//! A pose library: named poses as RON pose files ([`PoseFile`]) in one folder, the file stem
//! being the name. Apply one with [`PoseFile::apply`], mirror it with
//! [`crate::pose::rig::mirror::Mirror::mirror`], blend two with [`crate::pose::animation::blend::blend_pose`].

use std::path::{Path, PathBuf};

use crate::pose::animation::pose_file::{PoseFile, PoseFileError, io_error};

/// Named poses in a folder of `.ron` pose files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoseLibrary {
    folder: PathBuf,
}

impl PoseLibrary {
    /// The library in `folder` (created when a pose is first saved).
    pub fn new(folder: impl Into<PathBuf>) -> Self {
        Self {
            folder: folder.into(),
        }
    }

    /// The folder.
    pub fn folder(&self) -> &Path {
        &self.folder
    }

    /// The names of the poses, sorted; none when the folder does not exist yet.
    pub fn names(&self) -> Result<Vec<String>, PoseFileError> {
        let entries = match std::fs::read_dir(&self.folder) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
            Err(e) => return Err(io_error(&self.folder, e)),
        };
        let mut names: Vec<String> = entries
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "ron"))
            .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .collect();
        names.sort();
        Ok(names)
    }

    /// Reads pose `name`.
    pub fn load(&self, name: &str) -> Result<PoseFile, PoseFileError> {
        PoseFile::load(&self.path_of(name)?)
    }

    /// Writes `pose` as `name` (replacing a pose of that name); returns its path. Names are
    /// file stems: letters, digits, spaces, `-`, `_` and `.`, not empty, not starting with `.`.
    pub fn save(&self, name: &str, pose: &PoseFile) -> Result<PathBuf, PoseFileError> {
        let path = self.path_of(name)?;
        std::fs::create_dir_all(&self.folder).map_err(|e| io_error(&self.folder, e))?;
        pose.save(&path)?;
        Ok(path)
    }

    fn path_of(&self, name: &str) -> Result<PathBuf, PoseFileError> {
        let valid = !name.trim().is_empty()
            && !name.starts_with('.')
            && name
                .chars()
                .all(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_' | '.'));
        if !valid {
            return Err(PoseFileError::BadName(name.to_string()));
        }
        Ok(self.folder.join(format!("{name}.ron")))
    }
}
