//! Tree statistics: sizes, depth, references and the SAH cost of the finished tree
//! (thesis 2.2.1 cost model).

use crate::build::surface_area64;
use crate::triangle::is_degenerate;
use crate::{Aabb, KdTree};

/// Statistics of a built tree ([`KdTree::stats`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TreeStats {
    /// Triangles given to the build, degenerate ones included.
    pub triangles: usize,
    /// Non-degenerate triangles (the ones the tree holds).
    pub triangles_in_tree: usize,
    /// All nodes.
    pub nodes: usize,
    /// Inner (split) nodes.
    pub inner_nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Leaves without triangles.
    pub empty_leaves: usize,
    /// Deepest leaf (the root alone is depth 0).
    pub depth: usize,
    /// Total triangle references of all leaves.
    pub refs: usize,
    /// `refs / triangles_in_tree` (0 for an empty tree): the duplication caused by
    /// straddling triangles.
    pub refs_per_triangle: f64,
    /// Average triangle count of the non-empty leaves.
    pub avg_tris_per_nonempty_leaf: f64,
    /// The tree's SAH cost: `C_trav` per inner node plus `C_isect * ceil(count / W)` per leaf
    /// (`W` the tree's [`crate::BuildConfig::leaf_width`]), each weighted by its box's surface
    /// area over the root's.
    pub sah_cost: f64,
    /// Memory: 8 bytes per node, 4 per reference slot (leaf padding included), the
    /// per-triangle intersection records and the SIMD leaf groups ([`crate::leaf`]).
    pub bytes: usize,
}

impl KdTree {
    /// Statistics of this tree, with the SAH cost under the tree's own [`crate::BuildConfig`].
    pub fn stats(&self) -> TreeStats {
        let (inner, leaves, empty, depth, sah) =
            self.walk(f64::from(self.config.c_trav), f64::from(self.config.c_isect), self.config.leaf_width);
        let in_tree = self.tris.iter().filter(|t| !is_degenerate(t)).count();
        let refs: usize = self.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.prim_count()).sum();
        let nonempty = leaves - empty;
        TreeStats {
            triangles: self.tris.len(),
            triangles_in_tree: in_tree,
            nodes: self.nodes.len(),
            inner_nodes: inner,
            leaves,
            empty_leaves: empty,
            depth,
            refs,
            refs_per_triangle: if in_tree > 0 { refs as f64 / in_tree as f64 } else { 0.0 },
            avg_tris_per_nonempty_leaf: if nonempty > 0 { refs as f64 / nonempty as f64 } else { 0.0 },
            sah_cost: sah,
            bytes: std::mem::size_of_val(self.nodes.as_slice())
                + std::mem::size_of_val(self.prim_refs.as_slice())
                + std::mem::size_of_val(self.wald.as_slice())
                + std::mem::size_of_val(self.watertight.as_slice())
                + std::mem::size_of_val(self.wald4.as_slice())
                + std::mem::size_of_val(self.watertight4.as_slice()),
        }
    }

    /// The tree's SAH cost (thesis 2.2.1) under the cost model `c_trav`, `c_isect`, whatever
    /// model it was built with, so that trees built with different models can be compared.
    /// A leaf costs `c_isect` per triangle.
    pub fn sah_cost(&self, c_trav: f64, c_isect: f64) -> f64 {
        self.walk(c_trav, c_isect, 1).4
    }

    /// Inner nodes, leaves, empty leaves, depth and SAH cost under `c_trav`, `c_isect`, a
    /// leaf of `n` triangles costing `c_isect * ceil(n / width)`.
    fn walk(&self, c_trav: f64, c_isect: f64, width: u32) -> (usize, usize, usize, usize, f64) {
        let sa_root = surface_area64(&self.bounds);
        let weight = |b: &Aabb| if sa_root > 0.0 { surface_area64(b) / sa_root } else { 1.0 };
        let (mut inner, mut leaves, mut empty, mut depth, mut sah) = (0, 0, 0, 0, 0.0);
        let mut stack = vec![(0usize, self.bounds, 0usize)];
        while let Some((i, b, d)) = stack.pop() {
            let n = self.nodes[i];
            depth = depth.max(d);
            if n.is_leaf() {
                leaves += 1;
                empty += usize::from(n.prim_count() == 0);
                sah += c_isect * n.prim_count().div_ceil(width.max(1) as usize) as f64 * weight(&b);
            } else {
                inner += 1;
                sah += c_trav * weight(&b);
                let (mut l, mut r) = (b, b);
                l.max[n.axis()] = n.split();
                r.min[n.axis()] = n.split();
                stack.push((n.left_child(), l, d + 1));
                stack.push((n.left_child() + 1, r, d + 1));
            }
        }
        (inner, leaves, empty, depth, sah)
    }
}
