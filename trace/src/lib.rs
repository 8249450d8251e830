//! The tracing interface of the workspace: one [`Method`] trait for every traversal method,
//! one method [`Registry`], and one frame driver.
//!
//! - [`method`]: the queries. [`Tracer`] is the single-ray query (closest hit, any hit), the
//!   scalar twin; [`Method`] the group queries (a tile of primary rays, a tile's shadow rays,
//!   a point's 16 soft-shadow rays, a stream of arbitrary rays).
//! - [`kernel`]: typed kernels, one trait per pass (primary, hard shadow, soft shadow,
//!   stream), our kd-tree kernels (single rays, packets, frusta, MFT, cones, shadow frusta;
//!   thesis 2.2.1, 4.1.2-4.1.9, Benthin & Wald 2009), and `Composed`, a method made of four;
//!   [`shadow_frusta`]: a tile's shadow rays gathered in Morton order for the grouped ones.
//! - [`ours`]: our methods, one registry line each composing kernels; [`multibvh`]: our 4-
//!   and 8-wide BVHs (crate `mbvh`, Wald, Benthin & Boulos 2008) as the single-ray methods
//!   `mbvh-4` and `mbvh-8`.
//! - [`registry`]: names to methods (`mono`, `mft-16`, `embree-8`, ...), the structures they
//!   trace, their kernels' names, and the name list and summaries for `--help`.
//! - [`frame`]: the frame driver: primary, hard-shadow and soft-shadow passes over tiles with
//!   rayon, the same for every method, and ray streams.
//! - [`render`]: one view rendered with one method: timed tracing, then shading or AOVs;
//!   [`aov`]: cost images, each pixel's share of its method's traversal counts.
//! - [`shade`]: hard shadow rays and the thesis's diffuse point-light shading; [`soft`]: the
//!   rays of 16-sample soft shadows.
//! - [`setup`]: scene, tree, camera and ray setup; [`report`]: tree, build and render
//!   reports; [`timing`]: timed calls, interleaved rounds, medians; [`progress`]: progress
//!   reporting without drawing; [`error`]: the one error type.
//!
//! - [`workload`]: the incoherent rays (ambient occlusion, one diffuse bounce) generated once
//!   from a frame's primary hits and traced by every method's stream queries.
//!
//! Adding a method: one line in [`Registry::ours`] composing existing kernels, or a new
//! kernel type in [`kernel`] plus the lines that compose it (another tracer: a [`Method`]
//! registered whole by `baselines`); the conformance test (crate `conformance`, `tests/ours.rs`) then
//! checks it against the brute-force oracle and single rays, and every command takes it by
//! name.

pub mod aov;
pub mod error;
pub mod frame;
pub mod kernel;
pub mod machine;
pub mod method;
pub mod multibvh;
pub mod ours;
pub mod progress;
pub mod registry;
pub mod render;
pub mod report;
pub mod secondary;
pub mod setup;
pub mod shade;
pub mod shadow_frusta;
pub mod soft;
pub mod ties;
pub mod timing;
pub mod workload;

pub use error::Error;
pub use frame::{FrameTracer, TileLayout};
pub use machine::{Machine, SimdLevel};
pub use method::{Method, ShadowJob, SingleRays, SoftJob, SoftStats, TileCounters, Tracer};
pub use registry::{Bound, KernelNames, Options, Registry, SoftGrouping, Structures};
pub use render::{FrameBuffers, FrameStats, IntersectionShares, Renderer, Shadows};
