//! Perfect-split SAH kd-tree (Tsakok 2008, sections 2.2.1, 3.2.1 and 4.2).
//!
//! - [`build`]: the surface area heuristic build with perfect splits (triangles clipped to the
//!   node box) evaluated by the O(N log N) event sweep of Wald & Havran 2006, parallel over
//!   subtrees and identical whatever the thread count.
//! - [`node`]: the 8-byte node layout, children adjacent, leaves pointing into one
//!   contiguous triangle-reference array.
//! - [`triangle`]: Wald's projected-barycentric test (thesis 4.2) and the watertight test of
//!   Woop, Benthin and Wald 2013, selectable per tree.
//! - [`intersect`]: the triangle test as a type ([`TreeTest`]: [`WaldTest`], [`WatertightTest`]),
//!   chosen once when a kernel is bound to a tree, so no kernel matches on the intersector.
//! - [`leaf`]: SIMD leaves, each leaf's triangle records stored inline in groups of four
//!   (structure-of-arrays) and tested four at a time against one ray.
//! - [`traverse`]: iterative single-ray traversal with a fixed stack, closest hit
//!   ([`KdTree::intersect`]) and any hit ([`KdTree::occluded`]).
//! - [`stack`]: the fixed, uninitialised traversal stack every kernel's deferred voxels go
//!   on.
//! - [`oracle`]: a brute-force intersector over all triangles, the reference every traversal
//!   method is tested against.
//! - [`surface`]: per-triangle records for starting rays on surfaces (hit point, facing
//!   normal, offset origin), one cache line each.
//! - [`counters`]: node / leaf / intersection counters that compile to nothing when off.
//!
//! This crate knows nothing about files, images or packets: it takes positions and triangle
//! indices and answers ray queries. Its kernels never allocate.

pub mod aabb;
pub mod build;
pub mod clock;
pub mod counters;
pub mod descent;
pub mod intersect;
pub mod isa;
pub mod leaf;
pub mod node;
pub mod oracle;
pub mod ray;
pub mod stack;
pub mod stats;
pub mod surface;
#[cfg(test)]
mod test_rng;
pub mod traverse;
pub mod tree;
pub mod treefile;
pub mod triangle;
mod validate;

pub use aabb::Aabb;
pub use build::{BuildConfig, BuildError, BuildStrategy, CostModel, first_phase_bytes, human_bytes};
pub use clock::LeafClock;
pub use counters::{Counters, Counts, NoCounters};
pub use intersect::{PreparedRays, TreeTest, WaldTest, WatertightTest};
pub use node::KdNode;
pub use oracle::BruteForce;
pub use ray::{Hit, Ray, RayError};
pub use stats::TreeStats;
pub use tree::KdTree;
pub use treefile::TreeFileError;
pub use triangle::Intersector;

/// Depth of the fixed traversal stack. The builder never makes a tree deeper than
/// [`MAX_DEPTH`], which is below this, so the stack cannot overflow.
pub const STACK_SIZE: usize = 64;

/// The deepest tree the builder makes, whatever the configuration asks.
pub const MAX_DEPTH: u32 = 60;
