//! Explicit x86-64 lane types for 8- and 16-ray packets (issue 28, "wide SIMD"):
//! [`F32x8`] / [`Mask8`] (AVX2, one 256-bit register per vector and per mask),
//! [`F32x16`] / [`Mask16`] (AVX-512F, one 512-bit register and one `k` mask register) and
//! [`F32x8x2`] / [`Mask8x2`] (16 lanes as two AVX2 registers, for CPUs without AVX-512). Each
//! implements [`SimdF32`] / [`SimdMask`] with the semantics the traits document, and gives
//! bit for bit the answers of the portable twin [`PortableF32<8>`](crate::simd::PortableF32)
//! / `PortableF32<16>` (tested below, operation by operation and through the packet
//! kernels): so an 8- or 16-wide packet of [`crate::omni`], [`crate::samesign`] or
//! [`crate::triangle4`] answers exactly as single rays do (Tsakok 2008, 4.1.1-4.1.2: the
//! thesis's 2x2 packets, here 8 or 16 rays per instruction).
//!
//! - `min` / `max` are `vminps` / `vmaxps` (`a < b ? a : b`, the second operand on NaN and
//!   on equal values), as the trait and the portable twin define them.
//! - `recip` is the division `1.0 / x` (`vdivps`), not the `rcp14` approximation.
//! - `abs` and `copysign` are bit operations on the sign bit; `is_negative_bitmask` reads the
//!   sign bits (`-0.0` and negative NaNs included).
//! - Comparisons are ordered and quiet (`_CMP_*_OQ`: false where either lane is NaN) except
//!   `cmpne`, which is unordered (`_CMP_NEQ_UQ`: true where either is NaN), as Rust's
//!   `!=`.
//! - No fused multiply-add: each operation rounds once, as the scalar code does (LLVM does
//!   not contract separate `vmulps` / `vaddps` without fast-math flags, `fma` enabled or
//!   not).
//! - `axes` (one point per lane to one vector per axis) loads the `3 W` floats of the points
//!   as three vectors; lane `l` of axis `a` is float `3 l + a`, at position `(3 l + a) % W`
//!   of vector `(3 l + a) / W`. Because 3 does not divide `W`, each position `p` of the
//!   three vectors holds exactly one float of axis `a` (the `k` with `k W + p = a mod 3`):
//!   two blends gather them into one vector and one permutation puts them in lane order.
//!
//! # How these types are used (and why misuse is undefined behaviour)
//!
//! Every operation is `#[inline(always)]`, most of them one `core::arch::x86_64` intrinsic,
//! but the trait methods themselves cannot carry `#[target_feature]`. The intrinsics only become
//! single instructions when the operation is inlined into a function compiled with the
//! feature. So a kernel instantiated with [`F32x16`] (or [`F32x8`]) is only ever called:
//! 1. after run-time detection said the CPU has the feature ([`F32x16::available`],
//!    [`F32x8::available`], `is_x86_feature_detected!`), and
//! 2. from inside a `#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]` (or
//!    `"avx2,fma"`) function, with everything from that function down to the lane
//!    operations inlined into it (the kernels' hot functions are `#[inline(always)]`; an
//!    entry point that is only `#[inline]` is inlined there only if the optimiser chooses).
//!
//! [`with_avx512`] and [`with_avx2`] do both for a [`LaneKernel`] (a kernel call and its
//! arguments): they detect, then call its `run` from an `#[inline(never)]`
//! `#[target_feature]` function. A `run` marked `#[inline(always)]` is inlined into that
//! function at every optimisation level, and with it every `#[inline(always)]` function it
//! reaches, down to the lane operations and their intrinsics. A closure is a `LaneKernel`
//! too: written in argument position as `#[inline(always)] || ...` it joins the runner the
//! same way ([`crate::at_width!`] passes its kernels so); without the attribute, whether its
//! body joins is the optimiser's choice (in the workspace's `opt-level = 1` test builds it
//! does not, and each lane operation in it stays a call into `core::core_arch`).
//! Likewise a function on the way that is neither `#[inline(always)]` nor inlined by choice
//! is compiled without the feature: still correct on a CPU that has it, only slow.
//!
//! Checked by disassembly (`objdump -d` of the `opt-level = 1` test binary): the runner of
//! the test kernel `CheckAll::<F32x16, 16>` is one function of about 7000 instructions, 270
//! of them on `zmm` registers, with no call into `core::core_arch` (the `F32x8` one: `ymm`
//! instructions, no such call); the same test body passed as a closure left the runner a
//! jump to the closure, whose body called `_mm512_mask_blend_ps` and the other intrinsics as
//! functions.
//!
//! Using these types on a CPU without the feature runs instructions it does not have
//! (illegal instruction): undefined behaviour. The operations are safe functions (the trait
//! requires it), so that contract is the caller's, stated under **Safety** on each type.
//!
//! # Why `core::arch` and not a SIMD crate
//!
//! The intrinsics were chosen over `wide` or `pulp` for control of the exact semantics (which
//! operand `min` returns on NaN, a real division for `recip`, no approximations) and of the
//! code generated, with no new dependency.

use std::arch::x86_64::*;
use std::fmt::{self, Debug};
use std::mem::transmute;
use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Index, Mul, Not, Sub};

use glam::Vec3;

use crate::simd::{SimdF32, SimdMask};

// `axes` reads `W` points as `3 W` contiguous floats.
const _: () = assert!(size_of::<Vec3>() == 12 && align_of::<Vec3>() == 4);

/// Which of the three vectors loaded by `axes` position `p` takes for axis `axis` with `w`
/// lanes: the `k` in `0..3` with `k w + p = axis (mod 3)` (unique: 3 does not divide `w`).
const fn source(w: usize, axis: usize, p: usize) -> usize {
    let mut k = 0;
    while (k * w + p) % 3 != axis {
        k += 1;
    }
    k
}

/// Bit `p` set where position `p` of axis `axis` comes from loaded vector `k` (`w` lanes).
const fn blend_bits(w: usize, axis: usize, k: usize) -> u32 {
    let mut bits = 0;
    let mut p = 0;
    while p < w {
        if source(w, axis, p) == k {
            bits |= 1 << p;
        }
        p += 1;
    }
    bits
}

/// Lane `l` of axis `axis` is position `(3 l + axis) % W` of the blended vector.
const fn permutation<const W: usize>(axis: usize) -> [i32; W] {
    let mut idx = [0; W];
    let mut l = 0;
    while l < W {
        idx[l] = ((3 * l + axis) % W) as i32;
        l += 1;
    }
    idx
}

/// The all-ones / zero lanes of an AVX mask with bit `l` of `bits` in lane `l`.
const fn lane_mask8(bits: u32) -> [u32; 8] {
    let mut m = [0; 8];
    let mut l = 0;
    while l < 8 {
        if bits >> l & 1 != 0 {
            m[l] = u32::MAX;
        }
        l += 1;
    }
    m
}

// --------------------------------------------------------------------------------------------
// AVX2: F32x8 / Mask8
// --------------------------------------------------------------------------------------------

/// Eight f32 lanes in one AVX register (`__m256`): the lane type of 8-ray packets.
///
/// # Safety
/// Its operations execute AVX2 instructions: use it only on a CPU with AVX2 and FMA
/// ([`F32x8::available`]), and for speed only inside a function compiled for them
/// ([`with_avx2`]; see the [module documentation](self)). On a CPU without them, using it is
/// undefined behaviour (illegal instruction).
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F32x8(pub __m256);

/// The lane mask of [`F32x8`]: per lane all ones (set) or all zeros (clear), in an AVX
/// register, as `vcmpps` makes it and `vblendvps` reads it.
///
/// # Safety
/// As [`F32x8`]: only on a CPU with AVX2 and FMA.
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct Mask8(pub __m256);

impl F32x8 {
    /// Whether this CPU has what the type needs (AVX2 and FMA), detected at run time.
    pub fn available() -> bool {
        is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
    }

    /// The lanes of `lanes`, in order (no instruction needed: usable anywhere).
    #[inline(always)]
    pub const fn from_array(lanes: [f32; 8]) -> F32x8 {
        // SAFETY: `__m256` is 32 bytes of plain data, any bits valid.
        F32x8(unsafe { transmute::<[f32; 8], __m256>(lanes) })
    }

    /// One axis of `axes`: the blends and permutation of the module documentation.
    #[inline(always)]
    fn axis(v: &[__m256; 3], axis: usize) -> F32x8 {
        const BLENDS: [[[u32; 8]; 2]; 3] = {
            let mut b = [[[0; 8]; 2]; 3];
            let mut a = 0;
            while a < 3 {
                b[a][0] = lane_mask8(blend_bits(8, a, 1));
                b[a][1] = lane_mask8(blend_bits(8, a, 2));
                a += 1;
            }
            b
        };
        const PERMUTATIONS: [[i32; 8]; 3] = [permutation::<8>(0), permutation::<8>(1), permutation::<8>(2)];
        // SAFETY: the type's contract (AVX2); the tables are plain 32-byte data.
        unsafe {
            let from1 = transmute::<[u32; 8], __m256>(BLENDS[axis][0]);
            let from2 = transmute::<[u32; 8], __m256>(BLENDS[axis][1]);
            let blended = _mm256_blendv_ps(_mm256_blendv_ps(v[0], v[1], from1), v[2], from2);
            F32x8(_mm256_permutevar8x32_ps(blended, transmute::<[i32; 8], __m256i>(PERMUTATIONS[axis])))
        }
    }
}

/// The lanes as an array.
impl Debug for F32x8 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("F32x8").field(&SimdF32::to_array(*self)).finish()
    }
}

/// Lane by lane `==`, as `PortableF32`'s derived equality (NaN lanes are unequal).
impl PartialEq for F32x8 {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        SimdF32::to_array(*self) == SimdF32::to_array(*other)
    }
}

impl Index<usize> for F32x8 {
    type Output = f32;
    /// Lane `lane` (panics past lane 7).
    #[inline(always)]
    fn index(&self, lane: usize) -> &f32 {
        // SAFETY: `F32x8` is `repr(transparent)` over `__m256`, 32 bytes holding 8 f32.
        let lanes = unsafe { &*(self as *const F32x8).cast::<[f32; 8]>() };
        &lanes[lane]
    }
}

/// `F32x8`'s binary arithmetic operators, one AVX instruction each.
macro_rules! avx_binary_ops {
    ($($trait:ident $method:ident $intrinsic:ident),*) => {$(
        impl $trait for F32x8 {
            type Output = F32x8;
            #[inline(always)]
            fn $method(self, rhs: F32x8) -> F32x8 {
                // SAFETY: the type's contract (AVX2).
                F32x8(unsafe { $intrinsic(self.0, rhs.0) })
            }
        }
    )*};
}
avx_binary_ops!(Add add _mm256_add_ps, Sub sub _mm256_sub_ps, Mul mul _mm256_mul_ps, Div div _mm256_div_ps);

impl F32x8 {
    /// The comparison `IMM` of each lane pair (`vcmpps`).
    #[inline(always)]
    fn cmp<const IMM: i32>(self, rhs: F32x8) -> Mask8 {
        // SAFETY: the type's contract (AVX2).
        Mask8(unsafe { _mm256_cmp_ps::<IMM>(self.0, rhs.0) })
    }
}

/// Every lane's sign bit set, nothing else.
const SIGN8: F32x8 = F32x8::from_array([-0.0; 8]);

impl SimdF32 for F32x8 {
    const LANES: usize = 8;
    const ZERO: F32x8 = F32x8::from_array([0.0; 8]);
    const ONE: F32x8 = F32x8::from_array([1.0; 8]);
    const INFINITY: F32x8 = F32x8::from_array([f32::INFINITY; 8]);
    const NEG_INFINITY: F32x8 = F32x8::from_array([f32::NEG_INFINITY; 8]);
    type Mask = Mask8;
    type Array<T: Copy + Debug> = [T; 8];

    #[inline(always)]
    fn array_from_fn<T: Copy + Debug>(f: impl FnMut(usize) -> T) -> [T; 8] {
        crate::simd::array_fn(f)
    }
    #[inline(always)]
    fn splat(v: f32) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_set1_ps(v) })
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> F32x8 {
        F32x8::from_array(crate::simd::array_fn(f))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        // SAFETY: `__m256` is 32 bytes of eight f32.
        unsafe { transmute::<__m256, [f32; 8]>(self.0) }
    }
    #[inline(always)]
    fn axes(points: [Vec3; 8]) -> [F32x8; 4] {
        let p = points.as_ptr().cast::<f32>();
        // SAFETY: eight `Vec3` are 24 contiguous f32 (asserted at the top); AVX2 is the
        // type's contract.
        let v = unsafe { [_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8)), _mm256_loadu_ps(p.add(16))] };
        [F32x8::axis(&v, 0), F32x8::axis(&v, 1), F32x8::axis(&v, 2), F32x8::ZERO]
    }
    #[inline(always)]
    fn min(self, rhs: F32x8) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_min_ps(self.0, rhs.0) })
    }
    #[inline(always)]
    fn max(self, rhs: F32x8) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_max_ps(self.0, rhs.0) })
    }
    #[inline(always)]
    fn abs(self) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_andnot_ps(SIGN8.0, self.0) })
    }
    #[inline(always)]
    fn copysign(self, sign: F32x8) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_or_ps(_mm256_andnot_ps(SIGN8.0, self.0), _mm256_and_ps(SIGN8.0, sign.0)) })
    }
    #[inline(always)]
    fn recip(self) -> F32x8 {
        F32x8::ONE / self
    }
    #[inline(always)]
    fn sqrt(self) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn strided(values: &[f32], start: usize, stride: usize) -> F32x8 {
        let lanes = crate::simd::strided_lanes(values, start, stride, 8);
        if stride == 1 {
            // SAFETY: `lanes` holds 8 f32 (checked above); an unaligned load; the type's
            // contract (AVX2).
            return F32x8(unsafe { _mm256_loadu_ps(lanes.as_ptr()) });
        }
        // Stride 2 as two vectors and shuffles where they fit (see `F32x16::strided`).
        let whole = &values[start..];
        if stride == 2 && whole.len() >= 16 {
            // SAFETY: `whole` holds 16 f32 (checked); unaligned loads; the type's contract.
            return F32x8(unsafe {
                let (a, b) = (_mm256_loadu_ps(whole.as_ptr()), _mm256_loadu_ps(whole.as_ptr().add(8)));
                // Per 128-bit half: a0 a2 b0 b2 | a4 a6 b4 b6; then the 64-bit pairs in order.
                let even = _mm256_shuffle_ps::<0b10_00_10_00>(a, b);
                _mm256_castpd_ps(_mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_castps_pd(even)))
            });
        }
        // The lanes' offsets in f32, `l * stride`, at most `lanes.len() - 1`.
        assert!(i32::try_from(lanes.len()).is_ok(), "a gather's offsets are i32");
        let step = stride as i32;
        let offsets: [i32; 8] = crate::simd::array_fn(|l| l as i32 * step);
        // SAFETY: every offset is inside `lanes` (checked above); the type's contract (AVX2).
        F32x8(unsafe {
            let idx = transmute::<[i32; 8], __m256i>(offsets);
            _mm256_i32gather_ps::<4>(lanes.as_ptr(), idx)
        })
    }
    #[inline(always)]
    fn cmpeq(self, rhs: F32x8) -> Mask8 {
        self.cmp::<_CMP_EQ_OQ>(rhs)
    }
    #[inline(always)]
    fn cmpne(self, rhs: F32x8) -> Mask8 {
        self.cmp::<_CMP_NEQ_UQ>(rhs)
    }
    #[inline(always)]
    fn cmplt(self, rhs: F32x8) -> Mask8 {
        self.cmp::<_CMP_LT_OQ>(rhs)
    }
    #[inline(always)]
    fn cmple(self, rhs: F32x8) -> Mask8 {
        self.cmp::<_CMP_LE_OQ>(rhs)
    }
    #[inline(always)]
    fn cmpgt(self, rhs: F32x8) -> Mask8 {
        self.cmp::<_CMP_GT_OQ>(rhs)
    }
    #[inline(always)]
    fn cmpge(self, rhs: F32x8) -> Mask8 {
        self.cmp::<_CMP_GE_OQ>(rhs)
    }
    /// `|x| < inf`: false for infinities and (unordered) NaNs.
    #[inline(always)]
    fn is_finite_mask(self) -> Mask8 {
        self.abs().cmplt(F32x8::INFINITY)
    }
    #[inline(always)]
    fn is_nan_mask(self) -> Mask8 {
        self.cmp::<_CMP_UNORD_Q>(self)
    }
    #[inline(always)]
    fn is_negative_bitmask(self) -> u32 {
        // SAFETY: the type's contract (AVX2).
        unsafe { _mm256_movemask_ps(self.0) as u32 }
    }
    #[inline(always)]
    fn select(mask: Mask8, if_true: F32x8, if_false: F32x8) -> F32x8 {
        // SAFETY: the type's contract (AVX2).
        F32x8(unsafe { _mm256_blendv_ps(if_false.0, if_true.0, mask.0) })
    }
    /// A volatile store of the blend: a plain one becomes `vmaskmovps` (see the trait).
    #[inline(always)]
    fn blend_into(mask: Mask8, value: F32x8, place: &mut F32x8) {
        let blend = F32x8::select(mask, value, *place);
        // SAFETY: `place` is a valid, aligned, exclusive reference.
        unsafe { std::ptr::write_volatile(place, blend) }
    }
    #[inline(always)]
    fn blend_u32(mask: Mask8, value: u32, lanes: &mut [u32; 8]) {
        let p = lanes.as_mut_ptr().cast::<__m256i>();
        // SAFETY: the type's contract (AVX2); `p` points to the 32 bytes of `lanes`
        // (unaligned loads and stores, a volatile store only where aligned). The blend moves
        // bits: any `u32` survives it.
        unsafe {
            let old = _mm256_castsi256_ps(_mm256_loadu_si256(p));
            let new = _mm256_castsi256_ps(_mm256_set1_epi32(value as i32));
            let blend = _mm256_castps_si256(_mm256_blendv_ps(old, new, mask.0));
            // A plain store becomes `vmaskmovps` (see `SimdF32::blend_into`); a volatile one
            // is a plain `vmovdqa`. A packet hit's indices are 32-byte aligned (its fields are
            // all 32 bytes, beside `F32x8`s), so the other branch is never taken there.
            if p.is_aligned() {
                std::ptr::write_volatile(p, blend);
            } else {
                _mm256_storeu_si256(p, blend);
            }
        }
    }
}

impl Mask8 {
    /// The mask whose lane `l` is bit `l` of `bits` (no instruction needed: usable anywhere).
    #[inline(always)]
    const fn from_bits(bits: u32) -> Mask8 {
        // SAFETY: `__m256` is 32 bytes of plain data, any bits valid.
        Mask8(unsafe { transmute::<[u32; 8], __m256>(lane_mask8(bits)) })
    }
}

/// The set lanes as bits (`Mask8(0b...)`, lane 0 the lowest bit).
impl Debug for Mask8 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Mask8({:#010b})", self.bitmask())
    }
}

/// The same lanes set.
impl PartialEq for Mask8 {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        self.bitmask() == other.bitmask()
    }
}

impl Eq for Mask8 {}

/// `Mask8`'s binary operators, one AVX instruction each.
macro_rules! mask8_ops {
    ($($trait:ident $method:ident $assign_trait:ident $assign:ident $intrinsic:ident),*) => {$(
        impl $trait for Mask8 {
            type Output = Mask8;
            #[inline(always)]
            fn $method(self, rhs: Mask8) -> Mask8 {
                // SAFETY: the type's contract (AVX2).
                Mask8(unsafe { $intrinsic(self.0, rhs.0) })
            }
        }
        impl $assign_trait for Mask8 {
            #[inline(always)]
            fn $assign(&mut self, rhs: Mask8) {
                *self = $trait::$method(*self, rhs);
            }
        }
    )*};
}
mask8_ops!(BitAnd bitand BitAndAssign bitand_assign _mm256_and_ps, BitOr bitor BitOrAssign bitor_assign _mm256_or_ps);

impl Not for Mask8 {
    type Output = Mask8;
    #[inline(always)]
    fn not(self) -> Mask8 {
        // SAFETY: the type's contract (AVX2).
        Mask8(unsafe { _mm256_xor_ps(self.0, Mask8::from_bits(0xff).0) })
    }
}

impl SimdMask for Mask8 {
    #[inline(always)]
    fn splat(v: bool) -> Mask8 {
        // SAFETY: the type's contract (AVX2).
        Mask8(unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(-i32::from(v))) })
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> bool) -> Mask8 {
        Mask8::from_bits((0..8).fold(0, |bits, l| bits | u32::from(f(l)) << l))
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        // SAFETY: the type's contract (AVX2).
        unsafe { _mm256_movemask_ps(self.0) as u32 }
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.bitmask() != 0
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.bitmask() == 0xff
    }
}

// --------------------------------------------------------------------------------------------
// AVX2, two registers: F32x8x2 / Mask8x2
// --------------------------------------------------------------------------------------------

/// Sixteen f32 lanes in two AVX registers (lanes 0-7, then 8-15): the lane type of 16-ray
/// packets on a CPU with AVX2 but not AVX-512, as Embree runs its 16-ray packets there. Each
/// operation is [`F32x8`]'s on both halves, so the answers are `PortableF32<16>`'s bit for
/// bit; what the 16-ray packet saves over two 8-ray ones is its per-packet work (traversal
/// steps, culling, the walk's decisions), not arithmetic.
///
/// # Safety
/// As [`F32x8`]: use it only on a CPU with AVX2 and FMA, and for speed only inside a
/// function compiled for them ([`with_avx2`], [`crate::at_width!`]).
#[derive(Clone, Copy)]
pub struct F32x8x2(pub F32x8, pub F32x8);

/// The lane mask of [`F32x8x2`]: [`Mask8`]s of lanes 0-7 and 8-15.
///
/// # Safety
/// As [`F32x8`]: only on a CPU with AVX2 and FMA.
#[derive(Clone, Copy)]
pub struct Mask8x2(pub Mask8, pub Mask8);

impl F32x8x2 {
    /// `f` on both halves.
    #[inline(always)]
    fn halves(self, rhs: F32x8x2, f: impl Fn(F32x8, F32x8) -> F32x8) -> F32x8x2 {
        F32x8x2(f(self.0, rhs.0), f(self.1, rhs.1))
    }

    /// `f` on both halves, to a mask.
    #[inline(always)]
    fn test(self, rhs: F32x8x2, f: impl Fn(F32x8, F32x8) -> Mask8) -> Mask8x2 {
        Mask8x2(f(self.0, rhs.0), f(self.1, rhs.1))
    }
}

/// The lanes as an array.
impl Debug for F32x8x2 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("F32x8x2").field(&SimdF32::to_array(*self)).finish()
    }
}

/// Lane by lane `==` (NaN lanes are unequal).
impl PartialEq for F32x8x2 {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        self.0 == other.0 && self.1 == other.1
    }
}

impl Index<usize> for F32x8x2 {
    type Output = f32;
    /// Lane `lane` (panics past lane 15).
    #[inline(always)]
    fn index(&self, lane: usize) -> &f32 {
        if lane < 8 { &self.0[lane] } else { &self.1[lane - 8] }
    }
}

/// `F32x8x2`'s binary arithmetic operators, [`F32x8`]'s on each half.
macro_rules! pair_binary_ops {
    ($($trait:ident $method:ident),*) => {$(
        impl $trait for F32x8x2 {
            type Output = F32x8x2;
            #[inline(always)]
            fn $method(self, rhs: F32x8x2) -> F32x8x2 {
                self.halves(rhs, $trait::$method)
            }
        }
    )*};
}
pair_binary_ops!(Add add, Sub sub, Mul mul, Div div);

impl SimdF32 for F32x8x2 {
    const LANES: usize = 16;
    const ZERO: F32x8x2 = F32x8x2(F32x8::ZERO, F32x8::ZERO);
    const ONE: F32x8x2 = F32x8x2(F32x8::ONE, F32x8::ONE);
    const INFINITY: F32x8x2 = F32x8x2(F32x8::INFINITY, F32x8::INFINITY);
    const NEG_INFINITY: F32x8x2 = F32x8x2(F32x8::NEG_INFINITY, F32x8::NEG_INFINITY);
    type Mask = Mask8x2;
    type Array<T: Copy + Debug> = [T; 16];

    #[inline(always)]
    fn array_from_fn<T: Copy + Debug>(f: impl FnMut(usize) -> T) -> [T; 16] {
        crate::simd::array_fn(f)
    }
    #[inline(always)]
    fn splat(v: f32) -> F32x8x2 {
        let half = F32x8::splat(v);
        F32x8x2(half, half)
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> F32x8x2 {
        let lanes: [f32; 16] = crate::simd::array_fn(f);
        let (lo, hi) = lanes.split_at(8);
        F32x8x2(F32x8::from_fn(|l| lo[l]), F32x8::from_fn(|l| hi[l]))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 16] {
        let (lo, hi) = (self.0.to_array(), self.1.to_array());
        crate::simd::array_fn(|l| if l < 8 { lo[l] } else { hi[l - 8] })
    }
    #[inline(always)]
    fn axes(points: [Vec3; 16]) -> [F32x8x2; 4] {
        let lo = F32x8::axes(crate::simd::array_fn(|l| points[l]));
        let hi = F32x8::axes(crate::simd::array_fn(|l| points[8 + l]));
        [F32x8x2(lo[0], hi[0]), F32x8x2(lo[1], hi[1]), F32x8x2(lo[2], hi[2]), F32x8x2(lo[3], hi[3])]
    }
    #[inline(always)]
    fn min(self, rhs: F32x8x2) -> F32x8x2 {
        self.halves(rhs, F32x8::min)
    }
    #[inline(always)]
    fn max(self, rhs: F32x8x2) -> F32x8x2 {
        self.halves(rhs, F32x8::max)
    }
    #[inline(always)]
    fn abs(self) -> F32x8x2 {
        F32x8x2(self.0.abs(), self.1.abs())
    }
    #[inline(always)]
    fn copysign(self, sign: F32x8x2) -> F32x8x2 {
        self.halves(sign, F32x8::copysign)
    }
    #[inline(always)]
    fn recip(self) -> F32x8x2 {
        F32x8x2(self.0.recip(), self.1.recip())
    }
    #[inline(always)]
    fn sqrt(self) -> F32x8x2 {
        F32x8x2(self.0.sqrt(), self.1.sqrt())
    }
    #[inline(always)]
    fn strided(values: &[f32], start: usize, stride: usize) -> F32x8x2 {
        // Checks the whole range (and the stride) once; each half then reads inside it.
        let lanes = crate::simd::strided_lanes(values, start, stride, 16);
        F32x8x2(F32x8::strided(lanes, 0, stride), F32x8::strided(lanes, 8 * stride, stride))
    }
    #[inline(always)]
    fn cmpeq(self, rhs: F32x8x2) -> Mask8x2 {
        self.test(rhs, F32x8::cmpeq)
    }
    #[inline(always)]
    fn cmpne(self, rhs: F32x8x2) -> Mask8x2 {
        self.test(rhs, F32x8::cmpne)
    }
    #[inline(always)]
    fn cmplt(self, rhs: F32x8x2) -> Mask8x2 {
        self.test(rhs, F32x8::cmplt)
    }
    #[inline(always)]
    fn cmple(self, rhs: F32x8x2) -> Mask8x2 {
        self.test(rhs, F32x8::cmple)
    }
    #[inline(always)]
    fn cmpgt(self, rhs: F32x8x2) -> Mask8x2 {
        self.test(rhs, F32x8::cmpgt)
    }
    #[inline(always)]
    fn cmpge(self, rhs: F32x8x2) -> Mask8x2 {
        self.test(rhs, F32x8::cmpge)
    }
    #[inline(always)]
    fn is_finite_mask(self) -> Mask8x2 {
        Mask8x2(self.0.is_finite_mask(), self.1.is_finite_mask())
    }
    #[inline(always)]
    fn is_nan_mask(self) -> Mask8x2 {
        Mask8x2(self.0.is_nan_mask(), self.1.is_nan_mask())
    }
    #[inline(always)]
    fn is_negative_bitmask(self) -> u32 {
        self.0.is_negative_bitmask() | self.1.is_negative_bitmask() << 8
    }
    #[inline(always)]
    fn select(mask: Mask8x2, if_true: F32x8x2, if_false: F32x8x2) -> F32x8x2 {
        F32x8x2(F32x8::select(mask.0, if_true.0, if_false.0), F32x8::select(mask.1, if_true.1, if_false.1))
    }
    #[inline(always)]
    fn blend_into(mask: Mask8x2, value: F32x8x2, place: &mut F32x8x2) {
        F32x8::blend_into(mask.0, value.0, &mut place.0);
        F32x8::blend_into(mask.1, value.1, &mut place.1);
    }
    #[inline(always)]
    fn blend_u32(mask: Mask8x2, value: u32, lanes: &mut [u32; 16]) {
        let (halves, _) = lanes.as_chunks_mut::<8>();
        F32x8::blend_u32(mask.0, value, &mut halves[0]);
        F32x8::blend_u32(mask.1, value, &mut halves[1]);
    }
}

/// The set lanes as bits (`Mask8x2(0b...)`, lane 0 the lowest bit).
impl Debug for Mask8x2 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Mask8x2({:#018b})", self.bitmask())
    }
}

/// The same lanes set.
impl PartialEq for Mask8x2 {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        self.bitmask() == other.bitmask()
    }
}

impl Eq for Mask8x2 {}

/// `Mask8x2`'s binary operators, [`Mask8`]'s on each half.
macro_rules! mask_pair_ops {
    ($($trait:ident $method:ident $assign_trait:ident $assign:ident),*) => {$(
        impl $trait for Mask8x2 {
            type Output = Mask8x2;
            #[inline(always)]
            fn $method(self, rhs: Mask8x2) -> Mask8x2 {
                Mask8x2($trait::$method(self.0, rhs.0), $trait::$method(self.1, rhs.1))
            }
        }
        impl $assign_trait for Mask8x2 {
            #[inline(always)]
            fn $assign(&mut self, rhs: Mask8x2) {
                *self = $trait::$method(*self, rhs);
            }
        }
    )*};
}
mask_pair_ops!(BitAnd bitand BitAndAssign bitand_assign, BitOr bitor BitOrAssign bitor_assign);

impl Not for Mask8x2 {
    type Output = Mask8x2;
    #[inline(always)]
    fn not(self) -> Mask8x2 {
        Mask8x2(!self.0, !self.1)
    }
}

impl SimdMask for Mask8x2 {
    #[inline(always)]
    fn splat(v: bool) -> Mask8x2 {
        let half = Mask8::splat(v);
        Mask8x2(half, half)
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> bool) -> Mask8x2 {
        let lanes: [bool; 16] = crate::simd::array_fn(f);
        Mask8x2(Mask8::from_fn(|l| lanes[l]), Mask8::from_fn(|l| lanes[8 + l]))
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        self.0.bitmask() | self.1.bitmask() << 8
    }
    /// One `vorps` and one `vmovmskps`.
    #[inline(always)]
    fn any(self) -> bool {
        (self.0 | self.1).any()
    }
    /// One `vandps` and one `vmovmskps`.
    #[inline(always)]
    fn all(self) -> bool {
        (self.0 & self.1).all()
    }
}

// --------------------------------------------------------------------------------------------
// AVX-512: F32x16 / Mask16
// --------------------------------------------------------------------------------------------

/// Sixteen f32 lanes in one AVX-512 register (`__m512`): the lane type of 16-ray packets.
///
/// # Safety
/// Its operations execute AVX-512F instructions: use it only on a CPU with AVX-512F and VL,
/// AVX2 and FMA ([`F32x16::available`]), and for speed only inside a function compiled for
/// them ([`with_avx512`]; see the [module documentation](self)). On a CPU without them,
/// using it is undefined behaviour (illegal instruction).
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F32x16(pub __m512);

/// The lane mask of [`F32x16`]: one bit per lane in an AVX-512 `k` register (`__mmask16`,
/// a `u16`), as `vcmpps` makes it and `vblendmps` reads it. Its own operations are integer
/// operations, usable anywhere.
///
/// # Safety
/// As [`F32x16`]: the comparisons and selects that make and read it need AVX-512F.
#[derive(Clone, Copy, PartialEq, Eq)]
#[repr(transparent)]
pub struct Mask16(pub __mmask16);

impl F32x16 {
    /// Whether this CPU has what the type needs (AVX-512F and VL, AVX2 and FMA), detected
    /// at run time.
    pub fn available() -> bool {
        is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
            && is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
    }

    /// The lanes of `lanes`, in order (no instruction needed: usable anywhere).
    #[inline(always)]
    pub const fn from_array(lanes: [f32; 16]) -> F32x16 {
        // SAFETY: `__m512` is 64 bytes of plain data, any bits valid.
        F32x16(unsafe { transmute::<[f32; 16], __m512>(lanes) })
    }

    /// The lanes' bits as integers.
    #[inline(always)]
    fn bits(self) -> __m512i {
        // SAFETY: the type's contract (AVX-512F).
        unsafe { _mm512_castps_si512(self.0) }
    }

    /// The lanes with bits `bits`.
    #[inline(always)]
    fn from_bits(bits: __m512i) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16(unsafe { _mm512_castsi512_ps(bits) })
    }

    /// The comparison `IMM` of each lane pair (`vcmpps` into a `k` register).
    #[inline(always)]
    fn cmp<const IMM: i32>(self, rhs: F32x16) -> Mask16 {
        // SAFETY: the type's contract (AVX-512F).
        Mask16(unsafe { _mm512_cmp_ps_mask::<IMM>(self.0, rhs.0) })
    }

    /// One axis of `axes`: the blends and permutation of the module documentation.
    #[inline(always)]
    fn axis(v: &[__m512; 3], axis: usize) -> F32x16 {
        const BLENDS: [[u16; 2]; 3] = {
            let mut b = [[0; 2]; 3];
            let mut a = 0;
            while a < 3 {
                b[a][0] = blend_bits(16, a, 1) as u16;
                b[a][1] = blend_bits(16, a, 2) as u16;
                a += 1;
            }
            b
        };
        const PERMUTATIONS: [[i32; 16]; 3] = [permutation::<16>(0), permutation::<16>(1), permutation::<16>(2)];
        // SAFETY: the type's contract (AVX-512F); the table is plain 64-byte data.
        unsafe {
            let [from1, from2] = BLENDS[axis];
            let blended = _mm512_mask_blend_ps(from2, _mm512_mask_blend_ps(from1, v[0], v[1]), v[2]);
            F32x16(_mm512_permutexvar_ps(transmute::<[i32; 16], __m512i>(PERMUTATIONS[axis]), blended))
        }
    }
}

/// The lanes as an array.
impl Debug for F32x16 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("F32x16").field(&SimdF32::to_array(*self)).finish()
    }
}

/// Lane by lane `==`, as `PortableF32`'s derived equality (NaN lanes are unequal).
impl PartialEq for F32x16 {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        SimdF32::to_array(*self) == SimdF32::to_array(*other)
    }
}

impl Index<usize> for F32x16 {
    type Output = f32;
    /// Lane `lane` (panics past lane 15).
    #[inline(always)]
    fn index(&self, lane: usize) -> &f32 {
        // SAFETY: `F32x16` is `repr(transparent)` over `__m512`, 64 bytes holding 16 f32.
        let lanes = unsafe { &*(self as *const F32x16).cast::<[f32; 16]>() };
        &lanes[lane]
    }
}

/// `F32x16`'s binary arithmetic operators, one AVX-512 instruction each.
macro_rules! avx512_binary_ops {
    ($($trait:ident $method:ident $intrinsic:ident),*) => {$(
        impl $trait for F32x16 {
            type Output = F32x16;
            #[inline(always)]
            fn $method(self, rhs: F32x16) -> F32x16 {
                // SAFETY: the type's contract (AVX-512F).
                F32x16(unsafe { $intrinsic(self.0, rhs.0) })
            }
        }
    )*};
}
avx512_binary_ops!(Add add _mm512_add_ps, Sub sub _mm512_sub_ps, Mul mul _mm512_mul_ps, Div div _mm512_div_ps);

impl SimdF32 for F32x16 {
    const LANES: usize = 16;
    const ZERO: F32x16 = F32x16::from_array([0.0; 16]);
    const ONE: F32x16 = F32x16::from_array([1.0; 16]);
    const INFINITY: F32x16 = F32x16::from_array([f32::INFINITY; 16]);
    const NEG_INFINITY: F32x16 = F32x16::from_array([f32::NEG_INFINITY; 16]);
    type Mask = Mask16;
    type Array<T: Copy + Debug> = [T; 16];

    #[inline(always)]
    fn array_from_fn<T: Copy + Debug>(f: impl FnMut(usize) -> T) -> [T; 16] {
        crate::simd::array_fn(f)
    }
    #[inline(always)]
    fn splat(v: f32) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16(unsafe { _mm512_set1_ps(v) })
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> F32x16 {
        F32x16::from_array(crate::simd::array_fn(f))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 16] {
        // SAFETY: `__m512` is 64 bytes of sixteen f32.
        unsafe { transmute::<__m512, [f32; 16]>(self.0) }
    }
    #[inline(always)]
    fn axes(points: [Vec3; 16]) -> [F32x16; 4] {
        let p = points.as_ptr().cast::<f32>();
        // SAFETY: sixteen `Vec3` are 48 contiguous f32 (asserted at the top); AVX-512F is the
        // type's contract.
        let v = unsafe { [_mm512_loadu_ps(p), _mm512_loadu_ps(p.add(16)), _mm512_loadu_ps(p.add(32))] };
        [F32x16::axis(&v, 0), F32x16::axis(&v, 1), F32x16::axis(&v, 2), F32x16::ZERO]
    }
    #[inline(always)]
    fn min(self, rhs: F32x16) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16(unsafe { _mm512_min_ps(self.0, rhs.0) })
    }
    #[inline(always)]
    fn max(self, rhs: F32x16) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16(unsafe { _mm512_max_ps(self.0, rhs.0) })
    }
    /// The sign bit cleared (an integer `and`: AVX-512F has no float `and`, that is DQ).
    #[inline(always)]
    fn abs(self) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16::from_bits(unsafe { _mm512_andnot_si512(F32x16::ZERO_SIGN.bits(), self.bits()) })
    }
    #[inline(always)]
    fn copysign(self, sign: F32x16) -> F32x16 {
        let s = F32x16::ZERO_SIGN.bits();
        // SAFETY: the type's contract (AVX-512F).
        F32x16::from_bits(unsafe {
            _mm512_or_si512(_mm512_andnot_si512(s, self.bits()), _mm512_and_si512(s, sign.bits()))
        })
    }
    #[inline(always)]
    fn recip(self) -> F32x16 {
        F32x16::ONE / self
    }
    #[inline(always)]
    fn sqrt(self) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16(unsafe { _mm512_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn strided(values: &[f32], start: usize, stride: usize) -> F32x16 {
        let lanes = crate::simd::strided_lanes(values, start, stride, 16);
        if stride == 1 {
            // SAFETY: `lanes` holds 16 f32 (checked above); an unaligned load; the type's
            // contract (AVX-512F).
            return F32x16(unsafe { _mm512_loadu_ps(lanes.as_ptr()) });
        }
        // Strides 2 and 3 as whole vectors and permutes where they fit (a gather is slow on
        // some CPUs: on Zen 4 it was half of the convolution's time).
        let whole = &values[start..];
        if stride == 2 && whole.len() >= 32 {
            const EVEN: [i32; 16] = [0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30];
            // SAFETY: `whole` holds 32 f32 (checked); unaligned loads; the type's contract.
            return F32x16(unsafe {
                let (a, b) = (_mm512_loadu_ps(whole.as_ptr()), _mm512_loadu_ps(whole.as_ptr().add(16)));
                _mm512_permutex2var_ps(a, transmute::<[i32; 16], __m512i>(EVEN), b)
            });
        }
        if stride == 3 && whole.len() >= 48 {
            // Lanes 0 to 10 from the first two vectors (entries 0 to 30), 11 to 15 from the
            // third (entries 33 to 45, its 1 to 13).
            const FIRST: [i32; 16] = [0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 0, 0, 0, 0, 0];
            const THIRD: [i32; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 17, 20, 23, 26, 29];
            // SAFETY: `whole` holds 48 f32 (checked); unaligned loads; the type's contract.
            return F32x16(unsafe {
                let p = whole.as_ptr();
                let (a, b, c) = (_mm512_loadu_ps(p), _mm512_loadu_ps(p.add(16)), _mm512_loadu_ps(p.add(32)));
                let ab = _mm512_permutex2var_ps(a, transmute::<[i32; 16], __m512i>(FIRST), b);
                _mm512_permutex2var_ps(ab, transmute::<[i32; 16], __m512i>(THIRD), c)
            });
        }
        // The lanes' offsets in f32, `l * stride`, at most `lanes.len() - 1`.
        assert!(i32::try_from(lanes.len()).is_ok(), "a gather's offsets are i32");
        let step = stride as i32;
        let offsets: [i32; 16] = crate::simd::array_fn(|l| l as i32 * step);
        // SAFETY: every offset is inside `lanes` (checked above); the type's contract (AVX-512F).
        F32x16(unsafe {
            let idx = transmute::<[i32; 16], __m512i>(offsets);
            _mm512_i32gather_ps::<4>(idx, lanes.as_ptr())
        })
    }
    #[inline(always)]
    fn cmpeq(self, rhs: F32x16) -> Mask16 {
        self.cmp::<_CMP_EQ_OQ>(rhs)
    }
    #[inline(always)]
    fn cmpne(self, rhs: F32x16) -> Mask16 {
        self.cmp::<_CMP_NEQ_UQ>(rhs)
    }
    #[inline(always)]
    fn cmplt(self, rhs: F32x16) -> Mask16 {
        self.cmp::<_CMP_LT_OQ>(rhs)
    }
    #[inline(always)]
    fn cmple(self, rhs: F32x16) -> Mask16 {
        self.cmp::<_CMP_LE_OQ>(rhs)
    }
    #[inline(always)]
    fn cmpgt(self, rhs: F32x16) -> Mask16 {
        self.cmp::<_CMP_GT_OQ>(rhs)
    }
    #[inline(always)]
    fn cmpge(self, rhs: F32x16) -> Mask16 {
        self.cmp::<_CMP_GE_OQ>(rhs)
    }
    /// `|x| < inf`: false for infinities and (unordered) NaNs.
    #[inline(always)]
    fn is_finite_mask(self) -> Mask16 {
        self.abs().cmplt(F32x16::INFINITY)
    }
    #[inline(always)]
    fn is_nan_mask(self) -> Mask16 {
        self.cmp::<_CMP_UNORD_Q>(self)
    }
    /// The lanes whose bits, as signed integers, are negative: the sign bit set.
    #[inline(always)]
    fn is_negative_bitmask(self) -> u32 {
        // SAFETY: the type's contract (AVX-512F).
        u32::from(unsafe { _mm512_cmplt_epi32_mask(self.bits(), _mm512_setzero_si512()) })
    }
    #[inline(always)]
    fn select(mask: Mask16, if_true: F32x16, if_false: F32x16) -> F32x16 {
        // SAFETY: the type's contract (AVX-512F).
        F32x16(unsafe { _mm512_mask_blend_ps(mask.0, if_false.0, if_true.0) })
    }
    #[inline(always)]
    fn blend_u32(mask: Mask16, value: u32, lanes: &mut [u32; 16]) {
        let p = lanes.as_mut_ptr().cast::<__m512i>();
        // SAFETY: the type's contract (AVX-512F); `p` points to the 64 bytes of `lanes`
        // (unaligned loads and stores). LLVM makes the three one masked store
        // (`vmovdqa32` to memory under the mask).
        unsafe {
            let old = _mm512_loadu_si512(p);
            _mm512_storeu_si512(p, _mm512_mask_mov_epi32(old, mask.0, _mm512_set1_epi32(value as i32)));
        }
    }
}

impl F32x16 {
    /// Every lane `-0.0`: the sign bit alone.
    const ZERO_SIGN: F32x16 = F32x16::from_array([-0.0; 16]);
}

/// The set lanes as bits (`Mask16(0b...)`, lane 0 the lowest bit).
impl Debug for Mask16 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Mask16({:#018b})", self.0)
    }
}

/// `Mask16`'s binary operators: the `u16`'s.
macro_rules! mask16_ops {
    ($($trait:ident $method:ident $assign_trait:ident $assign:ident),*) => {$(
        impl $trait for Mask16 {
            type Output = Mask16;
            #[inline(always)]
            fn $method(self, rhs: Mask16) -> Mask16 {
                Mask16($trait::$method(self.0, rhs.0))
            }
        }
        impl $assign_trait for Mask16 {
            #[inline(always)]
            fn $assign(&mut self, rhs: Mask16) {
                *self = $trait::$method(*self, rhs);
            }
        }
    )*};
}
mask16_ops!(BitAnd bitand BitAndAssign bitand_assign, BitOr bitor BitOrAssign bitor_assign);

impl Not for Mask16 {
    type Output = Mask16;
    #[inline(always)]
    fn not(self) -> Mask16 {
        Mask16(!self.0)
    }
}

impl SimdMask for Mask16 {
    #[inline(always)]
    fn splat(v: bool) -> Mask16 {
        Mask16(if v { u16::MAX } else { 0 })
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> bool) -> Mask16 {
        Mask16((0..16).fold(0, |bits, l| bits | u16::from(f(l)) << l))
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        u32::from(self.0)
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.0 != 0
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.0 == u16::MAX
    }
}

// --------------------------------------------------------------------------------------------
// Runners
// --------------------------------------------------------------------------------------------

/// Work to run in a function compiled for a lane type's features ([`with_avx2`],
/// [`with_avx512`]): a kernel call with its arguments.
///
/// Mark `run` `#[inline(always)]`: then it, and every `#[inline(always)]` function it calls
/// (the lane operations, the kernels' hot functions), is compiled into the runner with the
/// feature, at every optimisation level. Closures `FnOnce() -> R` are kernels too; one
/// marked `#[inline(always)]` (in argument position) is inlined the same way, an unmarked
/// one only if the optimiser chooses (not at the workspace's `opt-level = 1` test builds).
pub trait LaneKernel {
    /// What the work returns.
    type Output;
    /// The work.
    fn run(self) -> Self::Output;
}

/// A closure as a kernel (its body inlined into the runner only if the optimiser chooses).
impl<R, F: FnOnce() -> R> LaneKernel for F {
    type Output = R;
    #[inline(always)]
    fn run(self) -> R {
        self()
    }
}

/// `kernel.run()` compiled for AVX2 and FMA, if this CPU has them ([`F32x8::available`]);
/// `None` (without running it) if not. Kernels instantiated with [`F32x8`] run with the
/// lane operations as single instructions when they are `#[inline(always)]`-reachable from
/// an `#[inline(always)]` [`LaneKernel::run`] (see the [module documentation](self)).
pub fn with_avx2<K: LaneKernel>(kernel: K) -> Option<K::Output> {
    F32x8::available().then(|| {
        // SAFETY: the CPU has AVX2 and FMA (just detected).
        unsafe {
            run_avx2(
                #[inline(always)]
                || kernel.run(),
            )
        }
    })
}

/// `kernel.run()` compiled for AVX-512F and VL, AVX2 and FMA, if this CPU has them
/// ([`F32x16::available`]); `None` (without running it) if not. Kernels instantiated with
/// [`F32x16`] run with the lane operations as single instructions when they are
/// `#[inline(always)]`-reachable from an `#[inline(always)]` [`LaneKernel::run`] (see the
/// [module documentation](self)).
pub fn with_avx512<K: LaneKernel>(kernel: K) -> Option<K::Output> {
    F32x16::available().then(|| {
        // SAFETY: the CPU has AVX-512F and VL, AVX2 and FMA (just detected).
        unsafe {
            run_avx512(
                #[inline(always)]
                || kernel.run(),
            )
        }
    })
}

/// Runs `f` in a function compiled for AVX2 and FMA, the features [`F32x8::available`]
/// checks: the one runner of the 8-lane kernels ([`with_avx2`], [`crate::at_width!`]). Pass
/// `f` as an `#[inline(always)]` closure so that its body is compiled into the runner (a
/// closure reached through another generic layer may be left in an out-of-line
/// `FnOnce::call_once` shim, compiled without the features).
///
/// # Safety
/// The CPU must have AVX2 and FMA ([`F32x8::available`]).
#[doc(hidden)]
#[inline(never)]
#[target_feature(enable = "avx2,fma")]
pub unsafe fn run_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// Runs `f` in a function compiled for AVX-512F and VL, AVX2 and FMA, the features
/// [`F32x16::available`] checks: the one runner of the 16-lane kernels ([`with_avx512`],
/// [`crate::at_width!`]), as [`run_avx2`].
///
/// # Safety
/// The CPU must have AVX-512F, AVX-512VL, AVX2 and FMA ([`F32x16::available`]).
#[doc(hidden)]
#[inline(never)]
#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
pub unsafe fn run_avx512<R>(f: impl FnOnce() -> R) -> R {
    f()
}

#[cfg(test)]
mod tests {
    use std::marker::PhantomData;

    use super::*;
    use crate::packet::{OmniPacket, PacketHit, RayPacket};
    use crate::simd::{PortableF32, PortableMask};
    use crate::test_support::{self, HardScene, Rng, packet_hit_bits, ray_packet_bits, specials};
    use crate::triangle4::PacketTest;
    use crate::{omni, samesign};
    use kdtree::Ray;
    use kdtree::counters::NoCounters;
    use kdtree::triangle::{WaldTriangle, WatertightTriangle};

    /// The lanes' bits, exactly.
    fn exact<V: SimdF32, const W: usize>(v: V) -> [u32; W] {
        std::array::from_fn(|l| v[l].to_bits())
    }

    /// The lanes' bits, every NaN as one value: which operand's NaN an arithmetic operation
    /// passes on is not specified (LLVM may swap the operands of the portable `+` and `*`),
    /// only that it is NaN.
    fn arith<V: SimdF32, const W: usize>(v: V) -> [u32; W] {
        std::array::from_fn(|l| if v[l].is_nan() { f32::NAN.to_bits() } else { v[l].to_bits() })
    }

    /// Every operation of `V` on lanes `a`, `b` and mask `m` gives `PortableF32<W>`'s lanes
    /// bit for bit: exactly for the operations that move or select bits (`min`, `max`,
    /// `abs`, `copysign`, `select`), a NaN for a NaN for the arithmetic; masks as bitmasks.
    #[inline(always)]
    fn check_ops<V: SimdF32, const W: usize>(a: [f32; W], b: [f32; W], m: [bool; W]) {
        assert_eq!(V::LANES, W);
        let (va, vb) = (V::from_fn(|l| a[l]), V::from_fn(|l| b[l]));
        let (pa, pb) = (PortableF32(a), PortableF32(b));
        let (vm, pm) = (V::Mask::from_fn(|l| m[l]), PortableMask(m));
        let what = |name: &str| format!("{name} of {a:?} and {b:?}");
        assert_eq!(exact::<V, W>(va), a.map(f32::to_bits), "from_fn and index");
        let array: Vec<u32> = V::to_array(va).as_ref().iter().map(|x| x.to_bits()).collect();
        assert_eq!(array, a.map(f32::to_bits), "to_array");
        let arithmetic: [(V, PortableF32<W>, &str); 6] = [
            (va + vb, pa + pb, "add"),
            (va - vb, pa - pb, "sub"),
            (va * vb, pa * pb, "mul"),
            (va / vb, pa / pb, "div"),
            (va.recip(), pa.recip(), "recip"),
            (va.sqrt(), pa.sqrt(), "sqrt"),
        ];
        for (v, p, name) in arithmetic {
            assert_eq!(arith::<V, W>(v), arith::<_, W>(p), "{}", what(name));
        }
        let bitwise: [(V, PortableF32<W>, &str); 7] = [
            (va.min(vb), pa.min(pb), "min"),
            (va.max(vb), pa.max(pb), "max"),
            (vb.min(va), pb.min(pa), "min swapped"),
            (va.abs(), pa.abs(), "abs"),
            (va.copysign(vb), pa.copysign(pb), "copysign"),
            (V::select(vm, va, vb), PortableF32::select(pm, pa, pb), "select"),
            (V::select(!vm, va, vb), PortableF32::select(!pm, pa, pb), "select not"),
        ];
        for (v, p, name) in bitwise {
            assert_eq!(exact::<V, W>(v), exact::<_, W>(p), "{}", what(name));
        }
        let masks: [(V::Mask, PortableMask<W>, &str); 8] = [
            (va.cmpeq(vb), pa.cmpeq(pb), "eq"),
            (va.cmpne(vb), pa.cmpne(pb), "ne"),
            (va.cmplt(vb), pa.cmplt(pb), "lt"),
            (va.cmple(vb), pa.cmple(pb), "le"),
            (va.cmpgt(vb), pa.cmpgt(pb), "gt"),
            (va.cmpge(vb), pa.cmpge(pb), "ge"),
            (va.is_finite_mask(), pa.is_finite_mask(), "finite"),
            (va.is_nan_mask(), pa.is_nan_mask(), "nan"),
        ];
        for (v, p, name) in masks {
            let name = what(name);
            assert_eq!(v.bitmask(), p.bitmask(), "{name}");
            assert_eq!((v & !vm).bitmask(), (p & !pm).bitmask(), "{name} and not");
            assert_eq!((v | vm).bitmask(), (p | pm).bitmask(), "{name} or");
            let (mut and, mut or) = (v, v);
            and &= vm;
            or |= vm;
            assert_eq!((and.bitmask(), or.bitmask()), ((p & pm).bitmask(), (p | pm).bitmask()), "{name} assign");
            assert_eq!((v.any(), v.all()), (p.any(), p.all()), "{name} any all");
            assert_eq!(v == vm, p == pm, "{name} ==");
            // A select by the comparison's mask, as the kernels use it.
            assert_eq!(
                exact::<V, W>(V::select(v, va, V::INFINITY)),
                exact::<_, W>(PortableF32::select(p, pa, PortableF32::INFINITY)),
                "{name} select"
            );
        }
        assert_eq!(va.is_negative_bitmask(), pa.is_negative_bitmask(), "{}", what("sign bits"));
        // `blend_u32` on the lanes' bits (every pattern, NaNs' included, an integer here).
        let (mut vi, mut pi) = (V::array_from_fn(|l| a[l].to_bits()), a.map(f32::to_bits));
        V::blend_u32(vm, b[0].to_bits(), &mut vi);
        PortableF32::<W>::blend_u32(pm, b[0].to_bits(), &mut pi);
        assert_eq!(vi.as_ref(), &pi[..], "{}", what("blend_u32"));
        // `blend_into`: `select` into the place, bit for bit.
        let (mut vp, mut pp) = (va, pa);
        V::blend_into(vm, vb, &mut vp);
        PortableF32::<W>::blend_into(pm, pb, &mut pp);
        assert_eq!(exact::<V, W>(vp), exact::<_, W>(pp), "{}", what("blend_into"));
        assert_eq!(exact::<V, W>(vp), exact::<V, W>(V::select(vm, vb, va)), "{}", what("blend_into is select"));
        assert_eq!(va == vb, pa == pb, "{}", what("=="));
        let (va2, pa2) = (V::from_fn(|l| a[l]), PortableF32(a));
        assert_eq!(va == va2, pa == pa2, "{}", what("== a copy (false with a NaN lane)"));
    }

    /// [`check_ops`] on every special value against a sweep of others, spread over the
    /// lanes; then the constants, constructors, masks and `axes`.
    #[inline(always)]
    fn check_all<V: SimdF32, const W: usize>() {
        let s = specials();
        let n = s.len();
        for i in 0..n {
            for j in (0..n).step_by(3) {
                let a: [f32; W] = std::array::from_fn(|l| s[(i + 7 * l) % n]);
                let b: [f32; W] = std::array::from_fn(|l| s[(j + 5 * l + l * l) % n]);
                let m: [bool; W] = std::array::from_fn(|l| (i + j + l) % 3 == 0 || a[l] < b[l]);
                check_ops::<V, W>(a, b, m);
                // Equal operands: `min` / `max` of equal values return the second.
                let c: [f32; W] = std::array::from_fn(|l| if l % 2 == 0 { -a[l] } else { a[l] });
                check_ops::<V, W>(a, c, m);
            }
        }
        let constants: [(V, PortableF32<W>); 5] = [
            (V::ZERO, PortableF32::ZERO),
            (V::ONE, PortableF32::ONE),
            (V::INFINITY, PortableF32::INFINITY),
            (V::NEG_INFINITY, PortableF32::NEG_INFINITY),
            (V::splat(-2.5e-40), PortableF32::splat(-2.5e-40)),
        ];
        for (v, p) in constants {
            assert_eq!(exact::<V, W>(v), exact::<_, W>(p));
        }
        assert_eq!(V::array_from_fn(|l| l * 3).as_ref(), &std::array::from_fn::<usize, W, _>(|l| l * 3)[..]);
        for bits in [0u32, 1, 0b1010_0101_1100_0011, (1 << W) - 1, 1 << (W - 1), 0x5555_5555] {
            let bits = bits & ((1u64 << W) - 1) as u32;
            let (v, p) = (V::Mask::from_fn(|l| bits >> l & 1 != 0), PortableMask::<W>::from_fn(|l| bits >> l & 1 != 0));
            assert_eq!(
                (v.bitmask(), (!v).bitmask(), v.any(), v.all()),
                (p.bitmask(), (!p).bitmask(), p.any(), p.all())
            );
            assert_eq!(v.bitmask(), bits);
        }
        for v in [false, true] {
            assert_eq!(V::Mask::splat(v).bitmask(), PortableMask::<W>::splat(v).bitmask());
        }
        // `strided`: every start and stride that fits, against the entries themselves; near
        // the end too, where whole vectors would not fit.
        let long: Vec<f32> = (0..100).map(|i| s[(7 * i) % n]).collect();
        for stride in 1..=4 {
            for start in 0..=long.len() - ((W - 1) * stride + 1) {
                let v = V::strided(&long, start, stride);
                assert_eq!(exact::<V, W>(v), std::array::from_fn(|l| long[start + l * stride].to_bits()), "strided");
                assert_eq!(exact::<V, W>(v), exact::<_, W>(PortableF32::<W>::strided(&long, start, stride)));
            }
        }
        // `axes`: the blends and permutation against the lane-by-lane transpose.
        let mut rng = Rng(0x0a8e_5eed);
        for round in 0..64 {
            let points: [Vec3; W] = std::array::from_fn(|l| {
                let p = rng.vec(Vec3::splat(-1e3), Vec3::splat(1e3));
                if round % 4 == 0 {
                    Vec3::new(s[(l + round) % n], s[(3 * l + 1) % n], s[(5 * l + round) % n])
                } else {
                    p
                }
            });
            let (v, p) = (V::axes(V::array_from_fn(|l| points[l])), PortableF32::<W>::axes(points));
            for axis in 0..4 {
                assert_eq!(exact::<V, W>(v[axis]), exact::<_, W>(p[axis]), "axis {axis} of {points:?}");
            }
        }
    }

    /// Skips with a note where the CPU lacks the feature.
    fn skipped(ran: Option<()>, what: &str) {
        if ran.is_none() {
            eprintln!("skipped: this CPU has no {what}");
        }
    }

    /// [`check_all`], [`triangles_agree`] and [`walks_agree`] as kernels: each test body is
    /// compiled into the runner, with the feature (a closure's body would not be, at
    /// `opt-level = 1`).
    struct CheckAll<V, const W: usize>(PhantomData<V>);
    struct TrianglesAgree<V, const W: usize>(PhantomData<V>);
    struct WalksAgree<'a, V, const W: usize>(&'a [HardScene], PhantomData<V>);

    impl<V: SimdF32, const W: usize> LaneKernel for CheckAll<V, W> {
        type Output = ();
        #[inline(always)]
        fn run(self) {
            check_all::<V, W>();
        }
    }

    impl<V: SimdF32, const W: usize> LaneKernel for TrianglesAgree<V, W> {
        type Output = usize;
        #[inline(always)]
        fn run(self) -> usize {
            triangles_agree::<V, W>()
        }
    }

    impl<V: SimdF32, const W: usize> LaneKernel for WalksAgree<'_, V, W> {
        type Output = usize;
        #[inline(always)]
        fn run(self) -> usize {
            walks_agree::<V, W>(self.0)
        }
    }

    /// Every operation of `F32x8` / `Mask8`, compiled for AVX2, is `PortableF32<8>`'s.
    #[test]
    fn avx2_lanes_are_the_portable_lanes_bit_for_bit() {
        skipped(with_avx2(CheckAll::<F32x8, 8>(PhantomData)), "AVX2 and FMA");
    }

    /// Every operation of `F32x8x2` / `Mask8x2`, compiled for AVX2, is `PortableF32<16>`'s.
    #[test]
    fn avx2_pairs_are_the_portable_lanes_bit_for_bit() {
        skipped(with_avx2(CheckAll::<F32x8x2, 16>(PhantomData)), "AVX2 and FMA");
    }

    /// Every operation of `F32x16` / `Mask16`, compiled for AVX-512, is `PortableF32<16>`'s.
    #[test]
    fn avx512_lanes_are_the_portable_lanes_bit_for_bit() {
        skipped(with_avx512(CheckAll::<F32x16, 16>(PhantomData)), "AVX-512F/VL");
    }

    #[test]
    fn masks_print_as_bits_and_detection_matches_the_runners() {
        assert_eq!(format!("{:?}", Mask16(0b101)), "Mask16(0b0000000000000101)");
        assert_eq!(format!("{:?}", F32x16::from_array([1.0; 16])), format!("F32x16({:?})", [1.0f32; 16]));
        assert_eq!(with_avx2(|| 1).is_some(), F32x8::available());
        assert_eq!(with_avx512(|| 1).is_some(), F32x16::available());
        if F32x8::available() {
            assert_eq!(format!("{:?}", Mask8::from_bits(0b11)), "Mask8(0b00000011)");
        }
    }

    /// Random triangles against packets of `W` random rays (mixed shear axes, so the
    /// watertight test's scalar lanes; one shared direction, so its SIMD path), both
    /// intersectors: `V`'s packets and hits are `PortableF32<W>`'s, bit for bit. Returns
    /// the number of lanes that hit.
    #[inline(always)]
    fn triangles_agree<V: SimdF32, const W: usize>() -> usize {
        let mut rng = Rng(0x7121_a9e1);
        let mut hits = 0;
        for round in 0..400 {
            let tri = [0; 3].map(|_| rng.vec(Vec3::splat(-4.0), Vec3::splat(4.0)));
            let shared = rng.vec(Vec3::splat(-1.0), Vec3::splat(1.0));
            let count = if round % 5 == 0 { 1 + round % W } else { W };
            let rays: Vec<Ray> = (0..count)
                .map(|lane| {
                    let o = rng.vec(Vec3::splat(-4.0), Vec3::splat(4.0));
                    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
                    let d = match round % 3 {
                        0 => shared,
                        1 if lane % 2 == 0 => centre - o,
                        _ => rng.vec(Vec3::splat(-1.0), Vec3::splat(1.0)),
                    };
                    Ray::new(o, if d == Vec3::ZERO { Vec3::X } else { d }, 0.1 * rng.next(), 1.0 + 20.0 * rng.next())
                })
                .collect();
            let (v, p) = (RayPacket::<V>::from_rays(&rays), RayPacket::<PortableF32<W>>::from_rays(&rays));
            assert_eq!(ray_packet_bits(&v), ray_packet_bits(&p), "packet of {rays:?}");
            hits += packet_agrees(&WaldTriangle::new(&tri), &v, &p, &rays);
            hits += packet_agrees(&WatertightTriangle::new(&tri), &v, &p, &rays);
        }
        hits
    }

    /// One packet-triangle test at `V` and at `PortableF32<W>`: the same hits and mask.
    #[inline(always)]
    fn packet_agrees<T: PacketTest<V> + PacketTest<PortableF32<W>>, V: SimdF32, const W: usize>(
        tri: &T,
        v: &RayPacket<V>,
        p: &RayPacket<PortableF32<W>>,
        rays: &[Ray],
    ) -> usize {
        let (mut vh, mut ph) = (PacketHit::new(v), PacketHit::new(p));
        let vm = tri.intersect4(v, &<T as PacketTest<V>>::prepare4(v), v.valid, &mut vh, 5);
        let pm = tri.intersect4(p, &<T as PacketTest<PortableF32<W>>>::prepare4(p), p.valid, &mut ph, 5);
        assert_eq!(vm.bitmask(), pm.bitmask(), "{rays:?}");
        assert_eq!(packet_hit_bits(&vh), packet_hit_bits(&ph), "{rays:?}");
        vm.bitmask().count_ones() as usize
    }

    /// The packet-triangle tests at 8 (AVX2) and 16 (AVX-512, and AVX2 pairs) lanes give the
    /// portable twin's answers bit for bit.
    #[test]
    fn packet_triangle_tests_at_8_and_16_lanes_are_the_portable_ones() {
        let hits = with_avx2(TrianglesAgree::<F32x8, 8>(PhantomData));
        assert!(hits.is_none_or(|h| h > 500), "8 lanes: {hits:?} hits");
        skipped(hits.map(|_| ()), "AVX2 and FMA");
        let hits = with_avx512(TrianglesAgree::<F32x16, 16>(PhantomData));
        assert!(hits.is_none_or(|h| h > 1000), "16 lanes: {hits:?} hits");
        skipped(hits.map(|_| ()), "AVX-512F/VL");
        let hits = with_avx2(TrianglesAgree::<F32x8x2, 16>(PhantomData));
        assert!(hits.is_none_or(|h| h > 1000), "16 lanes in AVX2 pairs: {hits:?} hits");
    }

    /// The omni-directional and same-sign walks over the hard scenes (both intersectors,
    /// every hard ray case): with `V` each packet's closest and any hits are
    /// `PortableF32<W>`'s, bit for bit. Returns the number of closest hits.
    #[inline(always)]
    fn walks_agree<V: SimdF32, const W: usize>(scenes: &[HardScene]) -> usize {
        let mut rng = Rng(0x0000_0a1c_0de5);
        let mut hits = 0;
        for scene in scenes {
            for (t, tree) in scene.trees.iter().enumerate() {
                for round in 0..24 {
                    let kind = round % 6;
                    let what = format!("{} tree {t} round {round} kind {kind}", scene.name);
                    // Same-sign: each ray its own origin.
                    let rays = scene.rays(&mut rng, W, kind, false);
                    let (v, p) = (RayPacket::<V>::from_rays(&rays), RayPacket::<PortableF32<W>>::from_rays(&rays));
                    let closest = samesign::intersect(tree, &v, &mut NoCounters);
                    assert_eq!(
                        packet_hit_bits(&closest),
                        packet_hit_bits(&samesign::intersect(tree, &p, &mut NoCounters)),
                        "samesign {what}"
                    );
                    assert_eq!(
                        packet_hit_bits(&samesign::occluded(tree, &v, &mut NoCounters)),
                        packet_hit_bits(&samesign::occluded(tree, &p, &mut NoCounters)),
                        "samesign any hit {what}"
                    );
                    hits += closest.found.bitmask().count_ones() as usize;
                    // Omni-directional: one shared origin.
                    let rays = scene.rays(&mut rng, W, kind, true);
                    let v = OmniPacket::new(RayPacket::<V>::from_rays(&rays)).expect("one origin");
                    let p = OmniPacket::new(RayPacket::<PortableF32<W>>::from_rays(&rays)).expect("one origin");
                    let closest = omni::intersect(tree, &v, &mut NoCounters);
                    assert_eq!(
                        packet_hit_bits(&closest),
                        packet_hit_bits(&omni::intersect(tree, &p, &mut NoCounters)),
                        "omni {what}"
                    );
                    assert_eq!(
                        packet_hit_bits(&omni::occluded(tree, &v, &mut NoCounters)),
                        packet_hit_bits(&omni::occluded(tree, &p, &mut NoCounters)),
                        "omni any hit {what}"
                    );
                    hits += closest.found.bitmask().count_ones() as usize;
                }
            }
        }
        hits
    }

    /// The packet walks at 8 (AVX2) and 16 (AVX-512, and AVX2 pairs) lanes give the portable
    /// twin's answers bit for bit on the hard scenes.
    #[test]
    fn packet_walks_at_8_and_16_lanes_are_the_portable_ones() {
        let scenes = test_support::hard_scenes();
        let hits = with_avx2(WalksAgree::<F32x8, 8>(&scenes, PhantomData));
        assert!(hits.is_none_or(|h| h > 500), "8 lanes: {hits:?} hits");
        skipped(hits.map(|_| ()), "AVX2 and FMA");
        let hits = with_avx512(WalksAgree::<F32x16, 16>(&scenes, PhantomData));
        assert!(hits.is_none_or(|h| h > 1000), "16 lanes: {hits:?} hits");
        skipped(hits.map(|_| ()), "AVX-512F/VL");
        let hits = with_avx2(WalksAgree::<F32x8x2, 16>(&scenes, PhantomData));
        assert!(hits.is_none_or(|h| h > 1000), "16 lanes in AVX2 pairs: {hits:?} hits");
    }
}
