//! The one error type of the tool: every failure becomes one line on stderr.

use std::path::PathBuf;

/// Everything that can make a command fail. Nothing in the tool panics on user input; every
/// failure is one of these, printed by the binary as `rttest: error: <message>`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene, view or image file could not be loaded or written.
    #[error(transparent)]
    Scene(#[from] scenes::SceneError),
    /// The kd-tree build refused the mesh or the configuration.
    #[error("kd-tree build failed: {0}")]
    Build(#[from] kdtree::BuildError),
    /// An argument that parsed but makes no sense (a degenerate camera, for example).
    #[error("{0}")]
    Usage(String),
    /// The thread pool could not be created.
    #[error("cannot create the thread pool: {0}")]
    ThreadPool(#[from] rayon::ThreadPoolBuildError),
    /// Writing a report to stdout failed.
    #[error("cannot write the report: {0}")]
    Output(#[from] std::io::Error),
    /// A bad ray in a ray file (`rttest raycast`): `rays.txt:17: ...` or
    /// `rays.bin: ray 16 at byte 512: ...`.
    #[error("{file}:{place}: {message}")]
    Rays {
        /// The ray file as given on the command line.
        file: String,
        /// A 1-based line number (text) or `ray N at byte B` (binary, with a leading space).
        place: String,
        /// What is wrong with the ray.
        message: String,
    },
    /// A file that should have been read or written could not be.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}
