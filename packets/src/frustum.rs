//! Frustum interval traversal with packet/leaf culling (thesis 2.3.2, 4.1.3-4.1.4, Listing
//! 4.2 with the omni-directional modification).
//!
//! A tile of 2x2 packets sharing one origin goes down the tree as **one interval**
//! `[near, far]` that bounds every ray's interval, computed from the tile's *extremal rays*.
//! Listing 4.2 takes the four corner rays of the tile and, at each split plane, the minimum
//! and maximum of their four plane distances. We use the same bound in a form that is exact
//! for any ray set: per axis `k`, the smallest and largest direction component over all the
//! tile's rays, `lo[k]` and `hi[k]`. A ray with component `n` in `[lo, hi]` reaches the plane
//! at `t = dist / n`, which is monotonic in `n` on each side of 0, so over the tile
//! `t in [min(dist/lo, dist/hi), max(...)]` once negative distances are taken as `+inf`
//! (modification 1; a mixed-sign range gives `+inf` at the top, as it must, since some rays
//! are then parallel to the plane). For unnormalised pinhole rays these extremes are corner
//! rays; for our normalised camera rays an inner ray can hold one (when the axis points into
//! the tile), which the corner rays would miss.
//!
//! Front and back voxels come from the origin's side of the plane alone (modification 2). At
//! an inner node the front voxel gets `[near, min(far, dmax)]` and the back voxel
//! `[max(near, dmin), far]`; an empty one is skipped. At a leaf each unfinished 2x2 packet
//! is first **culled** against the leaf's box (4.1.4): the exact slab test of its four rays,
//! clipped to each ray's closest hit so far; only the lanes that pass are tested against the
//! leaf's triangles. The voxel box is carried down the traversal and on the stack.
//!
//! **Finishing rays** (the thesis's "the tile finishes when all its rays have hit", made
//! exact): a lane is finished when its closest hit so far lies no further than where the
//! ray leaves the current leaf's box (moved inwards by a few ulps, so that rounding cannot
//! finish a ray whose hit lies just beyond the box). Every voxel visited later lies beyond a split plane
//! the ray crosses after that point, so no later voxel can hold a closer hit. The tile stops
//! when every lane is finished; deferred voxels are also dropped when they start beyond the
//! furthest hit of the unfinished lanes. Below an origin-on-the-plane node (the case where
//! both children are visited over the whole interval, out of order for some rays) no lane is
//! finished early.

use glam::Vec4;
use kdtree::triangle::{Intersector, TriangleTest};
use kdtree::{KdTree, STACK_SIZE};

use crate::packet::{widen_down, widen_down1, widen_up1};
use crate::stats::PacketCounters;
use crate::tile::{TileTracer, mask_of, max_where};
use crate::triangle4::PacketTest;

/// The bound a frustum of rays sharing one origin goes down the tree with: at a split plane
/// `dist = split - o[axis]` away from the origin, every ray of the frustum that crosses the
/// plane does so between `min(dist * k0[axis], dist * k1[axis])` and the `max` of the two,
/// negative values taken as `+inf` ([`plane_interval`]), and inside `[near, far]`.
///
/// Two shapes fill it in: the **pyramid** of the extremal rays ([`bound`]: `k0 = 1 / lo`,
/// `k1 = 1 / hi`, the per-axis direction extremes, distances in ray parameter `t`) and the
/// **cone** of the `cones` crate (thesis 4.1.7, "cone frustums": Listing 4.4's precomputed
/// values, distances measured along the cone's axis). `hit_scale` converts a ray's hit
/// parameter into the bound's distance: a hit at `t` lies no further than `t * hit_scale`
/// along the bound's measure (1 for the pyramid; for a cone the longest direction among its
/// rays, since a point at parameter `t` of ray `d` is `t |d| cos(angle)` along the axis;
/// the conversion must also cover the rounding of `t`, see [`distance_up`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrustumBound {
    /// First factor per axis (`[x, y, z, 0]`): `1 / lo[k]` for a pyramid.
    pub k0: [f32; 4],
    /// Second factor per axis: `1 / hi[k]` for a pyramid.
    pub k1: [f32; 4],
    /// Start of the interval (`+inf` when no ray is left).
    pub near: f32,
    /// End of the interval (`-inf` when no ray is left).
    pub far: f32,
    /// A bound on `distance / t` for a hit at ray parameter `t` (1 for a pyramid).
    pub hit_scale: f32,
}

impl FrustumBound {
    /// Whether a field is NaN: such a bound holds no ray, and
    /// [`crate::TileTracer::trace_frusta`] traces with the rays' pyramid instead.
    /// (Infinite fields are meaningful: a factor of `±inf` for a zero direction extreme,
    /// `near = +inf` when no ray is left.)
    pub fn has_nan(&self) -> bool {
        self.k0.iter().chain(&self.k1).any(|k| k.is_nan())
            || self.near.is_nan()
            || self.far.is_nan()
            || self.hit_scale.is_nan()
    }
}

/// Bound on the absolute rounding error of a ray parameter `t` computed in `f32` that
/// underflowed below `f32::MIN_POSITIVE`: the spacing of the subnormals, `2^-149` (the
/// smallest positive `f32`; the error of one rounding is half of it). The relative widening
/// ([`kdtree::traverse::WIDEN`]) adds nothing to such a `t` (`|t| W` rounds to zero), which is
/// harmless while `t` is compared with other parameters rounded alike, but not once `t` is
/// converted into another measure: scaled by a long direction (a cone's `hit_scale`, up to
/// `3e38`) it becomes a large distance. A clip exit of `1.7e-46` rounds to 0 and, times
/// `|d| = 1.7e32`, would put a cone's far end `2.9e-14` short of the ray's (a fuzz finding).
pub const T_UNDERFLOW: f32 = f32::from_bits(1);

/// An upper bound on the distance, along a bound's measure, of a point at a ray parameter
/// computed as `t`, with `scale` the bound's `hit_scale` (`t * scale` when exact):
/// `(t + T_UNDERFLOW) * scale` widened by [`kdtree::traverse::WIDEN`], so that both the
/// parameter's relative rounding and its underflow ([`T_UNDERFLOW`]) are covered.
/// Infinities stay as they are.
#[inline(always)]
pub fn distance_up(t: f32, scale: f32) -> f32 {
    widen_up1((t + T_UNDERFLOW) * scale)
}

/// Marks the lanes of `tracer`'s packets in `range` that miss the tree's root box as finished
/// (no hit), and returns the pyramid bound of the others: per axis the reciprocals of the
/// smallest and largest direction component, and the interval that holds every unfinished
/// ray's clip to the root box.
pub fn bound(tree: &KdTree, tracer: &mut TileTracer, range: std::ops::Range<usize>) -> FrustumBound {
    bound_of::<true>(tree, tracer, range)
}

/// [`bound`] without the direction extremes: finishes the lanes of the packets in `range`
/// that miss the root box and returns the interval `(near, far)` of the others' clips to
/// it. What a bound made elsewhere (a cone) needs from the rays.
pub fn root_interval(tree: &KdTree, tracer: &mut TileTracer, range: std::ops::Range<usize>) -> (f32, f32) {
    let b = bound_of::<false>(tree, tracer, range);
    (b.near, b.far)
}

/// [`bound`], with the direction extremes only when `DIRS` (else the factors are left 0).
#[inline(always)]
fn bound_of<const DIRS: bool>(tree: &KdTree, tracer: &mut TileTracer, range: std::ops::Range<usize>) -> FrustumBound {
    let b = tree.bounds();
    let (lo_box, hi_box) = (b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array());
    let (mut lo, mut hi) = ([Vec4::INFINITY; 3], [Vec4::NEG_INFINITY; 3]);
    let (mut near4, mut far4) = (Vec4::INFINITY, Vec4::NEG_INFINITY);
    for i in range {
        let rays = &tracer.packets[i].rays;
        let (enter, exit) = rays.clip(lo_box, hi_box);
        let inside = enter.cmple(exit) & !mask_of(tracer.done[i]);
        tracer.done[i] |= (!inside.bitmask() & 0xF) as u8;
        if !inside.any() {
            continue;
        }
        // Lane-wise accumulation; the horizontal reductions come once at the end.
        near4 = near4.min(Vec4::select(inside, enter, Vec4::INFINITY));
        far4 = far4.max(Vec4::select(inside, exit, Vec4::NEG_INFINITY));
        if !DIRS {
            continue;
        }
        for a in 0..3 {
            lo[a] = lo[a].min(Vec4::select(inside, rays.d[a], Vec4::INFINITY));
            hi[a] = hi[a].max(Vec4::select(inside, rays.d[a], Vec4::NEG_INFINITY));
        }
    }
    let (k0, k1) = if DIRS {
        let lo = Vec4::new(lo[0].min_element(), lo[1].min_element(), lo[2].min_element(), 0.0);
        let hi = Vec4::new(hi[0].max_element(), hi[1].max_element(), hi[2].max_element(), 0.0);
        (lo.recip().to_array(), hi.recip().to_array())
    } else {
        ([0.0; 4], [0.0; 4])
    };
    FrustumBound { k0, k1, near: near4.min_element(), far: far4.max_element(), hit_scale: 1.0 }
}

/// The plane distances bounding a frustum at a split plane `dist` away from the origin along
/// an axis with factors `k0`, `k1` (see [`FrustumBound`]): `(dmin, dmax)`, negative distances
/// taken as `+inf` (modification 1), widened by a few ulps. `dist` must not be 0.
///
/// A distance is negative when `dist` and the factor have opposite signs, whatever their
/// product rounds to: a product that underflows to -0.0 is still a plane behind the origin
/// (the fuzzer found rays sent to the far side of a plane 2.3e-38 behind their origin, at
/// distance -6e-54, and missing their hit).
#[inline(always)]
pub fn plane_interval(dist: f32, k0: f32, k1: f32) -> (f32, f32) {
    let fix = |k: f32| if (dist > 0.0 && k < 0.0) || (dist < 0.0 && k > 0.0) { f32::INFINITY } else { dist * k };
    let (a, b) = (fix(k0), fix(k1));
    (widen_down1(a.min(b)), widen_up1(a.max(b)))
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
pub(crate) fn leaf<T: PacketTest, C: PacketCounters>(
    records: &[T],
    prims: &[u32],
    tracer: &mut TileTracer,
    quadrants: std::ops::Range<usize>,
    rect: Option<[f32; 4]>,
    lo: [f32; 4],
    hi: [f32; 4],
    unordered: bool,
    previous: f32,
    counters: &mut C,
) -> f32 {
    let culling = tracer.culling;
    let (mut tested, mut closed) = (0u64, 0u64);
    for q in quadrants.clone() {
        let range = tracer.quadrants[q].clone();
        let grid = tracer.grids[q];
        let (cols, rows) = match rect {
            Some(rect) if culling && tracer.camera.is_some() => grid.within(rect),
            _ if tracer.camera.is_some() => (0..grid.cols, 0..grid.rows),
            // Loaded packets: one row of all of them.
            _ => (0..range.len() as u32, 0..1),
        };
        let width = if tracer.camera.is_some() { grid.cols as usize } else { range.len() };
        for row in rows {
            let first = range.start + row as usize * width;
            for i in first + cols.start as usize..first + cols.end as usize {
                let done = tracer.done[i];
                if done == 0xF {
                    continue;
                }
                let rays = &tracer.packets[i].rays;
                let hit = &mut tracer.hits[i];
                let open = !mask_of(done);
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
                    let now = done | (through & hit.found).bitmask() as u8;
                    tracer.done[i] = now;
                    closed += u64::from(now == 0xF);
                } else if !unordered {
                    // Against the exit moved *inwards* (about 16 ulps below its exact value,
                    // past the rounding of the clip and of the triangle test's t): a hit at
                    // the voxel's far boundary may have a rival a few ulps closer in the next
                    // voxel.
                    let exit_inside = widen_down(widen_down(widen_down(exit)));
                    let finished = through & hit.found & hit.t.cmple(exit_inside);
                    let now = done | finished.bitmask() as u8;
                    tracer.done[i] = now;
                    closed += u64::from(now == 0xF);
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
            if done != 0xF {
                open_packets += 1;
                limit = limit.max(max_where(!mask_of(done), tracer.hits[i].t));
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
pub(crate) struct Children {
    pub(crate) front: usize,
    pub(crate) back: usize,
    pub(crate) front_box: ([f32; 4], [f32; 4]),
    pub(crate) back_box: ([f32; 4], [f32; 4]),
}

/// The [`Children`] of the inner node with left child `left` splitting box `[lo, hi]` on
/// `axis` at `split`, the origin lying `dist = split - o[axis]` below the plane.
#[inline(always)]
pub(crate) fn children(left: usize, axis: usize, split: f32, dist: f32, lo: [f32; 4], hi: [f32; 4]) -> Children {
    let (mut below_hi, mut above_lo) = (hi, lo);
    below_hi[axis & 3] = split;
    above_lo[axis & 3] = split;
    let (below, above) = ((lo, below_hi), (above_lo, hi));
    if dist < 0.0 {
        Children { front: left + 1, back: left, front_box: above, back_box: below }
    } else {
        Children { front: left, back: left + 1, front_box: below, back_box: above }
    }
}

/// One deferred back voxel of the single frustum.
#[derive(Clone, Copy, Default)]
struct Entry {
    node: u32,
    unordered: bool,
    near: f32,
    far: f32,
    lo: [f32; 4],
    hi: [f32; 4],
}

/// Traces the loaded (and reset) tile as one frustum with bound `f`.
pub(crate) fn intersect<C: PacketCounters>(tree: &KdTree, tracer: &mut TileTracer, f: &FrustumBound, counters: &mut C) {
    match tree.intersector() {
        Intersector::Wald => traverse(tree, tree.wald_records(), tracer, f, counters),
        Intersector::Watertight => traverse(tree, tree.watertight_records(), tracer, f, counters),
    }
}

#[inline(always)]
fn traverse<T: TriangleTest + PacketTest, C: PacketCounters>(
    tree: &KdTree,
    records: &[T],
    tracer: &mut TileTracer,
    f: &FrustumBound,
    counters: &mut C,
) {
    let (mut near, mut far) = (f.near, f.far);
    if near.is_nan() || far.is_nan() || near > far {
        return;
    }
    let origin = tracer.origin;
    let b = tree.bounds();
    let (mut lo, mut hi) = (b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array());
    let mut unordered = false;
    // The furthest hit of the unfinished lanes: deferred voxels starting beyond it are dropped.
    let mut limit = f32::INFINITY;
    let nodes = tree.nodes();
    let refs = tree.prim_refs();
    let mut stack = [Entry::default(); STACK_SIZE];
    let mut sp = 0usize;
    let mut index = 0usize;
    loop {
        let node = nodes[index];
        counters.node();
        if !node.is_leaf() {
            let axis = node.axis() & 3;
            let split = node.split();
            let dist = split - origin[axis];
            let c = children(node.left_child(), axis, split, dist, lo, hi);
            if dist == 0.0 || dist.is_nan() {
                // Origin on the plane: both children over the whole interval, lower first.
                let (back_lo, back_hi) = c.back_box;
                stack[sp % STACK_SIZE] =
                    Entry { node: c.back as u32, unordered: true, near, far, lo: back_lo, hi: back_hi };
                sp += 1;
                (index, (lo, hi), unordered) = (c.front, c.front_box, true);
                continue;
            }
            let (dmin, dmax) = plane_interval(dist, f.k0[axis], f.k1[axis]);
            let front_far = far.min(dmax);
            let back_near = near.max(dmin);
            if back_near > far {
                (index, far, (lo, hi)) = (c.front, front_far, c.front_box);
            } else if near > front_far {
                (index, near, (lo, hi)) = (c.back, back_near, c.back_box);
            } else {
                let (back_lo, back_hi) = c.back_box;
                stack[sp % STACK_SIZE] =
                    Entry { node: c.back as u32, unordered, near: back_near, far, lo: back_lo, hi: back_hi };
                sp += 1;
                (index, far, (lo, hi)) = (c.front, front_far, c.front_box);
            }
            continue;
        }

        counters.leaf();
        let prims = &refs[node.prim_range()];
        if !prims.is_empty() {
            let rect = tracer.screen_rect(lo, hi);
            limit = leaf(records, prims, tracer, 0..4, rect, lo, hi, unordered, limit, counters);
            if limit == f32::NEG_INFINITY {
                return;
            }
        }
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            let e = stack[sp % STACK_SIZE];
            near = e.near;
            far = e.far.min(distance_up(limit, f.hit_scale));
            if near <= far {
                (index, unordered, lo, hi) = (e.node as usize, e.unordered, e.lo, e.hi);
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray parameter computed as `(plane - o) * (1 / d)` in `f32` (as the clips compute
    /// them), against its exact value: once it underflows below `f32::MIN_POSITIVE` the
    /// relative widening adds nothing, and only the absolute term keeps the converted
    /// distance an upper bound.
    #[test]
    fn distances_bound_parameters_that_underflowed() {
        let mut widened_short = 0;
        for i in 0..2000u32 {
            // Origins from 4e-31 down to the subnormals, direction lengths from 1.3 to 2e38:
            // the parameters span both sides of f32::MIN_POSITIVE.
            let o = f32::from_bits(0x0D00_0000 / 2000 * (2000 - i));
            let d = -1.3 * 2f32.powi((i % 127) as i32);
            let (t, exact) = ((0.0 - o) * (1.0 / d), (0.0 - f64::from(o)) / f64::from(d));
            assert!(t >= 0.0 && exact > 0.0);
            let scale = d.abs();
            let bound = f64::from(distance_up(t, scale));
            assert!(bound >= exact * f64::from(scale), "t = {t:e} (exact {exact:e}), |d| = {scale:e}");
            // Without the absolute term some of them fall short.
            widened_short += usize::from(f64::from(widen_up1(t * scale)) < exact * f64::from(scale));
        }
        assert!(widened_short > 0, "the cases include underflowed parameters");
        assert_eq!(distance_up(f32::INFINITY, 3.0), f32::INFINITY);
        assert_eq!(distance_up(f32::NEG_INFINITY, 3.0), f32::NEG_INFINITY);
        assert_eq!(distance_up(0.0, 1.0), T_UNDERFLOW, "at least one subnormal spacing");
        // Normal parameters: the absolute term is below their rounding.
        assert_eq!(distance_up(1.0, 1.0), widen_up1(1.0));
    }
}
