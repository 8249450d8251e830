//! Checks of a built tree: structure, split positions, depth and completeness (every
//! triangle referenced by every leaf whose box it enters; thesis 2.2.1: "polygons can belong
//! to more than one leaf node if it straddles a split plane").

use crate::build::{Polygon, clip_triangle};
use crate::triangle::is_degenerate;
use crate::{Aabb, KdTree, MAX_DEPTH, STACK_SIZE};

/// The boxes of a node's children split on `axis` at `split`.
fn child_boxes(b: &Aabb, axis: usize, split: f32) -> (Aabb, Aabb) {
    let (mut l, mut r) = (*b, *b);
    l.max[axis] = split;
    r.min[axis] = split;
    (l, r)
}

/// True if the clipped polygon `p` (inside the closed box `b`) certainly meets the relative
/// interior of `b`. A convex set inside a box that misses its interior lies in one face plane,
/// so it is enough to test the vertex centroid (a relative-interior point of the polygon)
/// strictly on every axis of non-zero extent; a flat axis is a closed equality (a flat box
/// comes from a flat root box, whose triangles all have that coordinate exactly).
///
/// The computed polygon lies within its error bound ([`Polygon::err`]) of the exact one, and
/// the centroid adds one rounding step ([`Polygon::rho`]), so the centroid is required to be
/// inside by more than both: then a point of the exact triangle is inside the box. A polygon
/// that enters by less is not judged (the builder may or may not have referenced it).
fn enters_interior(p: &Polygon, b: &Aabb) -> bool {
    let verts = p.verts();
    let inv = 1.0 / verts.len() as f64;
    let err = p.err();
    (0..3).all(|k| {
        let (lo, hi) = (f64::from(b.min[k]), f64::from(b.max[k]));
        if lo == hi {
            return true;
        }
        let c = verts.iter().map(|v| v[k]).sum::<f64>() * inv;
        let margin = err[k] + p.rho();
        lo + margin < c && c < hi - margin
    })
}

/// The polygon of triangle `tri` clipped to `b` if it enters the relative interior of `b`.
fn entering(tri: &[glam::Vec3; 3], b: &Aabb) -> bool {
    let lo = b.min.to_array().map(f64::from);
    let hi = b.max.to_array().map(f64::from);
    clip_triangle(tri, lo, hi).is_some_and(|p| enters_interior(&p, b))
}

impl KdTree {
    /// Checks the tree and names the first violation:
    ///
    /// - node indices in range, every node reached exactly once from the root (a tree, not a
    ///   DAG, and no unreachable node), children adjacent (`right = left + 1`);
    /// - leaf reference ranges inside the reference array, references naming triangles;
    /// - depth at most [`crate::STACK_SIZE`] and [`crate::MAX_DEPTH`];
    /// - every split plane finite and inside its node's box (`min <= split <= max`);
    /// - completeness: every non-degenerate triangle that enters the interior of a leaf's box
    ///   (relative interior on a flat axis) is referenced by that leaf. Triangles lying in a
    ///   split plane or only touching a face need not be. The check is exact up to the
    ///   clip's error bound: a triangle entering by less than about `1e-14` of its largest
    ///   coordinate magnitude is not judged (see `enters_interior`).
    ///
    /// Completeness descends once per triangle from the root, into the children whose box the
    /// clipped triangle enters, and looks the triangle up in the leaf's sorted references, so
    /// the cost is comparable to the build (about 1.5x the build time on Sponza).
    pub fn validate(&self) -> Result<(), String> {
        let boxes = self.check_structure()?;
        self.check_complete(&boxes)
    }

    /// The structural checks; returns every node's box.
    fn check_structure(&self) -> Result<Vec<Aabb>, String> {
        let nodes = &self.nodes;
        if nodes.is_empty() {
            return Err("the tree has no nodes".into());
        }
        let mut boxes = vec![Aabb::EMPTY; nodes.len()];
        let mut seen = vec![false; nodes.len()];
        let mut stack = vec![(0usize, self.bounds, 0usize)];
        let max_depth = STACK_SIZE.min(MAX_DEPTH as usize);
        while let Some((i, b, depth)) = stack.pop() {
            if seen[i] {
                return Err(format!("node {i} is reached twice"));
            }
            seen[i] = true;
            boxes[i] = b;
            if depth > max_depth {
                return Err(format!("node {i} is at depth {depth} > {max_depth}"));
            }
            let n = nodes[i];
            if n.is_leaf() {
                let r = n.prim_range();
                if r.end > self.prim_refs.len() {
                    return Err(format!("leaf {i} references {r:?} beyond {} references", self.prim_refs.len()));
                }
                if let Some(&t) = self.prim_refs[r].iter().find(|&&t| t as usize >= self.tris.len()) {
                    return Err(format!("leaf {i} references triangle {t} of {}", self.tris.len()));
                }
                continue;
            }
            let (axis, split) = (n.axis(), n.split());
            if !(split.is_finite() && b.min[axis] <= split && split <= b.max[axis]) {
                return Err(format!(
                    "node {i} splits axis {axis} at {split} outside its box [{}, {}]",
                    b.min[axis], b.max[axis]
                ));
            }
            let l = n.left_child();
            if l == 0 || l + 1 >= nodes.len() {
                return Err(format!("node {i} has children {l}, {} out of range 1..{}", l + 1, nodes.len()));
            }
            let (bl, br) = child_boxes(&b, axis, split);
            stack.push((l + 1, br, depth + 1));
            stack.push((l, bl, depth + 1));
        }
        if let Some(i) = seen.iter().position(|&s| !s) {
            return Err(format!("node {i} is not reachable from the root"));
        }
        Ok(boxes)
    }

    /// The completeness check (see [`KdTree::validate`]).
    fn check_complete(&self, boxes: &[Aabb]) -> Result<(), String> {
        let mut sorted = self.prim_refs.clone();
        for n in self.nodes.iter().filter(|n| n.is_leaf()) {
            sorted[n.prim_range()].sort_unstable();
        }
        let mut stack = Vec::new();
        for (t, tri) in self.tris.iter().enumerate() {
            if is_degenerate(tri) || !entering(tri, &boxes[0]) {
                continue;
            }
            stack.clear();
            stack.push(0usize);
            while let Some(i) = stack.pop() {
                let n = self.nodes[i];
                if n.is_leaf() {
                    if sorted[n.prim_range()].binary_search(&(t as u32)).is_err() {
                        return Err(format!(
                            "triangle {t} {tri:?} enters leaf {i} {:?} but the leaf does not reference it",
                            boxes[i]
                        ));
                    }
                    continue;
                }
                let l = n.left_child();
                for c in [l, l + 1] {
                    if entering(tri, &boxes[c]) {
                        stack.push(c);
                    }
                }
            }
        }
        Ok(())
    }
}
