//! The single-ray edge-width traversal (Tsakok 2008, chapter 5, Listing 5.1 and Figure 5.7).
//!
//! The shadow ray runs from the shaded point (offset by `kdtree::ray::offset_origin`) to the
//! light, `t` in `[0, 1]`, so widths are fractions of the ray as in the thesis. The descent is
//! `kdtree::descent`, with the single-ray step of `kdtree::traverse` (front voxel, back voxel
//! or both, the same hard cases); only the leaf visitor and the pop rule differ.
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

use kdtree::descent::{Descent, Entry, Flow, Visit, descend};
use kdtree::stack::Stack;
use kdtree::traverse::{RaySpan, clip_to_box, ray_step};
use kdtree::triangle::TriangleTest;
use kdtree::{Aabb, Counters, Intersector, KdNode, KdTree, NoCounters, Ray, TreeTest, WaldTest, WatertightTest};

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
        Intersector::Wald => edge_width_with::<WaldTest>(tree, ray, r, remedies, scratch),
        Intersector::Watertight => edge_width_with::<WatertightTest>(tree, ray, r, remedies, scratch),
    }
}

/// [`edge_width`] with the tree's triangle test `I`, chosen once by the caller (see
/// [`TreeTest`]).
pub fn edge_width_with<I: TreeTest>(
    tree: &KdTree,
    ray: &Ray,
    r: f32,
    remedies: &LeakRemedies,
    scratch: &mut EdgeScratch,
) -> f32 {
    kernel(tree, I::records(tree), ray, r, remedies, scratch)
}

/// The edge-width ray walking the tree: the single-ray step ([`ray_step`]), a leaf visitor
/// that adds every hit to the pending list and pairs those no later voxel can precede, and a
/// pop rule that drops nothing (every crossing counts, not only the closest).
struct EdgeRay<'a, T: TriangleTest> {
    tree: &'a KdTree,
    records: &'a [T],
    ray: &'a Ray,
    prepared: T::RayData,
    origin: [f32; 4],
    inv_dir: [f32; 4],
    upper_first: usize,
    r: f32,
    slack: f32,
    remedies: &'a LeakRemedies<'a>,
    pending: &'a mut HitList,
    pairing: Pairing,
    passed_r: bool,
}

/// A deferred back voxel: its interval `(t0, t1)` and `min_t0`, the smallest start of this
/// entry and every entry below it (what bounds the hits still to be found while this entry is
/// the top of the stack).
type Deferred = (f32, f32, f32);

impl<T: TriangleTest> Descent for EdgeRay<'_, T> {
    type Span = RaySpan;
    type Deferred = Deferred;
    type Stack = Stack<Entry<Deferred>>;

    #[inline(always)]
    fn inner(&mut self, node: KdNode, span: &mut RaySpan, stack: &Self::Stack) -> Visit<Deferred> {
        match ray_step(node, (&self.origin, &self.inv_dir, self.upper_first), span) {
            Visit::Both { first, second, deferred: (t_split, t1) } => {
                let below = stack.top().map_or(f32::INFINITY, |e| e.value.2);
                Visit::Both { first, second, deferred: (t_split, t1, below.min(t_split)) }
            }
            Visit::One(child) => Visit::One(child),
            Visit::Neither => Visit::Neither,
        }
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, _: &RaySpan, stack: &Self::Stack, _: &mut C) -> Flow {
        // Every hit joins the pending list, which counts each triangle once.
        let tree = self.tree;
        for &prim in tree.leaf_prims(node) {
            if let Some((t, _, _)) = self.records[prim as usize].intersect(self.ray, &self.prepared, self.ray.t_max) {
                self.pending.insert(t, prim, tree, self.ray.dir);
            }
        }
        // Pair the hits no later leaf can precede; stop once the width passes R.
        let bound = stack.top().map_or(f32::INFINITY, |e| e.value.2 - self.slack);
        if self.pending.flush_below(bound, self.r, &mut self.pairing, tree, self.remedies) {
            self.passed_r = true;
            return Flow::Stop;
        }
        Flow::Continue
    }

    #[inline(always)]
    fn resume(&mut self, (t0, t1, _): Deferred) -> Option<RaySpan> {
        Some(RaySpan::new(t0, t1))
    }
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
    let Some((t0, t1)) = clip_to_box(ray, &tree.bounds()) else { return 0.0 };
    let mut group = EdgeRay {
        tree,
        records,
        ray,
        prepared: T::prepare(ray),
        origin: ray.origin.extend(0.0).to_array(),
        inv_dir: ray.inv_dir.extend(0.0).to_array(),
        upper_first: ray.dir.is_negative_bitmask() as usize,
        r,
        slack: slack(ray, &tree.bounds()),
        remedies,
        pending,
        pairing: Pairing::new(),
        passed_r: false,
    };
    descend(tree, &mut group, (0, RaySpan::new(t0, t1)), &mut Stack::new(), &mut NoCounters);
    if group.passed_r {
        return f32::INFINITY;
    }
    let width = group.pairing.finish();
    if width > r { f32::INFINITY } else { width }
}
