//! The build: a binary BVH by binned SAH, collapsed top-down into multi-nodes of any width (Wald,
//! Benthin & Boulos 2008, section 4: "build a binary BVH \[with\] SAH-based binning, ... copy
//! \[it\] into our multi-node layout ..., which we can then collapse").
//!
//! - **Binned SAH** (Wald 2007, "On fast construction of SAH-based bounding volume
//!   hierarchies"): per node, the triangles' centroids are put into [`BINS`] bins along each
//!   axis of the centroid box and the best of the `3 (BINS - 1)` planes is taken. The cost
//!   is the paper's SIMD-aware SAH (section 4): a leaf of `n` triangles costs `ceil(n / 4)`
//!   4-wide tests, so splits are weighed by `SA(child) ceil(n_child / 4)`. Binning rather than
//!   the kd-tree's exact sweep: a BVH split only partitions triangles (no clipping), binned
//!   SAH finds trees of nearly the quality of the full sweep (Wald 2007) in `O(N)` per level
//!   without the sort, and the paper itself collapses a binned build. Nodes of more than
//!   [`LEAF_SIZE`] triangles are always split (a leaf is one 4-wide block); at most 4 are a
//!   leaf, which the SIMD cost always prefers (one chunk). Large nodes are split in parallel
//!   (`rayon::join`); the result does not depend on the thread count.
//! - **Depth.** Beyond binary depth [`MEDIAN_DEPTH`] nodes are split at the object median,
//!   so the binary depth stays below `MEDIAN_DEPTH + 33` and the multi-node tree's (each
//!   multi-node takes at least one binary level) within [`MAX_DEPTH`]: the traversal's
//!   fixed stacks ([`crate::node::stack_capacity`]) cannot overflow.
//! - **Collapse** (section 4.2, "merging a child node into its parent", top-down): starting
//!   at the root, the inner child of largest surface area is replaced by its two children
//!   while the node has fewer than its width (`MultiNode::WIDTH`: 4, 8 or 16); then each
//!   inner child is collapsed the same way. The trees of every width are collapsed from the
//!   same binary BVH (the build is deterministic) and have the same leaves. The paper's other two
//!   moves (merging two leaves, two inner nodes) serve 16-wide leaves; with leaves of one
//!   4-wide block they do not apply.

use glam::Vec3;
use kdtree::Aabb;
use kdtree::triangle::is_degenerate;

use crate::node::{LEAF, MAX_DEPTH, MultiNode};

/// Bins per axis of the binned SAH.
pub const BINS: usize = 32;

/// The most triangles in a leaf: one 4-wide block.
pub const LEAF_SIZE: usize = 4;

/// Binary depth beyond which nodes are split at the object median (48): the binary depth
/// then stays below `MEDIAN_DEPTH + 33` and the multi-node tree's within [`MAX_DEPTH`].
pub const MEDIAN_DEPTH: u32 = MAX_DEPTH - 37;

/// Binary nodes with more triangles than this are split in parallel.
const PARALLEL: usize = 4096;

/// Why a build failed: the kd-tree's errors (a non-finite vertex, an index out of range,
/// more than the index widths hold), so that both structures refuse the same input alike.
pub use kdtree::BuildError;

/// One triangle in the build: its box, centroid and id.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prim {
    pub bounds: Aabb,
    pub centroid: Vec3,
    pub id: u32,
}

/// A node of the binary BVH.
#[derive(Debug)]
pub(crate) enum Binary {
    /// `prims[start..start + len]`.
    Leaf { bounds: Aabb, start: usize, len: usize },
    /// Two children.
    Inner { bounds: Aabb, kids: Box<[Binary; 2]> },
}

impl Binary {
    fn bounds(&self) -> &Aabb {
        match self {
            Binary::Leaf { bounds, .. } | Binary::Inner { bounds, .. } => bounds,
        }
    }
}

/// The build's primitives: the non-degenerate triangles with their boxes, after checking the
/// input.
pub(crate) fn prims(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Vec<Prim>, BuildError> {
    if let Some(index) = positions.iter().position(|p| !p.is_finite()) {
        return Err(BuildError::NonFiniteVertex { index, position: positions[index] });
    }
    if triangles.len() >= LEAF as usize {
        return Err(BuildError::TooLarge(format!("{} triangles", triangles.len())));
    }
    let mut out = Vec::with_capacity(triangles.len());
    for (i, t) in triangles.iter().enumerate() {
        if let Some(&vertex) = t.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(BuildError::IndexOutOfRange { triangle: i, vertex, vertices: positions.len() });
        }
        let tri = t.map(|v| positions[v as usize]);
        if is_degenerate(&tri) {
            continue;
        }
        let bounds = Aabb::from_points(&tri);
        out.push(Prim { bounds, centroid: (bounds.min + bounds.max) * 0.5, id: i as u32 });
    }
    Ok(out)
}

/// The binary BVH over `prims` (reordered in place; leaves index into them), `offset` being
/// the slice's start in the whole array.
pub(crate) fn binary(prims: &mut [Prim], offset: usize, depth: u32) -> Binary {
    let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds));
    if prims.len() <= LEAF_SIZE {
        return Binary::Leaf { bounds, start: offset, len: prims.len() };
    }
    let mid = split(prims, depth);
    let (left, right) = prims.split_at_mut(mid);
    let (l, r) = if left.len() + right.len() > PARALLEL {
        rayon::join(|| binary(left, offset, depth + 1), || binary(right, offset + mid, depth + 1))
    } else {
        (binary(left, offset, depth + 1), binary(right, offset + mid, depth + 1))
    };
    Binary::Inner { bounds, kids: Box::new([l, r]) }
}

/// `ceil(n / 4)`: 4-wide tests for `n` triangles.
fn chunks(n: usize) -> f32 {
    n.div_ceil(LEAF_SIZE) as f32
}

/// Partitions `prims` by the best binned-SAH plane (or the object median) and returns the
/// size of the first part, in `1..prims.len()`.
fn split(prims: &mut [Prim], depth: u32) -> usize {
    let n = prims.len();
    let cb = prims.iter().fold(Aabb::EMPTY, |b, p| b.grow(p.centroid));
    let extent = cb.max - cb.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if depth >= MEDIAN_DEPTH || extent[axis] <= 0.0 {
        return median(prims, axis);
    }
    // Per axis: bin counts and boxes; sweep for the best plane (between bins b and b + 1).
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, last bin on the left)
    for a in 0..3 {
        if extent[a] <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent[a];
        let bin = |p: &Prim| (((p.centroid[a] - cb.min[a]) * scale) as usize).min(BINS - 1);
        let mut counts = [0usize; BINS];
        let mut boxes = [Aabb::EMPTY; BINS];
        for p in prims.iter() {
            let b = bin(p);
            counts[b] += 1;
            boxes[b] = boxes[b].union(p.bounds);
        }
        let mut right_area = [0.0f32; BINS];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        let mut right_count = [0usize; BINS];
        for b in (1..BINS).rev() {
            acc = acc.union(boxes[b]);
            count += counts[b];
            right_area[b] = acc.surface_area();
            right_count[b] = count;
        }
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for b in 0..BINS - 1 {
            acc = acc.union(boxes[b]);
            count += counts[b];
            let rc = right_count[b + 1];
            if count == 0 || rc == 0 {
                continue;
            }
            let cost = acc.surface_area() * chunks(count) + right_area[b + 1] * chunks(rc);
            if best.is_none_or(|(c, ..)| cost < c) {
                best = Some((cost, a, b));
            }
        }
    }
    let Some((_, a, last)) = best else { return median(prims, axis) };
    let scale = BINS as f32 / extent[a];
    let left = |p: &Prim| (((p.centroid[a] - cb.min[a]) * scale) as usize).min(BINS - 1) <= last;
    // Two-pointer partition (deterministic).
    let (mut i, mut j) = (0, n);
    while i < j {
        if left(&prims[i]) {
            i += 1;
        } else {
            j -= 1;
            prims.swap(i, j);
        }
    }
    if i == 0 || i == n { median(prims, axis) } else { i }
}

/// The object median along `axis` (centroid order, then id, so the order is total).
fn median(prims: &mut [Prim], axis: usize) -> usize {
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |p, q| p.centroid[axis].total_cmp(&q.centroid[axis]).then(p.id.cmp(&q.id)));
    mid
}

/// The collapsed tree: multi-nodes (root at 0) and, per leaf, the ids of its triangles.
pub(crate) struct Collapsed<N> {
    pub nodes: Vec<N>,
    pub leaves: Vec<Vec<u32>>,
    pub depth: u32,
}

/// Collapses `root` into multi-nodes.
pub(crate) fn collapse<N: MultiNode>(root: &Binary, prims: &[Prim]) -> Result<Collapsed<N>, BuildError> {
    let mut out = Collapsed { nodes: Vec::new(), leaves: Vec::new(), depth: 0 };
    match root {
        Binary::Leaf { .. } => {
            let mut node = N::empty();
            if let Some(child) = leaf(root, prims, &mut out)? {
                node.set(0, child, root.bounds());
            }
            out.nodes.push(node);
            out.depth = 1;
        }
        Binary::Inner { .. } => {
            multi(root, prims, &mut out, 1)?;
        }
    }
    Ok(out)
}

/// A leaf child word (`LEAF | block`), or `None` for an empty leaf.
fn leaf<N>(b: &Binary, prims: &[Prim], out: &mut Collapsed<N>) -> Result<Option<u32>, BuildError> {
    let Binary::Leaf { start, len, .. } = b else { unreachable!("leaf() takes leaves") };
    if *len == 0 {
        return Ok(None);
    }
    let index = out.leaves.len();
    if index >= LEAF as usize - 1 {
        return Err(BuildError::TooLarge(format!("{index} leaves")));
    }
    out.leaves.push(prims[*start..start + len].iter().map(|p| p.id).collect());
    Ok(Some(LEAF | index as u32))
}

/// The multi-node of inner binary node `b` (section 4.2: pull up the largest inner child
/// while there is room), then its inner children recursively. Returns its index.
fn multi<N: MultiNode>(b: &Binary, prims: &[Prim], out: &mut Collapsed<N>, depth: u32) -> Result<u32, BuildError> {
    let Binary::Inner { kids, .. } = b else { unreachable!("multi() takes inner nodes") };
    let mut slots: Vec<&Binary> = kids.iter().collect();
    while slots.len() < N::WIDTH {
        let largest = slots
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s, Binary::Inner { .. }))
            .max_by(|(_, a), (_, b)| a.bounds().surface_area().total_cmp(&b.bounds().surface_area()))
            .map(|(i, _)| i);
        let Some(i) = largest else { break };
        let Binary::Inner { kids, .. } = slots[i] else { unreachable!() };
        slots.splice(i..=i, kids.iter());
    }
    let index = out.nodes.len();
    if index >= LEAF as usize - 1 {
        return Err(BuildError::TooLarge(format!("{index} nodes")));
    }
    out.nodes.push(N::empty());
    out.depth = out.depth.max(depth);
    for (i, s) in slots.iter().enumerate() {
        let child = match s {
            Binary::Leaf { .. } => leaf(s, prims, out)?,
            Binary::Inner { .. } => Some(multi(s, prims, out, depth + 1)?),
        };
        if let Some(child) = child {
            let bounds = *s.bounds();
            out.nodes[index].set(i, child, &bounds);
        }
    }
    Ok(index as u32)
}
