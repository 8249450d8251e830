//! Single-ray traversal of the 4-wide BVH (Wald, Benthin & Boulos 2008, section 5): one ray,
//! the SIMD lanes spent on the four children of a node and the four triangles of a leaf.
//!
//! - **Closest hit** ([`Traversal::intersect_counted`]): depth-first with a fixed stack of
//!   `(node, entry distance)`; the children a ray enters are visited nearest first (the
//!   others pushed farthest first), and an entry whose distance is beyond the closest hit so
//!   far is dropped when popped. The paper keeps an unsorted active list scanned 16 wide for
//!   the nearest entry (section 5.3); with at most four children per node the sort of two
//!   to four entries is cheaper on this CPU than a scan, and gives the same front-to-back
//!   order within a node.
//! - **Any hit** ([`Traversal::occluded_counted`]): the same descent without ordering, and
//!   the first hit ends it.
//!
//! Both are generic over the leaf block (the intersector) and over `SIMD`: `false` is the
//! scalar twin (`node::hit4_scalar`, the scalar triangle records one by one), which must give
//! the same answers bit for bit (tested in `tests/oracle.rs`). No allocation, no locking, no
//! dynamic dispatch; counting compiles away with `kdtree::NoCounters`.

use glam::Vec4;
use kdtree::{Counters, Hit, Ray};

use crate::leaf::{LANES, LeafBlock};
use crate::node::{EMPTY, LEAF, Node4, RayBoxes, hit4, hit4_scalar};
use crate::{Mbvh, STACK_SIZE};

/// The tree bound to one intersector's leaf blocks: what a method traces.
#[derive(Debug)]
pub struct Traversal<'a, B> {
    pub(crate) nodes: &'a [Node4],
    pub(crate) blocks: &'a [B],
}

impl<B> Clone for Traversal<'_, B> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<B> Copy for Traversal<'_, B> {}

/// Whether a ray can hit anything: finite origin and direction, a non-NaN interval. Others
/// get "no hit" (as from `kdtree::KdTree::intersect`).
#[inline(always)]
fn traceable(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite() && !ray.t_min.is_nan() && !ray.t_max.is_nan()
}

/// The box test of `SIMD` or its scalar twin: slot mask and entry distances.
#[inline(always)]
fn boxes<const SIMD: bool>(node: &Node4, rb: &RayBoxes, ray: &Ray, t_min: f32, t_max: f32) -> (u32, [f32; 4]) {
    if SIMD {
        let (m, near): (u32, Vec4) = hit4(node, rb, t_min, t_max);
        (m, near.to_array())
    } else {
        hit4_scalar(node, ray, t_min, t_max)
    }
}

impl<'a, B: LeafBlock> Traversal<'a, B> {
    /// The tree `bvh` with the blocks `blocks` (one of its intersectors).
    pub(crate) fn new(bvh: &'a Mbvh, blocks: &'a [B]) -> Self {
        Traversal { nodes: &bvh.nodes, blocks }
    }

    /// The closest hit of `ray` in `[t_min, t_max]` (SIMD node and leaf tests).
    #[inline]
    pub fn intersect_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        self.closest::<true, C>(ray, counters)
    }

    /// Whether anything is hit in `[t_min, t_max]` (SIMD node and leaf tests).
    #[inline]
    pub fn occluded_counted<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        self.any::<true, C>(ray, counters)
    }

    /// The scalar twin of [`Traversal::intersect_counted`].
    pub fn intersect_scalar<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        self.closest::<false, C>(ray, counters)
    }

    /// The scalar twin of [`Traversal::occluded_counted`].
    pub fn occluded_scalar<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        self.any::<false, C>(ray, counters)
    }

    #[inline(always)]
    fn closest<const SIMD: bool, C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        if !traceable(ray) {
            return None;
        }
        let rb = RayBoxes::new(ray);
        let data = B::prepare(ray);
        let mut stack = [(0u32, 0.0f32); STACK_SIZE];
        let mut sp = 1;
        stack[0] = (0, ray.t_min);
        let mut best: Option<Hit> = None;
        let mut t_max = ray.t_max;
        while sp > 0 {
            sp -= 1;
            let (mut child, near) = stack[sp];
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
                    let hit = if SIMD { block.closest(ray, &data, t_max) } else { block.closest_scalar(ray, t_max) };
                    if let Some((lane, t, u, v)) = hit {
                        t_max = t;
                        best = Some(Hit { t, u, v, prim: block.record_prim(lane) });
                    }
                    break;
                }
                counters.node();
                let node = &self.nodes[child as usize];
                let (mask, nears) = boxes::<SIMD>(node, &rb, ray, ray.t_min, t_max);
                if mask == 0 {
                    break;
                }
                if mask & (mask - 1) == 0 {
                    child = node.child[(mask.trailing_zeros() & 3) as usize];
                    continue;
                }
                // Two to four children: sort by entry distance, farthest first.
                let mut order = [(EMPTY, 0.0f32); 4];
                let mut k = 0;
                for (i, &near) in nears.iter().enumerate() {
                    if mask & (1 << i) != 0 {
                        let mut j = k;
                        while j > 0 && order[j - 1].1 < near {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = (node.child[i], near);
                        k += 1;
                    }
                }
                for &entry in &order[..k - 1] {
                    stack[sp] = entry;
                    sp += 1;
                }
                child = order[k - 1].0;
            }
        }
        best
    }

    #[inline(always)]
    fn any<const SIMD: bool, C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool {
        if !traceable(ray) {
            return false;
        }
        let rb = RayBoxes::new(ray);
        let data = B::prepare(ray);
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 1;
        stack[0] = 0;
        while sp > 0 {
            sp -= 1;
            let child = stack[sp];
            if child & LEAF != 0 {
                let block = &self.blocks[(child & !LEAF) as usize];
                counters.leaf();
                if C::ENABLED {
                    counters.tests(block_count(block));
                }
                let hit = if SIMD {
                    block.any(ray, &data, ray.t_max)
                } else {
                    block.closest_scalar(ray, ray.t_max).is_some()
                };
                if hit {
                    return true;
                }
                continue;
            }
            counters.node();
            let node = &self.nodes[child as usize];
            let (mut mask, _) = boxes::<SIMD>(node, &rb, ray, ray.t_min, ray.t_max);
            while mask != 0 {
                stack[sp] = node.child[(mask.trailing_zeros() & 3) as usize];
                sp += 1;
                mask &= mask - 1;
            }
        }
        false
    }
}

/// The triangles in a block (its used lanes), for the counters.
fn block_count<B: LeafBlock>(block: &B) -> u64 {
    (0..LANES).filter(|&l| block.record_prim(l) != u32::MAX).count() as u64
}
