//! Single-ray traversal: closest hit and any hit (thesis 2.2.1, Listing 2.1).
//!
//! Iterative, with an explicit fixed-size stack: the ray's interval `[t0, t1]` is clipped to
//! the root box, then at each inner node the distance to the split plane,
//! `t_plane = (split - o[axis]) / d[axis]`, decides whether the ray visits the *front voxel*
//! only (the child on the origin's side), the *back voxel* only, or both, front first with the
//! back voxel pushed. Leaves are intersected front to back.
//!
//! ## The hard cases, and how each is handled
//! - **Front and back voxels** come from the sign of `d[axis]` (Listing 2.1): with a clear
//!   sign bit the ray is below the plane for `t < t_plane`. Then the interval alone decides:
//!   `t_plane > t1` front only, `t_plane < t0` back only (this covers planes behind the
//!   origin), else both. Negative `t_min` works too.
//! - **Zero direction components** (`+0.0` or `-0.0`): `1/d` is an infinity of the same sign
//!   as the zero, so `t_plane` is `+inf` (front voxel only) or `-inf` (back voxel only), and
//!   the sign-bit rule makes that voxel the origin's side in all four sign combinations.
//! - **Ray lying in a split plane** (`o[axis] == split`, `d[axis] == 0`): `t_plane` is
//!   `0 * inf = NaN`. Triangles touching the plane may sit on either side, so both children
//!   are visited over the whole interval.
//! - **Origin on a split plane** (`o[axis] == split`, `d[axis] != 0`): `t_plane = ±0`. The
//!   front voxel is the side the ray comes from (`t < 0`), the back voxel the side it goes to;
//!   with `t_min > 0` only the back voxel is visited, with `t_min <= 0` both (so a triangle in
//!   the plane hit at exactly `t = 0` is found whichever side holds it).
//! - **Rounding**: the interval comparisons are widened by a few ulps, so a child is never
//!   skipped because `t_plane` was rounded past an interval end. Visiting an extra child costs
//!   a little time and never changes the answer, because a leaf accepts any hit in
//!   `[t_min, closest so far]`, not only hits inside its own interval.
//! - **Early exit**: once a hit at `t_hit` is known, stack entries starting beyond `t_hit`
//!   are dropped when popped and children beyond it are never pushed, so the traversal ends
//!   as soon as no remaining voxel can hold a closer hit. (A plain "hit inside this leaf's
//!   interval, stop" test would be wrong for the in-plane case, whose two children share one
//!   interval.)

use crate::counters::{Counters, NoCounters};
use crate::leaf::{LANES, LeafGroup};
use crate::stack::Stack;
use crate::triangle::{Intersector, TriangleTest};
use crate::{Aabb, Hit, KdTree, Ray};

/// Relative widening of interval comparisons: about 8 ulps. Every traversal method of the
/// workspace widens its plane distances and box intervals by this much.
pub const WIDEN: f32 = 8.0 * f32::EPSILON;

impl KdTree {
    /// The closest hit of `ray` in `[ray.t_min, ray.t_max]`, or `None`.
    ///
    /// A ray with NaN components gets `None` (never a panic), and so does one made by
    /// [`Ray::new`] from an infinite origin or direction (stored as NaN); reject such rays
    /// earlier with [`Ray::try_new`].
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_counted(ray, &mut NoCounters)
    }

    /// True if anything blocks `ray` in `[ray.t_min, ray.t_max]` (any hit, the shadow query).
    ///
    /// A ray with NaN components is not blocked (never a panic), nor one made by
    /// [`Ray::new`] from an infinite origin or direction; reject such rays earlier with
    /// [`Ray::try_new`].
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_counted(ray, &mut NoCounters)
    }

    /// [`KdTree::intersect`], counting nodes, leaves and intersection tests into `counters`.
    #[inline]
    pub fn intersect_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        match self.intersector {
            Intersector::Wald => traverse::<_, C, false, true>(self, &self.wald4, &self.wald, ray, counters),
            Intersector::Watertight => {
                traverse::<_, C, false, true>(self, &self.watertight4, &self.watertight, ray, counters)
            }
        }
    }

    /// [`KdTree::occluded`], counting nodes, leaves and intersection tests into `counters`.
    #[inline]
    pub fn occluded_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        match self.intersector {
            Intersector::Wald => traverse::<_, C, true, true>(self, &self.wald4, &self.wald, ray, counters).is_some(),
            Intersector::Watertight => {
                traverse::<_, C, true, true>(self, &self.watertight4, &self.watertight, ray, counters).is_some()
            }
        }
    }

    /// [`KdTree::intersect`] with the scalar twin of the SIMD leaves: each leaf's triangles
    /// tested one by one through the reference array and the per-triangle records. Gives
    /// the same answer, bit for bit ([`crate::leaf`]); for tests and measurements.
    pub fn intersect_scalar_leaves(&self, ray: &Ray) -> Option<Hit> {
        match self.intersector {
            Intersector::Wald => traverse::<_, _, false, false>(self, &self.wald4, &self.wald, ray, &mut NoCounters),
            Intersector::Watertight => {
                traverse::<_, _, false, false>(self, &self.watertight4, &self.watertight, ray, &mut NoCounters)
            }
        }
    }

    /// [`KdTree::occluded`] with the scalar twin of the SIMD leaves (see
    /// [`KdTree::intersect_scalar_leaves`]).
    pub fn occluded_scalar_leaves(&self, ray: &Ray) -> bool {
        match self.intersector {
            Intersector::Wald => {
                traverse::<_, _, true, false>(self, &self.wald4, &self.wald, ray, &mut NoCounters).is_some()
            }
            Intersector::Watertight => {
                traverse::<_, _, true, false>(self, &self.watertight4, &self.watertight, ray, &mut NoCounters).is_some()
            }
        }
    }
}

/// The ray's parameter interval inside `bounds` intersected with `[t_min, t_max]`, widened by
/// a few ulps, or `None` if it misses the box. An axis with a zero direction component
/// constrains nothing when the origin is inside the slab (avoids `0 * inf`).
#[inline]
pub fn clip_to_box(ray: &Ray, bounds: &Aabb) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (ray.t_min, ray.t_max);
    let (o, d, inv) = (ray.origin.to_array(), ray.dir.to_array(), ray.inv_dir.to_array());
    let (lo, hi) = (bounds.min.to_array(), bounds.max.to_array());
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (near, far) = ((lo[a] - o[a]) * inv[a], (hi[a] - o[a]) * inv[a]);
        let (near, far) = if near > far { (far, near) } else { (near, far) };
        t0 = t0.max(near - near.abs() * WIDEN);
        t1 = t1.min(far + far.abs() * WIDEN);
    }
    // Also false for NaN input.
    if t0 <= t1 { Some((t0, t1)) } else { None }
}

/// One deferred back voxel: node index and its interval.
#[derive(Clone, Copy)]
struct StackEntry {
    node: u32,
    t0: f32,
    t1: f32,
}

/// `t` moved outward by [`WIDEN`]: `t + |t| W` (towards +inf) or `t - |t| W` (towards -inf).
#[inline(always)]
fn widen_up(t: f32) -> f32 {
    t + t.abs() * WIDEN
}

#[inline(always)]
fn widen_down(t: f32) -> f32 {
    t - t.abs() * WIDEN
}

/// The traversal kernel, generic over the triangle test (its SIMD leaf groups `groups` and
/// per-triangle `records`), the counters, the query kind (`ANY_HIT`: a dedicated any-hit
/// path, which returns at the first hit without ordering the leaf's hits) and the leaf kernel
/// (`SIMD`: the groups of [`crate::leaf`]; else the scalar twin over `records`). Never
/// allocates.
#[inline(always)]
fn traverse<G: LeafGroup, C: Counters, const ANY_HIT: bool, const SIMD: bool>(
    tree: &KdTree,
    groups: &[G],
    records: &[G::Record],
    ray: &Ray,
    counters: &mut C,
) -> Option<Hit> {
    let (mut t0, mut t1) = clip_to_box(ray, &tree.bounds)?;
    let prepared = <G::Record as TriangleTest>::prepare(ray);
    let prepared4 = G::prepare(ray);
    // Per-axis ray data as 4-lane arrays: an axis `& 3` indexes them without bounds checks.
    let origin = ray.origin.extend(0.0).to_array();
    let inv_dir = ray.inv_dir.extend(0.0).to_array();
    // Bit `axis` is set where the direction's sign bit is: then the front voxel is the upper
    // child. A bit mask in a register, not an array, keeps the next node's address off a
    // memory load (the traversal step is bound by this dependency chain).
    let upper_first = ray.dir.is_negative_bitmask() as usize;
    let nodes = tree.nodes.as_slice();
    let mut stack = Stack::new();
    let mut best: Option<Hit> = None;
    let mut t_hit = ray.t_max;
    let mut index = 0usize;
    let (mut t0_wide, mut t1_wide) = (widen_down(t0), widen_up(t1));
    loop {
        // SAFETY: `index` is the root (0), a child of an inner node, or a stack entry pushed
        // as one, and `KdTree`'s invariant (checked by `KdTree::assemble`, through which every
        // tree is made) puts the root and every inner node's children in `nodes`. The bounds
        // check this skips cost 2% of single-ray throughput.
        let node = unsafe { *nodes.get_unchecked(index) };
        counters.node();
        if !node.is_leaf() {
            // Inner node: front voxel, back voxel or both.
            let axis = node.axis() & 3;
            let t_plane = (node.split() - origin[axis]) * inv_dir[axis];
            // The front voxel holds the ray for t < t_plane: below the plane when the
            // direction's sign bit is clear (this also sends +0.0 and -0.0 the right way).
            let upper = (upper_first >> axis) & 1;
            let front = node.left_child() + upper;
            let back = node.left_child() + 1 - upper;
            if t_plane > t1_wide {
                index = front;
            } else if t_plane < t0_wide {
                index = back;
            } else {
                // Both (NaN lands here too: a ray lying in the split plane, 0 * inf, visits
                // both children over the whole interval).
                let t_split = if t_plane.is_nan() { t0 } else { t_plane };
                stack.push(StackEntry { node: back as u32, t0: t_split, t1 });
                index = front;
                if !t_plane.is_nan() {
                    t1 = t_plane;
                    t1_wide = widen_up(t1);
                }
            }
            continue;
        }

        // Leaf: test its triangles against the closest hit so far (I counts triangles, not
        // groups, so that it stays the thesis's measure).
        counters.leaf();
        counters.tests(node.prim_count() as u64);
        if SIMD {
            // The leaf's references start at a multiple of 4: its groups are `first / 4 ..`.
            let first = node.first_ref() / LANES;
            let count = node.prim_count().div_ceil(LANES);
            for (g, group) in groups[first..first + count].iter().enumerate() {
                let hits = group.intersect(ray, &prepared4, t_hit);
                let lane = if ANY_HIT {
                    let bits = hits.mask.bitmask();
                    if bits == 0 { None } else { Some(bits.trailing_zeros() as usize) }
                } else {
                    hits.closest()
                };
                if let Some(lane) = lane {
                    let prim = tree.prim_refs[(first + g) * LANES + lane];
                    let (t, u, v) = (hits.t.to_array()[lane], hits.u.to_array()[lane], hits.v.to_array()[lane]);
                    let hit = Hit { t, u, v, prim };
                    if ANY_HIT {
                        return Some(hit);
                    }
                    best = Some(hit);
                    t_hit = t;
                }
            }
        } else {
            for &prim in &tree.prim_refs[node.prim_range()] {
                if let Some((t, u, v)) = records[prim as usize].intersect(ray, &prepared, t_hit) {
                    let hit = Hit { t, u, v, prim };
                    if ANY_HIT {
                        return Some(hit);
                    }
                    best = Some(hit);
                    t_hit = t;
                }
            }
        }

        // Next voxel: pop, skipping those that start beyond the closest hit.
        loop {
            let Some(entry) = stack.pop() else {
                return best;
            };
            if entry.t0 <= t_hit {
                index = entry.node as usize;
                t0 = entry.t0;
                t1 = entry.t1.min(t_hit);
                (t0_wide, t1_wide) = (widen_down(t0), widen_up(t1));
                break;
            }
        }
    }
}
