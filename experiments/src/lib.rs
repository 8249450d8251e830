//! The experiments of the workspace as library functions: each takes a plain config struct,
//! reports progress through [`trace::progress::Progress`] and returns a report (text tables
//! through `Display`, JSON rows through `serde`). The `rttest` binary turns its arguments into
//! these configs; the criterion benches and the tests call the same functions.
//!
//! - [`tables`]: the thesis's Tables 4.1-4.6 (packets, frusta, culling, MFT, cones, soft
//!   shadows) and, through [`scaling`] and [`table51`], Tables 6.2 and 5.1, and through
//!   [`ladder`] the width ladder (each kernel at 1, 4, 8 and 16 rays per instruction beside
//!   Embree's);
//! - [`compare`]: every registered method, ours and the baselines, on the same rays (build,
//!   primary, hard-shadow and soft-shadow Mrays/s, primitive mismatches classified);
//! - [`shadows`]: edge-width against sampled soft shadows (images, errors, a plot drawn by
//!   [`shadow_plot`]);
//! - [`leaks`]: watertightness measured, rays aimed at shared edges and vertices;
//! - [`culling`]: pre-BVH culling for shadow rays (Selgrad et al.): culled fraction, build
//!   and trace with and without, identical answers checked; [`dynamic`]: the same on every
//!   frame of an animated scene rebuilt per frame;
//! - [`sah_sweep`]: the SAH cost model chosen by measurement (tree shape against speed).

pub mod compare;
pub mod culling;
pub mod dynamic;
pub mod ladder;
pub mod leaks;
pub mod pipeline;
pub mod sah_sweep;
pub mod scaling;
pub mod shadow_plot;
pub mod shadows;
pub mod table51;
pub mod tables;

pub use trace::Error;
