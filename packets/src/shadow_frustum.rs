//! Shadow frusta: a group of shadow rays (finite segments that need not share an origin)
//! traced down the kd-tree as one frustum, the way Benthin & Wald (2009, sections 3-4)
//! trace the shadow rays of a tile of shading points toward one light cell.
//!
//! **The bound.** Every ray of the group is a segment from `o + t_min d` to `o + t_max d`.
//! Let `A` be the box of the segments' starts and `B` the box of their ends, both padded
//! outward by [`pad`]. With the affine parameter `s` in `[0, 1]` (0 at the starts, 1 at the
//! ends), every point of every segment lies in the *swept box* `A (1 - s) + B s`, whose
//! bounds on each axis are linear in `s`: `lo(s) = A.min + s (B.min - A.min)` and likewise
//! `hi(s)`. This is the thesis's frustum interval traversal (2.3.2, Listing 4.2) with the
//! frustum's origin widened from a point to a box: for a hard shadow the ends share the
//! light's position (`B` is a point, the frustum is the pyramid from the light through the
//! shading points, traced from its base), and for one light cell of soft shadows `B` is the
//! box of the cell's samples.
//!
//! **Traversal.** The group goes down the tree with one interval `[s0, s1]`. At a split
//! plane `x_a = p` the lower child keeps the part of the interval where `lo_a(s) <= p`, the
//! upper child the part where `hi_a(s) >= p`: each is one division, as a ray's plane
//! distance is. A child with an empty interval is skipped; of two, the one entered first at
//! smaller `s` (nearer the shading points) goes first, the other on the stack with the
//! voxel's box. The padding keeps it conservative: every segment point is at least `pad`
//! inside the swept box, far more than the rounding of `(p - lo) / slope`, so a voxel a
//! segment enters is never skipped. The group is a tree of blocks (chunks of four rays, then
//! blocks of four blocks); a block much wider than the voxel it enters goes on as its
//! children, and a chunk as a 2x2 same-sign packet through the voxel's subtree. The walk is
//! `kdtree::descent`'s, those two hand-overs its `enter` hook.
//!
//! **Leaves** (4.1.4, Benthin & Wald's per-ray culling). Each unfinished ray of the group is
//! first culled against the voxel's box (padded, slab test, four rays per `Vec4`); the rays
//! left test the leaf's SIMD triangle groups (`kdtree::leaf`), one ray against four
//! triangles, exactly as `KdTree::occluded` does. A ray is finished at its first hit (any
//! hit: no ordering), and the group at the last unfinished ray. When at most
//! [`ShadowFrustum::FEW`] rays are left unfinished, the rest go as single rays
//! (`KdTree::occluded` from the root), as Embree's hybrid traversal falls back to single rays
//! once few are active.
//!
//! **Exactness.** A ray's answer is a test of its own segment, with the single-ray test and
//! the same triangle groups, against every leaf its segment passes through (and maybe a few
//! more): occluded exactly when a triangle of those leaves meets the segment, which is the
//! single ray's answer under the oracle's rules (`kdtree::oracle`). Rays that are not finite
//! segments (NaN input, an infinite `t_max`) go as single rays.

use glam::{BVec4A, Vec3};
use kdtree::descent::{Descent, Entry, Flow, Visit, descend};
use kdtree::leaf::{LANES, LeafGroup};
use kdtree::triangle::Intersector;
use kdtree::{Aabb, Counters, KdNode, KdTree, PreparedRays, Ray, TreeTest, WaldTest, WatertightTest};

use crate::packet::RayPacket;
use crate::samesign;
use crate::triangle4::PacketTest;

/// The padding of the start and end boxes and of the voxel boxes at leaves: `2^-16` of the
/// largest coordinate magnitude of the tree's bounds and the boxes (plus the smallest normal
/// float, for scenes at the origin). It dwarfs the rounding of the plane distances (a few
/// ulps of those magnitudes) and is small beside any voxel.
pub fn pad(tree_bounds: &Aabb, a: &Aabb, b: &Aabb) -> f32 {
    let m = [tree_bounds.min, tree_bounds.max, a.min, a.max, b.min, b.max]
        .iter()
        .fold(0.0f32, |m, v| m.max(v.abs().max_element()));
    m * (1.0 / 65536.0) + f32::MIN_POSITIVE
}

/// One axis of the swept box: `lo(s) = lo0 + s * lo_slope`, `hi(s) = hi0 + s * hi_slope`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SweptAxis {
    pub(crate) lo0: f32,
    pub(crate) lo_slope: f32,
    pub(crate) lo_inv: f32,
    pub(crate) hi0: f32,
    pub(crate) hi_slope: f32,
    pub(crate) hi_inv: f32,
}

impl SweptAxis {
    /// The part of `[s0, s1]` where `lo(s) <= p` (the lower child's share).
    #[inline(always)]
    pub(crate) fn below(&self, s0: f32, s1: f32, p: f32) -> (f32, f32) {
        if self.lo_slope > 0.0 {
            (s0, s1.min((p - self.lo0) * self.lo_inv))
        } else if self.lo_slope < 0.0 {
            (s0.max((p - self.lo0) * self.lo_inv), s1)
        } else if self.lo0 <= p {
            (s0, s1)
        } else {
            (1.0, 0.0)
        }
    }

    /// The part of `[s0, s1]` where `hi(s) >= p` (the upper child's share).
    #[inline(always)]
    pub(crate) fn above(&self, s0: f32, s1: f32, p: f32) -> (f32, f32) {
        if self.hi_slope > 0.0 {
            (s0.max((p - self.hi0) * self.hi_inv), s1)
        } else if self.hi_slope < 0.0 {
            (s0, s1.min((p - self.hi0) * self.hi_inv))
        } else if self.hi0 >= p {
            (s0, s1)
        } else {
            (1.0, 0.0)
        }
    }
}

/// A block of the group's rays: one chunk of four (consecutive in push order) or up to four
/// blocks of the level below, with the swept box of its segments.
#[derive(Clone, Copy, Debug)]
struct Block {
    axes: [SweptAxis; 3],
    /// Its chunks of four rays: `first_chunk..end_chunk`.
    first_chunk: u32,
    end_chunk: u32,
    /// Its children `first_child..first_child + children` (none for a chunk).
    first_child: u32,
    children: u32,
    /// The block above it (`u32::MAX` for the whole group).
    parent: u32,
    /// Its rays not finished yet.
    open: u32,
}

/// The group's state in a voxel: the block of rays in it, their interval and the voxel's
/// box (what is carried down, and pushed with a deferred voxel).
#[derive(Clone, Copy, Debug)]
struct Span {
    block: u32,
    s0: f32,
    s1: f32,
    lo: Vec3,
    hi: Vec3,
}

/// A block is split into its children at a voxel when its cross-section is wider than this
/// many times the voxel's largest extent.
const SPLIT_RATIO: f32 = 0.5;

/// What a group's trace did, for the tables: frustum steps and leaves, rays tested against
/// triangles at leaves and culled there (these four only when counting, `Counters::ENABLED`),
/// and rays finished as single rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrustumStats {
    /// Inner and leaf nodes the frustum visited.
    pub nodes: u64,
    /// Leaves the frustum visited.
    pub leaves: u64,
    /// Ray-leaf pairs considered at leaves (unfinished rays).
    pub ray_leaves: u64,
    /// Of those, culled by the voxel's box before any triangle test.
    pub culled: u64,
    /// Rays handed to single-ray traversal.
    pub single: u64,
}

/// A group of shadow rays traced as one frustum: the scratch space (made once per thread,
/// reused for every group) and the kernel. Push the rays with [`ShadowFrustum::push`], trace
/// with [`ShadowFrustum::trace`], read [`ShadowFrustum::blocked`].
#[derive(Debug, Default)]
pub struct ShadowFrustum {
    rays: Vec<Ray>,
    packets: Vec<RayPacket>,
    /// Per 4 rays, the lanes not finished yet (bit `i`: ray `4c + i`).
    open: Vec<u8>,
    blocked: Vec<bool>,
    /// The rays prepared for the tree test's SIMD leaf groups.
    prepared: PreparedRays,
    blocks: Vec<Block>,
    boxes: Vec<(Aabb, Aabb)>,
    stack: Vec<Entry<Span>>,
    stats: FrustumStats,
}

impl ShadowFrustum {
    /// At most this many unfinished rays go on as single rays.
    pub const FEW: usize = 2;

    /// An empty group.
    pub fn new() -> ShadowFrustum {
        ShadowFrustum::default()
    }

    /// Empties the group.
    pub fn clear(&mut self) {
        self.rays.clear();
    }

    /// Adds a ray; its answer will be `blocked()[i]` for the `i`-th ray pushed.
    pub fn push(&mut self, ray: Ray) {
        self.rays.push(ray);
    }

    /// The rays pushed.
    pub fn len(&self) -> usize {
        self.rays.len()
    }

    /// Whether no ray was pushed.
    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }

    /// Whether each ray of the last trace is blocked, in push order.
    pub fn blocked(&self) -> &[bool] {
        &self.blocked
    }

    /// What the last trace did.
    pub fn stats(&self) -> FrustumStats {
        self.stats
    }

    /// Traces the group through `tree` (any hit per ray), counting frustum steps as nodes,
    /// frustum leaves as leaves, ray-triangle tests as tests and rays culled at leaves as
    /// culled packets. Then [`ShadowFrustum::blocked`] holds the answers.
    pub fn trace<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`ShadowFrustum::trace`] with the tree's triangle test `I`, chosen once by the caller
    /// (see [`TreeTest`]).
    pub fn trace_with<I: TreeTest<Record: PacketTest>, C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        self.stats = FrustumStats::default();
        let n = self.rays.len();
        self.blocked.clear();
        self.blocked.resize(n, false);
        // Rays that are not finite segments go alone; so does a group of few.
        let grouped = self.rays.iter().filter(|r| is_segment(r)).count();
        for (ray, blocked) in self.rays.iter().zip(&mut self.blocked) {
            if grouped <= Self::FEW || !is_segment(ray) {
                *blocked = tree.occluded_with_counted::<I, C>(ray, counters);
                self.stats.single += 1;
            }
        }
        if grouped <= Self::FEW {
            return;
        }
        self.load(&tree.bounds());
        let mut data = std::mem::take(I::prepared(&mut self.prepared));
        data.clear();
        data.extend(self.rays.iter().map(I::Group::prepare));
        self.run::<I, C>(tree, &data, counters);
        *I::prepared(&mut self.prepared) = data;
    }

    /// Fills the structure-of-arrays copy, the open lanes (the finite segments) and the
    /// blocks: chunks of four rays, then blocks of four blocks up to the whole group, each
    /// with its swept box padded by [`pad`].
    fn load(&mut self, bounds: &Aabb) {
        self.packets.clear();
        self.open.clear();
        self.blocks.clear();
        self.boxes.clear();
        let empty = Aabb::new(Vec3::INFINITY, Vec3::NEG_INFINITY);
        for (c, four) in self.rays.chunks(LANES).enumerate() {
            self.packets.push(RayPacket::new(four));
            let (mut open, mut count, mut a, mut b) = (0u8, 0u32, empty, empty);
            for (i, ray) in four.iter().enumerate() {
                if is_segment(ray) {
                    open |= 1 << i;
                    count += 1;
                    a = a.grow(ray.at(ray.t_min));
                    b = b.grow(ray.at(ray.t_max));
                }
            }
            self.open.push(open);
            self.boxes.push((a, b));
            let c = c as u32;
            self.blocks.push(Block {
                axes: [SweptAxis::default(); 3],
                first_chunk: c,
                end_chunk: c + 1,
                first_child: 0,
                children: 0,
                parent: u32::MAX,
                open: count,
            });
        }
        // Blocks of four blocks, level by level, up to one.
        let mut level = 0..self.blocks.len();
        while level.len() > 1 {
            let next = self.blocks.len();
            for first in level.clone().step_by(4) {
                let end = (first + 4).min(level.end);
                let parent = self.blocks.len() as u32;
                let (mut a, mut b, mut open) = (empty, empty, 0);
                for child in first..end {
                    a = a.union(self.boxes[child].0);
                    b = b.union(self.boxes[child].1);
                    open += self.blocks[child].open;
                    self.blocks[child].parent = parent;
                }
                self.boxes.push((a, b));
                self.blocks.push(Block {
                    axes: [SweptAxis::default(); 3],
                    first_chunk: self.blocks[first].first_chunk,
                    end_chunk: self.blocks[end - 1].end_chunk,
                    first_child: first as u32,
                    children: (end - first) as u32,
                    parent: u32::MAX,
                    open,
                });
            }
            level = next..self.blocks.len();
        }
        let (a, b) = self.boxes[self.boxes.len() - 1];
        let pad = pad(bounds, &a, &b);
        for (block, (a, b)) in self.blocks.iter_mut().zip(&self.boxes) {
            if block.open > 0 {
                block.axes = swept_axes(a, b, pad);
            }
        }
    }

    /// The traversal with the tree test `I`'s leaf groups and the rays' prepared data `data`.
    #[inline(always)]
    fn run<I: TreeTest<Record: PacketTest>, C: Counters>(
        &mut self,
        tree: &KdTree,
        data: &[<I::Group as LeafGroup>::RayData],
        counters: &mut C,
    ) {
        let groups = I::groups(tree);
        let bounds = tree.bounds();
        let (root_a, root_b) = self.boxes[self.boxes.len() - 1];
        let pad = pad(&bounds, &root_a, &root_b);
        let root = self.blocks.len() - 1;
        let (s0, s1) = clip(&self.blocks[root].axes, (0.0, 1.0), bounds.min, bounds.max);
        // Also true for a NaN interval.
        if s0.partial_cmp(&s1).is_none_or(|o| o.is_gt()) {
            return;
        }
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        let span = Span { block: root as u32, s0, s1, lo: bounds.min, hi: bounds.max };
        let mut walk = BlockWalk::<I> { frustum: self, tree, groups, data, pad, root, few: false };
        descend(tree, &mut walk, (0, span), &mut stack, counters);
        let few = walk.few;
        self.stack = stack;
        if !few {
            return;
        }
        // Few rays left: each from the root on its own.
        for c in 0..self.open.len() {
            let mut lanes = self.open[c];
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let i = c * LANES + lane;
                self.blocked[i] = tree.occluded_with_counted::<I, C>(&self.rays[i], counters);
                self.stats.single += 1;
            }
            self.open[c] = 0;
        }
    }
}

/// The blocks of a group walking the tree ([`kdtree::descent`]): on entering a voxel a block
/// of four rays goes on as a 2x2 packet and a block much wider than the voxel splits into its
/// children; otherwise the swept-box interval step, the culling leaf visitor (which stops
/// the walk when few rays are left), and a pop rule that drops the voxels of finished blocks.
struct BlockWalk<'a, I: TreeTest> {
    frustum: &'a mut ShadowFrustum,
    tree: &'a KdTree,
    groups: &'a [I::Group],
    data: &'a [<I::Group as LeafGroup>::RayData],
    pad: f32,
    /// The block of the whole group.
    root: usize,
    /// Whether the walk stopped with at most [`ShadowFrustum::FEW`] rays (and some) left.
    few: bool,
}

impl<I: TreeTest<Record: PacketTest>> Descent for BlockWalk<'_, I> {
    type Span = Span;
    type Deferred = Span;
    type Stack = Vec<Entry<Span>>;

    #[inline(always)]
    fn enter<C: Counters>(&mut self, index: usize, span: &mut Span, stack: &mut Self::Stack, counters: &mut C) -> bool {
        let f = &mut *self.frustum;
        let block = &f.blocks[span.block as usize];
        if block.children == 0 {
            // Four rays or fewer: a 2x2 packet through this voxel's subtree, each lane in
            // its own interval (thesis 2.3.1), exact per lane.
            let c = block.first_chunk as usize;
            let open = f.open[c];
            let mut packet = f.packets[c];
            packet.valid &= lane_mask(open);
            let (lo, hi) = (span.lo - Vec3::splat(self.pad), span.hi + Vec3::splat(self.pad));
            let from = (index, packet.clip(lo.extend(0.0).to_array(), hi.extend(0.0).to_array()));
            let found =
                open & samesign::occluded_in_with::<I, _, C>(self.tree, &packet, from, counters).found.bitmask() as u8;
            f.finish(c, found);
            false
        } else if wider_than(&block.axes, span, SPLIT_RATIO * (span.hi - span.lo).max_element()) {
            // A block much wider than the voxel: its children, each clipped to the voxel
            // (a child's swept box lies inside its parent's at every `s`).
            for child in block.first_child..block.first_child + block.children {
                let b = &f.blocks[child as usize];
                if b.open == 0 {
                    continue;
                }
                let (c0, c1) = clip(&b.axes, (span.s0, span.s1), span.lo, span.hi);
                if c0 <= c1 {
                    stack.push(Entry { node: index as u32, value: Span { block: child, s0: c0, s1: c1, ..*span } });
                }
            }
            false
        } else {
            if C::ENABLED {
                f.stats.nodes += 1;
            }
            true
        }
    }

    #[inline(always)]
    fn inner(&mut self, node: KdNode, span: &mut Span, _: &Self::Stack) -> Visit<Span> {
        let k = node.axis();
        let p = node.split();
        let axis = &self.frustum.blocks[span.block as usize].axes[k];
        let (l0, l1) = axis.below(span.s0, span.s1, p);
        let (r0, r1) = axis.above(span.s0, span.s1, p);
        let left = node.left_child() as u32;
        let mut lower = Span { s0: l0, s1: l1, ..*span };
        lower.hi[k] = p;
        let mut upper = Span { s0: r0, s1: r1, ..*span };
        upper.lo[k] = p;
        let lower = (l0 <= l1).then_some(Entry { node: left, value: lower });
        let upper = (r0 <= r1).then_some(Entry { node: left + 1, value: upper });
        nearer_first(lower, upper, l0 <= r0, span)
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, span: &Span, _: &Self::Stack, counters: &mut C) -> Flow {
        if node.prim_count() == 0 {
            return Flow::Continue;
        }
        counters.leaf();
        let f = &mut *self.frustum;
        let block = &f.blocks[span.block as usize];
        let first = node.first_ref() / LANES;
        let leaf_groups = &self.groups[first..first + node.prim_count().div_ceil(LANES)];
        let (lo, hi) = (span.lo - Vec3::splat(self.pad), span.hi + Vec3::splat(self.pad));
        let (mut considered, mut culled, mut tested) = (0u64, 0u64, 0u64);
        for c in block.first_chunk as usize..block.end_chunk as usize {
            let open = f.open[c];
            if open == 0 {
                continue;
            }
            let inside = open & inside(&f.packets[c], lo, hi);
            if C::ENABLED {
                // `count_ones` is no single instruction in the x86-64 baseline (no POPCNT):
                // only when counting.
                considered += u64::from(open.count_ones());
                culled += u64::from((open & !inside).count_ones());
            }
            let mut lanes = inside;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let i = c * LANES + lane;
                let ray = &f.rays[i];
                tested += 1;
                if leaf_groups.iter().any(|g| g.intersect(ray, &self.data[i], ray.t_max).mask.any()) {
                    f.finish(c, 1 << lane);
                }
            }
        }
        counters.tests(tested * node.prim_count() as u64);
        counters.leaf_packets(considered, culled);
        if C::ENABLED {
            f.stats.ray_leaves += considered;
            f.stats.culled += culled;
            f.stats.leaves += 1;
        }
        let left = f.blocks[self.root].open as usize;
        if left <= ShadowFrustum::FEW {
            self.few = left > 0;
            return Flow::Stop;
        }
        Flow::Continue
    }

    /// A deferred voxel goes on while its block still has rays.
    #[inline(always)]
    fn resume(&mut self, span: Span) -> Option<Span> {
        (self.frustum.blocks[span.block as usize].open > 0).then_some(span)
    }
}

impl ShadowFrustum {
    /// Marks the lanes `lanes` of chunk `c` blocked: they leave the chunk's block and every
    /// block above it.
    #[inline(always)]
    fn finish(&mut self, c: usize, lanes: u8) {
        let n = (0..LANES).filter(|i| lanes >> i & 1 != 0).count() as u32;
        if n == 0 {
            return;
        }
        for lane in (0..LANES).filter(|i| lanes >> i & 1 != 0) {
            self.blocked[c * LANES + lane] = true;
        }
        self.open[c] &= !lanes;
        let mut b = c as u32;
        while b != u32::MAX {
            self.blocks[b as usize].open -= n;
            b = self.blocks[b as usize].parent;
        }
    }
}

/// The child a frustum goes on with: of two, the one entered first (`lower_first`: the lower
/// one), the other deferred; else the one it enters; neither when it enters none. `span`
/// becomes the entered child's.
#[inline(always)]
pub(crate) fn nearer_first<T: Copy>(
    lower: Option<Entry<T>>,
    upper: Option<Entry<T>>,
    lower_first: bool,
    span: &mut T,
) -> Visit<T> {
    match (lower, upper) {
        (Some(lower), Some(upper)) => {
            let (first, second) = if lower_first { (lower, upper) } else { (upper, lower) };
            *span = first.value;
            Visit::Both { first: first.node as usize, second: second.node as usize, deferred: second.value }
        }
        (Some(one), None) | (None, Some(one)) => {
            *span = one.value;
            Visit::One(one.node as usize)
        }
        (None, None) => Visit::Neither,
    }
}

/// The lanes of the bit mask `bits` as a `BVec4A`.
#[inline(always)]
fn lane_mask(bits: u8) -> BVec4A {
    BVec4A::new(bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0)
}

/// The swept box of segments starting in `a` and ending in `b`, both padded by `pad`.
pub(crate) fn swept_axes(a: &Aabb, b: &Aabb, pad: f32) -> [SweptAxis; 3] {
    let (a_lo, a_hi) = (a.min - Vec3::splat(pad), a.max + Vec3::splat(pad));
    let (b_lo, b_hi) = (b.min - Vec3::splat(pad), b.max + Vec3::splat(pad));
    std::array::from_fn(|k| {
        let (lo_slope, hi_slope) = (b_lo[k] - a_lo[k], b_hi[k] - a_hi[k]);
        SweptAxis { lo0: a_lo[k], lo_slope, lo_inv: 1.0 / lo_slope, hi0: a_hi[k], hi_slope, hi_inv: 1.0 / hi_slope }
    })
}

/// The part of `(s0, s1)` where the swept box `axes` overlaps the box `lo..hi`.
#[inline(always)]
fn clip(axes: &[SweptAxis; 3], (mut s0, mut s1): (f32, f32), lo: Vec3, hi: Vec3) -> (f32, f32) {
    for (k, axis) in axes.iter().enumerate() {
        (s0, s1) = axis.below(s0, s1, hi[k]);
        (s0, s1) = axis.above(s0, s1, lo[k]);
    }
    (s0, s1)
}

/// Whether the swept box `axes` is wider than `width` on some axis at either end of the
/// voxel's interval.
#[inline(always)]
fn wider_than(axes: &[SweptAxis; 3], at: &Span, width: f32) -> bool {
    axes.iter().any(|a| {
        let w = |s: f32| (a.hi0 + s * a.hi_slope) - (a.lo0 + s * a.lo_slope);
        w(at.s0).max(w(at.s1)) > width
    })
}

/// Whether `ray` is a valid ray with finite ends: one the frustum can bound.
#[inline]
fn is_segment(ray: &Ray) -> bool {
    ray.is_valid() && ray.at(ray.t_min).is_finite() && ray.at(ray.t_max).is_finite()
}

/// The lanes (bit mask) of `rays` whose `[t_min, t_max]` meets the box `lo..hi`
/// (`RayPacket::clip`, widened).
#[inline(always)]
fn inside(rays: &RayPacket, lo: Vec3, hi: Vec3) -> u8 {
    let (near, far) = rays.clip(lo.extend(0.0).to_array(), hi.extend(0.0).to_array());
    near.cmple(far).bitmask() as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{Rng, grid, soup, trees};

    /// Every ray's answer from the frustum equals the single ray's.
    fn check(tree: &KdTree, rays: &[Ray]) -> FrustumStats {
        let mut group = ShadowFrustum::new();
        for r in rays {
            group.push(*r);
        }
        let mut counts = kdtree::Counts::default();
        group.trace(tree, &mut counts);
        for (i, (ray, &got)) in rays.iter().zip(group.blocked()).enumerate() {
            assert_eq!(got, tree.occluded(ray), "ray {i}: {ray:?}");
        }
        // The same rays as 2x2 same-sign packets from the root (the `kd-packets` kernel).
        for (c, four) in rays.chunks(4).enumerate() {
            let found = samesign::occluded(tree, &RayPacket::new(four), &mut kdtree::NoCounters).found.bitmask();
            for (lane, ray) in four.iter().enumerate() {
                assert_eq!(found >> lane & 1 != 0, tree.occluded(ray), "packet {c} lane {lane}: {ray:?}");
            }
        }
        group.stats()
    }

    /// Rays from points of `tile` (a box) to one light, as hard shadows.
    fn hard(rng: &mut Rng, n: usize, lo: Vec3, hi: Vec3, light: Vec3) -> Vec<Ray> {
        (0..n)
            .map(|_| {
                let p = rng.vec(lo, hi);
                Ray::segment(p, light)
            })
            .collect()
    }

    #[test]
    fn hard_shadows_of_random_soups_match_single_rays() {
        let mut rng = Rng(0x5eed_1234_abcd);
        let (mut blocked, mut total) = (0, 0);
        for _ in 0..12 {
            let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
            let (positions, triangles) = soup(&mut rng, 300, lo, hi);
            let light = rng.vec(Vec3::splat(-1.5), Vec3::splat(1.5));
            let c = rng.vec(lo, hi);
            let size = 0.05 + rng.next() * 0.8;
            let rays = hard(&mut rng, 64, c - size, c + size, light);
            for tree in trees(&positions, &triangles) {
                check(&tree, &rays);
                blocked += rays.iter().filter(|r| tree.occluded(r)).count();
                total += rays.len();
            }
        }
        // Both answers occur, so the comparison means something.
        assert!(blocked > total / 10 && blocked < total * 9 / 10, "{blocked} of {total}");
    }

    #[test]
    fn soft_shadow_cells_far_from_the_origin_match_single_rays() {
        // Rays from a tile to a small light cell, the scene 1e5 units out.
        let mut rng = Rng(77);
        let offset = Vec3::new(1.0e5, -2.0e5, 3.0e5);
        let (positions, triangles) = soup(&mut rng, 400, offset - 10.0, offset + 10.0);
        for tree in trees(&positions, &triangles) {
            for _ in 0..6 {
                let c = rng.vec(offset - 8.0, offset + 8.0);
                let cell = rng.vec(offset - 12.0, offset + 12.0);
                let rays: Vec<Ray> = (0..100)
                    .map(|_| {
                        let p = rng.vec(c - 1.0, c + 1.0);
                        let q = rng.vec(cell - 0.3, cell + 0.3);
                        Ray::segment(p, q)
                    })
                    .collect();
                check(&tree, &rays);
            }
        }
    }

    #[test]
    fn hard_cases_match_single_rays() {
        let (positions, triangles) = grid();
        for tree in trees(&positions, &triangles) {
            let mut rays = Vec::new();
            // Shading points on the quads' planes (on split planes), the light on a split
            // plane (y = 2) inside the scene's box, and at a quad's corner.
            for light in [Vec3::new(2.5, 2.0, 2.5), Vec3::new(3.0, 2.0, 3.0), Vec3::new(4.8, 5.0, 4.8)] {
                for i in 0..8 {
                    for j in 0..8 {
                        let p = Vec3::new(i as f32 * 0.7, 1.0, j as f32 * 0.7);
                        rays.push(Ray::segment(p, light));
                    }
                }
                check(&tree, &rays);
                // Grazing rays: along the quads' plane y = 1, and with zero direction
                // components.
                rays.clear();
                for i in 0..16 {
                    let p = Vec3::new(-0.5, 1.0, i as f32 * 0.37);
                    rays.push(Ray::new(p, Vec3::new(7.0, 0.0, 0.0), 0.0, 1.0));
                    rays.push(Ray::new(p, Vec3::new(6.0, 0.0, 1.0), 0.0, 1.0));
                }
                check(&tree, &rays);
                // Rays whose far end lies exactly on an occluder (the quad at y = 2).
                rays.clear();
                for i in 0..16 {
                    let p = Vec3::new(0.2 + i as f32 * 0.3, 0.5, 2.3);
                    let end = Vec3::new(p.x, 2.0, 2.3);
                    rays.push(Ray::segment(p, end));
                }
                check(&tree, &rays);
            }
        }
    }

    #[test]
    fn degenerate_lanes_go_alone_and_agree() {
        let (positions, triangles) = grid();
        let tree = &trees(&positions, &triangles)[0];
        let light = Vec3::new(2.5, 6.0, 2.5);
        let mut rays = hard(&mut Rng(3), 21, Vec3::ZERO, Vec3::new(5.0, 0.5, 5.0), light);
        rays.push(Ray::new(Vec3::NAN, Vec3::Y, 0.0, 1.0));
        rays.push(Ray::new(Vec3::ONE, Vec3::new(f32::NAN, 1.0, 0.0), 0.0, 1.0));
        rays.push(Ray::new(Vec3::new(1.0, -1.0, 1.0), Vec3::Y, 0.0, f32::INFINITY));
        let stats = check(tree, &rays);
        assert_eq!(stats.single, 3);
        // Too few rays for a frustum: all single.
        assert_eq!(check(tree, &rays[..2]).single, 2);
        assert_eq!(check(tree, &[]).single, 0);
    }

    #[test]
    fn the_swept_box_culls() {
        // A tight group far from most triangles visits few leaves and culls rays there.
        let (positions, triangles) = grid();
        let tree = &trees(&positions, &triangles)[0];
        let light = Vec3::new(0.4, 8.0, 0.4);
        let rays = hard(&mut Rng(9), 64, Vec3::new(0.1, -1.0, 0.1), Vec3::new(0.7, -0.5, 0.7), light);
        let stats = check(tree, &rays);
        assert!(stats.leaves > 0 && stats.leaves < tree.nodes().len() as u64 / 4, "{stats:?}");
        assert_eq!(stats.single, 0);
    }
}
