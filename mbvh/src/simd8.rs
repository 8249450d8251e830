//! The 8-wide node test in AVX2 (Wald, Benthin & Boulos 2008, section 5.2, at the
//! branching factor their section 6.4 finds best by the cost metric, "somewhere between 4
//! and 8"): [`crate::boxtest`]'s slab test, one 256-bit register per box coordinate of a
//! [`Node8`]'s eight children, with the same arithmetic in the same order as its scalar
//! twin [`crate::boxtest::FusedScalar8`]: planes picked by the direction's sign bit,
//! `(p - o) * (1 / d)`, the candidate first in `max` / `min` so that a `0 * inf` NaN leaves
//! the accumulator (`vmaxps` returns its second operand when either is NaN, like `maxps`),
//! then the entry lowered and the exit raised by `WIDEN` and `TINY` with one fused
//! multiply-add each (`vfnmadd` / `vfmadd`, as [`crate::boxtest::lowered`] and
//! [`crate::boxtest::raised`]):
//! every lane rounds as [`crate::boxtest::hit_scalar`] does, so the AVX2 test and its twin
//! give the same mask and distances bit for bit (`tests/twins.rs`).
//!
//! **AVX2 is chosen at run time.** [`Avx2::detect`] asks the CPU once
//! (`is_x86_feature_detected!` for AVX2 and FMA) and returns a token only where it has both; a
//! traversal made with the token ([`crate::Traversal::with_test`]) runs its whole loop in a
//! `#[target_feature(enable = "avx2,fma")]` function (so the node test inlines into it), and no
//! check is made per ray. Without the token, or on another architecture, the 8-wide tree is
//! traversed with [`crate::Scalar8`] (the unfused portable test). On a CPU that executes
//! every 256-bit operation as two 128-bit halves, one 8-wide node test costs about two
//! 4-wide ones; what the wider node can save there is node fetches and traversal steps, not
//! arithmetic.
//!
//! The 16-wide AVX-512 test is this module's sibling, [`crate::simd16`]: the token
//! [`crate::Avx512`] (AVX-512 F and VL, under the same SIMD cap), the test on
//! [`crate::Node16`] with `_mm512_*` and a k-mask, and the same two entry points compiled for
//! AVX-512.

use kdtree::{Counters, Hit, Ray};

use crate::boxtest::{BoxTest, FusedScalar8, RayBoxes, TraversalLoop};
#[cfg(target_arch = "x86_64")]
use crate::boxtest::{TINY, WIDEN};
use crate::node::Node8;

/// The eight children's box test in AVX2 (256-bit `vsubps`, `vmulps`, `vmaxps`, `vminps`,
/// `vfnmadd` / `vfmadd` for the widening, one `vcmpps` and `vmovmskps`).
///
/// # Safety
/// The CPU must have AVX2 and FMA: call it where an [`Avx2`] token exists (or from a
/// function compiled for both).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub fn hit8_avx2(node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;

    use crate::node::Lanes;
    let load = |lanes: &Lanes<8>| {
        // SAFETY: a `Lanes<8>` is eight `f32` aligned to 32 bytes.
        unsafe { _mm256_load_ps(lanes.as_array().as_ptr()) }
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
    // `boxtest::lowered` / `raised`: `near - |near| WIDEN` rounded once, then `TINY`.
    let near = _mm256_sub_ps(_mm256_fnmadd_ps(_mm256_andnot_ps(sign, near), widen, near), tiny);
    let far = _mm256_add_ps(_mm256_fmadd_ps(_mm256_andnot_ps(sign, far), widen, far), tiny);
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    let mut nears = Lanes::<8>::splat(0.0);
    // SAFETY: a `Lanes<8>` is eight `f32` aligned to 32 bytes.
    unsafe { _mm256_store_ps(nears.as_mut_array().as_mut_ptr(), near) };
    (mask, *nears.as_array())
}

/// The eight children's forward test in AVX2, for `t_min >= 0` (`crate::boxtest`'s **The
/// forward test**): per axis a `vsubps` and one `vfmadd` with the ray's scaled reciprocal and
/// `-+ TINY` for each of the entry and exit planes, the reductions, one `vcmpps`; nothing
/// after the reductions. The same arithmetic in the same order as its scalar twin
/// [`crate::boxtest::hit_scalar_forward`].
///
/// # Safety
/// The CPU must have AVX2 and FMA: call it where an [`Avx2`] token exists (or from a
/// function compiled for both).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub fn hit8_avx2_forward(node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;

    use crate::node::Lanes;
    let load = |lanes: &Lanes<8>| {
        // SAFETY: a `Lanes<8>` is eight `f32` aligned to 32 bytes.
        unsafe { _mm256_load_ps(lanes.as_array().as_ptr()) }
    };
    let (tiny, minus_tiny) = (_mm256_set1_ps(TINY), _mm256_set1_ps(-TINY));
    let mut near = _mm256_set1_ps(t_min);
    let mut far = _mm256_set1_ps(t_max);
    for axis in 0..3 {
        let planes = &node.bounds[axis];
        let o = _mm256_set1_ps(r.o[axis]);
        let (entry, exit) = (_mm256_set1_ps(r.inv_entry[axis]), _mm256_set1_ps(r.inv_exit[axis]));
        let n = _mm256_fmadd_ps(_mm256_sub_ps(load(&planes[r.near[axis] & 1]), o), entry, minus_tiny);
        let f = _mm256_fmadd_ps(_mm256_sub_ps(load(&planes[(r.near[axis] ^ 1) & 1]), o), exit, tiny);
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator.
        near = _mm256_max_ps(n, near);
        far = _mm256_min_ps(f, far);
    }
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    let mut nears = Lanes::<8>::splat(0.0);
    // SAFETY: a `Lanes<8>` is eight `f32` aligned to 32 bytes.
    unsafe { _mm256_store_ps(nears.as_mut_array().as_mut_ptr(), near) };
    (mask, *nears.as_array())
}

/// The AVX2 box test ([`hit8_avx2`]), as a token: made only by [`Avx2::detect`] on a CPU
/// with AVX2 and FMA, so a traversal holding one may run those instructions.
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _detected: (),
}

impl Avx2 {
    /// The token if this CPU has AVX2 and FMA (`is_x86_feature_detected!`; and BMI1, BMI2,
    /// POPCNT and LZCNT, which every AVX2 CPU has, for the packet runners of
    /// [`crate::packet`]) and the SIMD level is not
    /// capped below it (`kdtree::isa::SimdLevel::active`, `rttest --simd`), else `None`
    /// (always on architectures other than x86-64). Call it once, when a traversal is set up.
    pub fn detect() -> Option<Avx2> {
        #[cfg(target_arch = "x86_64")]
        if kdtree::isa::SimdLevel::allows(kdtree::isa::SimdLevel::Avx2)
            && is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("bmi1")
            && is_x86_feature_detected!("bmi2")
            && is_x86_feature_detected!("popcnt")
            && is_x86_feature_detected!("lzcnt")
        {
            return Some(Avx2 { _detected: () });
        }
        None
    }
}

impl BoxTest for Avx2 {
    type Node = Node8;
    type RayData = RayBoxes;
    type Nears = [f32; 8];
    type Twin = FusedScalar8;

    fn twin(self) -> FusedScalar8 {
        FusedScalar8::default()
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes {
        RayBoxes::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        avx2::hit(self, node, r, t_min, t_max)
    }

    #[inline(always)]
    fn hit_forward(self, node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        avx2::hit_forward(self, node, r, t_min, t_max)
    }

    #[inline]
    fn closest<L: TraversalLoop, C: Counters>(self, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        avx2::closest(self, l, ray, counters)
    }

    #[inline]
    fn any<L: TraversalLoop, C: Counters>(self, l: &L, ray: &Ray, counters: &mut C) -> bool {
        avx2::any(self, l, ray, counters)
    }
}

/// What an [`Avx2`] token runs on x86-64: the node test, and the traversal loops compiled
/// for AVX2 (the loop, `#[inline(always)]`, and the node test inline into them, so the whole
/// descent runs with 256-bit registers and no call per node).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;

    #[inline(always)]
    pub(super) fn hit(_: Avx2, node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        // SAFETY: an `Avx2` exists, so `Avx2::detect` found AVX2 and FMA on this CPU.
        unsafe { hit8_avx2(node, r, t_min, t_max) }
    }

    #[inline(always)]
    pub(super) fn hit_forward(_: Avx2, node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        // SAFETY: an `Avx2` exists, so `Avx2::detect` found AVX2 and FMA on this CPU.
        unsafe { hit8_avx2_forward(node, r, t_min, t_max) }
    }

    #[inline(always)]
    pub(super) fn closest<L: TraversalLoop, C: Counters>(_: Avx2, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        // SAFETY: an `Avx2` exists, so `Avx2::detect` found AVX2 and FMA on this CPU.
        unsafe { closest_avx2(l, ray, counters) }
    }

    #[inline(always)]
    pub(super) fn any<L: TraversalLoop, C: Counters>(_: Avx2, l: &L, ray: &Ray, counters: &mut C) -> bool {
        // SAFETY: an `Avx2` exists, so `Avx2::detect` found AVX2 and FMA on this CPU.
        unsafe { any_avx2(l, ray, counters) }
    }

    #[target_feature(enable = "avx2,fma")]
    fn closest_avx2<L: TraversalLoop, C: Counters>(l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        l.closest(ray, counters)
    }

    #[target_feature(enable = "avx2,fma")]
    fn any_avx2<L: TraversalLoop, C: Counters>(l: &L, ray: &Ray, counters: &mut C) -> bool {
        l.any(ray, counters)
    }
}

/// Elsewhere no [`Avx2`] token is ever made ([`Avx2::detect`] returns `None`); these keep
/// the type usable: the scalar test and the plain loops.
#[cfg(not(target_arch = "x86_64"))]
mod avx2 {
    use super::*;

    pub(super) fn hit(_: Avx2, node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        crate::boxtest::hit_scalar::<8, true>(node, r, t_min, t_max)
    }

    pub(super) fn hit_forward(_: Avx2, node: &Node8, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        crate::boxtest::hit_scalar_forward::<8, true>(node, r, t_min, t_max)
    }

    pub(super) fn closest<L: TraversalLoop, C: Counters>(_: Avx2, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        l.closest(ray, counters)
    }

    pub(super) fn any<L: TraversalLoop, C: Counters>(_: Avx2, l: &L, ray: &Ray, counters: &mut C) -> bool {
        l.any(ray, counters)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boxtest::cases::{check, check_forward, hard_cases};

    #[test]
    fn the_hard_cases_equal_the_scalar_twin() {
        if let Some(avx) = Avx2::detect() {
            hard_cases::<8>(|n, ray| check(avx, n, ray));
            hard_cases::<8>(|n, ray| check_forward(avx, n, ray));
        }
    }
}
