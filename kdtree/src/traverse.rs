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
use crate::descent::{Descent, Entry, Flow, Visit, descend};
use crate::intersect::{TreeTest, WaldTest, WatertightTest};
use crate::leaf::{LANES, LeafGroup};
use crate::node::KdNode;
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
    /// Matches on the tree's intersector once and calls [`KdTree::intersect_with`].
    #[inline]
    pub fn intersect_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        match self.intersector {
            Intersector::Wald => self.intersect_with_counted::<WaldTest, C>(ray, counters),
            Intersector::Watertight => self.intersect_with_counted::<WatertightTest, C>(ray, counters),
        }
    }

    /// [`KdTree::occluded`], counting nodes, leaves and intersection tests into `counters`.
    /// Matches on the tree's intersector once and calls [`KdTree::occluded_with`].
    #[inline]
    pub fn occluded_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        match self.intersector {
            Intersector::Wald => self.occluded_with_counted::<WaldTest, C>(ray, counters),
            Intersector::Watertight => self.occluded_with_counted::<WatertightTest, C>(ray, counters),
        }
    }

    /// [`KdTree::intersect`] with the triangle test `I` chosen by the caller, once, when it
    /// bound the tree (`I` must be the tree's own: see [`TreeTest`]). No match inside.
    #[inline]
    pub fn intersect_with<I: TreeTest>(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_with_counted::<I, _>(ray, &mut NoCounters)
    }

    /// [`KdTree::occluded`] with the triangle test `I` (see [`KdTree::intersect_with`]).
    #[inline]
    pub fn occluded_with<I: TreeTest>(&self, ray: &Ray) -> bool {
        self.occluded_with_counted::<I, _>(ray, &mut NoCounters)
    }

    /// [`KdTree::intersect_with`], counting into `counters`.
    #[inline]
    pub fn intersect_with_counted<I: TreeTest, C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        traverse::<I::Group, C, false, true>(self, I::groups(self), I::records(self), ray, counters)
    }

    /// [`KdTree::occluded_with`], counting into `counters`.
    #[inline]
    pub fn occluded_with_counted<I: TreeTest, C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        traverse::<I::Group, C, true, true>(self, I::groups(self), I::records(self), ray, counters).is_some()
    }

    /// [`KdTree::intersect`] with the scalar twin of the SIMD leaves: each leaf's triangles
    /// tested one by one through the reference array and the per-triangle records. Gives
    /// the same answer, bit for bit ([`crate::leaf`]); for tests and measurements.
    pub fn intersect_scalar_leaves(&self, ray: &Ray) -> Option<Hit> {
        match self.intersector {
            Intersector::Wald => self.intersect_scalar_leaves_with::<WaldTest>(ray),
            Intersector::Watertight => self.intersect_scalar_leaves_with::<WatertightTest>(ray),
        }
    }

    /// [`KdTree::occluded`] with the scalar twin of the SIMD leaves (see
    /// [`KdTree::intersect_scalar_leaves`]).
    pub fn occluded_scalar_leaves(&self, ray: &Ray) -> bool {
        match self.intersector {
            Intersector::Wald => self.occluded_scalar_leaves_with::<WaldTest>(ray),
            Intersector::Watertight => self.occluded_scalar_leaves_with::<WatertightTest>(ray),
        }
    }

    /// [`KdTree::intersect_scalar_leaves`] with the triangle test `I` (see
    /// [`KdTree::intersect_with`]).
    pub fn intersect_scalar_leaves_with<I: TreeTest>(&self, ray: &Ray) -> Option<Hit> {
        traverse::<I::Group, _, false, false>(self, I::groups(self), I::records(self), ray, &mut NoCounters)
    }

    /// [`KdTree::occluded_scalar_leaves`] with the triangle test `I` (see
    /// [`KdTree::intersect_with`]).
    pub fn occluded_scalar_leaves_with<I: TreeTest>(&self, ray: &Ray) -> bool {
        traverse::<I::Group, _, true, false>(self, I::groups(self), I::records(self), ray, &mut NoCounters).is_some()
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

/// `t` moved outward by [`WIDEN`]: `t + |t| W` (towards +inf) or `t - |t| W` (towards -inf).
#[inline(always)]
pub fn widen_up(t: f32) -> f32 {
    t + t.abs() * WIDEN
}

/// `t` moved towards -inf by [`WIDEN`]: `t - |t| W`.
#[inline(always)]
pub fn widen_down(t: f32) -> f32 {
    t - t.abs() * WIDEN
}

/// A single ray's interval in the voxel it is in, with its ends widened by [`WIDEN`] for the
/// plane comparisons (kept beside the exact ends so they are widened once per voxel, not once
/// per node).
#[derive(Clone, Copy, Debug)]
pub struct RaySpan {
    /// Entry parameter.
    pub t0: f32,
    /// Exit parameter.
    pub t1: f32,
    /// `t0` widened down.
    pub t0_wide: f32,
    /// `t1` widened up.
    pub t1_wide: f32,
}

impl RaySpan {
    /// The span `[t0, t1]` with its widened ends.
    #[inline(always)]
    pub fn new(t0: f32, t1: f32) -> RaySpan {
        RaySpan { t0, t1, t0_wide: widen_down(t0), t1_wide: widen_up(t1) }
    }
}

/// The interval step of one ray at an inner node (Listing 2.1, with the hard cases of this
/// module's documentation): the front voxel, the back voxel, or both, front first, the back
/// voxel deferred with `[t_split, t1]`. `origin` and `inv_dir` are the ray's as 4-lane arrays
/// (an axis `& 3` indexes them without bounds checks), `upper_first` has bit `axis` set where
/// the direction's sign bit is. Every single-ray kd-tree kernel (closest and any hit, edge
/// widths) steps with it.
#[inline(always)]
pub fn ray_step(
    node: KdNode,
    (origin, inv_dir, upper_first): (&[f32; 4], &[f32; 4], usize),
    span: &mut RaySpan,
) -> Visit<(f32, f32)> {
    let axis = node.axis() & 3;
    let t_plane = (node.split() - origin[axis]) * inv_dir[axis];
    // The front voxel holds the ray for t < t_plane: below the plane when the direction's
    // sign bit is clear (this also sends +0.0 and -0.0 the right way).
    let upper = (upper_first >> axis) & 1;
    let front = node.left_child() + upper;
    let back = node.left_child() + 1 - upper;
    if t_plane > span.t1_wide {
        Visit::One(front)
    } else if t_plane < span.t0_wide {
        Visit::One(back)
    } else {
        // Both (NaN lands here too: a ray lying in the split plane, 0 * inf, visits both
        // children over the whole interval).
        let t_split = if t_plane.is_nan() { span.t0 } else { t_plane };
        let deferred = (t_split, span.t1);
        if !t_plane.is_nan() {
            span.t1 = t_plane;
            span.t1_wide = widen_up(t_plane);
        }
        Visit::Both { first: front, second: back, deferred }
    }
}

/// One ray walking the tree for its closest hit (or any hit, `ANY_HIT`: a dedicated any-hit
/// path, which returns at the first hit without ordering the leaf's hits), with the triangle
/// test's SIMD leaf groups `groups` (`SIMD`; else the scalar twin over the per-triangle
/// `records`).
struct SingleRay<'a, G: LeafGroup, const ANY_HIT: bool, const SIMD: bool> {
    tree: &'a KdTree,
    groups: &'a [G],
    records: &'a [G::Record],
    ray: &'a Ray,
    prepared: <G::Record as TriangleTest>::RayData,
    prepared4: G::RayData,
    origin: [f32; 4],
    inv_dir: [f32; 4],
    upper_first: usize,
    best: Option<Hit>,
    t_hit: f32,
}

impl<G: LeafGroup, const ANY_HIT: bool, const SIMD: bool> Descent for SingleRay<'_, G, ANY_HIT, SIMD> {
    type Span = RaySpan;
    type Deferred = (f32, f32);
    type Stack = Stack<Entry<(f32, f32)>>;

    #[inline(always)]
    fn inner(&mut self, node: KdNode, span: &mut RaySpan, _: &Self::Stack) -> Visit<(f32, f32)> {
        ray_step(node, (&self.origin, &self.inv_dir, self.upper_first), span)
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, _: &RaySpan, _: &Self::Stack, counters: &mut C) -> Flow {
        // Test the leaf's triangles against the closest hit so far (I counts triangles, not
        // groups, so that it stays the thesis's measure).
        counters.leaf();
        counters.tests(node.prim_count() as u64);
        let (tree, ray) = (self.tree, self.ray);
        if SIMD {
            // The leaf's references start at a multiple of 4: its groups are `first / 4 ..`.
            let first = node.first_ref() / LANES;
            let count = node.prim_count().div_ceil(LANES);
            for (g, group) in self.groups[first..first + count].iter().enumerate() {
                let hits = group.intersect(ray, &self.prepared4, self.t_hit);
                let lane = if ANY_HIT {
                    let bits = hits.mask.bitmask();
                    if bits == 0 { None } else { Some(bits.trailing_zeros() as usize) }
                } else {
                    hits.closest()
                };
                if let Some(lane) = lane {
                    let prim = tree.prim_refs[(first + g) * LANES + lane];
                    let (t, u, v) = (hits.t.to_array()[lane], hits.u.to_array()[lane], hits.v.to_array()[lane]);
                    self.best = Some(Hit { t, u, v, prim });
                    if ANY_HIT {
                        return Flow::Stop;
                    }
                    self.t_hit = t;
                }
            }
        } else {
            for &prim in &tree.prim_refs[node.prim_range()] {
                if let Some((t, u, v)) = self.records[prim as usize].intersect(ray, &self.prepared, self.t_hit) {
                    self.best = Some(Hit { t, u, v, prim });
                    if ANY_HIT {
                        return Flow::Stop;
                    }
                    self.t_hit = t;
                }
            }
        }
        Flow::Continue
    }

    /// Drops voxels that start beyond the closest hit; clamps the others to it.
    #[inline(always)]
    fn resume(&mut self, (t0, t1): (f32, f32)) -> Option<RaySpan> {
        (t0 <= self.t_hit).then(|| RaySpan::new(t0, t1.min(self.t_hit)))
    }
}

/// The single-ray kernel: [`SingleRay`] through [`descend`]. Never allocates.
#[inline(always)]
fn traverse<G: LeafGroup, C: Counters, const ANY_HIT: bool, const SIMD: bool>(
    tree: &KdTree,
    groups: &[G],
    records: &[G::Record],
    ray: &Ray,
    counters: &mut C,
) -> Option<Hit> {
    let (t0, t1) = clip_to_box(ray, &tree.bounds)?;
    let mut group = SingleRay::<G, ANY_HIT, SIMD> {
        tree,
        groups,
        records,
        ray,
        prepared: <G::Record as TriangleTest>::prepare(ray),
        prepared4: G::prepare(ray),
        origin: ray.origin.extend(0.0).to_array(),
        inv_dir: ray.inv_dir.extend(0.0).to_array(),
        // A bit mask in a register, not an array, keeps the next node's address off a memory
        // load (the traversal step is bound by this dependency chain).
        upper_first: ray.dir.is_negative_bitmask() as usize,
        best: None,
        t_hit: ray.t_max,
    };
    descend(tree, &mut group, (0, RaySpan::new(t0, t1)), &mut Stack::new(), counters);
    group.best
}
