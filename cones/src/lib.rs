//! Cone proxy traversal (Tsakok 2008, sections 4.1.6-4.1.9): a group of rays sharing one
//! origin goes down the kd-tree as one cone instead of a pyramid frustum.
//!
//! - [`cone`]: the cone, Eq. 4.8 (where a cone meets an axis-aligned split plane) with the
//!   cases the formula leaves open decided and tested, and Listing 4.4's per-cone factors.
//! - [`traverse`]: a tile of packets (2x2, or wider: `TileTracer<V>`) traced with one cone (Listing 4.5, corrected) or
//!   with four quadrant cones in the lanes of a `Vec4` (MFT cones). The cone is handed to
//!   `packets`' frustum traversal, whose step has the same form, and the leaves cull and
//!   intersect the packets exactly, so the hits are the single rays' hits.
//! - [`shadows`]: 16-sample soft shadows to a spherical light, the 16 rays of a point traced
//!   under the cone tangent to the light, under their pyramid, or one by one (Table 4.6).
//!
//! Nothing here allocates during traversal: `packets::TileTracer` and
//! [`shadows::SoftShadowTracer`] are scratch space made once per thread.

pub mod cone;
pub mod shadows;
pub mod traverse;

pub use cone::{Cone, ConeError};
pub use shadows::{ShadowMethod, SoftShadowTracer};
