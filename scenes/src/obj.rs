//! OBJ loading (plain and gzip-compressed).
use std::path::Path;

use crate::{Mesh, SceneError};

/// What the loader did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Triangles kept.
    pub triangles: usize,
    /// Degenerate (zero-area) triangles dropped.
    pub degenerate_dropped: usize,
}

/// Loads an `.obj` or `.obj.gz` file.
pub fn load_obj(path: &Path) -> Result<(Mesh, LoadReport), SceneError> {
    let _ = path;
    todo!("scenes helper")
}
