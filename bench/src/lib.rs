//! The `rttest` command line tool and the shared harness of the criterion benches.
//!
//! The tool re-creates the "RTTest" application of Tsakok's thesis (2008): it loads a scene,
//! builds its kd-tree, renders it with a chosen traversal method and reports build time, tree
//! statistics and ray throughput, for people (a table) or for scripts (`--json`).
//!
//! Modules, one concept each:
//! - [`cli`]: the command line (clap) and the driver that runs one command;
//! - [`render`]: the tile renderer; tracing is a separate, timed pass over preallocated
//!   per-pixel buffers, shading and image output come after and are timed apart;
//! - [`shade`]: shadow-ray construction and the diffuse point-light shading of the thesis;
//! - [`report`]: tree statistics and the text / JSON reports;
//! - [`progress`]: progress bars that only appear for work taking more than a second;
//! - [`harness`]: scene, tree and ray setup shared by the benches (and the tests);
//! - [`error`]: the one error type, printed as a single line by the binary.

pub mod cli;
pub mod compat;
pub mod error;
pub mod harness;
pub mod progress;
pub mod render;
pub mod report;
pub mod shade;

pub use error::Error;
