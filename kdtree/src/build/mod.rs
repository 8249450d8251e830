//! The perfect-split SAH build (thesis 2.2.1, 3.2.1).

use glam::Vec3;

use crate::{Aabb, KdNode, triangle::Intersector};

/// Build parameters: the SAH terms with the thesis's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildConfig {
    /// Cost of one traversal step, `C_trav`.
    pub c_trav: f32,
    /// Cost of one ray-triangle test, `C_isect` (thesis: 5 x `C_trav`).
    pub c_isect: f32,
    /// Fraction of the cost taken off a split that leaves one side empty (0 = off).
    pub empty_bonus: f32,
    /// Maximum depth; `None` means `8 + 1.3 log2 N` (pbrt's rule). Capped at [`crate::MAX_DEPTH`].
    pub max_depth: Option<u32>,
    /// The ray-triangle test the tree's traversal uses.
    pub intersector: Intersector,
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig { c_trav: 1.0, c_isect: 5.0, empty_bonus: 0.0, max_depth: None, intersector: Intersector::Wald }
    }
}

impl BuildConfig {
    /// The maximum depth for `n` triangles.
    pub fn depth_limit(&self, n: usize) -> u32 {
        let d = self.max_depth.unwrap_or_else(|| (8.0 + 1.3 * (n.max(1) as f64).log2()).round() as u32);
        d.min(crate::MAX_DEPTH)
    }
}

/// Why a build was refused. Builds never panic on user input.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BuildError {
    /// A vertex position has a NaN or infinite component.
    #[error("vertex {index} is not finite: {position}")]
    NonFiniteVertex {
        /// Index into the positions.
        index: usize,
        /// The position.
        position: Vec3,
    },
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {vertex} but there are {vertices} vertices")]
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The vertex index it uses.
        vertex: u32,
        /// The number of vertices.
        vertices: usize,
    },
    /// The tree would need more nodes, references or triangles than its 32-bit (30-bit for
    /// node fields) indices can address.
    #[error("the tree is too large for its index widths: {0}")]
    TooLarge(String),
    /// A configuration value is out of range.
    #[error("bad build configuration: {0}")]
    BadConfig(String),
}

/// What the builder hands to [`crate::KdTree`]: the node array (root at 0) and the
/// triangle-reference array the leaves point into.
pub(crate) struct BuiltNodes {
    /// Nodes, root first, children adjacent.
    pub nodes: Vec<KdNode>,
    /// Leaf triangle references (indices into the triangle array).
    pub prim_refs: Vec<u32>,
}

/// Builds the node and reference arrays for the triangles `prims` (indices into `tris`;
/// degenerate triangles already removed) inside `bounds`.
pub(crate) fn build_nodes(
    tris: &[[Vec3; 3]],
    prims: &[u32],
    bounds: Aabb,
    config: &BuildConfig,
) -> Result<BuiltNodes, BuildError> {
    let _ = (tris, bounds, config);
    // Placeholder until the SAH builder lands: one leaf with everything.
    Ok(BuiltNodes { nodes: vec![KdNode::leaf(0, prims.len() as u32)], prim_refs: prims.to_vec() })
}
