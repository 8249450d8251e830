//! Tracing rays in groups through the kd-tree (Tsakok 2008, sections 2.3.1-2.3.2 and
//! 4.1.1-4.1.5).
//!
//! - [`simd`]: the lane types a packet is generic over ([`simd::SimdF32`], [`simd::SimdMask`]):
//!   glam's `Vec4` / `BVec4A` (4 lanes, SSE, the default) and the portable
//!   [`simd::PortableF32<W>`] (any width, the scalar twin; 8 and 16 lanes).
//! - [`simd_x86`] (x86-64): the explicit 8-lane AVX2 ([`simd_x86::F32x8`]) and 16-lane
//!   AVX-512 ([`simd_x86::F32x16`]) lane types, bit for bit the portable twin's, with the
//!   run-time-detected runners that compile a kernel for them.
//! - [`packet`]: SoA packets of rays, one lane vector per coordinate (by default four rays,
//!   one glam `Vec4`, an SSE register; the width is the lane type's), and their hits.
//! - [`triangle4`]: the packet x 1-triangle tests, for both intersectors of `kdtree`, giving
//!   bit for bit the answers of the single-ray tests, at every width.
//! - [`omni`]: omni-directional packet traversal (4.1.2, Listing 4.1): the rays of a packet
//!   with a common origin and any mix of direction signs, front and back voxels chosen from
//!   the origin; written once for every width.
//! - [`samesign`]: the standard packet traversal (2.3.1, Listing 2.4 corrected) beside it,
//!   which splits a packet whose rays disagree on direction signs; every width.
//! - [`bound`]: the bound a frustum goes down the tree with ([`FrustumBound`]): the pyramid
//!   of its extremal rays (2.3.2) or a cone (4.1.7, made by the `cones` crate), and the plane
//!   intervals and distance conversions the traversal does with it.
//! - [`frustum`]: frustum interval traversal (2.3.2, Listing 4.2 with the omni modification)
//!   of a tile of packets (2x2, or 4x2 and 4x4 pixels at 8 and 16 lanes), with packet/leaf
//!   culling (4.1.4), written once for one frustum
//!   and for Multiple Frustum Traversal (4.1.5: the tile's four quadrant frusta in the four
//!   lanes of a `Vec4`, masked when inactive or complete).
//! - [`shadow_frustum`]: groups of shadow rays that share no origin (a tile's rays to a
//!   light, or to one cell of an area light) as one frustum from the box of their starts to
//!   the box of their ends (Benthin & Wald 2009), any hit per ray, exact per ray.
//! - [`lane_frusta`]: Benthin & Wald's multi-frusta: shadow frusta that share one end (a
//!   point's 16 soft-shadow rays, a 4x4 block's hard ones), 4 or 8 of them in SIMD lanes,
//!   with plane and edge culling of each leaf triangle before any ray is made.
//! - [`mirror`]: mirror reflections as omni-directional packets from the mirrored eye.
//! - [`tile`]: a tile of primary rays laid out as packets of any width (2x2 pixels for the
//!   default `Vec4`, 4x2 for 8 lanes, 4x4 for 16), quadrant by quadrant: the scratch state
//!   of a trace.
//! - [`method`]: the per-tile entry points the renderer's kernels call:
//!   [`TileTracer::trace_packets`], [`TileTracer::trace_samesign`],
//!   [`TileTracer::trace_frustum`], [`TileTracer::trace_mft`].
//!
//! The kernels count the thesis's N (steps per 2x2 packet), I (packet-triangle tests per
//! 2x2 packet) and the share of packets culled at leaves through [`kdtree::Counters`], which
//! compiles to nothing with [`kdtree::NoCounters`].
//!
//! Every method here returns exactly the closest hit (or occlusion) that single-ray
//! traversal returns for the same rays; the tests check it against `KdTree::intersect` and
//! the brute-force oracle. Nothing here allocates during traversal: tiles are traced in
//! scratch space allocated once per thread ([`tile::TileTracer`]).

pub mod bound;
pub mod frustum;
pub mod lane_frusta;
pub mod method;
pub mod mirror;
pub mod omni;
pub mod omni_lanes;
pub mod packet;
pub mod samesign;
pub mod shadow_cache;
pub mod shadow_frustum;
pub mod simd;
#[cfg(target_arch = "x86_64")]
pub mod simd_x86;
#[cfg(test)]
mod test_support;
pub mod tile;
pub mod triangle4;
pub mod width;

pub use bound::FrustumBound;
pub use frustum::Frusta;
pub use lane_frusta::{LaneFrusta, LaneWidth};
pub use packet::{OmniPacket, PacketHit, RayPacket};
pub use shadow_frustum::ShadowFrustum;
#[cfg(target_arch = "x86_64")]
pub use simd_x86::{F32x8, F32x8x2, F32x16, Mask8, Mask8x2, Mask16, with_avx2, with_avx512};
pub use tile::TileTracer;
pub use triangle4::PacketTreeTest;
pub use width::Width;
