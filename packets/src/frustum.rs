//! Frustum interval traversal of a tile of packets, with one frustum (thesis 2.3.2,
//! 4.1.3-4.1.4, Listing 4.2 with the omni-directional modification) or four (Multiple Frustum
//! Traversal, 4.1.5), written once with the number of frusta as a parameter (`Lanes`:
//! `f32` for one frustum, `Vec4` for four, as a 2x2 packet traces four rays), the way
//! Embree's frustum kernel takes its width as a parameter. Both are monomorphic: each width
//! gets its own code, with no dispatch and no allocation inside the traversal.
//!
//! A tile of packets (2x2 by default, `V::LANES` rays each: [`crate::tile`]) sharing one
//! origin goes down the tree as **one interval**
//! `[near, far]` per frustum that bounds every ray's interval, computed from the frustum's
//! [`FrustumBound`] (the pyramid of the extremal rays or a cone, see [`crate::bound`]).
//! Front and back voxels come from the origin's side of the plane alone (modification 2).
//! At an inner node the front voxel gets `[near, min(far, dmax)]` and the back voxel
//! `[max(near, dmin), far]`; a child in which no frustum's interval is left is skipped. At
//! a leaf each unfinished packet of an active frustum is first **culled** against the
//! leaf's box (4.1.4): the exact slab test of its `W` rays, clipped to each ray's closest
//! hit so far; only the lanes that pass are tested against the leaf's triangles. The voxel
//! box is carried down the traversal and on the stack.
//!
//! **Multiple frusta** (4.1.5). The tile is split into its four quadrants, each bounded as a
//! frustum of its own, and the four go down the tree together, one per lane of a `Vec4`.
//! Following the thesis's list of changes:
//! 1. each frustum is a "ray" with its own interval `[near, far]`;
//! 2. a frustum is active where `near <= far` and it still has unfinished rays (a complete
//!    frustum's interval is clamped empty);
//! 3. the four intervals are updated together at each split plane;
//! 4. the active state is pushed with each deferred voxel (as the four intervals: a lane is
//!    active in it where `near <= far`);
//! 5. a child in which no frustum is active is not entered;
//! 6. at a leaf only the packets of the active frusta are culled and intersected;
//! 7. a frustum whose rays are all finished is masked from then on.
//!
//! Since the four quadrants' extremal rays are the tile's, each frustum's interval is never
//! wider than the single frustum's, so MFT visits no node and tests no packet that the single
//! frustum of the same tile would not (checked by the tests, tile by tile).
//!
//! **Finishing rays** (the thesis's "the tile finishes when all its rays have hit", made
//! exact): a lane is finished when its closest hit so far lies no further than where the
//! ray leaves the current leaf's box (moved inwards by a few ulps, so that rounding cannot
//! finish a ray whose hit lies just beyond the box). Every voxel visited later lies beyond a
//! split plane the ray crosses after that point, so no later voxel can hold a closer hit. A
//! frustum stops when every lane of its packets is finished; deferred voxels are also
//! dropped when they start beyond the furthest hit of the unfinished lanes. Below an
//! origin-on-the-plane node (the case where both children are visited over the whole
//! interval, out of order for some rays) no lane is finished early.

use std::ops::Range;

use glam::{BVec4A, Vec4};
use kdtree::descent::{Descent, Entry, Flow, Visit, descend};
use kdtree::stack::Stack;
use kdtree::triangle::{Intersector, TriangleTest};
use kdtree::{Counters, KdNode, KdTree};
use kdtree::{TreeTest, WaldTest, WatertightTest};

use crate::bound::{self, FrustumBound, distance_up, plane_interval};
use crate::packet::{all_lanes, mask_of, max_where, widen_down};
use crate::simd::{SimdF32, SimdMask};
use crate::tile::TileTracer;
use crate::triangle4::PacketTest;

/// The frusta a loaded tile is traced with by [`TileTracer::trace_frusta`]: one for the
/// whole tile (2.3.2), or one per quadrant traced together in the lanes of a `Vec4` (MFT,
/// 4.1.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Frusta {
    /// One frustum over every packet (interval traversal, 2.3.2).
    One(FrustumBound),
    /// Quadrant `q`'s packets bounded by frustum `q` (Multiple Frustum Traversal).
    Four([FrustumBound; 4]),
}

impl<V: SimdF32> TileTracer<V> {
    /// Starts a frustum trace of the loaded tile with frusta made elsewhere (the cones of
    /// the `cones` crate, thesis 4.1.7-4.1.9): resets the hits, finishes the lanes that miss
    /// the tree's root box and returns each quadrant's pyramid bound ([`bound::pyramid`]),
    /// whose `near` and `far` bound the ray parameters of its rays inside the root box.
    /// Follow it with [`TileTracer::trace_frusta`].
    pub fn prepare(&mut self, tree: &KdTree) -> [FrustumBound; 4] {
        match tree.intersector() {
            Intersector::Wald => self.prepare_with::<WaldTest>(tree),
            Intersector::Watertight => self.prepare_with::<WatertightTest>(tree),
        }
    }

    /// [`TileTracer::prepare`] with the tree's triangle test `I`, chosen once by the caller
    /// (see [`TreeTest`]).
    #[inline(always)]
    pub fn prepare_with<I: TreeTest>(&mut self, tree: &KdTree) -> [FrustumBound; 4] {
        self.prepare_regions_with::<I, 4>(tree)
    }

    /// [`TileTracer::prepare_with`] for a tile split into `N` regions
    /// ([`TileTracer::set_regions`]): each region's pyramid bound, region `q` at `q`.
    #[inline(always)]
    pub fn prepare_regions_with<I: TreeTest, const N: usize>(&mut self, tree: &KdTree) -> [FrustumBound; N] {
        debug_assert_eq!(N, self.region_count(), "one bound per region");
        self.reset::<I>(true);
        let regions = self.quadrants.clone();
        crate::simd::array_fn(
            #[inline(always)]
            |q| {
                let range = regions[q].clone();
                bound::pyramid(tree, &self.packets[range.clone()], &mut self.done[range])
            },
        )
    }

    /// [`TileTracer::prepare`] without the pyramids: resets the hits, finishes the lanes
    /// that miss the root box and returns each quadrant's interval `(near, far)` of ray
    /// parameters inside it (what a cone needs, thesis 4.1.7; its per-ray cost is the box
    /// clip alone).
    pub fn prepare_intervals(&mut self, tree: &KdTree) -> [(f32, f32); 4] {
        match tree.intersector() {
            Intersector::Wald => self.prepare_intervals_with::<WaldTest>(tree),
            Intersector::Watertight => self.prepare_intervals_with::<WatertightTest>(tree),
        }
    }

    /// [`TileTracer::prepare_intervals`] with the tree's triangle test `I` (see [`TreeTest`]).
    #[inline(always)]
    pub fn prepare_intervals_with<I: TreeTest>(&mut self, tree: &KdTree) -> [(f32, f32); 4] {
        self.reset::<I>(true);
        let quadrants = self.quadrants.clone();
        crate::simd::array_fn(
            #[inline(always)]
            |q| {
                let range = quadrants[q].clone();
                bound::root_interval(tree, &self.packets[range.clone()], &mut self.done[range])
            },
        )
    }

    /// The pyramid bound (thesis 2.3.2) of quadrant `q` of a prepared tile
    /// ([`bound::pyramid`]), for a cone that cannot be made.
    #[inline(always)]
    pub fn pyramid(&mut self, tree: &KdTree, q: usize) -> FrustumBound {
        let range = self.quadrants[q & 3].clone();
        bound::pyramid(tree, &self.packets[range.clone()], &mut self.done[range])
    }

    /// Traces the tile [`TileTracer::prepare`]d with `frusta` (thesis 2.3.2 for one, 4.1.5
    /// for four), which must bound its rays (every ray of the frustum, or of quadrant `q` for
    /// frustum `q`, inside the frustum).
    ///
    /// A bound with a NaN field bounds nothing: it is replaced by the pyramid of its rays
    /// ([`TileTracer::pyramid`], or [`bound::pyramid`] of the whole tile for
    /// [`Frusta::One`]), so the hits are still exactly the single rays'.
    pub fn trace_frusta<C: Counters>(&mut self, tree: &KdTree, frusta: &Frusta, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_frusta_with::<WaldTest, C>(tree, frusta, counters),
            Intersector::Watertight => self.trace_frusta_with::<WatertightTest, C>(tree, frusta, counters),
        }
    }

    /// [`TileTracer::trace_frusta`] with the tree's triangle test `I`, the one the tile was
    /// prepared with ([`TileTracer::prepare_with`]; see [`TreeTest`]).
    #[inline(always)]
    pub fn trace_frusta_with<I: TreeTest<Record: PacketTest<V>>, C: Counters>(
        &mut self,
        tree: &KdTree,
        frusta: &Frusta,
        counters: &mut C,
    ) {
        // One traversal per number of frusta (the NaN fallback only changes the bound).
        match frusta {
            Frusta::One(f) => {
                let f = if f.has_nan() { bound::pyramid(tree, &self.packets, &mut self.done) } else { *f };
                intersect::<I, V, _, C>(tree, self, &Bounds::one(&f), counters)
            }
            Frusta::Four(bounds) => {
                let bounds: [FrustumBound; 4] = crate::simd::array_fn(
                    #[inline(always)]
                    |q| if bounds[q].has_nan() { self.pyramid(tree, q) } else { bounds[q] },
                );
                intersect::<I, V, _, C>(tree, self, &Bounds::four(&bounds), counters)
            }
        }
    }
}

/// The number of frusta traced together, as the type of one interval end: `f32` for one
/// frustum (2.3.2), `Vec4` for the four of MFT (4.1.5), one per lane. Every operation the
/// traversal does on intervals goes through it, so the traversal is written once.
pub(crate) trait Lanes: Copy {
    /// `+inf` in every lane.
    const INFINITY: Self;
    /// Lane-wise minimum.
    fn min(a: Self, b: Self) -> Self;
    /// Lane-wise maximum.
    fn max(a: Self, b: Self) -> Self;
    /// Whether some frustum's interval `[near, far]` is not empty (is active).
    fn any_open(near: Self, far: Self) -> bool;
    /// Whether no frustum's interval `[near, far]` is left (the child is not entered).
    fn none_open(near: Self, far: Self) -> bool;
    /// Each frustum's plane interval at a split plane `dist` away ([`plane_interval`]).
    fn plane_interval(dist: f32, k0: Self, k1: Self) -> (Self, Self);
    /// Each frustum's hit limit in its bound's measure ([`distance_up`]).
    fn distance_up(t: Self, scale: Self) -> Self;
    /// Runs `visit(quadrants, previous)` at a leaf for each active frustum, `quadrants` being
    /// the packets it bounds and `previous` its current `limit`, and returns the new limits.
    fn leaf(near: Self, far: Self, limit: Self, visit: impl FnMut(Range<usize>, f32) -> f32) -> Self;
    /// Whether every frustum is complete (its limit `-inf`: no unfinished lane left).
    fn all_complete(limit: Self) -> bool;
}

impl Lanes for f32 {
    const INFINITY: f32 = f32::INFINITY;
    #[inline(always)]
    fn min(a: f32, b: f32) -> f32 {
        a.min(b)
    }
    #[inline(always)]
    fn max(a: f32, b: f32) -> f32 {
        a.max(b)
    }
    #[inline(always)]
    fn any_open(near: f32, far: f32) -> bool {
        near <= far
    }
    #[inline(always)]
    fn none_open(near: f32, far: f32) -> bool {
        near > far
    }
    #[inline(always)]
    fn plane_interval(dist: f32, k0: f32, k1: f32) -> (f32, f32) {
        plane_interval(dist, k0, k1)
    }
    #[inline(always)]
    fn distance_up(t: f32, scale: f32) -> f32 {
        distance_up(t, scale)
    }
    #[inline(always)]
    fn leaf(_near: f32, _far: f32, limit: f32, mut visit: impl FnMut(Range<usize>, f32) -> f32) -> f32 {
        // The one frustum is active wherever the traversal goes, over every region.
        visit(0..crate::tile::MAX_REGIONS, limit)
    }
    #[inline(always)]
    fn all_complete(limit: f32) -> bool {
        limit == f32::NEG_INFINITY
    }
}

/// Any number of frusta in the lanes of a lane type: the four of MFT in a `Vec4` (4.1.5), or
/// sixteen in a 16-lane type (one per region of a tile split 4 x 4:
/// [`TileTracer::trace_mft_regions_with`]). Lane `q` is region `q`.
impl<F: SimdF32> Lanes for F {
    const INFINITY: F = F::INFINITY;
    #[inline(always)]
    fn min(a: F, b: F) -> F {
        a.min(b)
    }
    #[inline(always)]
    fn max(a: F, b: F) -> F {
        a.max(b)
    }
    #[inline(always)]
    fn any_open(near: F, far: F) -> bool {
        near.cmple(far).any()
    }
    #[inline(always)]
    fn none_open(near: F, far: F) -> bool {
        !near.cmple(far).any()
    }
    #[inline(always)]
    fn plane_interval(dist: f32, k0: F, k1: F) -> (F, F) {
        bound::plane_interval_lanes(dist, k0, k1)
    }
    #[inline(always)]
    fn distance_up(t: F, scale: F) -> F {
        bound::distance_up_lanes(t, scale)
    }
    #[inline(always)]
    fn leaf(near: F, far: F, limit: F, mut visit: impl FnMut(Range<usize>, f32) -> f32) -> F {
        let mut active = near.cmple(far).bitmask();
        let mut l = limit.to_array();
        while active != 0 {
            let q = active.trailing_zeros() as usize;
            active &= active - 1;
            l[q] = visit(q..q + 1, l[q]);
        }
        F::from_fn(
            #[inline(always)]
            |q| l[q],
        )
    }
    #[inline(always)]
    fn all_complete(limit: F) -> bool {
        limit.cmpeq(F::NEG_INFINITY).all()
    }
}

/// The bounds of the frusta in lanes: per axis each factor (`k0`, `k1` of [`FrustumBound`]),
/// the initial intervals and the hit scales.
#[derive(Clone, Copy)]
pub(crate) struct Bounds<L> {
    k0: [L; 4],
    k1: [L; 4],
    near: L,
    far: L,
    hit_scale: L,
}

impl Bounds<f32> {
    /// One frustum.
    pub(crate) fn one(b: &FrustumBound) -> Bounds<f32> {
        Bounds { k0: b.k0, k1: b.k1, near: b.near, far: b.far, hit_scale: b.hit_scale }
    }
}

impl Bounds<Vec4> {
    /// Four frusta, quadrant `q` in lane `q`.
    #[inline(always)]
    pub(crate) fn four(bounds: &[FrustumBound; 4]) -> Bounds<Vec4> {
        Bounds::lanes(bounds)
    }
}

impl<F: SimdF32> Bounds<F> {
    /// `F::LANES` frusta, region `q` in lane `q` (`bounds` holds one per lane).
    #[inline(always)]
    pub(crate) fn lanes(bounds: &[FrustumBound]) -> Bounds<F> {
        #[inline(always)]
        fn lane<F: SimdF32>(bounds: &[FrustumBound], f: impl Fn(&FrustumBound) -> f32) -> F {
            F::from_fn(
                #[inline(always)]
                |q| f(&bounds[q]),
            )
        }
        Bounds {
            k0: [lane(bounds, |b| b.k0[0]), lane(bounds, |b| b.k0[1]), lane(bounds, |b| b.k0[2]), F::ZERO],
            k1: [lane(bounds, |b| b.k1[0]), lane(bounds, |b| b.k1[1]), lane(bounds, |b| b.k1[2]), F::ZERO],
            near: lane(bounds, |b| b.near),
            far: lane(bounds, |b| b.far),
            hit_scale: lane(bounds, |b| b.hit_scale),
        }
    }
}

/// Culls and intersects the packets of quadrant `q` (or of every quadrant, `q = None`) at a
/// leaf with box `[lo, hi]`, finishing the lanes whose closest hit lies inside the box
/// (unless `unordered`). Returns the furthest hit of the lanes left unfinished (`+inf` while
/// one has no hit, `-inf` when none is left; `previous`, the value before this leaf, when
/// no packet was tested).
///
/// Culling runs in two steps. For a primary tile, the box's corners are projected onto the
/// image and only the packets whose pixels fall in that rectangle (grown by a pixel) are
/// looked at; the others cannot reach the box. Each of those then gets the exact slab test
/// of its four rays against the box, each ray clipped to its closest hit so far, and only
/// the lanes that pass are tested against the leaf's triangles. With culling off every
/// unfinished lane is tested.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn leaf<V: SimdF32, T: PacketTest<V>, C: Counters>(
    records: &[T],
    prims: &[u32],
    tracer: &mut TileTracer<V>,
    quadrants: std::ops::Range<usize>,
    rect: Option<[f32; 4]>,
    lo: [f32; 4],
    hi: [f32; 4],
    unordered: bool,
    previous: f32,
    counters: &mut C,
) -> f32 {
    let culling = tracer.culling;
    let all = all_lanes::<V>();
    // One frustum visits every region: as many as the tile was split into.
    let quadrants = quadrants.start..quadrants.end.min(tracer.region_count());
    let (mut tested, mut closed) = (0u64, 0u64);
    for q in quadrants.clone() {
        let range = tracer.quadrants[q].clone();
        let grid = tracer.grids[q];
        let (cols, rows) = match rect {
            Some(rect) if culling && tracer.camera.is_some() => grid.within(rect, TileTracer::<V>::PACKET_SHAPE),
            _ if tracer.camera.is_some() => (0..grid.cols, 0..grid.rows),
            // Loaded packets: one row of all of them.
            _ => (0..range.len() as u32, 0..1),
        };
        let width = if tracer.camera.is_some() { grid.cols as usize } else { range.len() };
        for row in rows {
            let first = range.start + row as usize * width;
            for i in first + cols.start as usize..first + cols.end as usize {
                let done = tracer.done[i];
                if done == all {
                    continue;
                }
                let rays = &tracer.packets[i].rays;
                let hit = &mut tracer.hits[i];
                let open = !mask_of::<V>(done);
                let (enter, exit) = rays.clip(lo, hi);
                let through = open & enter.cmple(exit) & enter.cmple(hit.t);
                if culling && !through.any() {
                    continue;
                }
                tested += 1;
                let lanes = if culling { through } else { open };
                let data = T::tile_data(&tracer.sheared, i);
                counters.tests(prims.len() as u64);
                for &prim in prims {
                    records[prim as usize].intersect4(rays, &data, lanes, hit, prim);
                }
                if tracer.any_hit {
                    // Any hit finishes a lane, wherever it lies.
                    let now = done | (through & hit.found).bitmask();
                    tracer.done[i] = now;
                    closed += u64::from(now == all);
                } else if !unordered {
                    // Against the exit moved *inwards* (about 16 ulps below its exact value,
                    // past the rounding of the clip and of the triangle test's t): a hit at
                    // the voxel's far boundary may have a rival a few ulps closer in the next
                    // voxel.
                    let exit_inside = widen_down(widen_down(widen_down(exit)));
                    let finished = through & hit.found & hit.t.cmple(exit_inside);
                    let now = done | finished.bitmask();
                    tracer.done[i] = now;
                    closed += u64::from(now == all);
                }
            }
        }
    }
    // The furthest hit of the unfinished lanes (unchanged when no packet was tested), and the
    // unfinished packets for the counters.
    if tested == 0 && !C::ENABLED {
        return previous;
    }
    let mut limit = f32::NEG_INFINITY;
    let mut open_packets = 0u64;
    for q in quadrants {
        for i in tracer.quadrants[q].clone() {
            let done = tracer.done[i];
            if done != all {
                open_packets += 1;
                limit = limit.max(max_where(!mask_of::<V>(done), tracer.hits[i].t));
            }
        }
    }
    let considered = open_packets + closed;
    counters.leaf_packets(considered, considered - tested);
    limit
}

/// An inner node's children in visiting order, with their boxes: the front voxel is the
/// child on the origin's side of the plane (modification 2), the lower child when the origin
/// lies on it (`dist == 0`, where both are visited over the whole interval).
struct Children {
    front: usize,
    back: usize,
    front_box: ([f32; 4], [f32; 4]),
    back_box: ([f32; 4], [f32; 4]),
}

/// The [`Children`] of the inner node with left child `left` splitting box `[lo, hi]` on
/// `axis` at `split`, the origin lying `dist = split - o[axis]` below the plane.
///
/// Register blends, no branch: writing the split into one lane of a box in memory and
/// reading the box back as a vector stalls the load (the store cannot be forwarded to it),
/// and which child is in front is the traversal's least predictable branch. The two held
/// about 5% of a 16-lane MFT frame (`perf`, Sponza).
#[inline(always)]
fn children(left: usize, axis: usize, split: f32, dist: f32, lo: [f32; 4], hi: [f32; 4]) -> Children {
    let (lo, hi) = (Vec4::from_array(lo), Vec4::from_array(hi));
    let on_axis = Vec4::new(0.0, 1.0, 2.0, 3.0).cmpeq(Vec4::splat((axis & 3) as f32));
    let split = Vec4::splat(split);
    let (below_hi, above_lo) = (Vec4::select(on_axis, split, hi), Vec4::select(on_axis, split, lo));
    // The origin above the plane: the upper child is in front.
    let above_first = dist < 0.0;
    let flip = BVec4A::splat(above_first);
    let (front_lo, front_hi) = (Vec4::select(flip, above_lo, lo), Vec4::select(flip, hi, below_hi));
    let (back_lo, back_hi) = (Vec4::select(flip, lo, above_lo), Vec4::select(flip, below_hi, hi));
    Children {
        front: left + usize::from(above_first),
        back: left + usize::from(!above_first),
        front_box: (front_lo.to_array(), front_hi.to_array()),
        back_box: (back_lo.to_array(), back_hi.to_array()),
    }
}

/// The frusta's state in one voxel: their intervals, the voxel's box (for leaf culling), and
/// whether it lies below an origin-on-the-plane node (no lane is finished early there).
#[derive(Clone, Copy)]
struct Span<L> {
    unordered: bool,
    near: L,
    far: L,
    lo: [f32; 4],
    hi: [f32; 4],
}

/// The frusta of a loaded tile walking the tree ([`kdtree::descent`]): the frustum interval
/// step (Listing 4.2 with the omni-directional modification), the culling leaf visitor, and
/// the pop rule clamping each frustum to the furthest hit of its unfinished lanes.
struct FrustaWalk<'a, L: Lanes, V: SimdF32, T: PacketTest<V>> {
    records: &'a [T],
    refs: &'a [u32],
    tracer: &'a mut TileTracer<V>,
    origin: [f32; 4],
    f: &'a Bounds<L>,
    // Per frustum, the furthest hit of its unfinished lanes (-inf once it is complete):
    // deferred voxels starting beyond it are dropped.
    limit: L,
}

impl<L: Lanes, V: SimdF32, T: PacketTest<V>> Descent for FrustaWalk<'_, L, V, T> {
    type Span = Span<L>;
    type Deferred = Span<L>;
    type Stack = Stack<Entry<Span<L>>>;

    #[inline(always)]
    fn inner(&mut self, node: KdNode, span: &mut Span<L>, _: &Self::Stack) -> Visit<Span<L>> {
        let axis = node.axis() & 3;
        let split = node.split();
        let dist = split - self.origin[axis];
        let c = children(node.left_child(), axis, split, dist, span.lo, span.hi);
        let (back_lo, back_hi) = c.back_box;
        if dist == 0.0 || dist.is_nan() {
            // Origin on the plane: both children over the whole intervals, lower first.
            let deferred = Span { unordered: true, lo: back_lo, hi: back_hi, ..*span };
            (span.lo, span.hi) = c.front_box;
            span.unordered = true;
            return Visit::Both { first: c.front, second: c.back, deferred };
        }
        let (dmin, dmax) = L::plane_interval(dist, self.f.k0[axis], self.f.k1[axis]);
        let front_far = L::min(span.far, dmax);
        let back_near = L::max(span.near, dmin);
        if L::none_open(back_near, span.far) {
            span.far = front_far;
            (span.lo, span.hi) = c.front_box;
            Visit::One(c.front)
        } else if L::none_open(span.near, front_far) {
            span.near = back_near;
            (span.lo, span.hi) = c.back_box;
            Visit::One(c.back)
        } else {
            let deferred = Span { near: back_near, lo: back_lo, hi: back_hi, ..*span };
            span.far = front_far;
            (span.lo, span.hi) = c.front_box;
            Visit::Both { first: c.front, second: c.back, deferred }
        }
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, span: &Span<L>, _: &Self::Stack, counters: &mut C) -> Flow {
        counters.leaf();
        let prims = &self.refs[node.prim_range()];
        if !prims.is_empty() {
            let Span { unordered, near, far, lo, hi } = *span;
            let rect = self.tracer.screen_rect(lo, hi);
            let (records, tracer) = (self.records, &mut *self.tracer);
            self.limit = L::leaf(
                near,
                far,
                self.limit,
                // Inlined, so that the leaf's packet tests compile into a `#[target_feature]`
                // caller (`at_width!`).
                #[inline(always)]
                |quadrants, previous| {
                    leaf(records, prims, tracer, quadrants, rect, lo, hi, unordered, previous, counters)
                },
            );
            if L::all_complete(self.limit) {
                return Flow::Stop;
            }
        }
        Flow::Continue
    }

    #[inline(always)]
    fn resume(&mut self, e: Span<L>) -> Option<Span<L>> {
        let far = L::min(e.far, L::distance_up(self.limit, self.f.hit_scale));
        L::any_open(e.near, far).then_some(Span { far, ..e })
    }
}

/// Traces the loaded (and reset) tile with the frusta `f`: one over the whole tile, or four,
/// quadrant `q` in lane `q`, with the tree's triangle test `I` (chosen once by the caller).
#[inline(always)]
pub(crate) fn intersect<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, L: Lanes, C: Counters>(
    tree: &KdTree,
    tracer: &mut TileTracer<V>,
    f: &Bounds<L>,
    counters: &mut C,
) {
    traverse(tree, I::records(tree), tracer, f, counters)
}

#[inline(always)]
fn traverse<L: Lanes, V: SimdF32, T: TriangleTest + PacketTest<V>, C: Counters>(
    tree: &KdTree,
    records: &[T],
    tracer: &mut TileTracer<V>,
    f: &Bounds<L>,
    counters: &mut C,
) {
    if !L::any_open(f.near, f.far) {
        return;
    }
    let b = tree.bounds();
    let span = Span {
        unordered: false,
        near: f.near,
        far: f.far,
        lo: b.min.extend(0.0).to_array(),
        hi: b.max.extend(0.0).to_array(),
    };
    let origin = tracer.origin;
    let mut group = FrustaWalk { records, refs: tree.prim_refs(), tracer, origin, f, limit: L::INFINITY };
    descend(tree, &mut group, (0, span), &mut Stack::new(), counters);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blends of [`children`] give the boxes and order of the plain construction: the
    /// split written into one coordinate, the origin's side first (below on the plane, and
    /// for a NaN distance).
    #[test]
    fn children_are_the_split_boxes_in_front_to_back_order() {
        let (lo, hi) = ([-1.0, -2.0, -3.0, 0.0], [4.0, 5.0, 6.0, 0.0]);
        for axis in 0..3 {
            let split = [0.5, -0.25, 2.0][axis];
            let (mut below_hi, mut above_lo) = (hi, lo);
            below_hi[axis] = split;
            above_lo[axis] = split;
            for (dist, above_first) in [(-1.0, true), (-0.0, false), (0.0, false), (2.0, false), (f32::NAN, false)] {
                let c = children(10, axis, split, dist, lo, hi);
                let (below, above) = ((lo, below_hi), (above_lo, hi));
                let want = if above_first { (11, 10, above, below) } else { (10, 11, below, above) };
                assert_eq!((c.front, c.back, c.front_box, c.back_box), want, "axis {axis}, dist {dist}");
            }
        }
    }
}
