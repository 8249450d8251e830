//! The edge-width traversal for four shadow rays at once (Tsakok 2008, chapter 5: "the
//! algorithm can be efficiently implemented using SSE for shadowing packets at a time").
//!
//! The four rays sit in a [`RayPacket`] (SoA, one `Vec4` per coordinate) and walk the tree
//! together with `kdtree::descent`, each lane with its own interval, as the same-sign packets
//! of thesis 2.3.1: the valid lanes must share their direction signs, so that one child is
//! the front voxel of all of them (shadow rays from neighbouring pixels to one light almost
//! always do); a packet whose lanes differ is traced lane by lane with [`crate::edge_width`].
//! Leaves test each triangle against the four rays with the 4-wide tests of
//! `packets::triangle4`, which compute bit for bit what the single-ray tests compute; each
//! lane keeps its own pending list and pairing, with the single-ray rules (see
//! [`crate::traverse`]): every hit a leaf reports joins the lane's list, and hits are paired
//! up to the smallest start on the stack (kept per entry, as there) less the slack. The
//! answer of a lane depends only on the set of hits along its segment, which both traversals
//! find whole, so it equals the single-ray answer (tested).

use glam::{BVec4A, Vec3, Vec4};
use kdtree::descent::{Descent, Entry, Flow, Visit, descend};
use kdtree::stack::Stack;
use kdtree::{Counters, Intersector, KdNode, KdTree, NoCounters, TreeTest, WaldTest, WatertightTest};
use packets::packet::{widen_down, widen_up};
use packets::triangle4::PacketTest;
use packets::{PacketHit, RayPacket};

use crate::pairing::{LeakRemedies, Pairing};
use crate::traverse::{EdgeScratch, edge_width_with, slack};

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
        Intersector::Wald => edge_width4_with::<WaldTest>(tree, rays, r, remedies, scratch),
        Intersector::Watertight => edge_width4_with::<WatertightTest>(tree, rays, r, remedies, scratch),
    }
}

/// [`edge_width4`] with the tree's triangle test `I`, chosen once by the caller (see
/// [`TreeTest`]).
pub fn edge_width4_with<I: TreeTest<Record: PacketTest>>(
    tree: &KdTree,
    rays: &RayPacket,
    r: [f32; 4],
    remedies: &LeakRemedies,
    scratch: &mut EdgeScratch4,
) -> [f32; 4] {
    kernel4::<I>(tree, rays, r, remedies, scratch)
}

/// The four rays walking the tree ([`kdtree::descent`]): the same-sign packet step of
/// thesis 2.3.1 with the single-ray kernel's widened comparisons, a leaf visitor adding each
/// lane's hits to its pending list and pairing those no later voxel can precede, and a pop
/// rule that drops only the voxels no live lane visits.
struct EdgePacket<'a, T: PacketTest> {
    tree: &'a KdTree,
    records: &'a [T],
    rays: &'a RayPacket,
    prepared: T::PacketData,
    upper_first: usize,
    dirs: [Vec3; 4],
    slacks: [f32; 4],
    r: [f32; 4],
    remedies: &'a LeakRemedies<'a>,
    scratch: &'a mut EdgeScratch4,
    pairing: [Pairing; 4],
    out: [f32; 4],
    /// Lanes still tracing (not ended early).
    live: BVec4A,
}

/// The lanes' state in a voxel: each lane's interval `(t0, t1)` and the lanes that visit it
/// (`t0 = +inf`, `t1 = -inf` in the others).
type Span = (Vec4, Vec4, BVec4A);

/// A deferred back voxel: its span and, per lane, `min_t0`, the smallest start of this entry
/// and every entry below it (what bounds the lane's hits still to be found while this entry
/// is the top of the stack; `+inf` in lanes that visit none of them).
type Deferred = (Span, Vec4);

impl<T: PacketTest> Descent for EdgePacket<'_, T> {
    type Span = Span;
    type Deferred = Deferred;
    type Stack = Stack<Entry<Deferred>>;

    #[inline(always)]
    fn inner(&mut self, node: KdNode, (t0, t1, active): &mut Span, stack: &Self::Stack) -> Visit<Deferred> {
        let rays = self.rays;
        let axis = node.axis() & 3;
        let t_plane = (Vec4::splat(node.split()) - rays.o[axis]) * rays.inv[axis];
        let upper = (self.upper_first >> axis) & 1;
        let front = node.left_child() + upper;
        let back = node.left_child() + 1 - upper;
        let (t0_wide, t1_wide) = (widen_down(*t0), widen_up(*t1));
        // As the single-ray kernel, per lane: front only when the plane lies beyond the
        // interval, back only when before it, else both (NaN: a ray in the plane, both).
        let wants_front = *active & !t_plane.cmplt(t0_wide);
        let wants_back = *active & !t_plane.cmpgt(t1_wide);
        if !wants_back.any() {
            Visit::One(front)
        } else if !wants_front.any() {
            Visit::One(back)
        } else {
            let nan = t_plane.cmpne(t_plane);
            let both = wants_front & wants_back;
            let back_t0 = Vec4::select(wants_back, Vec4::select(both & !nan, t_plane, *t0), Vec4::INFINITY);
            let back_t1 = Vec4::select(wants_back, *t1, Vec4::NEG_INFINITY);
            let below = stack.top().map_or(Vec4::INFINITY, |e| e.value.1);
            let deferred = ((back_t0, back_t1, wants_back), below.min(back_t0));
            *t1 = Vec4::select(both & !nan, t_plane, *t1);
            *active = wants_front;
            Visit::Both { first: front, second: back, deferred }
        }
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, &(_, _, active): &Span, stack: &Self::Stack, _: &mut C) -> Flow {
        // Each lane's pending list takes every hit, and counts each triangle once.
        let (tree, rays) = (self.tree, self.rays);
        let leaf_lanes = active & self.live;
        if leaf_lanes.any() {
            for &prim in tree.leaf_prims(node) {
                let mut hit = PacketHit::new(rays);
                let found = self.records[prim as usize].intersect4(rays, &self.prepared, leaf_lanes, &mut hit, prim);
                for lane in lanes(found) {
                    self.scratch.lanes[lane].pending.insert(hit.t[lane], prim, tree, self.dirs[lane]);
                }
            }
        }
        // Pair what no later leaf can precede, lane by lane (as the single-ray kernel: the
        // smallest start on the stack, less the slack).
        let next_start = stack.top().map_or(Vec4::INFINITY, |e| e.value.1);
        for lane in lanes(self.live) {
            let s = &mut self.scratch.lanes[lane];
            let bound = next_start[lane] - self.slacks[lane];
            if s.pending.flush_below(bound, self.r[lane], &mut self.pairing[lane], tree, self.remedies) {
                self.out[lane] = f32::INFINITY;
                self.live &= !BVec4A::from_array(std::array::from_fn(|i| i == lane));
            }
        }
        if self.live.any() { Flow::Continue } else { Flow::Stop }
    }

    /// The next voxel that a live lane visits.
    #[inline(always)]
    fn resume(&mut self, ((t0, t1, mask), _): Deferred) -> Option<Span> {
        (mask & self.live).any().then_some((t0, t1, mask & self.live))
    }
}

#[inline(always)]
fn lanes(mask: BVec4A) -> impl Iterator<Item = usize> {
    let bits = mask.bitmask();
    (0..4).filter(move |lane| bits >> lane & 1 != 0)
}

#[inline(always)]
fn kernel4<I: TreeTest<Record: PacketTest>>(
    tree: &KdTree,
    rays: &RayPacket,
    r: [f32; 4],
    remedies: &LeakRemedies,
    scratch: &mut EdgeScratch4,
) -> [f32; 4] {
    let records = I::records(tree);
    let mut out = [0.0f32; 4];
    let bounds = tree.bounds();
    let (t0, t1) = rays.clip(bounds.min.extend(0.0).to_array(), bounds.max.extend(0.0).to_array());
    let active = rays.valid & t0.cmple(t1);
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
                out[lane] = edge_width_with::<I>(tree, &rays.ray(lane), r[lane], remedies, &mut scratch.lanes[lane]);
            }
            return out;
        }
        upper_first |= usize::from(neg != 0) << axis;
    }
    for s in &mut scratch.lanes {
        s.pending.clear();
    }
    let mut group = EdgePacket {
        tree,
        records,
        rays,
        prepared: <I::Record as PacketTest>::prepare4(rays),
        upper_first,
        dirs: [0, 1, 2, 3].map(|lane| rays.ray(lane).dir),
        slacks: [0, 1, 2, 3].map(|lane| slack(&rays.ray(lane), &bounds)),
        r,
        remedies,
        scratch,
        pairing: [Pairing::new(); 4],
        out,
        live: active,
    };
    descend(tree, &mut group, (0, (t0, t1, active)), &mut Stack::new(), &mut NoCounters);
    for lane in lanes(group.live) {
        let width = group.pairing[lane].finish();
        group.out[lane] = if width > r[lane] { f32::INFINITY } else { width };
    }
    group.out
}
