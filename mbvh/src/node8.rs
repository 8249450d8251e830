//! The 8-wide multi-node (Wald, Benthin & Boulos 2008, section 3, at the branching factor
//! their section 6.4 finds best by the cost metric, "somewhere between 4 and 8") and its
//! ray-box test (section 5.2) in AVX2, with a scalar twin.
//!
//! A [`Node8`] holds the boxes of up to eight children SoA: one 8-lane array per box
//! coordinate, one 256-bit AVX register each. The test is [`crate::node`]'s, eight lanes at
//! a time, with the same arithmetic in the same order: planes picked by the direction's sign
//! bit, `(p - o) * (1 / d)`, the candidate first in `max` / `min` so that a `0 * inf` NaN
//! leaves the accumulator (`vmaxps` returns its second operand when either is NaN, like
//! `maxps`), then the entry lowered and the exit raised by `WIDEN` and `TINY`. No fused
//! multiply-add: every lane rounds as [`hit8_scalar`] does, so the AVX2 test and its scalar
//! twin give the same mask and distances bit for bit (`avx2_matches_scalar_twin`).
//!
//! **AVX2 is chosen at run time.** [`Avx2::detect`] asks the CPU once
//! (`is_x86_feature_detected!("avx2")`) and returns a token only where it has AVX2; a
//! traversal made with the token ([`crate::Traversal::with_test`]) runs its whole loop in a
//! `#[target_feature(enable = "avx2")]` function (so the node test inlines into it), and no
//! check is made per ray. Without the token, or on another architecture, the 8-wide tree is
//! traversed with [`Scalar8`]. On this project's CPU (AMD Zen 1) every 256-bit operation is
//! executed as two 128-bit halves, so one 8-wide node test costs about two 4-wide ones; what
//! the wider node can save is node fetches and traversal steps, not arithmetic.

use std::fmt::Debug;

use glam::Vec3;
use kdtree::{Aabb, Counters, Hit, Ray};

use crate::leaf::LeafBlock;
use crate::node::{BoxTest, EMPTY, MultiNode, TINY, WIDEN};
use crate::traverse::Traversal;

/// The branching factor of [`Node8`].
pub const WIDTH8: usize = 8;

/// Eight lanes of one box coordinate, aligned for one 256-bit load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Lanes8(pub [f32; WIDTH8]);

/// An 8-wide multi-node: the boxes of up to eight children, SoA, and what each child is.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Node8 {
    /// Per axis `[min, max]`, each over the eight children.
    pub bounds: [[Lanes8; 2]; 3],
    /// Per slot: [`EMPTY`], a leaf (`LEAF | block`) or the index of an inner [`Node8`].
    pub child: [u32; WIDTH8],
}

impl Node8 {
    /// A node with eight empty slots (`min = +inf`, `max = -inf`: no ray enters them).
    pub fn empty() -> Node8 {
        let (inf, ninf) = (Lanes8([f32::INFINITY; WIDTH8]), Lanes8([f32::NEG_INFINITY; WIDTH8]));
        Node8 { bounds: [[inf, ninf]; 3], child: [EMPTY; WIDTH8] }
    }

    /// Sets slot `i` to `child` with box `b`.
    pub fn set(&mut self, i: usize, child: u32, b: &Aabb) {
        for axis in 0..3 {
            self.bounds[axis][0].0[i] = b.min[axis];
            self.bounds[axis][1].0[i] = b.max[axis];
        }
        self.child[i] = child;
    }

    /// The box of slot `i` (empty for an empty slot).
    pub fn child_box(&self, i: usize) -> Aabb {
        let c = |k: usize| Vec3::new(self.bounds[0][k].0[i], self.bounds[1][k].0[i], self.bounds[2][k].0[i]);
        Aabb { min: c(0), max: c(1) }
    }
}

impl MultiNode for Node8 {
    const WIDTH: usize = WIDTH8;
    type Test = Scalar8;

    fn empty() -> Node8 {
        Node8::empty()
    }

    fn set(&mut self, i: usize, child: u32, b: &Aabb) {
        Node8::set(self, i, child, b);
    }

    fn child_box(&self, i: usize) -> Aabb {
        Node8::child_box(self, i)
    }

    #[inline(always)]
    fn children(&self) -> &[u32] {
        &self.child
    }
}

/// What the 8-wide box test needs of a ray: origin, `1 / d` and per axis the near plane
/// (`0`: `min` for a positive direction, `1`: `max` for a negative one, `-0.0` included).
/// Kept scalar; the AVX2 test broadcasts them (hoisted out of the traversal loop).
#[derive(Clone, Copy, Debug)]
pub struct RayBoxes8 {
    /// The origin.
    pub o: [f32; 3],
    /// `1 / d`.
    pub inv: [f32; 3],
    /// Per axis, the near plane's index in `Node8::bounds[axis]`.
    pub near: [usize; 3],
}

impl RayBoxes8 {
    /// The box-test data of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> RayBoxes8 {
        RayBoxes8 {
            o: ray.origin.to_array(),
            inv: ray.inv_dir.to_array(),
            near: [0, 1, 2].map(|axis| usize::from(ray.dir[axis].is_sign_negative())),
        }
    }
}

/// The eight children's box test, scalar: lane by lane the arithmetic of the AVX2 test
/// (and of `node::hit4_scalar`), NaN dropped by an explicit test.
#[inline(always)]
pub fn hit8_scalar(node: &Node8, r: &RayBoxes8, t_min: f32, t_max: f32) -> (u32, [f32; WIDTH8]) {
    let mut mask = 0;
    let mut nears = [0.0; WIDTH8];
    for (i, slot) in nears.iter_mut().enumerate() {
        let (mut near, mut far) = (t_min, t_max);
        for axis in 0..3 {
            let planes = &node.bounds[axis];
            let n = (planes[r.near[axis] & 1].0[i] - r.o[axis]) * r.inv[axis];
            let f = (planes[(r.near[axis] ^ 1) & 1].0[i] - r.o[axis]) * r.inv[axis];
            if !n.is_nan() {
                near = if n > near { n } else { near };
            }
            if !f.is_nan() {
                far = if f < far { f } else { far };
            }
        }
        let near = near - (near.abs() * WIDEN + TINY);
        let far = far + (far.abs() * WIDEN + TINY);
        if near <= far {
            mask |= 1 << i;
        }
        *slot = near;
    }
    (mask, nears)
}

/// The eight children's box test in AVX2 (256-bit `vsubps`, `vmulps`, `vmaxps`, `vminps`,
/// one `vcmpps` and `vmovmskps`).
///
/// # Safety
/// The CPU must have AVX2: call it where an [`Avx2`] token exists (or from a function
/// compiled for AVX2).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub fn hit8_avx2(node: &Node8, r: &RayBoxes8, t_min: f32, t_max: f32) -> (u32, [f32; WIDTH8]) {
    use std::arch::x86_64::*;
    let load = |lanes: &Lanes8| {
        // SAFETY: `Lanes8` is eight `f32` aligned to 32 bytes.
        unsafe { _mm256_load_ps(lanes.0.as_ptr()) }
    };
    let mut near = _mm256_set1_ps(t_min);
    let mut far = _mm256_set1_ps(t_max);
    for axis in 0..3 {
        let planes = &node.bounds[axis];
        let (o, inv) = (_mm256_set1_ps(r.o[axis]), _mm256_set1_ps(r.inv[axis]));
        let n = _mm256_mul_ps(_mm256_sub_ps(load(&planes[r.near[axis] & 1]), o), inv);
        let f = _mm256_mul_ps(_mm256_sub_ps(load(&planes[(r.near[axis] ^ 1) & 1]), o), inv);
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator.
        near = _mm256_max_ps(n, near);
        far = _mm256_min_ps(f, far);
    }
    let sign = _mm256_set1_ps(-0.0);
    let (widen, tiny) = (_mm256_set1_ps(WIDEN), _mm256_set1_ps(TINY));
    let near = _mm256_sub_ps(near, _mm256_add_ps(_mm256_mul_ps(_mm256_andnot_ps(sign, near), widen), tiny));
    let far = _mm256_add_ps(far, _mm256_add_ps(_mm256_mul_ps(_mm256_andnot_ps(sign, far), widen), tiny));
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    let mut nears = Lanes8([0.0; WIDTH8]);
    // SAFETY: `Lanes8` is eight `f32` aligned to 32 bytes.
    unsafe { _mm256_store_ps(nears.0.as_mut_ptr(), near) };
    (mask, nears.0)
}

/// [`hit8_scalar`] as a [`BoxTest`]: the 8-wide tree's portable test and the scalar twin of
/// [`Avx2`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Scalar8;

impl BoxTest for Scalar8 {
    type Node = Node8;
    type RayData = RayBoxes8;
    type Nears = [f32; WIDTH8];
    type Twin = Scalar8;

    fn twin(self) -> Scalar8 {
        Scalar8
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes8 {
        RayBoxes8::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node8, r: &RayBoxes8, t_min: f32, t_max: f32) -> (u32, [f32; WIDTH8]) {
        hit8_scalar(node, r, t_min, t_max)
    }
}

/// The AVX2 box test ([`hit8_avx2`]), as a token: made only by [`Avx2::detect`] on a CPU
/// with AVX2, so a traversal holding one may run AVX2 instructions.
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _detected: (),
}

impl Avx2 {
    /// The token if this CPU has AVX2 (`is_x86_feature_detected!`), else `None` (always on
    /// architectures other than x86-64). Call it once, when a traversal is set up.
    pub fn detect() -> Option<Avx2> {
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            return Some(Avx2 { _detected: () });
        }
        None
    }
}

impl BoxTest for Avx2 {
    type Node = Node8;
    type RayData = RayBoxes8;
    type Nears = [f32; WIDTH8];
    type Twin = Scalar8;

    fn twin(self) -> Scalar8 {
        Scalar8
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes8 {
        RayBoxes8::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node8, r: &RayBoxes8, t_min: f32, t_max: f32) -> (u32, [f32; WIDTH8]) {
        avx2::hit(self, node, r, t_min, t_max)
    }

    #[inline]
    fn closest<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Avx2>, ray: &Ray, counters: &mut C) -> Option<Hit> {
        avx2::closest(tr, ray, counters)
    }

    #[inline]
    fn any<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Avx2>, ray: &Ray, counters: &mut C) -> bool {
        avx2::any(tr, ray, counters)
    }
}

/// What an [`Avx2`] token runs on x86-64: the node test, and the traversal loops compiled
/// for AVX2 (the loop, `#[inline(always)]`, and the node test inline into them, so the whole
/// descent runs with 256-bit registers and no call per node).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;

    #[inline(always)]
    pub(super) fn hit(_: Avx2, node: &Node8, r: &RayBoxes8, t_min: f32, t_max: f32) -> (u32, [f32; WIDTH8]) {
        // SAFETY: an `Avx2` exists, so `Avx2::detect` found AVX2 on this CPU.
        unsafe { hit8_avx2(node, r, t_min, t_max) }
    }

    #[inline(always)]
    pub(super) fn closest<B: LeafBlock, C: Counters>(
        tr: &Traversal<'_, B, Avx2>,
        ray: &Ray,
        counters: &mut C,
    ) -> Option<Hit> {
        // SAFETY: `tr` holds an `Avx2`, so `Avx2::detect` found AVX2 on this CPU.
        unsafe { closest_avx2(tr, ray, counters) }
    }

    #[inline(always)]
    pub(super) fn any<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Avx2>, ray: &Ray, counters: &mut C) -> bool {
        // SAFETY: `tr` holds an `Avx2`, so `Avx2::detect` found AVX2 on this CPU.
        unsafe { any_avx2(tr, ray, counters) }
    }

    #[target_feature(enable = "avx2")]
    fn closest_avx2<B: LeafBlock, C: Counters>(
        tr: &Traversal<'_, B, Avx2>,
        ray: &Ray,
        counters: &mut C,
    ) -> Option<Hit> {
        tr.closest_loop::<true, C>(ray, counters)
    }

    #[target_feature(enable = "avx2")]
    fn any_avx2<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Avx2>, ray: &Ray, counters: &mut C) -> bool {
        tr.any_loop::<true, C>(ray, counters)
    }
}

/// Elsewhere no [`Avx2`] token is ever made ([`Avx2::detect`] returns `None`); these keep
/// the type usable: the scalar test and the plain loops.
#[cfg(not(target_arch = "x86_64"))]
mod avx2 {
    use super::*;

    pub(super) fn hit(_: Avx2, node: &Node8, r: &RayBoxes8, t_min: f32, t_max: f32) -> (u32, [f32; WIDTH8]) {
        hit8_scalar(node, r, t_min, t_max)
    }

    pub(super) fn closest<B: LeafBlock, C: Counters>(
        tr: &Traversal<'_, B, Avx2>,
        ray: &Ray,
        counters: &mut C,
    ) -> Option<Hit> {
        tr.closest_loop::<true, C>(ray, counters)
    }

    pub(super) fn any<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Avx2>, ray: &Ray, counters: &mut C) -> bool {
        tr.any_loop::<true, C>(ray, counters)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn node(boxes: &[Aabb]) -> Node8 {
        let mut n = Node8::empty();
        for (i, b) in boxes.iter().enumerate() {
            n.set(i, i as u32, b);
        }
        n
    }

    fn unit(offset: Vec3) -> Aabb {
        Aabb { min: offset, max: offset + Vec3::ONE }
    }

    /// The mask of the scalar test, after checking the AVX2 test (where the CPU has it)
    /// against it bit for bit, and the 4-wide test on the first four slots.
    fn both(n: &Node8, ray: &Ray) -> u32 {
        let r = RayBoxes8::new(ray);
        let (ms, nears) = hit8_scalar(n, &r, ray.t_min, ray.t_max);
        if let Some(avx) = Avx2::detect() {
            let (m, near) = avx.hit(n, &r, ray.t_min, ray.t_max);
            assert_eq!(m, ms, "{ray:?}");
            for i in 0..WIDTH8 {
                assert_eq!(near[i].to_bits(), nears[i].to_bits(), "{ray:?} lane {i}");
            }
        }
        let mut n4 = crate::Node4::empty();
        for i in 0..4 {
            n4.set(i, n.child[i], &n.child_box(i));
        }
        let (m4, near4) = crate::node::hit4_scalar(&n4, ray, ray.t_min, ray.t_max);
        assert_eq!(m4, ms & 0xf, "{ray:?}: the 8-wide test differs from the 4-wide one");
        for i in 0..4 {
            assert_eq!(near4[i].to_bits(), nears[i].to_bits());
        }
        ms
    }

    #[test]
    fn plain_rays_enter_the_boxes_they_cross() {
        let boxes: Vec<Aabb> = (0..8).map(|i| unit(Vec3::new(2.0 * i as f32, 0.0, 0.0))).collect();
        let ray = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(&node(&boxes), &ray), 0xff);
        let short = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, 6.5);
        assert_eq!(both(&node(&boxes), &short), 0b111);
        let back = Ray::new(Vec3::new(9.5, 0.5, 0.5), -Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(&node(&boxes), &back), 0b11111);
        let above = Ray::new(Vec3::new(-1.0, 5.0, 0.5), Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(&node(&boxes), &above), 0);
    }

    #[test]
    fn empty_slots_are_never_entered() {
        let n = Node8::empty();
        for d in [Vec3::X, -Vec3::X, Vec3::new(0.0, 0.0, 1.0), Vec3::new(-0.0, 1.0, -0.0), Vec3::ONE] {
            for o in [Vec3::ZERO, Vec3::splat(1e30), Vec3::splat(-1e30)] {
                assert_eq!(both(&n, &Ray::new(o, d, f32::NEG_INFINITY, f32::INFINITY)), 0);
            }
        }
    }

    #[test]
    fn rays_in_face_planes_enter_the_box() {
        // Zero direction components with the origin exactly on a face plane: 0 * inf, in
        // every lane position.
        for slot in 0..WIDTH8 {
            let mut boxes = vec![unit(Vec3::splat(50.0)); WIDTH8];
            boxes[slot] = unit(Vec3::ZERO);
            let n = node(&boxes);
            for (o, d) in [
                (Vec3::new(-1.0, 0.0, 0.5), Vec3::X),
                (Vec3::new(-1.0, 1.0, 1.0), Vec3::X),
                (Vec3::new(2.0, 0.0, 0.0), -Vec3::X),
                (Vec3::new(0.5, 0.0, -3.0), Vec3::new(-0.0, -0.0, 1.0)),
            ] {
                assert_eq!(both(&n, &Ray::new(o, d, 0.0, f32::INFINITY)), 1 << slot, "{o} {d}");
            }
        }
    }

    #[test]
    fn grazing_rays_keep_the_box() {
        let n = node(&[unit(Vec3::ZERO)]);
        let d = Vec3::new(1.0, 1.0, 1.0) / 3.0f32.sqrt();
        let ray = Ray::new(Vec3::new(1.0, 1.0, 1.0) + d * 0.3, d, -1.0, f32::INFINITY);
        assert_eq!(both(&n, &ray), 1);
    }

    proptest! {
        #[test]
        fn avx2_matches_scalar_twin(
            boxes in prop::collection::vec((prop::array::uniform3(-4i32..4), prop::array::uniform3(0i32..4)), 1..9),
            o in prop::array::uniform3(-6i32..6), d in prop::array::uniform3(-2i32..3), t_min in -2.0f32..1.0,
            t_max in prop_oneof![Just(f32::INFINITY), 0.0f32..8.0],
        ) {
            let boxes: Vec<Aabb> = boxes.iter().map(|(lo, ext)| {
                let lo = Vec3::new(lo[0] as f32, lo[1] as f32, lo[2] as f32);
                Aabb { min: lo, max: lo + Vec3::new(ext[0] as f32, ext[1] as f32, ext[2] as f32) }
            }).collect();
            let d = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
            prop_assume!(d != Vec3::ZERO);
            let o = Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32) * 0.5;
            let ray = Ray::new(o, d, t_min, t_max);
            let m = both(&node(&boxes), &ray);
            // Against an exact-enough reference: sample the segment densely in f64.
            for (i, b) in boxes.iter().enumerate() {
                let inside = (0..=4000).map(|k| t_min as f64 + k as f64 * 0.005).filter(|&t| t <= t_max as f64).any(|t| {
                    (0..3).all(|a| {
                        let p = o[a] as f64 + t * d[a] as f64;
                        p >= b.min[a] as f64 && p <= b.max[a] as f64
                    })
                });
                if inside {
                    prop_assert!(m & (1 << i) != 0, "box {i} {b:?} missed by {ray:?}");
                }
            }
        }
    }
}
