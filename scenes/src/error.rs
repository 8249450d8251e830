//! The one error type of the scene crate: every failure names the file or scene it came from.

use std::path::PathBuf;

/// Everything that can go wrong loading or saving scenes and images.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file's contents are malformed.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong, with a line or element number where known.
        message: String,
    },
    /// The file holds no (non-degenerate) triangle.
    #[error("{path}: the mesh has no non-degenerate triangle")]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// A scene name that is neither built in nor a file that exists.
    #[error("unknown scene '{0}': not a built-in scene ({1}) and no such file")]
    UnknownScene(String, String),
    /// A named view that the scene does not have.
    #[error("scene '{scene}' has no view '{view}' (views: {available})")]
    UnknownView {
        /// The scene.
        scene: String,
        /// The view asked for.
        view: String,
        /// The views the scene has, comma separated.
        available: String,
    },
    /// Two images that should be compared have different sizes.
    #[error("image sizes differ: {a:?} and {b:?} (width, height)")]
    SizeMismatch {
        /// Size of the first image.
        a: (usize, usize),
        /// Size of the second image.
        b: (usize, usize),
    },
}
