//! Shadow frusta in SIMD lanes: Benthin & Wald's multi-frusta tracing (2009, sections
//! 4.1-4.4) over the kd-tree.
//!
//! A *frustum* here is up to [`FRUSTUM_RAYS`] shadow segments that share one end, its
//! *apex*: a shading point's 16 rays to the samples of an area light (soft shadows, the
//! paper's shadow frusta), or a 4x4 block of shading points' rays to a point light (hard
//! shadows, the apex being the light). Several frusta, 4 or 8, go down the tree together,
//! one per SIMD lane; each lane is culled on its own, and ends when all its rays are blocked.
//!
//! **Traversal** (4.1, interval culling). Each lane bounds its segments by the swept box of
//! [`crate::shadow_frustum`] (from the box of their starts to the box of their ends, padded)
//! and carries its own interval `[s0, s1]` of that sweep. At a split plane every lane's
//! interval is cut for both children, lane by lane without branches; the group goes
//! to a child if any lane's share is not empty, nearer child first, the other on the stack
//! with every lane's share. The walk is `kdtree::descent`'s; on entering a voxel, lanes with
//! an empty share or no unblocked ray drop out (its `enter` hook), and a voxel no lane is
//! left in is skipped.
//!
//! **Leaves** (4.2, triangle culling before any ray). For each triangle and every lane at
//! once, two exact tests decide whether no segment of the frustum can meet the triangle:
//! - *the plane test*: the apex and the whole ball around the other ends lie on one side of
//!   the triangle's plane;
//! - *the edge test* (the paper's corner rays, with the ball of the ends in place of four
//!   corner rays): every segment leaves the apex outside the plane through the apex and one
//!   edge of the triangle.
//!
//! Both keep a margin [`margin`] far above the rounding of the single-ray triangle tests,
//! and bound the rounding of their own arithmetic, so a culled triangle is one no single ray
//! of the frustum hits. For a triangle a lane keeps, its rays are made (4.4, on demand, as
//! 2x2 packets built from the segments' ends, `RayPacket::segments`, then kept for the rest
//! of the trace), slab-tested against the leaf's voxel four at a time, and those inside
//! tested against the triangle with the 4-ray test that gives the single-ray answer bit for
//! bit ([`crate::triangle4`]), each ray finished at its first hit. The paper's back-face
//! culling is not applied: the single-ray test is two-sided, so a back face blocks a shadow
//! ray, and skipping it would change the answer on open meshes. Nor is the paper's 16-wide
//! ray test: here 16 rays are four 4-wide packet tests.
//!
//! **Exactness.** A ray's answer is its own segment tested with the single-ray triangle test
//! against the triangles of every leaf its segment passes through (and perhaps a few more),
//! less triangles no segment of its frustum comes near and voxels its segment misses: the
//! single ray's answer (`KdTree::occluded`). Frusta with a non-finite end, or without one
//! shared end, are traced ray by ray.
//!
//! **Lanes.** The kernel is written once over `[f32; L]` lanes, each step a loop over the
//! lanes without branches for the compiler to vectorise: [`LaneWidth::Scalar`] is the scalar
//! twin (one frustum at a time), [`LaneWidth::Four`] four frusta, [`LaneWidth::Eight`]
//! eight, compiled for AVX2, and [`LaneWidth::Sixteen`] sixteen, compiled for AVX-512 (the
//! paper's width), each chosen at run time (`is_x86_feature_detected!`). All give the same
//! answers, bit for bit (tested). On Zen 1, 8 lanes measure 1.1-1.4x faster than 4,
//! and up to 1.8x the scalar twin (`docs/results/coherent-shadows.md`).

use glam::{BVec4A, Vec3};
use kdtree::descent::{Descent, Entry, Flow, Visit, descend};
use kdtree::triangle::Intersector;
use kdtree::{Aabb, Counters, KdNode, KdTree, Ray, TreeTest, WaldTest, WatertightTest};

use crate::packet::{PacketHit, RayPacket};
use crate::shadow_frustum::{SweptAxis, nearer_first, pad, swept_axes};
use crate::triangle4::PacketTest;

/// The most segments one frustum holds (a point's 16 soft-shadow rays, a 4x4 block's hard
/// ones).
pub const FRUSTUM_RAYS: usize = 16;

/// How many frusta go down the tree together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LaneWidth {
    /// One frustum at a time: the scalar twin.
    Scalar,
    /// Four frusta, one per lane of a 128-bit (SSE) register.
    Four,
    /// Eight frusta, one per lane of a 256-bit (AVX2) register; four where the CPU has no
    /// AVX2.
    Eight,
    /// Sixteen frusta, one per lane of a 512-bit (AVX-512) register, the paper's own width
    /// (Larrabee's 16 lanes); eight where the CPU has AVX2 but no AVX-512, else four.
    Sixteen,
}

impl LaneWidth {
    /// The widest width this CPU runs natively: [`LaneWidth::Sixteen`] with AVX-512,
    /// [`LaneWidth::Eight`] with AVX2 (unless the SIMD level is capped below them,
    /// `kdtree::isa::SimdLevel::active`), else [`LaneWidth::Four`].
    pub fn widest() -> LaneWidth {
        if avx512() {
            LaneWidth::Sixteen
        } else if avx2() {
            LaneWidth::Eight
        } else {
            LaneWidth::Four
        }
    }

    /// This width narrowed to what `level` runs natively: sixteen lanes need AVX-512, eight
    /// AVX2 (the scalar twin and four lanes run everywhere).
    pub fn capped(self, level: kdtree::isa::SimdLevel) -> LaneWidth {
        use kdtree::isa::SimdLevel;
        match self {
            LaneWidth::Sixteen if level < SimdLevel::Avx2 => LaneWidth::Four,
            LaneWidth::Sixteen if level < SimdLevel::Avx512 => LaneWidth::Eight,
            LaneWidth::Eight if level < SimdLevel::Avx2 => LaneWidth::Four,
            width => width,
        }
    }

    /// Frusta per trace.
    pub fn lanes(self) -> usize {
        match self {
            LaneWidth::Scalar => 1,
            LaneWidth::Four => 4,
            LaneWidth::Eight => 8,
            LaneWidth::Sixteen => 16,
        }
    }
}

/// Whether this CPU has AVX-512 (F and VL, with AVX2 and FMA: `SimdLevel::Avx512`) and the
/// SIMD level is not capped below it (`rttest --simd`).
fn avx512() -> bool {
    kdtree::isa::SimdLevel::allows(kdtree::isa::SimdLevel::Avx512)
        && kdtree::isa::SimdLevel::detect() >= kdtree::isa::SimdLevel::Avx512
}

/// Whether this CPU has AVX2 and FMA and the SIMD level is not capped below them
/// (`rttest --simd`).
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        kdtree::isa::SimdLevel::allows(kdtree::isa::SimdLevel::Avx2)
            && is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// What the traces since [`LaneFrusta::clear_stats`] did (counted only when
/// `Counters::ENABLED`, except `frusta`, `single` and `rays_made`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LaneStats {
    /// Frusta traced in lanes.
    pub frusta: u64,
    /// Traversal steps of a group of lanes (one per node fetched).
    pub steps: u64,
    /// Non-empty leaves reached.
    pub leaves: u64,
    /// Lane-triangle pairs considered at leaves.
    pub pairs: u64,
    /// Of those, culled by the plane test.
    pub plane_culled: u64,
    /// Of those, culled by the edge test.
    pub edge_culled: u64,
    /// Packet-triangle tests (up to four rays against one triangle).
    pub ray_tests: u64,
    /// Rays made (on demand) in lanes.
    pub rays_made: u64,
    /// Rays traced one by one (frusta that cannot be bounded).
    pub single: u64,
}

/// One frustum's segments as pushed.
#[derive(Clone, Copy, Debug)]
struct Segments {
    starts: [Vec3; FRUSTUM_RAYS],
    ends: [Vec3; FRUSTUM_RAYS],
    count: usize,
}

/// The shadow frusta of one batch and the scratch space of the kernel, made once per thread
/// and reused. Push frusta with [`LaneFrusta::push`], trace with [`LaneFrusta::trace`], read
/// [`LaneFrusta::blocked`].
#[derive(Debug, Default)]
pub struct LaneFrusta {
    frusta: Vec<Segments>,
    blocked: Vec<u16>,
    stacks: Stacks,
    stats: LaneStats,
}

/// The traversal stacks of each lane count, kept between traces (a `Span<L>` holds `L`
/// intervals, so each width has its own).
#[derive(Debug, Default)]
struct Stacks {
    one: Vec<Entry<Span<1>>>,
    four: Vec<Entry<Span<4>>>,
    eight: Vec<Entry<Span<8>>>,
    sixteen: Vec<Entry<Span<16>>>,
}

/// The stack of [`Stacks`] for `L` lanes.
trait StackOf<const L: usize> {
    fn stack(&mut self) -> &mut Vec<Entry<Span<L>>>;
}

macro_rules! stack_of {
    ($($lanes:literal => $field:ident),*) => {$(
        impl StackOf<$lanes> for Stacks {
            #[inline(always)]
            fn stack(&mut self) -> &mut Vec<Entry<Span<$lanes>>> {
                &mut self.$field
            }
        }
    )*};
}

stack_of!(1 => one, 4 => four, 8 => eight, 16 => sixteen);

/// The frusta's state in a voxel: every lane's interval (empty, `s0 > s1`, in lanes that
/// take no part) and the voxel's box.
#[derive(Clone, Copy, Debug)]
struct Span<const L: usize> {
    s0: [f32; L],
    s1: [f32; L],
    lo: Vec3,
    hi: Vec3,
}

impl LaneFrusta {
    /// An empty batch.
    pub fn new() -> LaneFrusta {
        LaneFrusta::default()
    }

    /// Empties the batch (not the statistics).
    pub fn clear(&mut self) {
        self.frusta.clear();
    }

    /// Adds a frustum of the segments `starts[k] -> ends[k]` (ray `k` is
    /// `Ray::segment(starts[k], ends[k])`). Its answers will be bit `k` of
    /// `blocked()[i]` for the `i`-th frustum pushed.
    ///
    /// # Panics
    /// If the slices differ in length or hold more than [`FRUSTUM_RAYS`] segments (a caller's
    /// bug, not input).
    pub fn push(&mut self, starts: &[Vec3], ends: &[Vec3]) {
        assert!(starts.len() == ends.len() && starts.len() <= FRUSTUM_RAYS, "at most 16 segments, paired");
        let mut s =
            Segments { starts: [Vec3::ZERO; FRUSTUM_RAYS], ends: [Vec3::ZERO; FRUSTUM_RAYS], count: starts.len() };
        s.starts[..starts.len()].copy_from_slice(starts);
        s.ends[..ends.len()].copy_from_slice(ends);
        self.frusta.push(s);
    }

    /// Per frustum pushed, its blocked rays (bit `k`: ray `k`), after [`LaneFrusta::trace`].
    pub fn blocked(&self) -> &[u16] {
        &self.blocked
    }

    /// What the traces did since the last [`LaneFrusta::clear_stats`].
    pub fn stats(&self) -> LaneStats {
        self.stats
    }

    /// Zeroes the statistics.
    pub fn clear_stats(&mut self) {
        self.stats = LaneStats::default();
    }

    /// Traces every frustum pushed, `width` of them at a time (any hit per ray), counting
    /// a group's steps as nodes, its leaves, 4-ray packet-triangle tests as tests, and
    /// lane-triangle pairs at leaves as packets considered, those culled as culled.
    pub fn trace<C: Counters>(&mut self, tree: &KdTree, width: LaneWidth, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_with::<WaldTest, C>(tree, width, counters),
            Intersector::Watertight => self.trace_with::<WatertightTest, C>(tree, width, counters),
        }
    }

    /// [`LaneFrusta::trace`] with the tree's triangle test `I`, chosen once by the caller
    /// (see [`TreeTest`]).
    pub fn trace_with<I: TreeTest<Record: PacketTest>, C: Counters>(
        &mut self,
        tree: &KdTree,
        width: LaneWidth,
        counters: &mut C,
    ) {
        let n = self.frusta.len();
        self.blocked.clear();
        self.blocked.resize(n, 0);
        self.at_width::<I, C>(tree, width, counters);
    }

    /// [`LaneFrusta::batches`] with the lanes of `width` (eight only where the CPU has AVX2,
    /// else four).
    fn at_width<I: TreeTest<Record: PacketTest>, C: Counters>(
        &mut self,
        tree: &KdTree,
        width: LaneWidth,
        counters: &mut C,
    ) {
        match width {
            LaneWidth::Scalar => self.batches::<I, C, 1>(tree, counters),
            #[cfg(target_arch = "x86_64")]
            LaneWidth::Sixteen if avx512() => {
                // SAFETY: the CPU has AVX-512 F and VL, AVX2 and FMA (the guard).
                unsafe { self.batches_avx512::<I, C>(tree, counters) }
            }
            #[cfg(target_arch = "x86_64")]
            LaneWidth::Eight | LaneWidth::Sixteen if avx2() => {
                // SAFETY: the CPU has AVX2 and FMA (the guard).
                unsafe { self.batches_avx2::<I, C>(tree, counters) }
            }
            LaneWidth::Four | LaneWidth::Eight | LaneWidth::Sixteen => self.batches::<I, C, 4>(tree, counters),
        }
    }

    /// [`LaneFrusta::batches`] with sixteen lanes, compiled for AVX-512 (the paper's width).
    ///
    /// # Safety
    /// The CPU must have AVX-512 F and VL, AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
    unsafe fn batches_avx512<I: TreeTest<Record: PacketTest>, C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        self.batches::<I, C, 16>(tree, counters);
    }

    /// [`LaneFrusta::batches`] with eight lanes, compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must have AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn batches_avx2<I: TreeTest<Record: PacketTest>, C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        self.batches::<I, C, 8>(tree, counters);
    }

    /// Every frustum, `L` at a time; those that cannot be bounded ray by ray.
    #[inline(always)]
    fn batches<I: TreeTest<Record: PacketTest>, C: Counters, const L: usize>(&mut self, tree: &KdTree, counters: &mut C)
    where
        Stacks: StackOf<L>,
    {
        let records = I::records(tree);
        let bounds = tree.bounds();
        let mut lanes = Lanes::<L>::empty();
        let mut which: [usize; L] = [0; L];
        let mut filled = 0;
        for f in 0..self.frusta.len() {
            let Some(lane) = Lane::new(&self.frusta[f], &bounds) else {
                self.single::<I, C>(tree, f, counters);
                continue;
            };
            lanes.set(filled, &lane, self.frusta[f].count);
            which[filled] = f;
            filled += 1;
            if filled == L {
                self.group::<I::Record, C, L>(tree, records, &mut lanes, &which[..filled], counters);
                lanes = Lanes::empty();
                filled = 0;
            }
        }
        if filled > 0 {
            self.group::<I::Record, C, L>(tree, records, &mut lanes, &which[..filled], counters);
        }
    }

    /// Frustum `f`'s rays one by one.
    fn single<I: TreeTest, C: Counters>(&mut self, tree: &KdTree, f: usize, counters: &mut C) {
        let s = &self.frusta[f];
        for k in 0..s.count {
            let ray = Ray::segment(s.starts[k], s.ends[k]);
            self.blocked[f] |= u16::from(tree.occluded_with_counted::<I, C>(&ray, counters)) << k;
            self.stats.single += 1;
        }
    }

    /// The frusta `which` (at most `L`) traced together, lane `i` frustum `which[i]` with
    /// the bound `lanes` lane `i`.
    #[inline(always)]
    fn group<T: PacketTest, C: Counters, const L: usize>(
        &mut self,
        tree: &KdTree,
        records: &[T],
        lanes: &mut Lanes<L>,
        which: &[usize],
        counters: &mut C,
    ) where
        Stacks: StackOf<L>,
    {
        let bounds = tree.bounds();
        let pad = lanes.pad.iter().fold(0.0f32, |m, &p| m.max(p));
        self.stats.frusta += which.len() as u64;
        // Every lane's interval inside the tree's box.
        let (mut s0, mut s1) = ([f32::INFINITY; L], [f32::NEG_INFINITY; L]);
        for i in 0..which.len() {
            (s0[i], s1[i]) = lanes.clip(i, bounds.min, bounds.max);
        }
        let mut stack = std::mem::take(StackOf::<L>::stack(&mut self.stacks));
        stack.clear();
        let unmade = RayPacket::new(&[]);
        let mut walk = LaneWalk {
            tree,
            records,
            frusta: &self.frusta,
            stats: &mut self.stats,
            lanes,
            which,
            pad,
            packets: [[Packet { data: T::prepare4(&unmade), rays: unmade }; FRUSTUM_RAYS / 4]; L],
            made: [0; L],
            blocked: [0; L],
        };
        let span = Span { s0, s1, lo: bounds.min, hi: bounds.max };
        descend(tree, &mut walk, (0, span), &mut stack, counters);
        let blocked = walk.blocked;
        *StackOf::<L>::stack(&mut self.stacks) = stack;
        for (i, &f) in which.iter().enumerate() {
            self.blocked[f] = blocked[i];
        }
    }
}

/// `L` frusta walking the tree together ([`kdtree::descent`]): lanes whose interval is empty
/// or whose rays are all blocked drop out on entering a voxel (none left: the voxel is
/// skipped), the swept-box interval step lane by lane, and the culling leaf visitor, which
/// stops the walk once every ray is blocked. No deferred voxel is dropped on popping: the
/// lanes drop out on entering it.
struct LaneWalk<'a, T: PacketTest, const L: usize> {
    tree: &'a KdTree,
    records: &'a [T],
    frusta: &'a [Segments],
    stats: &'a mut LaneStats,
    lanes: &'a mut Lanes<L>,
    which: &'a [usize],
    /// The largest padding of the lanes' swept boxes, the voxels' at leaves.
    pad: f32,
    /// Per lane, its rays as 2x2 packets, made on demand.
    packets: [[Packet<T::PacketData>; FRUSTUM_RAYS / 4]; L],
    /// Per lane, its 2x2 packets made so far (bit q: packet q, rays 4q..4q+4).
    made: [u8; L],
    /// Per lane, its rays found blocked (bit `k`: ray `k`).
    blocked: [u16; L],
}

impl<T: PacketTest, const L: usize> Descent for LaneWalk<'_, T, L> {
    type Span = Span<L>;
    type Deferred = Span<L>;
    type Stack = Vec<Entry<Span<L>>>;

    /// Lanes whose interval is empty or whose rays are all blocked take no part.
    #[inline(always)]
    fn enter<C: Counters>(&mut self, _: usize, span: &mut Span<L>, _: &mut Self::Stack, _: &mut C) -> bool {
        let mut live = false;
        for i in 0..L {
            let on = self.lanes.open[i] != 0 && span.s0[i] <= span.s1[i];
            live |= on;
            if !on {
                span.s0[i] = f32::INFINITY;
                span.s1[i] = f32::NEG_INFINITY;
            }
        }
        if live && C::ENABLED {
            self.stats.steps += 1;
        }
        live
    }

    #[inline(always)]
    fn inner(&mut self, node: KdNode, span: &mut Span<L>, _: &Self::Stack) -> Visit<Span<L>> {
        let k = node.axis();
        let p = node.split();
        let left = node.left_child() as u32;
        let (mut lower, mut upper) = (*span, *span);
        lower.hi[k] = p;
        upper.lo[k] = p;
        self.lanes.split(k, p, span, &mut lower, &mut upper);
        let (mut lower_any, mut upper_any) = (false, false);
        let (mut lower_first, mut upper_first) = (f32::INFINITY, f32::INFINITY);
        for i in 0..L {
            let (l, u) = (lower.s0[i] <= lower.s1[i], upper.s0[i] <= upper.s1[i]);
            lower_any |= l;
            upper_any |= u;
            lower_first = lower_first.min(if l { lower.s0[i] } else { f32::INFINITY });
            upper_first = upper_first.min(if u { upper.s0[i] } else { f32::INFINITY });
        }
        let lower = lower_any.then_some(Entry { node: left, value: lower });
        let upper = upper_any.then_some(Entry { node: left + 1, value: upper });
        nearer_first(lower, upper, lower_first <= upper_first, span)
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, span: &Span<L>, _: &Self::Stack, counters: &mut C) -> Flow {
        if node.prim_count() == 0 {
            return Flow::Continue;
        }
        counters.leaf();
        if C::ENABLED {
            self.stats.leaves += 1;
        }
        let (tree, lanes, which) = (self.tree, &mut *self.lanes, self.which);
        let mut on: [bool; L] = std::array::from_fn(|i| span.s0[i] <= span.s1[i]);
        // The voxel, padded as the swept boxes are, for the packets' slab test.
        let (lo, hi) = (span.lo - Vec3::splat(self.pad), span.hi + Vec3::splat(self.pad));
        let (lo, hi) = (lo.extend(0.0).to_array(), hi.extend(0.0).to_array());
        // Per lane, its unfinished rays inside the voxel (made on first need).
        let mut inside = [0u16; L];
        let mut looked = [false; L];
        for &prim in &tree.prim_refs()[node.prim_range()] {
            let tri = Triangle::new(tree.triangle(prim));
            let kept = lanes.keeps(&tri, &on);
            if C::ENABLED {
                let (mut pairs, mut culled) = (0, 0);
                for i in 0..L {
                    if on[i] {
                        pairs += 1;
                        culled += u64::from(kept[i] != Cull::Kept);
                        self.stats.plane_culled += u64::from(kept[i] == Cull::Plane);
                        self.stats.edge_culled += u64::from(kept[i] == Cull::Edge);
                    }
                }
                self.stats.pairs += pairs;
                counters.leaf_packets(pairs, culled);
            }
            let record = &self.records[prim as usize];
            for i in 0..which.len() {
                if !on[i] || kept[i] != Cull::Kept {
                    continue;
                }
                if !looked[i] {
                    looked[i] = true;
                    let f = which[i];
                    for (q, packet) in self.packets[i].iter_mut().enumerate() {
                        let open = lanes.open[i] >> (4 * q) & 15;
                        if open == 0 {
                            continue;
                        }
                        if self.made[i] >> q & 1 == 0 {
                            let s = &self.frusta[f];
                            let rays = RayPacket::segments(&s.starts[4 * q..s.count], &s.ends[4 * q..s.count]);
                            *packet = Packet { data: T::prepare4(&rays), rays };
                            self.made[i] |= 1 << q;
                            self.stats.rays_made += u64::from(open.count_ones());
                        }
                        let (near, far) = packet.rays.clip(lo, hi);
                        inside[i] |= (near.cmple(far).bitmask() as u16 & open) << (4 * q);
                    }
                }
                let mut quads = inside[i] & lanes.open[i];
                while quads != 0 {
                    let q = quads.trailing_zeros() as usize / 4;
                    let active = quads >> (4 * q) & 15;
                    quads &= !(15 << (4 * q));
                    let packet = &self.packets[i][q];
                    let mut hit = PacketHit::new(&packet.rays);
                    counters.tests(1);
                    if C::ENABLED {
                        self.stats.ray_tests += 1;
                    }
                    let found = record.intersect4(&packet.rays, &packet.data, lane_mask(active), &mut hit, prim);
                    let found = (found.bitmask() as u16 & active) << (4 * q);
                    self.blocked[i] |= found;
                    lanes.open[i] &= !found;
                }
                if lanes.open[i] == 0 {
                    on[i] = false;
                }
            }
            if on.iter().all(|&o| !o) {
                break;
            }
        }
        if lanes.open.iter().all(|&o| o == 0) { Flow::Stop } else { Flow::Continue }
    }

    #[inline(always)]
    fn resume(&mut self, span: Span<L>) -> Option<Span<L>> {
        Some(span)
    }
}

/// The lanes of the bit mask `bits` (low four bits) as a `BVec4A`.
#[inline(always)]
fn lane_mask(bits: u16) -> BVec4A {
    BVec4A::new(bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0)
}

/// Four rays of a frustum as a packet, with the triangle test's per-packet data.
#[derive(Clone, Copy, Debug)]
struct Packet<D> {
    rays: RayPacket,
    data: D,
}

/// One frustum's bound: its swept box (traversal) and its apex and ball (culling).
#[derive(Clone, Copy, Debug)]
struct Lane {
    axes: [SweptAxis; 3],
    /// The swept box's padding, which the voxels get too for the rays' slab test.
    pad: f32,
    apex: Vec3,
    centre: Vec3,
    /// The ball's radius, margin included.
    radius: f32,
    margin: f32,
}

impl Lane {
    /// The bound of `s`, or `None` when a segment is not a finite, valid ray or the segments
    /// share no end.
    fn new(s: &Segments, bounds: &Aabb) -> Option<Lane> {
        let (starts, ends) = (&s.starts[..s.count], &s.ends[..s.count]);
        if s.count == 0 {
            return None;
        }
        // What `Ray::segment(a, b).is_valid()` asks: finite ends, a non-zero and
        // finite direction.
        for (&a, &b) in starts.iter().zip(ends) {
            let d = b - a;
            if !(a.is_finite() && d.is_finite()) || d == Vec3::ZERO {
                return None;
            }
        }
        let same = |v: &[Vec3]| v.iter().all(|p| p.to_array().map(f32::to_bits) == v[0].to_array().map(f32::to_bits));
        let (apex, others) = if same(starts) {
            (starts[0], ends)
        } else if same(ends) {
            (ends[0], starts)
        } else {
            return None;
        };
        let boxed = |v: &[Vec3]| v.iter().fold(Aabb::new(Vec3::INFINITY, Vec3::NEG_INFINITY), |b, &p| b.grow(p));
        let (a, b) = (boxed(starts), boxed(ends));
        let pad = pad(bounds, &a, &b);
        let ball = boxed(others);
        let margin = margin(bounds, &ball, apex);
        let centre = (ball.min + ball.max) * 0.5;
        let radius = (ball.max - ball.min).length() * 0.5 + margin;
        Some(Lane { axes: swept_axes(&a, &b, pad), pad, apex, centre, radius, margin })
    }
}

/// The culling margin, a length: `2^-14` of the largest coordinate magnitude of the tree's
/// box, the ball's box and the apex (plus the smallest normal float). The single-ray
/// triangle tests round within a few ulps of those magnitudes (`2^-21` and below), so a
/// segment that stays this far from a triangle is one they never hit.
fn margin(bounds: &Aabb, ball: &Aabb, apex: Vec3) -> f32 {
    let m = [bounds.min, bounds.max, ball.min, ball.max, apex].iter().fold(0.0f32, |m, v| m.max(v.abs().max_element()));
    m * (1.0 / 16384.0) + f32::MIN_POSITIVE
}

/// Relative bound of the rounding of the culling tests' products: `2^-17`, far above the
/// few ulps (`2^-22` each) of a cross product and a dot product of `f32` differences.
const ROUNDING: f32 = 1.0 / 131072.0;

/// The lengths (1-norms) between which the culling tests run: their products of three
/// factors stay far inside the normal `f32` range, so the relative rounding bounds hold.
const SMALLEST: f32 = 1e-9;
const LARGEST: f32 = 1e9;

/// A triangle as the culling tests read it.
#[derive(Clone, Copy, Debug)]
struct Triangle {
    v: [Vec3; 3],
    /// `(b - a) x (c - a)`, its length, and the rounding bound of a product with it per unit
    /// of the other factor's 1-norm.
    n: Vec3,
    n_len: f32,
    n_err: f32,
}

impl Triangle {
    #[inline(always)]
    fn new(v: [Vec3; 3]) -> Triangle {
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        let n = e1.cross(e2);
        let norm1 = |x: Vec3| x.abs().element_sum();
        Triangle { v, n, n_len: n.length(), n_err: ROUNDING * norm1(e1) * norm1(e2) }
    }
}

/// What the culling tests decided for a lane and a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cull {
    /// Some segment may meet the triangle.
    Kept,
    /// No segment crosses the triangle's plane.
    Plane,
    /// Every segment passes outside one of the triangle's edges.
    Edge,
}

/// `L` frusta's bounds in structure-of-arrays form, lane `i` frustum `i`.
#[derive(Clone, Copy, Debug)]
struct Lanes<const L: usize> {
    /// Per axis: `lo0`, `lo_slope`, `lo_inv`, `hi0`, `hi_slope`, `hi_inv` of each lane.
    axes: [[[f32; L]; 6]; 3],
    apex: [[f32; L]; 3],
    centre: [[f32; L]; 3],
    radius: [f32; L],
    margin: [f32; L],
    pad: [f32; L],
    /// The rays not yet blocked (bit `k`: ray `k`); 0 for an unused lane.
    open: [u16; L],
}

impl<const L: usize> Lanes<L> {
    fn empty() -> Self {
        Lanes {
            axes: [[[0.0; L]; 6]; 3],
            apex: [[0.0; L]; 3],
            centre: [[0.0; L]; 3],
            radius: [0.0; L],
            margin: [0.0; L],
            pad: [0.0; L],
            open: [0; L],
        }
    }

    fn set(&mut self, i: usize, lane: &Lane, count: usize) {
        for k in 0..3 {
            let a = lane.axes[k];
            for (f, v) in [a.lo0, a.lo_slope, a.lo_inv, a.hi0, a.hi_slope, a.hi_inv].into_iter().enumerate() {
                self.axes[k][f][i] = v;
            }
            self.apex[k][i] = lane.apex[k];
            self.centre[k][i] = lane.centre[k];
        }
        self.radius[i] = lane.radius;
        self.margin[i] = lane.margin;
        self.pad[i] = lane.pad;
        self.open[i] = if count == FRUSTUM_RAYS { u16::MAX } else { (1u16 << count) - 1 };
    }

    /// Lane `i`'s share of `[0, 1]` inside the box `lo..hi`.
    fn clip(&self, i: usize, lo: Vec3, hi: Vec3) -> (f32, f32) {
        let (mut s0, mut s1) = (0.0f32, 1.0f32);
        for k in 0..3 {
            let f = |n: usize| self.axes[k][n][i];
            let axis = SweptAxis { lo0: f(0), lo_slope: f(1), lo_inv: f(2), hi0: f(3), hi_slope: f(4), hi_inv: f(5) };
            (s0, s1) = axis.below(s0, s1, hi[k]);
            (s0, s1) = axis.above(s0, s1, lo[k]);
        }
        (s0, s1)
    }

    /// Every lane's interval of `at` cut by the plane `x_k = p`: the lower child's share (where
    /// the sweep's low side is below `p`) into `lower`, the upper child's into `upper`
    /// (`SweptAxis::below` and `above`, lane by lane; an empty share has `s0 > s1`).
    #[inline(always)]
    fn split(&self, k: usize, p: f32, at: &Span<L>, lower: &mut Span<L>, upper: &mut Span<L>) {
        let [lo0, lo_slope, lo_inv, hi0, hi_slope, hi_inv] = &self.axes[k % 3];
        for i in 0..L {
            let (s0, s1) = (at.s0[i], at.s1[i]);
            // A NaN cut (0 * inf) keeps the interval: the comparisons below are false.
            let t = (p - lo0[i]) * lo_inv[i];
            let mut l1 = if lo_slope[i] > 0.0 && t < s1 { t } else { s1 };
            let l0 = if lo_slope[i] < 0.0 && t > s0 { t } else { s0 };
            if lo_slope[i] == 0.0 && lo0[i] > p {
                l1 = f32::NEG_INFINITY;
            }
            let t = (p - hi0[i]) * hi_inv[i];
            let u0 = if hi_slope[i] > 0.0 && t > s0 { t } else { s0 };
            let mut u1 = if hi_slope[i] < 0.0 && t < s1 { t } else { s1 };
            if hi_slope[i] == 0.0 && hi0[i] < p {
                u1 = f32::NEG_INFINITY;
            }
            lower.s0[i] = l0;
            lower.s1[i] = l1;
            upper.s0[i] = u0;
            upper.s1[i] = u1;
        }
    }

    /// The plane and edge tests of `tri` for every lane that is `on`, written lane by lane
    /// without branches so that the loop runs in SIMD lanes.
    #[inline(always)]
    fn keeps(&self, tri: &Triangle, on: &[bool; L]) -> [Cull; L] {
        let [a, b, c] = tri.v;
        let (n, n_len, n_err) = (tri.n, tri.n_len, tri.n_err);
        let edges = [(a, b - a), (b, c - b), (c, a - c)];
        let edge_norms = edges.map(|(_, e)| e.x.abs() + e.y.abs() + e.z.abs());
        let tri_in_range = edge_norms.iter().all(|&l| (SMALLEST..=LARGEST).contains(&l));
        let mut out = [Cull::Kept; L];
        for i in 0..L {
            let (px, py, pz) = (self.apex[0][i], self.apex[1][i], self.apex[2][i]);
            let (cx, cy, cz) = (self.centre[0][i], self.centre[1][i], self.centre[2][i]);
            let (radius, margin) = (self.radius[i], self.margin[i]);
            // Signed distances (times |n|) of the apex and the ball's centre from the
            // triangle's plane, each with its rounding bound.
            let (ax, ay, az) = (px - a.x, py - a.y, pz - a.z);
            let (bx, by, bz) = (cx - a.x, cy - a.y, cz - a.z);
            let d_apex = n.x * ax + n.y * ay + n.z * az;
            let d_centre = n.x * bx + n.y * by + n.z * bz;
            let e_apex = n_err * (ax.abs() + ay.abs() + az.abs());
            let e_centre = n_err * (bx.abs() + by.abs() + bz.abs());
            let slack = margin * n_len;
            let ball = radius * n_len * (1.0 + ROUNDING) + slack;
            // Far from the `f32` range's ends (products of three lengths neither underflow
            // nor overflow), where the rounding bounds hold; elsewhere nothing is culled.
            let lengths = [ax.abs() + ay.abs() + az.abs(), bx.abs() + by.abs() + bz.abs(), radius, edge_norms[0]];
            let in_range = lengths.iter().all(|&l| (SMALLEST..=LARGEST).contains(&l)) && tri_in_range;
            let apex_clear = in_range && d_apex.abs() > slack + e_apex;
            let above = d_apex > 0.0 && d_centre - ball > e_centre;
            let below = d_apex < 0.0 && d_centre + ball < -e_centre;
            let plane = apex_clear && (above || below);
            // Edge planes through the apex: the triangle lies on the side of each where its
            // third vertex is, the side of sign `-d_apex` for edges taken a->b->c. A segment
            // crosses the triangle's plane no nearer the apex than the fraction `reach` of
            // its length, so a margin of `margin / reach` at the ball keeps the crossing
            // `margin` outside the edge.
            let inside = if d_apex > 0.0 { -1.0 } else { 1.0 };
            let reach = d_apex.abs() / (d_apex.abs() + d_centre.abs() + ball + e_centre);
            let wide = radius + margin / reach;
            let (tx, ty, tz) = (cx - px, cy - py, cz - pz);
            let span = tx.abs() + ty.abs() + tz.abs() + wide;
            let mut edge = false;
            for ((v0, e), e_norm) in edges.iter().zip(edge_norms) {
                let (fx, fy, fz) = (v0.x - px, v0.y - py, v0.z - pz);
                let (wx, wy, wz) = (fy * e.z - fz * e.y, fz * e.x - fx * e.z, fx * e.y - fy * e.x);
                let len = (wx * wx + wy * wy + wz * wz).sqrt();
                let err = ROUNDING * (fx.abs() + fy.abs() + fz.abs()) * e_norm * span;
                let side = inside * (wx * tx + wy * ty + wz * tz);
                edge |= side + wide * len * (1.0 + ROUNDING) + err < 0.0;
            }
            let edge = apex_clear && edge;
            out[i] = if !on[i] || !(plane || edge) {
                Cull::Kept
            } else if plane {
                Cull::Plane
            } else {
                Cull::Edge
            };
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{self, Rng, soup, trees};

    type Frustum = (Vec<Vec3>, Vec<Vec3>);

    /// Every ray's answer, at every lane width, equals the single ray's; the statistics of
    /// the widest trace.
    fn check(tree: &KdTree, frusta: &[Frustum]) -> LaneStats {
        let mut stats = LaneStats::default();
        for width in [LaneWidth::Scalar, LaneWidth::Four, LaneWidth::Eight, LaneWidth::Sixteen] {
            let mut lanes = LaneFrusta::new();
            for (starts, ends) in frusta {
                lanes.push(starts, ends);
            }
            let mut counts = kdtree::Counts::default();
            lanes.trace(tree, width, &mut counts);
            for (f, ((starts, ends), &got)) in frusta.iter().zip(lanes.blocked()).enumerate() {
                for (k, (&a, &b)) in starts.iter().zip(ends).enumerate() {
                    let ray = Ray::segment(a, b);
                    assert_eq!(got >> k & 1 != 0, tree.occluded(&ray), "{width:?} frustum {f} ray {k}: {ray:?}");
                }
                assert_eq!(u32::from(got) >> starts.len(), 0, "no answer beyond the rays");
            }
            stats = lanes.stats();
        }
        stats
    }

    /// A point's 16 rays to samples on a disc of `radius` around `light` facing it.
    fn soft(p: Vec3, light: Vec3, radius: f32) -> Frustum {
        let w = (light - p).normalize();
        let u = w.any_orthonormal_vector();
        let v = w.cross(u);
        let ends = (0..16)
            .map(|k| {
                let (a, b) = ((k % 4) as f32 / 1.5 - 1.0, (k / 4) as f32 / 1.5 - 1.0);
                light + radius * 0.7 * (a * u + b * v)
            })
            .collect();
        (vec![p; 16], ends)
    }

    /// 16 points of the box `lo..hi` to one point light.
    fn hard(rng: &mut Rng, lo: Vec3, hi: Vec3, light: Vec3) -> Frustum {
        ((0..16).map(|_| rng.vec(lo, hi)).collect(), vec![light; 16])
    }

    #[test]
    fn soft_and_hard_frusta_of_random_soups_match_single_rays() {
        let mut rng = Rng(0x1a7e_f00d);
        let (mut blocked, mut total) = (0, 0);
        let mut stats = LaneStats::default();
        for _ in 0..8 {
            let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
            let (positions, triangles) = soup(&mut rng, 300, lo, hi);
            let light = rng.vec(Vec3::splat(-1.5), Vec3::splat(1.5));
            let radius = 0.02 + rng.next() * 0.3;
            let c = rng.vec(lo, hi);
            let mut frusta: Vec<Frustum> = (0..13).map(|_| soft(rng.vec(c - 0.2, c + 0.2), light, radius)).collect();
            frusta.extend((0..5).map(|_| {
                let q = rng.vec(lo, hi);
                hard(&mut rng, q - 0.1, q + 0.1, light)
            }));
            for tree in trees(&positions, &triangles) {
                let s = check(&tree, &frusta);
                stats.plane_culled += s.plane_culled;
                stats.edge_culled += s.edge_culled;
                stats.pairs += s.pairs;
                for (starts, ends) in &frusta {
                    for (&a, &b) in starts.iter().zip(ends) {
                        blocked += usize::from(tree.occluded(&Ray::segment(a, b)));
                        total += 1;
                    }
                }
            }
        }
        // Both answers occur, and both tests cull, so the comparison means something.
        assert!(blocked > total / 10 && blocked < total * 9 / 10, "{blocked} of {total}");
        assert!(stats.plane_culled > 0 && stats.edge_culled > 0, "{stats:?}");
        assert!(stats.plane_culled + stats.edge_culled < stats.pairs, "{stats:?}");
    }

    #[test]
    fn frusta_far_from_the_origin_match_single_rays() {
        let mut rng = Rng(77);
        for offset in [Vec3::new(1.0e5, -2.0e5, 3.0e5), Vec3::splat(1.0e6), Vec3::splat(-1.0e3)] {
            let (positions, triangles) = soup(&mut rng, 300, offset - 10.0, offset + 10.0);
            for tree in trees(&positions, &triangles) {
                let light = rng.vec(offset - 12.0, offset + 12.0);
                let frusta: Vec<Frustum> =
                    (0..12).map(|_| soft(rng.vec(offset - 8.0, offset + 8.0), light, 0.5)).collect();
                check(&tree, &frusta);
            }
        }
        // Tiny coordinates, down to where products of lengths underflow (found by the
        // `traversal` fuzz target).
        for scale in [1e-3f32, 1e-20, 1e-27] {
            let (positions, triangles) = soup(&mut rng, 200, Vec3::splat(-scale), Vec3::splat(scale));
            for tree in trees(&positions, &triangles) {
                let frusta: Vec<Frustum> = (0..12)
                    .map(|_| {
                        soft(rng.vec(Vec3::splat(-scale), Vec3::splat(scale)), Vec3::splat(2.0 * scale), 0.1 * scale)
                    })
                    .collect();
                check(&tree, &frusta);
            }
        }
    }

    /// The shared grid of quads, with a flat (zero-area) triangle and one with a repeated
    /// vertex.
    fn grid() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (mut positions, mut triangles) = test_support::grid();
        let base = positions.len() as u32;
        positions.extend([Vec3::new(1.0, 1.5, 1.0), Vec3::new(3.0, 1.5, 3.0), Vec3::new(2.0, 1.5, 2.0)]);
        triangles.push([base, base + 1, base + 2]);
        triangles.push([base, base, base + 1]);
        (positions, triangles)
    }

    #[test]
    fn hard_cases_match_single_rays() {
        let (positions, triangles) = grid();
        for tree in trees(&positions, &triangles) {
            // Shading points on the quads' planes (on split planes); the light on a split
            // plane (y = 2) inside the scene's box, and at a quad's corner.
            for light in [Vec3::new(2.5, 2.0, 2.5), Vec3::new(3.0, 2.0, 3.0), Vec3::new(4.8, 5.0, 4.8)] {
                let mut frusta = Vec::new();
                for i in 0..8 {
                    for j in 0..8 {
                        let p = Vec3::new(i as f32 * 0.7, 1.0, j as f32 * 0.7);
                        frusta.push(soft(p, light, 0.4));
                        // A point on the quads' plane y = 2, facing away from the light
                        // below it.
                        frusta.push(soft(Vec3::new(p.x, 2.0, p.z), light - Vec3::Y * 3.0, 0.3));
                    }
                }
                check(&tree, &frusta);
                // Hard shadows from 4x4 blocks of points on split planes.
                let mut rng = Rng(5);
                let frusta: Vec<Frustum> = (0..12)
                    .map(|i| {
                        let p = Vec3::new(i as f32 * 0.4, 1.0, 0.5);
                        hard(&mut rng, p, p + Vec3::new(0.3, 0.0, 0.3), light)
                    })
                    .collect();
                check(&tree, &frusta);
                // Grazing rays along the quads' plane y = 1, with zero direction
                // components, and rays whose far end lies exactly on an occluder (y = 2).
                let grazing: Vec<Frustum> = (0..4)
                    .map(|i| {
                        let p = Vec3::new(-0.5, 1.0, i as f32 * 0.37);
                        let ends = (0..16).map(|k| Vec3::new(6.5, 1.0, k as f32 * 0.3)).collect();
                        (vec![p; 16], ends)
                    })
                    .collect();
                check(&tree, &grazing);
                let on_occluder: Vec<Frustum> = (0..4)
                    .map(|i| {
                        let p = Vec3::new(0.2 + i as f32 * 0.9, 0.5, 2.3);
                        let ends = (0..16).map(|k| Vec3::new(p.x + (k % 4) as f32 * 0.1, 2.0, 2.3)).collect();
                        (vec![p; 16], ends)
                    })
                    .collect();
                check(&tree, &on_occluder);
            }
        }
    }

    #[test]
    fn frusta_that_cannot_be_bounded_go_ray_by_ray_and_agree() {
        let (positions, triangles) = grid();
        let tree = &trees(&positions, &triangles)[0];
        let light = Vec3::new(2.5, 6.0, 2.5);
        let mut rng = Rng(3);
        let mut frusta = vec![
            soft(Vec3::new(1.0, 0.5, 1.0), light, 0.5),
            // NaN and infinite ends.
            (vec![Vec3::NAN, Vec3::ONE], vec![light, light]),
            (vec![Vec3::ONE], vec![Vec3::new(f32::INFINITY, 1.0, 0.0)]),
            // No shared end.
            (
                (0..16).map(|_| rng.vec(Vec3::ZERO, Vec3::splat(5.0))).collect(),
                (0..16).map(|_| light + rng.vec(Vec3::ZERO, Vec3::ONE)).collect(),
            ),
            // Zero-length segments and an empty frustum.
            (vec![light; 3], vec![light; 3]),
            (Vec::new(), Vec::new()),
        ];
        frusta.push(soft(Vec3::new(3.0, 0.5, 3.0), light, 0.5));
        check(tree, &frusta);
        let mut lanes = LaneFrusta::new();
        for (s, e) in &frusta {
            lanes.push(s, e);
        }
        lanes.trace(tree, LaneWidth::Four, &mut kdtree::NoCounters);
        assert_eq!(lanes.stats().frusta, 2);
        assert_eq!(lanes.stats().single, 2 + 1 + 16 + 3);
    }

    #[test]
    fn culling_spares_the_rays_of_lit_points() {
        // Points under an open sky: the frusta reach leaves, but every triangle there is
        // culled before any ray is made.
        let (positions, triangles) = grid();
        let tree = &trees(&positions, &triangles)[0];
        let light = Vec3::new(2.5, 9.0, 2.5);
        // Points over the quads at y = 0 and y = 1 of the first two cells, below the top of
        // the scene's box (y = 2.8).
        let frusta: Vec<Frustum> = (0..8)
            .map(|i| soft(Vec3::new(0.1 + (i % 4) as f32 * 0.2 + (i / 4) as f32, 1.9, 0.4), light, 0.3))
            .collect();
        let stats = check(tree, &frusta);
        assert!(stats.leaves > 0 && stats.pairs > 0, "{stats:?}");
        assert_eq!(stats.plane_culled + stats.edge_culled, stats.pairs, "{stats:?}");
        assert_eq!(stats.rays_made, 0, "{stats:?}");
    }
}
