//! The conformance harness: every registered method gives the single-ray answer, on every
//! built-in scene and view, the shared scenes, random soups and the named hard cases.
//!
//! Test support, not API (as rust-analyzer's `test-utils`): `publish = false`, and the crates
//! that use it (`baselines`, the fuzz targets) take it as a dev-dependency; no build of
//! `trace`, `rttest` or `experiments` depends on it. Its own tests run it for our methods:
//! `tests/ours.rs` ([`Plan::ours`] on the kd-tree) and `tests/other_structures.rs` (our
//! methods on `mbvh-4` and `mbvh-8`).
//!
//! The model is Embree's `verify` (one verifier runs every scene through every path): a
//! [`Plan`] names methods and the single-ray twin each must agree with ([`Check`]), and
//! [`run()`] traces every [`Case`], with each intersector of the plan, through the frame driver
//! exactly as `rttest render` does, comparing per ray:
//!
//! 1. primary tiles (the frame driver's tile order) against the twin's hits;
//! 2. hard shadows ([`trace::frame::shadow_pass`], on the twin's hits) per pixel;
//! 3. soft shadows ([`trace::frame::soft_pass`], 16 rays per point) per pixel;
//! 4. a ray stream ([`trace::frame::stream_pass`] and [`trace::frame::stream_occluded_pass`])
//!    mixing camera rays (runs sharing an origin: packets and frusta), scattered origins,
//!    negative `t_min`, origins on surfaces, and axis-parallel rays with `0.0` and `-0.0`
//!    direction components;
//! 5. on the cases marked for it (soups, hard cases), the twin itself against the
//!    brute-force oracle (`kdtree::BruteForce::check`) on the stream and the primary rays.
//!
//! How close is close enough is the check's [`Rule`]: our methods on our tree must give the
//! twin's hit or a tie ([`Rule::Exact`]); a method with its own triangle test against ours
//! may differ at ties and a handful of edge rays ([`Rule::Loose`]). `tests/ours.rs` runs
//! [`Plan::ours`] for every method of [`trace::Registry::ours`]; `baselines/tests/conformance.rs`
//! the baselines against their own single rays and, loosely, against ours.
//!
//! - [`cases`]: the scenes, views, soups, hard cases and ray streams;
//! - [`plan`]: what to check, and under which [`Rule`];
//! - `judge` (private): the comparisons of one answer with its reference's;
//! - [`report`]: the tallies and failures;
//! - [`run`](mod@run): the plan run over the cases through the frame driver.

pub mod cases;
mod judge;
pub mod plan;
pub mod report;
pub mod run;

pub use cases::{
    Case, builtin_cases, hard_cases, random_soup, ray_list, shared_cases, shared_cases_or_skip, soup_cases, soup_scene,
    transformed,
};
pub use plan::{Check, INTERSECTORS, OracleCheck, OracleTest, Plan, Rule, TILES};
pub use report::{REPORTED, Report, Tally};
pub use run::{LIGHT_RADIUS, assert_conforms, run};
