//! Edge Width Soft Shadows (Tsakok 2008, chapter 5) and the sampled soft shadows they are
//! measured against.
//!
//! - [`occlusion`]: Eq. 5.1, the occlusion factor from an edge width and the width `R`, and
//!   `R` derived from the light's size.
//! - [`pairing`]: entry and exit hits paired in ray order (Listing 5.1, corrected), with the
//!   two light-leak remedies of section 5 ("Light Leaks"): a per-material thickness scale
//!   and the shared-vertex rule.
//! - [`traverse`]: the single-ray edge-width traversal over a [`kdtree::KdTree`], front to
//!   back, each hit counted once however many leaves reference its triangle.
//! - [`packet`]: the same for four rays at once (SoA `Vec4` lanes), identical results.
//! - [`brute`]: the brute-force twin (every triangle along the segment, sorted, paired).
//! - [`sampling`]: rectangular and spherical area lights, stratified visibility with `N`
//!   samples, and the 4x4 interleaved sample sets of Benthin & Wald 2009 (4.5).
//! - [`filter`]: Benthin & Wald's 4x4 discontinuity filter.
//! - [`adaptive`]: adaptive stratified sampling: four corner probes per pixel, all 16
//!   samples only where the probes of the pixel or a neighbour disagree.
//! - [`silhouette`]: silhouette widths, a variant of Eq. 5.1 that draws both halves of the
//!   penumbra and does not leak: one shadow ray, the silhouette edges in the light's cone
//!   projected onto the light (Parker, Shirley & Smits 1998).
//! - [`sparse`]: the silhouette search on a coarse lattice inside the penumbra mask, the
//!   pixels between blended from their corners where the surfaces and answers agree.
//! - [`convolution`]: convolved edge widths: the frame's hard shadow blurred on the receiver
//!   by the light's image through the nearest blocker (at most one shadow ray per pixel, no
//!   search).
//! - [`probe_packets`]: the convolution's hard probes traced as nearest-hit packets of the
//!   SIMD register's width, the single rays' probes bit for bit.
//! - [`analytic`]: the closed-form visible fraction of a spherical light behind a sphere.
//!
//! Like `kdtree`, this crate reads and writes no files; its kernels never allocate once their
//! scratch buffers have grown, and never lock.

pub mod adaptive;
pub mod analytic;
pub mod brute;
pub mod convolution;
pub mod filter;
pub mod occlusion;
pub mod packet;
pub mod pairing;
pub mod probe_packets;
pub mod sampling;
pub mod silhouette;
pub mod sparse;
#[cfg(test)]
mod test_scenes;
pub mod traverse;

pub use occlusion::{occlusion_factor, width_from_light};
pub use pairing::{LeakRemedies, Pairing};
pub use sampling::AreaLight;
pub use silhouette::{SilhouetteScratch, Silhouettes, silhouette_visibility};
pub use traverse::{EdgeScratch, edge_width, edge_width_with};
