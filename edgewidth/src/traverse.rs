//! The single-ray edge-width traversal (Tsakok 2008, chapter 5, Listing 5.1 and Figure 5.7).
//!
//! The shadow ray runs from the shaded point (offset by `kdtree::ray::offset_origin`) to the
//! light, `t` in `[0, 1]`, so widths are fractions of the ray as in the thesis. The descent is
//! the one of `kdtree::traverse` (front voxel, back voxel or both, the same hard cases); only
//! leaves differ.
//!
//! ## Leaves, and why each hit is counted once
//! A leaf's interval is `[t0, t1]`. Its triangles are tested with no culling, over the whole
//! segment, and a hit at `t >= t0` (widened down by a few ulps) joins the pending list
//! ([`HitList`]), sorted, unless its triangle is already there. Hits before `t0` belong to
//! earlier leaves, which found them already: the interval is half-open at its start, and a
//! triangle referenced by several leaves (straddling a split plane) is kept once. The widened
//! start and the duplicate check together make a hit on a split plane (a triangle lying in the
//! plane, or touching it) count exactly once whichever side's leaf holds it and whichever way
//! its `t` rounds.
//!
//! After a leaf, the pending hits before the start of the next voxel on the stack are
//! final: no later leaf can report a hit before the smallest start on the stack, which is the
//! top entry's (each entry pushed lies inside the interval that the entries below it were
//! split from). They are paired in order (the thesis's carry of the open entry across leaves,
//! Figure 5.7) and traversal stops once the width passes `R`. For a ray lying in a split plane
//! both children cover the same interval; the bound keeps the first child's hits pending until
//! the second child has added its own, so the order stays right.

use kdtree::traverse::{WIDEN, clip_to_box};
use kdtree::triangle::TriangleTest;
use kdtree::{Intersector, KdTree, Ray, STACK_SIZE};

use crate::pairing::{HitList, LeakRemedies, Pairing};

/// Per-thread scratch of the edge-width kernels: the pending hits. Reused from ray to ray,
/// so tracing allocates nothing once it has grown to the largest leaf's hit count.
#[derive(Clone, Debug, Default)]
pub struct EdgeScratch {
    pub(crate) pending: HitList,
}

/// `t` moved towards `-inf` by [`WIDEN`] (as the kd-tree traversal widens).
#[inline(always)]
pub(crate) fn widen_down(t: f32) -> f32 {
    t - t.abs() * WIDEN
}

#[inline(always)]
fn widen_up(t: f32) -> f32 {
    t + t.abs() * WIDEN
}

/// The edge width of `ray` (Listing 5.1, corrected): the largest entry-to-exit distance along
/// it, in units of its direction, or `f32::INFINITY` when it passes `r` (early exit) or an
/// entry is never closed. `0` when nothing is crossed. Give the result to
/// [`crate::occlusion_factor`] with the same `r`.
///
/// Never allocates once `scratch` has grown; a NaN ray gets `0` (no crossing), never a panic.
pub fn edge_width(tree: &KdTree, ray: &Ray, r: f32, remedies: &LeakRemedies, scratch: &mut EdgeScratch) -> f32 {
    match tree.intersector() {
        Intersector::Wald => kernel(tree, tree.wald_records(), ray, r, remedies, scratch),
        Intersector::Watertight => kernel(tree, tree.watertight_records(), ray, r, remedies, scratch),
    }
}

/// One deferred back voxel.
#[derive(Clone, Copy, Default)]
struct StackEntry {
    node: u32,
    t0: f32,
    t1: f32,
}

#[inline(always)]
fn kernel<T: TriangleTest>(
    tree: &KdTree,
    records: &[T],
    ray: &Ray,
    r: f32,
    remedies: &LeakRemedies,
    scratch: &mut EdgeScratch,
) -> f32 {
    let pending = &mut scratch.pending;
    pending.clear();
    let mut pairing = Pairing::new();
    let Some((mut t0, mut t1)) = clip_to_box(ray, &tree.bounds()) else { return 0.0 };
    let prepared = T::prepare(ray);
    let origin = ray.origin.extend(0.0).to_array();
    let inv_dir = ray.inv_dir.extend(0.0).to_array();
    let upper_first = ray.dir.is_negative_bitmask() as usize;
    let nodes = tree.nodes();
    let mut stack = [StackEntry::default(); STACK_SIZE];
    let mut sp = 0usize;
    let mut index = 0usize;
    let (mut t0_wide, mut t1_wide) = (widen_down(t0), widen_up(t1));
    loop {
        let node = nodes[index];
        if !node.is_leaf() {
            // Inner node: front voxel, back voxel or both (as `kdtree::traverse`).
            let axis = node.axis() & 3;
            let t_plane = (node.split() - origin[axis]) * inv_dir[axis];
            let upper = (upper_first >> axis) & 1;
            let front = node.left_child() + upper;
            let back = node.left_child() + 1 - upper;
            if t_plane > t1_wide {
                index = front;
            } else if t_plane < t0_wide {
                index = back;
            } else {
                // Both; a ray in the plane (NaN) visits both over its whole interval.
                let t_split = if t_plane.is_nan() { t0 } else { t_plane };
                stack[sp % STACK_SIZE] = StackEntry { node: back as u32, t0: t_split, t1 };
                sp += 1;
                index = front;
                if !t_plane.is_nan() {
                    t1 = t_plane;
                    t1_wide = widen_up(t1);
                }
            }
            continue;
        }

        // Leaf: every hit from this leaf's start on joins the pending list, once.
        for &prim in tree.leaf_prims(node) {
            if let Some((t, _, _)) = records[prim as usize].intersect(ray, &prepared, ray.t_max)
                && t >= t0_wide
            {
                pending.insert(t, prim, tree, ray.dir);
            }
        }

        // Pair the hits no later leaf can precede; stop once the width passes R.
        let bound = if sp == 0 { f32::INFINITY } else { widen_down(stack[(sp - 1) % STACK_SIZE].t0) };
        if pending.flush_below(bound, r, &mut pairing, tree, remedies) {
            return f32::INFINITY;
        }
        if sp == 0 {
            break;
        }
        sp -= 1;
        let entry = stack[sp % STACK_SIZE];
        index = entry.node as usize;
        (t0, t1) = (entry.t0, entry.t1);
        (t0_wide, t1_wide) = (widen_down(t0), widen_up(t1));
    }
    let width = pairing.finish();
    if width > r { f32::INFINITY } else { width }
}
