//! Checks of a built tree: structure, split positions, depth and completeness (every
//! triangle referenced by every leaf whose box it enters; thesis 2.2.1: "polygons can belong
//! to more than one leaf node if it straddles a split plane").

use rayon::prelude::*;

use crate::build::{Polygon, clip_triangle};
use crate::leaf::{GAP, LANES, LeafGroup, Wald4, Watertight4};
use crate::triangle::{Intersector, is_degenerate};
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
        self.check_leaf_groups()?;
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

    /// The completeness check (see [`KdTree::validate`]): the triangles are checked in
    /// parallel (rayon), each descending from the root; the error named is the one of the
    /// lowest-numbered failing triangle, whatever the thread count.
    fn check_complete(&self, boxes: &[Aabb]) -> Result<(), String> {
        let mut sorted = self.prim_refs.clone();
        for n in self.nodes.iter().filter(|n| n.is_leaf()) {
            sorted[n.prim_range()].sort_unstable();
        }
        let failure = self.tris.par_iter().enumerate().find_map_first(|(t, tri)| {
            if is_degenerate(tri) || !entering(tri, &boxes[0]) {
                return None;
            }
            let mut stack = vec![0usize];
            while let Some(i) = stack.pop() {
                let n = self.nodes[i];
                if n.is_leaf() {
                    if sorted[n.prim_range()].binary_search(&(t as u32)).is_err() {
                        return Some(format!(
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
            None
        });
        failure.map_or(Ok(()), Err)
    }

    /// The SIMD leaf layout ([`crate::leaf`]): each non-empty leaf's references start at a
    /// multiple of 4, every slot outside the leaves' ranges is [`GAP`], and group `g` holds,
    /// bit for bit, the records of references `4g .. 4g + 4` (NaN padding after a leaf's last).
    fn check_leaf_groups(&self) -> Result<(), String> {
        if !self.prim_refs.len().is_multiple_of(LANES) {
            return Err(format!("{} reference slots, not a multiple of {LANES}", self.prim_refs.len()));
        }
        let mut used = vec![false; self.prim_refs.len()];
        for (i, n) in self.nodes.iter().enumerate().filter(|(_, n)| n.is_leaf() && n.prim_count() > 0) {
            if !n.first_ref().is_multiple_of(LANES) {
                return Err(format!("leaf {i}'s references start at {}, not a multiple of {LANES}", n.first_ref()));
            }
            for slot in n.prim_range() {
                if used[slot] {
                    return Err(format!("reference slot {slot} belongs to two leaves (leaf {i} and another)"));
                }
                used[slot] = true;
            }
        }
        if let Some(slot) = (0..used.len()).find(|&k| !used[k] && self.prim_refs[k] != GAP) {
            return Err(format!(
                "reference slot {slot} is in no leaf but holds {}, not the gap value",
                self.prim_refs[slot]
            ));
        }
        let groups = self.prim_refs.len() / LANES;
        fn check<G: LeafGroup>(made: &[G], stored: &[G], what: &str) -> Result<(), String> {
            match made.iter().zip(stored).position(|(a, b)| a.bits() != b.bits()) {
                Some(g) => Err(format!("{what} SIMD leaf group {g} does not match its references' records")),
                None => Ok(()),
            }
        }
        match self.intersector {
            Intersector::Wald => {
                if self.wald4.len() != groups {
                    return Err(format!("{} Wald groups for {groups} groups of references", self.wald4.len()));
                }
                let made: Vec<Wald4> = rebuilt(&self.prim_refs, &self.wald);
                check(&made, &self.wald4, "Wald")
            }
            Intersector::Watertight => {
                if self.watertight4.len() != groups {
                    return Err(format!(
                        "{} watertight groups for {groups} groups of references",
                        self.watertight4.len()
                    ));
                }
                let made: Vec<Watertight4> = rebuilt(&self.prim_refs, &self.watertight);
                check(&made, &self.watertight4, "watertight")
            }
        }
    }
}

/// The groups of `prim_refs` made again from `records` (as the tree makes them).
fn rebuilt<G: LeafGroup>(prim_refs: &[u32], records: &[G::Record]) -> Vec<G>
where
    G::Record: Copy,
{
    prim_refs
        .chunks(LANES)
        .map(|refs| {
            let lanes: Vec<G::Record> =
                refs.iter().take_while(|&&r| r != GAP).filter_map(|&r| records.get(r as usize).copied()).collect();
            G::new(&lanes)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use crate::leaf::GAP;
    use crate::{BuildConfig, Intersector, KdNode, KdTree};

    fn tree(intersector: Intersector) -> KdTree {
        let tris: Vec<[Vec3; 3]> = (0..40)
            .map(|i| {
                let c = Vec3::new((i % 7) as f32, (i / 7) as f32, (i % 3) as f32);
                [c, c + Vec3::X, c + Vec3::new(0.0, 0.7, 0.4)]
            })
            .collect();
        let tree = KdTree::build_soup(&tris, &BuildConfig { intersector, ..BuildConfig::default() }).unwrap();
        tree.validate().unwrap();
        tree
    }

    #[test]
    fn the_simd_leaf_layout_is_checked() {
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let good = tree(intersector);
            let leaf = good.nodes.iter().position(|n| n.is_leaf() && n.prim_count() > 0).unwrap();

            // A group that no longer matches its references' records.
            let mut t = good.clone();
            match intersector {
                Intersector::Wald => t.wald4[0].n_u = t.wald4[0].n_u * 2.0 + glam::Vec4::ONE,
                Intersector::Watertight => t.watertight4[0].v[0][0] += glam::Vec4::ONE,
            }
            assert!(t.validate().unwrap_err().contains("SIMD leaf group 0"), "{intersector:?}");

            // A leaf whose references do not start at a multiple of 4.
            let mut t = good.clone();
            let n = t.nodes[leaf];
            t.nodes[leaf] = KdNode::leaf(n.first_ref() as u32 + 1, n.prim_count() as u32 - 1);
            assert!(t.validate().unwrap_err().contains("not a multiple of 4"), "{intersector:?}");

            // A gap that holds a reference.
            let mut t = good.clone();
            let gap = t.prim_refs.iter().position(|&r| r == GAP).expect("some leaf is padded");
            t.prim_refs[gap] = 0;
            assert!(t.validate().unwrap_err().contains("not the gap value"), "{intersector:?}");
        }
    }
}
