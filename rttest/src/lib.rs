//! The `rttest` command line: a thin layer that turns arguments into the configs of the
//! `trace` renderer and the `experiments`, runs them and prints their reports (a table for
//! people, one JSON object per result with `--json`). See `rttest --help` and the README.
//!
//! - [`cli`]: the arguments (clap), one module per command that has its own, and the driver
//!   that runs one command inside a rayon pool of `--threads` threads;
//! - [`raycast`]: ray files in (text or binary), one result per ray out (`rttest raycast`);
//! - [`progress`]: progress bars on stderr that only appear for work taking over a second.
//!
//! The library code lives in the other crates: `trace` (the method registry, the frame
//! driver, the renderer), `baselines` (Embree and the BVH crates), `experiments` (tables,
//! compare, shadows, leaks, scaling).

pub mod cli;
pub mod progress;
pub mod raycast;

pub use trace::Error;
