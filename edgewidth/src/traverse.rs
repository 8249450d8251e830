//! The single-ray edge-width traversal (Tsakok 2008, chapter 5, Listing 5.1 and Figure 5.7).
//!
//! The shadow ray runs from the shaded point (offset by `kdtree::ray::offset_origin`) to the
//! light, `t` in `[0, 1]`, so widths are fractions of the ray as in the thesis. The descent is
//! the one of `kdtree::traverse` (front voxel, back voxel or both, the same hard cases); only
//! leaves differ.
//!
//! ## Leaves, and why each hit is counted once, in order
//! A leaf's triangles are tested with no culling, over the whole segment, and every hit joins
//! the pending list ([`HitList`]), sorted. The list counts each triangle once: the test is
//! deterministic, so a triangle held by several leaves (straddling a split plane, or lying in
//! one) reports the same `t` to each, and a repeat is either still pending or below the
//! list's floor, the threshold up to which hits have been paired. Whether a hit counts does
//! not depend on the interval of the leaf that reports it, so a hit that the triangle test
//! computes a few ulps before the start of the only leaf holding its triangle (a face lying
//! in the split plane, seen at an angle) is still counted, as the brute force counts it.
//!
//! After a leaf, the pending hits before `min t0 - slack` are final and paired in order (the
//! thesis's carry of the open entry across leaves, Figure 5.7), `min t0` being the smallest
//! start of the voxels still on the stack: each stack entry keeps the minimum of its own
//! start and the starts below it. The top entry alone is not enough: a ray lying in a split
//! plane visits both children over the whole interval, so the second child is pushed with the
//! interval's start, and the entries pushed above it while the first child's subtree is
//! traversed all start later; pairing up to the top entry's start would pair the first
//! subtree's hits before the second child's earlier ones (a failure of the brute-force
//! comparison, `in_plane_ray_*` in `tests/traversal.rs`). The `slack` (see [`SLACK`]) absorbs
//! the rounding of plane distances and of the triangle test's `t`, so that no hit found later
//! lies before the hits already paired. Traversal stops once the width passes `R`.

use kdtree::stack::Stack;
use kdtree::traverse::{WIDEN, clip_to_box};
use kdtree::triangle::TriangleTest;
use kdtree::{Aabb, Intersector, KdTree, Ray};

use crate::pairing::{HitList, LeakRemedies, Pairing};

/// Per-thread scratch of the edge-width kernels: the pending hits. Reused from ray to ray,
/// so tracing allocates nothing once it has grown to the largest leaf's hit count.
#[derive(Clone, Debug, Default)]
pub struct EdgeScratch {
    pub(crate) pending: HitList,
}

/// The flush margin, relative to the span of ray parameter that crosses the scene: hits are
/// paired once they lie this far before every voxel still to visit. It covers the widened
/// plane distances of a descent of [`kdtree::STACK_SIZE`] levels (`64 * 8` ulps) and a triangle test's
/// error in `t` of up to about 2000 ulps of the scene's size (the error grows as the ray
/// grazes the triangle), and costs only that hits stay pending a little longer.
pub const SLACK: f32 = 1.0 / 4096.0;

/// [`SLACK`] in units of `ray`'s parameter for a scene within `bounds`: `SLACK` times the
/// parameter that spans the origin's and the scene's largest coordinates (a bound on the `t`
/// of any hit). `0` for a degenerate ray.
#[inline]
pub(crate) fn slack(ray: &Ray, bounds: &Aabb) -> f32 {
    let extent = bounds.min.abs().max(bounds.max.abs()).max_element();
    let s = SLACK * (ray.origin.abs().max_element() + extent) / ray.dir.abs().max_element();
    if s.is_finite() { s } else { 0.0 }
}

#[inline(always)]
fn widen_down(t: f32) -> f32 {
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
/// A NaN `r` never triggers the early exit (the width is computed in full, as with
/// `r = +inf`).
pub fn edge_width(tree: &KdTree, ray: &Ray, r: f32, remedies: &LeakRemedies, scratch: &mut EdgeScratch) -> f32 {
    match tree.intersector() {
        Intersector::Wald => kernel(tree, tree.wald_records(), ray, r, remedies, scratch),
        Intersector::Watertight => kernel(tree, tree.watertight_records(), ray, r, remedies, scratch),
    }
}

/// One deferred back voxel: its node and interval, and `min_t0`, the smallest start of this
/// entry and every entry below it (what bounds the hits still to be found while this entry
/// is the top of the stack).
#[derive(Clone, Copy)]
struct StackEntry {
    node: u32,
    t0: f32,
    t1: f32,
    min_t0: f32,
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
    let slack = slack(ray, &tree.bounds());
    let origin = ray.origin.extend(0.0).to_array();
    let inv_dir = ray.inv_dir.extend(0.0).to_array();
    let upper_first = ray.dir.is_negative_bitmask() as usize;
    let nodes = tree.nodes();
    let mut stack = Stack::<StackEntry>::new();
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
                let below = stack.top().map_or(f32::INFINITY, |e| e.min_t0);
                let min_t0 = below.min(t_split);
                stack.push(StackEntry { node: back as u32, t0: t_split, t1, min_t0 });
                index = front;
                if !t_plane.is_nan() {
                    t1 = t_plane;
                    t1_wide = widen_up(t1);
                }
            }
            continue;
        }

        // Leaf: every hit joins the pending list, which counts each triangle once.
        for &prim in tree.leaf_prims(node) {
            if let Some((t, _, _)) = records[prim as usize].intersect(ray, &prepared, ray.t_max) {
                pending.insert(t, prim, tree, ray.dir);
            }
        }

        // Pair the hits no later leaf can precede; stop once the width passes R.
        let bound = stack.top().map_or(f32::INFINITY, |e| e.min_t0 - slack);
        if pending.flush_below(bound, r, &mut pairing, tree, remedies) {
            return f32::INFINITY;
        }
        let Some(entry) = stack.pop() else { break };
        index = entry.node as usize;
        (t0, t1) = (entry.t0, entry.t1);
        (t0_wide, t1_wide) = (widen_down(t0), widen_up(t1));
    }
    let width = pairing.finish();
    if width > r { f32::INFINITY } else { width }
}
