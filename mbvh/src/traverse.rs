//! Single-ray traversal of the multi-branching BVH (Wald, Benthin & Boulos 2008, section 5):
//! one ray, the SIMD lanes spent on the `W` children of a node ([`BoxTest`]) and the four
//! triangles of a leaf. One loop per query, written once for every width and node test.
//!
//! - **Closest hit** ([`Traversal::intersect_counted`]): depth-first with a fixed stack of
//!   `(node, entry distance)`; the children a ray enters are visited nearest first (the
//!   others pushed farthest first), and an entry whose distance is beyond the closest hit so
//!   far is dropped when popped. The paper keeps an unsorted active list scanned 16 wide for
//!   the nearest entry (section 5.3); with the 4, 8 or 16 children of our SIMD nodes the
//!   entries are taken from the hit mask bit by bit and insertion-sorted straight onto the
//!   stack (two to `W` of them), which gives the same front-to-back order within a node
//!   without a scan per pop.
//! - **Any hit** ([`Traversal::occluded_counted`]): the same descent without ordering, and
//!   the first hit ends it.
//! - **Prefetch**: where a ray enters two or more children (closest hit), or any child (any
//!   hit), each is prefetched into the cache as it goes on the stack (every cache line of
//!   the node or leaf block, x86-64 `prefetcht0`), so that a deferred child's memory latency
//!   overlaps the work on the nearer ones. Incoherent rays wait on memory: the first reads
//!   of a node's planes and of a leaf block were the hottest instructions of diffuse rays,
//!   and the prefetch traces them 1.03-1.08x as fast, AO rays 1.01-1.02x, and coherent
//!   primary and shadow rays 0.98-1.00x (`docs/results/incoherent-mbvh.md#the-deferred-children-prefetched`).
//!
//! - **The forward test**: a ray whose interval starts at or after its origin (`t_min >= 0`)
//!   is walked with its node test's [`BoxTest::hit_forward`], which widens in the ray's
//!   reciprocals instead of after the reductions (`crate::boxtest`'s **The forward test**);
//!   the choice is made once per query, each walk compiled for one form.
//!
//! Both are generic over the leaf block (the intersector), the node test ([`BoxTest`]: 4-wide
//! SSE, 8-wide AVX2, 16-wide AVX-512, or the scalar test of any width) and over `SIMD` leaves; the stacks are
//! sized for the node's width (`node::stack_capacity`). A test enters the loops through its
//! [`BoxTest::closest`] / [`BoxTest::any`] ([`TraversalLoop`]), so that a test with target
//! features runs them compiled with those. The scalar twin ([`Traversal::intersect_scalar`])
//! runs the test's scalar twin and the scalar triangle records one by one, and must give the
//! same answers bit for bit (tested in `tests/oracle.rs`). No allocation (the stack is a fixed
//! array, left uninitialised: only entries below the stack pointer are read), no locking, no
//! dynamic dispatch; counting compiles away with `kdtree::NoCounters`.

use kdtree::{Counters, Hit, Ray};

use crate::boxtest::{self, BoxTest, TraversalLoop};
use crate::leaf::{LANES, LeafBlock};
use crate::node::{LEAF, MultiNode, StackArray};

/// The tree bound to one intersector's leaf blocks and one node test: what a method traces.
#[derive(Debug)]
pub struct Traversal<'a, B, K: BoxTest> {
    pub(crate) nodes: &'a [K::Node],
    pub(crate) blocks: &'a [B],
    pub(crate) test: K,
}

impl<B, K: BoxTest> Clone for Traversal<'_, B, K> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<B, K: BoxTest> Copy for Traversal<'_, B, K> {}

/// Whether a ray can hit anything: finite origin and direction, a non-NaN interval. Others
/// get "no hit" (as from `kdtree::KdTree::intersect`).
#[inline(always)]
pub(crate) fn traceable(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite() && !ray.t_min.is_nan() && !ray.t_max.is_nan()
}

impl<'a, B: LeafBlock, K: BoxTest> Traversal<'a, B, K> {
    /// The tree of `nodes` (the root first) with the blocks `blocks` (one of its
    /// intersectors) and the test `test`.
    pub(crate) fn new(nodes: &'a [K::Node], blocks: &'a [B], test: K) -> Self {
        Traversal { nodes, blocks, test }
    }

    /// The same tree and blocks traversed with another node test of the same width (e.g.
    /// [`crate::Avx2`] instead of the portable [`crate::Scalar8`], [`crate::Avx512`] instead
    /// of [`crate::Scalar16`]).
    pub fn with_test<T: BoxTest<Node = K::Node>>(self, test: T) -> Traversal<'a, B, T> {
        Traversal { nodes: self.nodes, blocks: self.blocks, test }
    }

    /// The node test.
    pub fn test(&self) -> K {
        self.test
    }

    /// The closest hit of `ray` in `[t_min, t_max]` (SIMD node and leaf tests).
    #[inline]
    pub fn intersect_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        self.test.closest(self, ray, counters)
    }

    /// Whether anything is hit in `[t_min, t_max]` (SIMD node and leaf tests).
    #[inline]
    pub fn occluded_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        self.test.any(self, ray, counters)
    }

    /// The scalar twin of [`Traversal::intersect_counted`]: the node test's scalar twin and
    /// the scalar triangle tests.
    pub fn intersect_scalar<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        self.with_test(self.test.twin()).closest_loop::<false, C>(ray, counters)
    }

    /// The scalar twin of [`Traversal::occluded_counted`].
    pub fn occluded_scalar<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        self.with_test(self.test.twin()).any_loop::<false, C>(ray, counters)
    }

    /// The closest-hit loop; `SIMD`: the leaves' SIMD test, else the scalar records. Called
    /// through [`BoxTest::closest`] (in the test's target features).
    #[inline(always)]
    fn closest_loop<const SIMD: bool, C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        if !traceable(ray) {
            return None;
        }
        let data = B::prepare(ray);
        self.closest_from::<SIMD, C>(0, ray, &data, ray.t_max, counters)
    }

    /// The closest-hit loop from node `start` (an inner node or `LEAF | block`) with the
    /// interval `[ray.t_min, t_max]`, for a traceable `ray` whose leaf data is `data`: the
    /// closest hit below `start`, `None` if none is at most `t_max`. The whole query is
    /// `closest_from(0, ray, .., ray.t_max)`; the packet traversal ([`crate::packet`]) finishes
    /// its lanes with it.
    #[inline(always)]
    pub(crate) fn closest_from<const SIMD: bool, C: Counters>(
        &self,
        start: u32,
        ray: &Ray,
        data: &B::RayData,
        t_max: f32,
        counters: &mut C,
    ) -> Option<Hit> {
        if boxtest::forward(ray) {
            self.closest_walk::<SIMD, true, C>(start, ray, data, t_max, counters)
        } else {
            self.closest_walk::<SIMD, false, C>(start, ray, data, t_max, counters)
        }
    }

    /// The node test of the walks: [`BoxTest::hit_forward`] where `FORWARD` (a ray with
    /// `t_min >= 0`, chosen once per query), else [`BoxTest::hit`].
    #[inline(always)]
    fn node_test<const FORWARD: bool>(
        &self,
        node: &K::Node,
        rb: &K::RayData,
        t_min: f32,
        t_max: f32,
    ) -> (u32, K::Nears) {
        if FORWARD { self.test.hit_forward(node, rb, t_min, t_max) } else { self.test.hit(node, rb, t_min, t_max) }
    }

    /// The body of [`Traversal::closest_from`], with the node test chosen by `FORWARD`.
    #[inline(always)]
    fn closest_walk<const SIMD: bool, const FORWARD: bool, C: Counters>(
        &self,
        start: u32,
        ray: &Ray,
        data: &B::RayData,
        t_max: f32,
        counters: &mut C,
    ) -> Option<Hit> {
        let rb = K::prepare(ray);
        // Invariant: `stack[..sp]` is initialised.
        let mut storage = <K::Node as MultiNode>::Stack::<(u32, f32)>::uninit();
        let stack = storage.entries();
        let mut sp = 1;
        stack[0].write((start, ray.t_min));
        let mut best: Option<Hit> = None;
        let mut t_max = t_max;
        while sp > 0 {
            sp -= 1;
            // SAFETY: below the stack pointer (invariant).
            let (mut child, near) = unsafe { stack[sp].assume_init() };
            if near > t_max {
                continue;
            }
            loop {
                if child & LEAF != 0 {
                    let block = &self.blocks[(child & !LEAF) as usize];
                    counters.leaf();
                    if C::ENABLED {
                        counters.tests(block_count(block));
                    }
                    let hit = if SIMD { block.closest(ray, data, t_max) } else { block.closest_scalar(ray, t_max) };
                    if let Some((lane, t, u, v)) = hit {
                        t_max = t;
                        best = Some(Hit { t, u, v, prim: block.record_prim(lane) });
                    }
                    break;
                }
                counters.node();
                let node = &self.nodes[child as usize];
                let (mut mask, nears) = self.node_test::<FORWARD>(node, &rb, ray.t_min, t_max);
                if mask == 0 {
                    break;
                }
                let slots = node.children();
                if mask & (mask - 1) == 0 {
                    child = slots[mask.trailing_zeros() as usize];
                    continue;
                }
                // Two or more children: insertion-sorted onto the stack by entry distance,
                // farthest lowest, so the nearest is on top (equal distances: the higher slot
                // above); it is taken at once.
                let base = sp;
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    self.prefetch(slots[i]);
                    let entry = (slots[i], nears[i]);
                    let mut j = sp;
                    // SAFETY: `base <= j - 1 < sp`: below the stack pointer (invariant).
                    while j > base && unsafe { stack[j - 1].assume_init() }.1 < entry.1 {
                        stack[j] = stack[j - 1];
                        j -= 1;
                    }
                    stack[j].write(entry);
                    sp += 1;
                }
                sp -= 1;
                // SAFETY: below the old stack pointer, written above.
                child = unsafe { stack[sp].assume_init() }.0;
            }
        }
        best
    }

    /// The any-hit loop (see [`Traversal::closest_loop`]).
    #[inline(always)]
    fn any_loop<const SIMD: bool, C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        if !traceable(ray) {
            return false;
        }
        let data = B::prepare(ray);
        self.any_from::<SIMD, C>(0, ray, &data, counters)
    }

    /// The any-hit loop from node `start` (see [`Traversal::closest_from`]): whether anything
    /// below `start` is hit in `[ray.t_min, ray.t_max]`.
    #[inline(always)]
    pub(crate) fn any_from<const SIMD: bool, C: Counters>(
        &self,
        start: u32,
        ray: &Ray,
        data: &B::RayData,
        counters: &mut C,
    ) -> bool {
        if boxtest::forward(ray) {
            self.any_walk::<SIMD, true, C>(start, ray, data, counters)
        } else {
            self.any_walk::<SIMD, false, C>(start, ray, data, counters)
        }
    }

    /// The body of [`Traversal::any_from`], with the node test chosen by `FORWARD`.
    #[inline(always)]
    fn any_walk<const SIMD: bool, const FORWARD: bool, C: Counters>(
        &self,
        start: u32,
        ray: &Ray,
        data: &B::RayData,
        counters: &mut C,
    ) -> bool {
        let rb = K::prepare(ray);
        // Invariant: `stack[..sp]` is initialised.
        let mut storage = <K::Node as MultiNode>::Stack::<u32>::uninit();
        let stack = storage.entries();
        let mut sp = 1;
        stack[0].write(start);
        while sp > 0 {
            sp -= 1;
            // SAFETY: below the stack pointer (invariant).
            let child = unsafe { stack[sp].assume_init() };
            if child & LEAF != 0 {
                let block = &self.blocks[(child & !LEAF) as usize];
                counters.leaf();
                if C::ENABLED {
                    counters.tests(block_count(block));
                }
                let hit =
                    if SIMD { block.any(ray, data, ray.t_max) } else { block.closest_scalar(ray, ray.t_max).is_some() };
                if hit {
                    return true;
                }
                continue;
            }
            counters.node();
            let node = &self.nodes[child as usize];
            let (mut mask, _) = self.node_test::<FORWARD>(node, &rb, ray.t_min, ray.t_max);
            let slots = node.children();
            while mask != 0 {
                self.prefetch(slots[mask.trailing_zeros() as usize]);
                stack[sp].write(slots[mask.trailing_zeros() as usize]);
                sp += 1;
                mask &= mask - 1;
            }
        }
        false
    }
}

impl<B, K: BoxTest> Traversal<'_, B, K> {
    /// Starts loading `child` (an inner node, or `LEAF | block`) into the cache without
    /// waiting for it ([`prefetch`]; the module documentation's **Prefetch**).
    #[inline(always)]
    fn prefetch(&self, child: u32) {
        // No bounds check: a prefetch of any address is harmless.
        if child & LEAF != 0 {
            prefetch(self.blocks.as_ptr().wrapping_add((child & !LEAF) as usize));
        } else {
            prefetch(self.nodes.as_ptr().wrapping_add(child as usize));
        }
    }
}

/// Asks the CPU to bring every cache line of the `T` at `item` into the L1 cache (x86-64
/// `prefetcht0`: a hint, which waits for nothing and faults on no address); nothing on other
/// architectures.
#[inline(always)]
fn prefetch<T>(item: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        for offset in (0..size_of::<T>()).step_by(64) {
            // SAFETY: a prefetch accesses no memory (it cannot fault, whatever the address),
            // and SSE, its instruction set, is part of every x86-64 CPU.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(item.cast::<i8>().wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = item;
}

impl<B: LeafBlock, K: BoxTest> TraversalLoop for Traversal<'_, B, K> {
    #[inline(always)]
    fn closest<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        self.closest_loop::<true, C>(ray, counters)
    }

    #[inline(always)]
    fn any<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        self.any_loop::<true, C>(ray, counters)
    }
}

/// The triangles in a block (its used lanes), for the counters.
pub(crate) fn block_count<B: LeafBlock>(block: &B) -> u64 {
    (0..LANES).filter(|&l| block.record_prim(l) != u32::MAX).count() as u64
}
