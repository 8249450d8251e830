//! The edge-width traversal for four shadow rays at once (Tsakok 2008, chapter 5: "the
//! algorithm can be efficiently implemented using SSE for shadowing packets at a time").
//!
//! The four rays sit in a [`RayPacket`] (SoA, one `Vec4` per coordinate) and descend the tree
//! together, each lane with its own interval, as the same-sign packets of thesis 2.3.1: the
//! valid lanes must share their direction signs, so that one child is the front voxel of all
//! of them (shadow rays from neighbouring pixels to one light almost always do); a packet
//! whose lanes differ is traced lane by lane with [`crate::edge_width`]. Leaves test each
//! triangle against the four rays with the 4-wide tests of `packets::triangle4`, which
//! compute bit for bit what the single-ray tests compute; each lane keeps its own pending
//! list and pairing, with the single-ray rules (see [`crate::traverse`]): every hit a leaf
//! reports joins the lane's list, and hits are paired up to the smallest start on the stack
//! less the slack. The answer of a lane depends only on the set of hits along its segment,
//! which both traversals find whole, so it equals the single-ray answer (tested).

use glam::{BVec4A, Vec3, Vec4};
use kdtree::stack::Stack;
use kdtree::{Intersector, KdTree};
use packets::packet::{widen_down, widen_up};
use packets::triangle4::PacketTest;
use packets::{PacketHit, RayPacket};

use crate::pairing::{LeakRemedies, Pairing};
use crate::traverse::{EdgeScratch, edge_width, slack};

/// Per-thread scratch of [`edge_width4`]: one pending list per lane.
#[derive(Clone, Debug, Default)]
pub struct EdgeScratch4 {
    lanes: [EdgeScratch; 4],
}

/// The edge widths of the four rays of `rays` (as [`crate::edge_width`] gives for each lane's
/// ray with `r[lane]`); invalid lanes, rays with NaN or infinite components among them (see
/// [`RayPacket::new`]), get `0`.
pub fn edge_width4(
    tree: &KdTree,
    rays: &RayPacket,
    r: [f32; 4],
    remedies: &LeakRemedies,
    scratch: &mut EdgeScratch4,
) -> [f32; 4] {
    match tree.intersector() {
        Intersector::Wald => kernel4(tree, tree.wald_records(), rays, r, remedies, scratch),
        Intersector::Watertight => kernel4(tree, tree.watertight_records(), rays, r, remedies, scratch),
    }
}

/// One deferred back voxel: the node, each lane's interval, and the lanes that visit it
/// (`t0 = +inf` in the others, so the minimum start over the stack ignores them).
#[derive(Clone, Copy)]
struct StackEntry4 {
    node: u32,
    t0: Vec4,
    t1: Vec4,
    mask: BVec4A,
}

#[inline(always)]
fn lanes(mask: BVec4A) -> impl Iterator<Item = usize> {
    let bits = mask.bitmask();
    (0..4).filter(move |lane| bits >> lane & 1 != 0)
}

#[inline(always)]
fn kernel4<T: PacketTest>(
    tree: &KdTree,
    records: &[T],
    rays: &RayPacket,
    r: [f32; 4],
    remedies: &LeakRemedies,
    scratch: &mut EdgeScratch4,
) -> [f32; 4] {
    let mut out = [0.0f32; 4];
    let bounds = tree.bounds();
    let (mut t0, mut t1) = rays.clip(bounds.min.extend(0.0).to_array(), bounds.max.extend(0.0).to_array());
    let mut active = rays.valid & t0.cmple(t1);
    if !active.any() {
        return out;
    }
    // Lanes with different direction signs have different front voxels: one lane at a time.
    let bits = active.bitmask();
    let mut upper_first = 0usize;
    for axis in 0..3 {
        let neg = rays.d[axis].is_negative_bitmask() & bits;
        if neg != 0 && neg != bits {
            for lane in lanes(active) {
                out[lane] = edge_width(tree, &rays.ray(lane), r[lane], remedies, &mut scratch.lanes[lane]);
            }
            return out;
        }
        upper_first |= usize::from(neg != 0) << axis;
    }
    let dirs: [Vec3; 4] = [0, 1, 2, 3].map(|lane| rays.ray(lane).dir);
    let slacks: [f32; 4] = [0, 1, 2, 3].map(|lane| slack(&rays.ray(lane), &bounds));
    let mut pairing = [Pairing::new(); 4];
    for s in &mut scratch.lanes {
        s.pending.clear();
    }
    let prepared = T::prepare4(rays);
    let nodes = tree.nodes();
    let mut stack = Stack::<StackEntry4>::new();
    let mut index = 0usize;
    // Lanes still tracing (not ended early).
    let mut live = active;
    'trace: loop {
        let node = nodes[index];
        if !node.is_leaf() {
            let axis = node.axis() & 3;
            let t_plane = (Vec4::splat(node.split()) - rays.o[axis]) * rays.inv[axis];
            let upper = (upper_first >> axis) & 1;
            let front = node.left_child() + upper;
            let back = node.left_child() + 1 - upper;
            let (t0_wide, t1_wide) = (widen_down(t0), widen_up(t1));
            // As the single-ray kernel, per lane: front only when the plane lies beyond the
            // interval, back only when before it, else both (NaN: a ray in the plane, both).
            let wants_front = active & !t_plane.cmplt(t0_wide);
            let wants_back = active & !t_plane.cmpgt(t1_wide);
            if !wants_back.any() {
                index = front;
            } else if !wants_front.any() {
                index = back;
            } else {
                let nan = t_plane.cmpne(t_plane);
                let both = wants_front & wants_back;
                let back_t0 = Vec4::select(both & !nan, t_plane, t0);
                stack.push(StackEntry4 {
                    node: back as u32,
                    t0: Vec4::select(wants_back, back_t0, Vec4::INFINITY),
                    t1: Vec4::select(wants_back, t1, Vec4::NEG_INFINITY),
                    mask: wants_back,
                });
                t1 = Vec4::select(both & !nan, t_plane, t1);
                active = wants_front;
                index = front;
            }
            continue;
        }

        // Leaf: each lane's pending list takes every hit, and counts each triangle once.
        let leaf_lanes = active & live;
        if leaf_lanes.any() {
            for &prim in tree.leaf_prims(node) {
                let mut hit = PacketHit::new(rays);
                let found = records[prim as usize].intersect4(rays, &prepared, leaf_lanes, &mut hit, prim);
                for lane in lanes(found) {
                    scratch.lanes[lane].pending.insert(hit.t[lane], prim, tree, dirs[lane]);
                }
            }
        }

        // Pair what no later leaf can precede, lane by lane (as the single-ray kernel: the
        // smallest start on the stack, less the slack).
        let mut next_start = Vec4::INFINITY;
        for e in stack.entries() {
            next_start = next_start.min(e.t0);
        }
        for lane in lanes(live) {
            let s = &mut scratch.lanes[lane];
            let bound = next_start[lane] - slacks[lane];
            if s.pending.flush_below(bound, r[lane], &mut pairing[lane], tree, remedies) {
                out[lane] = f32::INFINITY;
                live &= !BVec4A::from_array(std::array::from_fn(|i| i == lane));
            }
        }
        // Next voxel that a live lane visits.
        loop {
            if !live.any() {
                break 'trace;
            }
            let Some(entry) = stack.pop() else { break 'trace };
            if (entry.mask & live).any() {
                index = entry.node as usize;
                (t0, t1, active) = (entry.t0, entry.t1, entry.mask & live);
                break;
            }
        }
    }
    for lane in lanes(live) {
        let width = pairing[lane].finish();
        out[lane] = if width > r[lane] { f32::INFINITY } else { width };
    }
    out
}
