//! Scratch folders for tests: a fresh, empty folder under the system's temporary folder,
//! removed with everything in it when its handle is dropped, so that a test run leaves
//! nothing behind. A folder dropped while its thread panics (a failing test) is kept, and
//! its path printed, so that the files the test wrote can be looked at.

use std::ops::Deref;
use std::path::{Path, PathBuf};

use crate::SceneError;

/// A fresh, empty folder under [`std::env::temp_dir`], removed when dropped (see the module
/// documentation). Dereferences to its [`Path`].
#[derive(Debug)]
pub struct ScratchDir {
    path: PathBuf,
}

impl ScratchDir {
    /// The folder `{prefix}-{process id}-{name}` under the system's temporary folder, made
    /// empty (a folder of that name left by a killed run is cleared first).
    pub fn new(prefix: &str, name: &str) -> Result<ScratchDir, SceneError> {
        let path = std::env::temp_dir().join(format!("{prefix}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).map_err(|source| SceneError::Io { path: path.clone(), source })?;
        Ok(ScratchDir { path })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
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
        if std::thread::panicking() {
            eprintln!("scratch folder kept for the failure: {}", self.path.display());
        } else {
            // Nothing to report if it is already gone.
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

/// For this crate's tests: the file `name` in a scratch folder of its own,
/// `{prefix}-{process id}-{name}` (the folder goes when the returned handle is dropped).
#[cfg(test)]
pub(crate) fn scratch_file(prefix: &str, name: &str) -> (ScratchDir, PathBuf) {
    let dir = ScratchDir::new(prefix, name).expect("scratch folder");
    let path = dir.join(name);
    (dir, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scratch_folder_starts_empty_and_is_removed_when_dropped() {
        let dir = ScratchDir::new("scenes-scratch", "dropped").unwrap();
        std::fs::write(dir.join("left.txt"), "old run").unwrap();
        let path = dir.path().to_path_buf();
        drop(dir);
        assert!(!path.exists());
        // A folder left by a killed run is emptied.
        std::fs::create_dir_all(&path).unwrap();
        std::fs::write(path.join("left.txt"), "old run").unwrap();
        let dir = ScratchDir::new("scenes-scratch", "dropped").unwrap();
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        std::fs::create_dir_all(dir.join("a/b")).unwrap();
        std::fs::write(dir.join("a/b/c.txt"), "nested").unwrap();
        drop(dir);
        assert!(!path.exists());
    }

    #[test]
    fn a_failing_tests_folder_is_kept() {
        let (tx, rx) = std::sync::mpsc::channel();
        let failed = std::thread::spawn(move || {
            let dir = ScratchDir::new("scenes-scratch", "panicked").unwrap();
            std::fs::write(dir.join("evidence.txt"), "look here").unwrap();
            tx.send(dir.path().to_path_buf()).unwrap();
            panic!("deliberate panic (ScratchDir test): a failing test keeps its scratch folder");
        })
        .join();
        assert!(failed.is_err());
        let path = rx.recv().unwrap();
        assert_eq!(std::fs::read_to_string(path.join("evidence.txt")).unwrap(), "look here");
        std::fs::remove_dir_all(&path).unwrap();
    }

    #[test]
    fn an_unusable_temporary_folder_is_an_error_naming_it() {
        // A name that makes the folder's parent a file: creating it fails.
        let file = ScratchDir::new("scenes-scratch", "parent").unwrap();
        std::fs::write(file.join("plain"), "").unwrap();
        let e = ScratchDir::new("scenes-scratch", "parent/plain/child").unwrap_err().to_string();
        assert!(e.contains("plain"), "{e}");
    }
}
