//! Multiple Frustum Traversal (thesis 4.1.5).
//!
//! The tile is split into its four quadrants, each bounded as a frustum of its own (see
//! [`crate::frustum`]), and the four frusta go down the tree together, one per lane of a
//! `Vec4`: the interval traversal of Listing 4.2 done four times per instruction, the way a
//! 2x2 packet traces four rays. Following the thesis's list of changes:
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

use glam::Vec4;
use kdtree::triangle::{Intersector, TriangleTest};
use kdtree::{KdTree, STACK_SIZE};

use crate::frustum::{FrustumBound, T_UNDERFLOW, children, leaf};
use crate::packet::{widen_down, widen_up};
use crate::stats::PacketCounters;
use crate::tile::TileTracer;
use crate::triangle4::PacketTest;

/// One deferred back voxel: its box and the four frusta's intervals in it.
#[derive(Clone, Copy)]
struct Entry {
    node: u32,
    unordered: bool,
    near: Vec4,
    far: Vec4,
    lo: [f32; 4],
    hi: [f32; 4],
}

impl Default for Entry {
    fn default() -> Entry {
        Entry { node: 0, unordered: false, near: Vec4::INFINITY, far: Vec4::NEG_INFINITY, lo: [0.0; 4], hi: [0.0; 4] }
    }
}

/// Traces the loaded (and reset) tile as four quadrant frusta with bounds `bounds` (quadrant
/// `q` in lane `q`).
pub(crate) fn intersect<C: PacketCounters>(
    tree: &KdTree,
    tracer: &mut TileTracer,
    bounds: &[FrustumBound; 4],
    counters: &mut C,
) {
    match tree.intersector() {
        Intersector::Wald => traverse(tree, tree.wald_records(), tracer, bounds, counters),
        Intersector::Watertight => traverse(tree, tree.watertight_records(), tracer, bounds, counters),
    }
}

/// The four quadrants' bounds as lanes: per axis a `Vec4` of each factor (`k0`, `k1` of
/// [`FrustumBound`]), the initial intervals and the hit scales.
struct Lanes {
    k0: [Vec4; 4],
    k1: [Vec4; 4],
    near: Vec4,
    far: Vec4,
    hit_scale: Vec4,
}

fn lanes(bounds: &[FrustumBound; 4]) -> Lanes {
    let axis = |a: usize, second: bool| Vec4::from_array(bounds.map(|b| if second { b.k1[a] } else { b.k0[a] }));
    Lanes {
        k0: [axis(0, false), axis(1, false), axis(2, false), Vec4::ZERO],
        k1: [axis(0, true), axis(1, true), axis(2, true), Vec4::ZERO],
        near: Vec4::from_array(bounds.map(|b| b.near)),
        far: Vec4::from_array(bounds.map(|b| b.far)),
        hit_scale: Vec4::from_array(bounds.map(|b| b.hit_scale)),
    }
}

#[inline(always)]
fn traverse<T: TriangleTest + PacketTest, C: PacketCounters>(
    tree: &KdTree,
    records: &[T],
    tracer: &mut TileTracer,
    bounds: &[FrustumBound; 4],
    counters: &mut C,
) {
    let f = lanes(bounds);
    let (mut near, mut far) = (f.near, f.far);
    if !near.cmple(far).any() {
        return;
    }
    let origin = tracer.origin;
    let b = tree.bounds();
    let (mut lo, mut hi) = (b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array());
    let mut unordered = false;
    // Per frustum, the furthest hit of its unfinished lanes (-inf once it is complete).
    let mut limit = Vec4::INFINITY;
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
                // Origin on the plane: both children over the whole intervals, lower first.
                let (back_lo, back_hi) = c.back_box;
                stack[sp % STACK_SIZE] =
                    Entry { node: c.back as u32, unordered: true, near, far, lo: back_lo, hi: back_hi };
                sp += 1;
                (index, (lo, hi), unordered) = (c.front, c.front_box, true);
                continue;
            }
            // Modification 1 per frustum: negative distances become +inf, decided by the signs
            // of `dist` and the factor (a product that underflows to -0.0 is still behind).
            let dist4 = Vec4::splat(dist);
            let fix = |k: Vec4| {
                let behind = if dist > 0.0 { k.cmplt(Vec4::ZERO) } else { k.cmpgt(Vec4::ZERO) };
                Vec4::select(behind, Vec4::INFINITY, dist4 * k)
            };
            let (a, b) = (fix(f.k0[axis]), fix(f.k1[axis]));
            let (dmin, dmax) = (widen_down(a.min(b)), widen_up(a.max(b)));
            let front_far = far.min(dmax);
            let back_near = near.max(dmin);
            if !back_near.cmple(far).any() {
                (index, far, (lo, hi)) = (c.front, front_far, c.front_box);
            } else if !near.cmple(front_far).any() {
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
            let active = near.cmple(far).bitmask();
            let rect = tracer.screen_rect(lo, hi);
            let mut l = limit.to_array();
            for (q, slot) in l.iter_mut().enumerate() {
                if active >> q & 1 != 0 {
                    *slot = leaf(records, prims, tracer, q..q + 1, rect, lo, hi, unordered, *slot, counters);
                }
            }
            limit = Vec4::from_array(l);
            if limit.cmpeq(Vec4::NEG_INFINITY).all() {
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
            // As `frustum::distance_up`, lane-wise: the hit limit in the bounds' measures,
            // covering the underflow of the hit parameters.
            far = e.far.min(widen_up((limit + Vec4::splat(T_UNDERFLOW)) * f.hit_scale));
            if near.cmple(far).any() {
                (index, unordered, lo, hi) = (e.node as usize, e.unordered, e.lo, e.hi);
                break;
            }
        }
    }
}
