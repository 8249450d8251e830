//! Whole files as bytes, for the formats other crates encode themselves (the kd-tree files of
//! `kdtree::treefile`): this crate stays the one that opens files, and every error names the
//! file.

use std::path::Path;

use crate::SceneError;

/// The bytes of the file at `path`, in one read.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>, SceneError> {
    std::fs::read(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })
}

/// Writes `bytes` to the file at `path`, replacing it.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), SceneError> {
    std::fs::write(path, bytes).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors_name_the_file() {
        let dir = std::env::temp_dir().join(format!("scenes-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bytes.bin");
        write_bytes(&path, &[1, 2, 3]).unwrap();
        assert_eq!(read_bytes(&path).unwrap(), vec![1, 2, 3]);
        let missing = dir.join("missing.bin");
        let e = read_bytes(&missing).unwrap_err().to_string();
        assert!(e.contains("missing.bin"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
