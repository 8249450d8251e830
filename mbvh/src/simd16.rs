//! The 16-wide node test in AVX-512, the width Wald, Benthin & Boulos 2008 built for
//! (section 5.2: one 16-wide SIMD register per box coordinate, a node's sixteen children
//! tested at once): [`crate::boxtest`]'s slab test on a [`Node16`], one 512-bit register per
//! box coordinate, with the same arithmetic in the same order as its scalar twin
//! [`crate::boxtest::FusedScalar16`]: planes picked by the direction's sign bit,
//! `(p - o) * (1 / d)`, the candidate first in `max` / `min` so that a `0 * inf` NaN leaves
//! the accumulator (`vmaxps` / `vminps` on 512-bit registers return their second operand
//! when either is NaN, as on 128 and 256 bits), then the entry lowered and the exit raised
//! by `WIDEN` and `TINY`, and one ordered `<=` compare into a k-mask
//! (`vcmpps k, _CMP_LE_OQ`), which is the hit mask itself (bit `i` for slot `i`). The
//! widening is one fused multiply-add and one addition each (`vfnmadd` / `vfmadd`, as
//! [`crate::boxtest::lowered`] and [`crate::boxtest::raised`]); every lane rounds as
//! [`crate::boxtest::hit_scalar`] does, so the AVX-512 test and its twin give the same mask
//! and distances bit for bit (`tests/twins.rs`).
//!
//! **AVX-512 is chosen at run time**, as AVX2 is in [`crate::simd8`]: [`Avx512::detect`]
//! asks the CPU once (AVX-512 F and VL, with the AVX2, FMA, BMI1/2, POPCNT and LZCNT the
//! loops are compiled for) and the process-wide cap (`kdtree::isa::SimdLevel`, `rttest
//! --simd`), and returns a token only where both allow it; a traversal made with the token
//! ([`crate::Traversal::with_test`]) runs its whole loop in a function compiled for those
//! features (so the node test inlines into it), and no check is made per ray. Without the
//! token, or on another architecture, the 16-wide tree is traversed with [`crate::Scalar16`]
//! (the unfused portable test).
//!
//! The traversal is the one loop of every width ([`crate::traverse`]): the entered children
//! are taken from the mask bit by bit (`tzcnt`, `blsr`) and insertion-sorted onto the stack,
//! nearest on top; nothing is compressed (`vcompressps` to memory is microcoded on some
//! CPUs, AMD Zen 4 among them), and the paper's unsorted active list (section 5.3) is not
//! kept.

use kdtree::{Counters, Hit, Ray};

use crate::boxtest::{BoxTest, FusedScalar16, RayBoxes, TraversalLoop};
#[cfg(target_arch = "x86_64")]
use crate::boxtest::{TINY, WIDEN};
use crate::node::Node16;

/// The sixteen children's box test in AVX-512 (512-bit `vsubps`, `vmulps`, `vmaxps`,
/// `vminps`, `vandps` for the absolute values, `vfnmadd` / `vfmadd` for the widening, and one
/// `vcmpps` into a k-mask).
///
/// # Safety
/// The CPU must have AVX-512 F (which implies FMA): call it where an [`Avx512`] token exists
/// (or from a function compiled for AVX-512 F).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,fma")]
#[inline]
pub fn hit16_avx512(node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
    use std::arch::x86_64::*;

    use crate::node::Lanes;
    let load = |lanes: &Lanes<16>| {
        // SAFETY: a `Lanes<16>` is sixteen `f32` aligned to 64 bytes.
        unsafe { _mm512_load_ps(lanes.as_array().as_ptr()) }
    };
    let mut near = _mm512_set1_ps(t_min);
    let mut far = _mm512_set1_ps(t_max);
    for axis in 0..3 {
        let planes = &node.bounds[axis];
        let (o, inv) = (_mm512_set1_ps(r.o[axis]), _mm512_set1_ps(r.inv[axis]));
        let n = _mm512_mul_ps(_mm512_sub_ps(load(&planes[r.near[axis] & 1]), o), inv);
        let f = _mm512_mul_ps(_mm512_sub_ps(load(&planes[(r.near[axis] ^ 1) & 1]), o), inv);
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator.
        near = _mm512_max_ps(n, near);
        far = _mm512_min_ps(f, far);
    }
    let (widen, tiny) = (_mm512_set1_ps(WIDEN), _mm512_set1_ps(TINY));
    // `_mm512_abs_ps` clears the sign bit, as `f32::abs` does; `boxtest::lowered` / `raised`:
    // `near - |near| WIDEN` rounded once, then `TINY`.
    let near = _mm512_sub_ps(_mm512_fnmadd_ps(_mm512_abs_ps(near), widen, near), tiny);
    let far = _mm512_add_ps(_mm512_fmadd_ps(_mm512_abs_ps(far), widen, far), tiny);
    let mask = u32::from(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far));
    let mut nears = Lanes::<16>::splat(0.0);
    // SAFETY: a `Lanes<16>` is sixteen `f32` aligned to 64 bytes.
    unsafe { _mm512_store_ps(nears.as_mut_array().as_mut_ptr(), near) };
    (mask, *nears.as_array())
}

/// The sixteen children's forward test in AVX-512, for `t_min >= 0` (`crate::boxtest`'s
/// **The forward test**): [`crate::simd8::hit8_avx2_forward`]'s arithmetic in 512-bit registers and
/// a k-mask, the same operations in the same order as its scalar twin
/// [`crate::boxtest::hit_scalar_forward`].
///
/// # Safety
/// The CPU must have AVX-512 F (which implies FMA): call it where an [`Avx512`] token exists
/// (or from a function compiled for AVX-512 F).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,fma")]
#[inline]
pub fn hit16_avx512_forward(node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
    use std::arch::x86_64::*;

    use crate::node::Lanes;
    let load = |lanes: &Lanes<16>| {
        // SAFETY: a `Lanes<16>` is sixteen `f32` aligned to 64 bytes.
        unsafe { _mm512_load_ps(lanes.as_array().as_ptr()) }
    };
    let (tiny, minus_tiny) = (_mm512_set1_ps(TINY), _mm512_set1_ps(-TINY));
    let mut near = _mm512_set1_ps(t_min);
    let mut far = _mm512_set1_ps(t_max);
    for axis in 0..3 {
        let planes = &node.bounds[axis];
        let o = _mm512_set1_ps(r.o[axis]);
        let (entry, exit) = (_mm512_set1_ps(r.inv_entry[axis]), _mm512_set1_ps(r.inv_exit[axis]));
        let n = _mm512_fmadd_ps(_mm512_sub_ps(load(&planes[r.near[axis] & 1]), o), entry, minus_tiny);
        let f = _mm512_fmadd_ps(_mm512_sub_ps(load(&planes[(r.near[axis] ^ 1) & 1]), o), exit, tiny);
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator.
        near = _mm512_max_ps(n, near);
        far = _mm512_min_ps(f, far);
    }
    let mask = u32::from(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far));
    let mut nears = Lanes::<16>::splat(0.0);
    // SAFETY: a `Lanes<16>` is sixteen `f32` aligned to 64 bytes.
    unsafe { _mm512_store_ps(nears.as_mut_array().as_mut_ptr(), near) };
    (mask, *nears.as_array())
}

/// The AVX-512 box test ([`hit16_avx512`]), as a token: made only by [`Avx512::detect`] on a
/// CPU with AVX-512 F and VL (and the scalar extensions the loops are compiled for), so a
/// traversal holding one may run those instructions.
#[derive(Clone, Copy, Debug)]
pub struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The token if this CPU has AVX-512 F and VL, AVX2, FMA, BMI1, BMI2, POPCNT and LZCNT
    /// (`is_x86_feature_detected!`) and the SIMD level is not capped below AVX-512
    /// (`kdtree::isa::SimdLevel::allows`, `rttest --simd`), else `None` (always on
    /// architectures other than x86-64). Call it once, when a traversal is set up.
    pub fn detect() -> Option<Avx512> {
        #[cfg(target_arch = "x86_64")]
        if kdtree::isa::SimdLevel::allows(kdtree::isa::SimdLevel::Avx512)
            && is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
            && is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("bmi1")
            && is_x86_feature_detected!("bmi2")
            && is_x86_feature_detected!("popcnt")
            && is_x86_feature_detected!("lzcnt")
        {
            return Some(Avx512 { _detected: () });
        }
        None
    }
}

impl BoxTest for Avx512 {
    type Node = Node16;
    type RayData = RayBoxes;
    type Nears = [f32; 16];
    type Twin = FusedScalar16;

    fn twin(self) -> FusedScalar16 {
        FusedScalar16::default()
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes {
        RayBoxes::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
        avx512::hit(self, node, r, t_min, t_max)
    }

    #[inline(always)]
    fn hit_forward(self, node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
        avx512::hit_forward(self, node, r, t_min, t_max)
    }

    #[inline]
    fn closest<L: TraversalLoop, C: Counters>(self, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        avx512::closest(self, l, ray, counters)
    }

    #[inline]
    fn any<L: TraversalLoop, C: Counters>(self, l: &L, ray: &Ray, counters: &mut C) -> bool {
        avx512::any(self, l, ray, counters)
    }
}

/// What an [`Avx512`] token runs on x86-64: the node test, and the traversal loops compiled
/// for AVX-512 (the loop, `#[inline(always)]`, and the node test inline into them, so the
/// whole descent runs with 512-bit registers, k-masks and BMI bit operations, and no call
/// per node).
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::*;

    #[inline(always)]
    pub(super) fn hit(_: Avx512, node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
        // SAFETY: an `Avx512` exists, so `Avx512::detect` found AVX-512 F on this CPU.
        unsafe { hit16_avx512(node, r, t_min, t_max) }
    }

    #[inline(always)]
    pub(super) fn hit_forward(_: Avx512, node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
        // SAFETY: an `Avx512` exists, so `Avx512::detect` found AVX-512 F on this CPU.
        unsafe { hit16_avx512_forward(node, r, t_min, t_max) }
    }

    #[inline(always)]
    pub(super) fn closest<L: TraversalLoop, C: Counters>(_: Avx512, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        // SAFETY: an `Avx512` exists, so `Avx512::detect` found every feature enabled below.
        unsafe { closest_avx512(l, ray, counters) }
    }

    #[inline(always)]
    pub(super) fn any<L: TraversalLoop, C: Counters>(_: Avx512, l: &L, ray: &Ray, counters: &mut C) -> bool {
        // SAFETY: an `Avx512` exists, so `Avx512::detect` found every feature enabled below.
        unsafe { any_avx512(l, ray, counters) }
    }

    #[target_feature(enable = "avx512f,avx512vl,avx2,fma,bmi1,bmi2,popcnt,lzcnt")]
    fn closest_avx512<L: TraversalLoop, C: Counters>(l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        l.closest(ray, counters)
    }

    #[target_feature(enable = "avx512f,avx512vl,avx2,fma,bmi1,bmi2,popcnt,lzcnt")]
    fn any_avx512<L: TraversalLoop, C: Counters>(l: &L, ray: &Ray, counters: &mut C) -> bool {
        l.any(ray, counters)
    }
}

/// Elsewhere no [`Avx512`] token is ever made ([`Avx512::detect`] returns `None`); these
/// keep the type usable: the scalar test and the plain loops.
#[cfg(not(target_arch = "x86_64"))]
mod avx512 {
    use super::*;

    pub(super) fn hit(_: Avx512, node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
        crate::boxtest::hit_scalar::<16, true>(node, r, t_min, t_max)
    }

    pub(super) fn hit_forward(_: Avx512, node: &Node16, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 16]) {
        crate::boxtest::hit_scalar_forward::<16, true>(node, r, t_min, t_max)
    }

    pub(super) fn closest<L: TraversalLoop, C: Counters>(_: Avx512, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        l.closest(ray, counters)
    }

    pub(super) fn any<L: TraversalLoop, C: Counters>(_: Avx512, l: &L, ray: &Ray, counters: &mut C) -> bool {
        l.any(ray, counters)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use kdtree::Aabb;

    use super::*;
    use crate::boxtest::cases::{check, check_forward, hard_cases, node, unit};

    fn token() -> Option<Avx512> {
        let t = Avx512::detect();
        if t.is_none() {
            eprintln!("note: this CPU (or the SIMD cap) has no AVX-512; the AVX-512 test is not run");
        }
        t
    }

    #[test]
    fn the_hard_cases_equal_the_scalar_twin() {
        if let Some(avx) = token() {
            hard_cases::<16>(|n, ray| check(avx, n, ray));
            hard_cases::<16>(|n, ray| check_forward(avx, n, ray));
        }
    }

    /// Every slot's lane is its own: sixteen different boxes, each slot's bit and distance
    /// the twin's, and the mask's high bits (16..32) always clear.
    #[test]
    fn sixteen_distinct_slots_equal_the_scalar_twin() {
        let Some(avx) = token() else { return };
        let boxes: Vec<Aabb> = (0..16)
            .map(|i| {
                let b = unit(Vec3::new(i as f32 * 1.5 - 12.0, (i % 4) as f32 - 1.5, (i / 4) as f32 - 1.5));
                Aabb { min: b.min, max: b.max + Vec3::splat(0.25 * (i % 3) as f32) }
            })
            .collect();
        let n = node::<16>(&boxes);
        let mut entered = 0u32;
        // Origins on a quarter grid in y and z: through every box, and along its faces (the
        // boxes' planes lie on the grid), with zero and nonzero y and z direction components.
        for k in 0..24 * 24 {
            let (y, z) = (-3.0 + (k % 24) as f32 * 0.25, -3.0 + (k / 24) as f32 * 0.25);
            let o = Vec3::new(-20.0, y, z);
            for d in [Vec3::X, Vec3::new(1.0, -0.0, 0.0), Vec3::new(1.0, 0.01 * y, -0.02 * z)] {
                let ray = Ray::new(o, d, 0.0, f32::INFINITY);
                let m = check(avx, &n, &ray);
                assert_eq!(m >> 16, 0);
                assert_eq!(check_forward(avx, &n, &ray) >> 16, 0);
                entered |= m;
            }
        }
        // Every slot was entered by some ray: each lane was exercised with a hit.
        assert_eq!(entered, 0xffff);
    }

    /// An interval inverted by a hair, `[a, b]` with `a > b`, that the widening closes to one
    /// point (`a` lowered equals `b` raised): entered, as the twin's `near <= far` says (an
    /// ordered less-or-equal, not less-than), in every slot.
    #[test]
    fn an_interval_widened_to_a_point_is_entered() {
        use crate::boxtest::{lowered, raised};

        let Some(avx) = token() else { return };
        let everything = Aabb { min: Vec3::NEG_INFINITY, max: Vec3::INFINITY };
        let n = node::<16>(&[everything; 16]);
        let mut found = 0;
        for k in 1..200u32 {
            let b = k as f32 * 0.731;
            let up = raised(b);
            // The floats above `b` whose lowered value is `b` raised.
            let mut a = b;
            for _ in 0..64 {
                a = f32::from_bits(a.to_bits() + 1);
                if lowered(a) == up {
                    // The box is all of space: only the interval bounds the ray.
                    let ray = Ray::new(Vec3::ZERO, Vec3::X, a, b);
                    assert_eq!(check(avx, &n, &ray), 0xffff, "{ray:?}");
                    found += 1;
                    break;
                }
            }
        }
        assert!(found > 20, "{found} intervals found");
    }
}
