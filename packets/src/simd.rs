//! The lane types a ray packet is generic over: a vector of `W` f32 lanes ([`SimdF32`]) and
//! its lane mask ([`SimdMask`]), with exactly the operations the packet code uses.
//!
//! A packet's width is its lane type's: [`RayPacket<V>`](crate::RayPacket) holds `V::LANES`
//! rays, and the 2x2 packet walks of thesis 4.1.2 (omni-directional, [`crate::omni`]) and
//! 2.3.1 (same-sign, [`crate::samesign`]) and the packet-triangle tests
//! ([`crate::triangle4`]) are written once for every width. Two lane types are here:
//! - glam's [`Vec4`] / [`BVec4A`] (`W = 4`, one SSE register): the default everywhere, each
//!   operation the glam method the code called before it was generic, so the 4-wide code is
//!   the same instructions;
//! - [`PortableF32<W>`] / [`PortableMask<W>`]: plain `[f32; W]` / `[bool; W]` for any `W`
//!   from 1 to 32, the scalar twin (8 and 16 lanes on every machine). Each operation is
//!   the IEEE operation of each lane; `min` and `max` are SSE's (`minps`: `a < b ? a : b`,
//!   the second operand on NaN and on equal values), so `PortableF32<4>` gives the glam type's
//!   answers bit for bit (tested; which NaN a NaN operation returns is left unspecified, as
//!   by LLVM, and no kernel reads it).
//!
//! Every operation is `#[inline(always)]`: a kernel instantiated with a lane type has no
//! call or dispatch left for the lane operations.

use std::fmt::Debug;
use std::ops::{Add, BitAnd, BitAndAssign, BitOr, BitOrAssign, Div, Index, IndexMut, Mul, Not, Sub};

use glam::{BVec4A, Mat4, Vec3, Vec4};

/// A vector of [`SimdF32::LANES`] f32 lanes: the coordinate of a packet's rays on one axis,
/// their interval ends, their hits' distances.
pub trait SimdF32:
    Copy
    + Debug
    + PartialEq
    + Index<usize, Output = f32>
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
{
    /// The number of lanes `W` (at most 32, so that a mask fits a `u32` bitmask).
    const LANES: usize;
    /// Every lane `0.0`.
    const ZERO: Self;
    /// Every lane `1.0`.
    const ONE: Self;
    /// Every lane `+inf`.
    const INFINITY: Self;
    /// Every lane `-inf`.
    const NEG_INFINITY: Self;
    /// The lane mask.
    type Mask: SimdMask;
    /// `[T; W]`: one value per lane (a packet's triangle indices, per-lane precomputations).
    type Array<T: Copy + Debug>: Copy + Debug + AsRef<[T]> + AsMut<[T]> + Index<usize, Output = T> + IndexMut<usize>;

    /// The array of `f(lane)` for each lane, in lane order.
    fn array_from_fn<T: Copy + Debug>(f: impl FnMut(usize) -> T) -> Self::Array<T>;
    /// Every lane `v`.
    fn splat(v: f32) -> Self;
    /// Lane `l` is `f(l)`, called in lane order.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// The lanes as an array.
    fn to_array(self) -> Self::Array<f32>;
    /// One point per lane as one vector per axis, `[x, y, z, 0]` (the packet's per-axis
    /// arrays, whose fourth entry is padding).
    fn axes(points: Self::Array<Vec3>) -> [Self; 4];

    /// Per lane, `if self < rhs { self } else { rhs }` (SSE's `minps`).
    fn min(self, rhs: Self) -> Self;
    /// Per lane, `if self > rhs { self } else { rhs }` (SSE's `maxps`).
    fn max(self, rhs: Self) -> Self;
    /// Per lane, the absolute value (the sign bit cleared).
    fn abs(self) -> Self;
    /// Per lane, `self`'s magnitude with `sign`'s sign bit.
    fn copysign(self, sign: Self) -> Self;
    /// Per lane, `1.0 / self`.
    fn recip(self) -> Self;
    /// Per lane, the square root (IEEE, correctly rounded: the same bits at every width).
    fn sqrt(self) -> Self;
    /// Lane `l` is `values[start + l * stride]`: a row of a structure-of-arrays frame read
    /// every `stride`-th entry (one vector load at stride 1, a gather otherwise).
    ///
    /// # Panics
    /// If the last lane's index is past `values`, or `stride` is 0.
    fn strided(values: &[f32], start: usize, stride: usize) -> Self;

    /// Per lane, `self == rhs`.
    fn cmpeq(self, rhs: Self) -> Self::Mask;
    /// Per lane, `self != rhs` (true where either is NaN).
    fn cmpne(self, rhs: Self) -> Self::Mask;
    /// Per lane, `self < rhs`.
    fn cmplt(self, rhs: Self) -> Self::Mask;
    /// Per lane, `self <= rhs`.
    fn cmple(self, rhs: Self) -> Self::Mask;
    /// Per lane, `self > rhs`.
    fn cmpgt(self, rhs: Self) -> Self::Mask;
    /// Per lane, `self >= rhs`.
    fn cmpge(self, rhs: Self) -> Self::Mask;
    /// The lanes that are neither infinite nor NaN.
    fn is_finite_mask(self) -> Self::Mask;
    /// The lanes that are NaN.
    fn is_nan_mask(self) -> Self::Mask;
    /// Bit `l` set where lane `l`'s sign bit is (`-0.0` and negative NaNs included).
    fn is_negative_bitmask(self) -> u32;
    /// Per lane, `if_true` where `mask` is set, else `if_false`.
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self;
    /// `*place = select(mask, value, *place)`: a packet's hit taking a triangle's in some
    /// lanes ([`crate::packet::PacketHit::record`]). This default is the plain blend; the
    /// AVX lane types store the blend with a volatile write, because LLVM turns a plain
    /// store of a blend with the value it replaces into a masked store (`vmaskmovps`), which
    /// AMD's cores run as microcode: tens of µops for each, about 6% of the 16-lane MFT
    /// kernel (`perf annotate`, Sponza, where `rttest` printed `cpu: AMD EPYC (family 25
    /// model 1)`). The volatile write is one plain store.
    #[inline(always)]
    fn blend_into(mask: Self::Mask, value: Self, place: &mut Self) {
        *place = Self::select(mask, value, *place);
    }
    /// `lanes[l] = value` in the lanes set in `mask`, the others unchanged: a packet's
    /// triangle indices taking a hit ([`crate::packet::PacketHit::record`]). This default,
    /// one branch-free blend per lane, is the scalar twin; the x86 lane types blend the whole
    /// array at once (a blend between a load and a store, as [`SimdF32::blend_into`]).
    #[inline(always)]
    fn blend_u32(mask: Self::Mask, value: u32, lanes: &mut Self::Array<u32>) {
        let bits = mask.bitmask();
        for (lane, slot) in lanes.as_mut().iter_mut().enumerate() {
            let take = (bits >> lane & 1).wrapping_neg();
            *slot = (*slot & !take) | (value & take);
        }
    }
}

/// The lane mask of a [`SimdF32`]: one flag per lane.
pub trait SimdMask:
    Copy
    + Debug
    + PartialEq
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + Not<Output = Self>
    + BitAndAssign
    + BitOrAssign
{
    /// Every lane `v`.
    fn splat(v: bool) -> Self;
    /// Lane `l` is `f(l)`, called in lane order.
    fn from_fn(f: impl FnMut(usize) -> bool) -> Self;
    /// Bit `l` set where lane `l` is.
    fn bitmask(self) -> u32;
    /// Whether any lane is set.
    fn any(self) -> bool;
    /// Whether every lane is set.
    fn all(self) -> bool;
}

/// `[f(0), f(1), ..., f(N - 1)]`, built in place: `std::array::from_fn` without its generic
/// machinery. std's `from_fn` and `map` are ordinary `#[inline]` functions that the optimiser
/// may leave out of line, compiled without a kernel's target features; this one is
/// `#[inline(always)]`, so a kernel inlined into a `#[target_feature]` function (see
/// [`crate::at_width!`]) keeps its lane operations there as single instructions.
#[inline(always)]
pub fn array_fn<T: Copy, const N: usize>(mut f: impl FnMut(usize) -> T) -> [T; N] {
    let mut out = [std::mem::MaybeUninit::<T>::uninit(); N];
    let mut l = 0;
    while l < N {
        out[l].write(f(l));
        l += 1;
    }
    // SAFETY: every element was written above, and `[MaybeUninit<T>; N]` has the layout of
    // `[T; N]`.
    unsafe { std::mem::transmute_copy::<[std::mem::MaybeUninit<T>; N], [T; N]>(&out) }
}

/// The entries `values[start..]` that [`SimdF32::strided`]'s `lanes` lanes read, every
/// `stride`-th from the first; checked once, so that the lanes' reads need no check of their
/// own.
///
/// # Panics
/// If the last lane's index is past `values`, or `stride` is 0.
#[inline(always)]
pub fn strided_lanes(values: &[f32], start: usize, stride: usize, lanes: usize) -> &[f32] {
    assert!(stride > 0, "a strided read needs a stride");
    &values[start..=start + (lanes - 1) * stride]
}

/// glam's SSE vector: the 4-wide packets, each operation the glam method of the same name.
impl SimdF32 for Vec4 {
    const LANES: usize = 4;
    const ZERO: Vec4 = Vec4::ZERO;
    const ONE: Vec4 = Vec4::ONE;
    const INFINITY: Vec4 = Vec4::INFINITY;
    const NEG_INFINITY: Vec4 = Vec4::NEG_INFINITY;
    type Mask = BVec4A;
    type Array<T: Copy + Debug> = [T; 4];

    #[inline(always)]
    fn array_from_fn<T: Copy + Debug>(f: impl FnMut(usize) -> T) -> [T; 4] {
        array_fn(f)
    }
    #[inline(always)]
    fn splat(v: f32) -> Vec4 {
        Vec4::splat(v)
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Vec4 {
        let (x, y, z, w) = (f(0), f(1), f(2), f(3));
        Vec4::new(x, y, z, w)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 4] {
        Vec4::to_array(&self)
    }
    /// A 4x4 transpose in shuffles rather than scalar stores read back as vectors.
    #[inline(always)]
    fn axes(v: [Vec3; 4]) -> [Vec4; 4] {
        let m = Mat4::from_cols(v[0].extend(0.0), v[1].extend(0.0), v[2].extend(0.0), v[3].extend(0.0)).transpose();
        [m.x_axis, m.y_axis, m.z_axis, m.w_axis]
    }
    #[inline(always)]
    fn min(self, rhs: Vec4) -> Vec4 {
        Vec4::min(self, rhs)
    }
    #[inline(always)]
    fn max(self, rhs: Vec4) -> Vec4 {
        Vec4::max(self, rhs)
    }
    #[inline(always)]
    fn abs(self) -> Vec4 {
        Vec4::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Vec4) -> Vec4 {
        Vec4::copysign(self, sign)
    }
    #[inline(always)]
    fn recip(self) -> Vec4 {
        Vec4::recip(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Vec4 {
        Vec4::from_array(self.to_array().map(f32::sqrt))
    }
    #[inline(always)]
    fn strided(values: &[f32], start: usize, stride: usize) -> Vec4 {
        let lanes = strided_lanes(values, start, stride, 4);
        Vec4::new(lanes[0], lanes[stride], lanes[2 * stride], lanes[3 * stride])
    }
    #[inline(always)]
    fn cmpeq(self, rhs: Vec4) -> BVec4A {
        Vec4::cmpeq(self, rhs)
    }
    #[inline(always)]
    fn cmpne(self, rhs: Vec4) -> BVec4A {
        Vec4::cmpne(self, rhs)
    }
    #[inline(always)]
    fn cmplt(self, rhs: Vec4) -> BVec4A {
        Vec4::cmplt(self, rhs)
    }
    #[inline(always)]
    fn cmple(self, rhs: Vec4) -> BVec4A {
        Vec4::cmple(self, rhs)
    }
    #[inline(always)]
    fn cmpgt(self, rhs: Vec4) -> BVec4A {
        Vec4::cmpgt(self, rhs)
    }
    #[inline(always)]
    fn cmpge(self, rhs: Vec4) -> BVec4A {
        Vec4::cmpge(self, rhs)
    }
    #[inline(always)]
    fn is_finite_mask(self) -> BVec4A {
        Vec4::is_finite_mask(self)
    }
    #[inline(always)]
    fn is_nan_mask(self) -> BVec4A {
        Vec4::is_nan_mask(self)
    }
    #[inline(always)]
    fn is_negative_bitmask(self) -> u32 {
        Vec4::is_negative_bitmask(self)
    }
    #[inline(always)]
    fn select(mask: BVec4A, if_true: Vec4, if_false: Vec4) -> Vec4 {
        Vec4::select(mask, if_true, if_false)
    }
    /// A volatile store of the blend (see the trait): inside an AVX kernel a plain one could
    /// become `vmaskmovps`.
    #[inline(always)]
    fn blend_into(mask: BVec4A, value: Vec4, place: &mut Vec4) {
        let blend = Vec4::select(mask, value, *place);
        // SAFETY: `place` is a valid, aligned, exclusive reference.
        unsafe { std::ptr::write_volatile(place, blend) }
    }
}

/// glam's SSE mask of [`Vec4`].
impl SimdMask for BVec4A {
    #[inline(always)]
    fn splat(v: bool) -> BVec4A {
        BVec4A::splat(v)
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> bool) -> BVec4A {
        let (x, y, z, w) = (f(0), f(1), f(2), f(3));
        BVec4A::new(x, y, z, w)
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        BVec4A::bitmask(self)
    }
    #[inline(always)]
    fn any(self) -> bool {
        BVec4A::any(self)
    }
    #[inline(always)]
    fn all(self) -> bool {
        BVec4A::all(self)
    }
}

/// `W` f32 lanes in a plain array, each operation lane by lane: the portable (scalar) twin
/// of the SIMD lane types, for any width from 1 to 32. 8 and 16 lanes are the widths of
/// AVX2 and AVX-512 packets.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(transparent)]
pub struct PortableF32<const W: usize>(pub [f32; W]);

/// The lane mask of [`PortableF32<W>`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(transparent)]
pub struct PortableMask<const W: usize>(pub [bool; W]);

impl<const W: usize> PortableF32<W> {
    /// Lane by lane, `f(self[l], rhs[l])`.
    #[inline(always)]
    fn zip(self, rhs: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        PortableF32(array_fn(|l| f(self.0[l], rhs.0[l])))
    }

    /// Lane by lane, `f(self[l], rhs[l])` as a mask.
    #[inline(always)]
    fn test(self, rhs: Self, f: impl Fn(f32, f32) -> bool) -> PortableMask<W> {
        PortableMask(array_fn(|l| f(self.0[l], rhs.0[l])))
    }
}

impl<const W: usize> Index<usize> for PortableF32<W> {
    type Output = f32;
    #[inline(always)]
    fn index(&self, lane: usize) -> &f32 {
        &self.0[lane]
    }
}

impl<const W: usize> Add for PortableF32<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, rhs: Self) -> Self {
        self.zip(rhs, |a, b| a + b)
    }
}

impl<const W: usize> Sub for PortableF32<W> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, rhs: Self) -> Self {
        self.zip(rhs, |a, b| a - b)
    }
}

impl<const W: usize> Mul for PortableF32<W> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, rhs: Self) -> Self {
        self.zip(rhs, |a, b| a * b)
    }
}

impl<const W: usize> Div for PortableF32<W> {
    type Output = Self;
    #[inline(always)]
    fn div(self, rhs: Self) -> Self {
        self.zip(rhs, |a, b| a / b)
    }
}

impl<const W: usize> SimdF32 for PortableF32<W> {
    const LANES: usize = {
        assert!(W >= 1 && W <= 32, "a portable packet has 1 to 32 lanes");
        W
    };
    const ZERO: Self = PortableF32([0.0; W]);
    const ONE: Self = PortableF32([1.0; W]);
    const INFINITY: Self = PortableF32([f32::INFINITY; W]);
    const NEG_INFINITY: Self = PortableF32([f32::NEG_INFINITY; W]);
    type Mask = PortableMask<W>;
    type Array<T: Copy + Debug> = [T; W];

    #[inline(always)]
    fn array_from_fn<T: Copy + Debug>(f: impl FnMut(usize) -> T) -> [T; W] {
        array_fn(f)
    }
    #[inline(always)]
    fn splat(v: f32) -> Self {
        PortableF32([v; W])
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
        PortableF32(array_fn(f))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; W] {
        self.0
    }
    #[inline(always)]
    fn axes(points: [Vec3; W]) -> [Self; 4] {
        array_fn(|axis| if axis < 3 { Self::from_fn(|l| points[l][axis]) } else { Self::ZERO })
    }
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        self.zip(rhs, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        self.zip(rhs, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn abs(self) -> Self {
        PortableF32(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        self.zip(sign, f32::copysign)
    }
    #[inline(always)]
    fn recip(self) -> Self {
        PortableF32(self.0.map(|a| 1.0 / a))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        PortableF32(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn strided(values: &[f32], start: usize, stride: usize) -> Self {
        let lanes = strided_lanes(values, start, stride, W);
        Self::from_fn(|l| lanes[l * stride])
    }
    #[inline(always)]
    fn cmpeq(self, rhs: Self) -> PortableMask<W> {
        self.test(rhs, |a, b| a == b)
    }
    #[inline(always)]
    fn cmpne(self, rhs: Self) -> PortableMask<W> {
        self.test(rhs, |a, b| a != b)
    }
    #[inline(always)]
    fn cmplt(self, rhs: Self) -> PortableMask<W> {
        self.test(rhs, |a, b| a < b)
    }
    #[inline(always)]
    fn cmple(self, rhs: Self) -> PortableMask<W> {
        self.test(rhs, |a, b| a <= b)
    }
    #[inline(always)]
    fn cmpgt(self, rhs: Self) -> PortableMask<W> {
        self.test(rhs, |a, b| a > b)
    }
    #[inline(always)]
    fn cmpge(self, rhs: Self) -> PortableMask<W> {
        self.test(rhs, |a, b| a >= b)
    }
    #[inline(always)]
    fn is_finite_mask(self) -> PortableMask<W> {
        PortableMask(self.0.map(f32::is_finite))
    }
    #[inline(always)]
    fn is_nan_mask(self) -> PortableMask<W> {
        PortableMask(self.0.map(f32::is_nan))
    }
    #[inline(always)]
    fn is_negative_bitmask(self) -> u32 {
        (0..Self::LANES).fold(0, |bits, l| bits | u32::from(self.0[l].is_sign_negative()) << l)
    }
    #[inline(always)]
    fn select(mask: PortableMask<W>, if_true: Self, if_false: Self) -> Self {
        PortableF32(array_fn(|l| if mask.0[l] { if_true.0[l] } else { if_false.0[l] }))
    }
}

impl<const W: usize> BitAnd for PortableMask<W> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, rhs: Self) -> Self {
        PortableMask(array_fn(|l| self.0[l] & rhs.0[l]))
    }
}

impl<const W: usize> BitOr for PortableMask<W> {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, rhs: Self) -> Self {
        PortableMask(array_fn(|l| self.0[l] | rhs.0[l]))
    }
}

impl<const W: usize> Not for PortableMask<W> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        PortableMask(self.0.map(|b| !b))
    }
}

impl<const W: usize> BitAndAssign for PortableMask<W> {
    #[inline(always)]
    fn bitand_assign(&mut self, rhs: Self) {
        *self = *self & rhs;
    }
}

impl<const W: usize> BitOrAssign for PortableMask<W> {
    #[inline(always)]
    fn bitor_assign(&mut self, rhs: Self) {
        *self = *self | rhs;
    }
}

impl<const W: usize> SimdMask for PortableMask<W> {
    #[inline(always)]
    fn splat(v: bool) -> Self {
        PortableMask([v; W])
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> bool) -> Self {
        PortableMask(array_fn(f))
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        (0..<PortableF32<W> as SimdF32>::LANES).fold(0, |bits, l| bits | u32::from(self.0[l]) << l)
    }
    #[inline(always)]
    fn any(self) -> bool {
        self.0.iter().any(|&b| b)
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.0.iter().all(|&b| b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::specials;

    /// The lanes' bits, every NaN as one value: which operand's NaN an operation passes on
    /// is not specified (LLVM may swap the operands of `+` and `*`), only that it is NaN.
    fn bits(lanes: [f32; 4]) -> [u32; 4] {
        lanes.map(|x| if x.is_nan() { f32::NAN.to_bits() } else { x.to_bits() })
    }

    fn bits4(v: Vec4) -> [u32; 4] {
        bits(v.to_array())
    }

    fn bits_p(v: PortableF32<4>) -> [u32; 4] {
        bits(v.0)
    }

    /// Every operation of the portable type at 4 lanes gives the glam type's lanes bit for
    /// bit (a NaN for a NaN), on every pair of special values.
    #[test]
    fn portable_lanes_are_the_glam_lanes_bit_for_bit() {
        let s = specials();
        let n = s.len();
        for i in 0..n {
            for j in (0..n).step_by(4) {
                let a = [s[i], s[(i + 1) % n], s[(i + 7) % n], s[(i + 13) % n]];
                let b = [s[j], s[(j + 3) % n], s[(j + 5) % n], s[(j + 11) % n]];
                let (ga, gb) = (Vec4::from_array(a), Vec4::from_array(b));
                let (pa, pb) = (PortableF32(a), PortableF32(b));
                let m = BVec4A::from_array([s[i] < s[j], true, false, s[i].is_nan()]);
                let pm = PortableMask(m.into());
                let ops: [(Vec4, PortableF32<4>, &str); 11] = [
                    (ga + gb, pa + pb, "add"),
                    (ga - gb, pa - pb, "sub"),
                    (ga * gb, pa * pb, "mul"),
                    (ga / gb, pa / pb, "div"),
                    (SimdF32::min(ga, gb), SimdF32::min(pa, pb), "min"),
                    (SimdF32::max(ga, gb), SimdF32::max(pa, pb), "max"),
                    (SimdF32::abs(ga), SimdF32::abs(pa), "abs"),
                    (SimdF32::copysign(ga, gb), SimdF32::copysign(pa, pb), "copysign"),
                    (SimdF32::recip(ga), SimdF32::recip(pa), "recip"),
                    (SimdF32::sqrt(ga), SimdF32::sqrt(pa), "sqrt"),
                    (<Vec4 as SimdF32>::select(m, ga, gb), PortableF32::select(pm, pa, pb), "select"),
                ];
                for (g, p, name) in ops {
                    assert_eq!(bits4(g), bits_p(p), "{name} {a:?} {b:?}");
                }
                let masks: [(BVec4A, PortableMask<4>, &str); 8] = [
                    (SimdF32::cmpeq(ga, gb), pa.cmpeq(pb), "eq"),
                    (SimdF32::cmpne(ga, gb), pa.cmpne(pb), "ne"),
                    (SimdF32::cmplt(ga, gb), pa.cmplt(pb), "lt"),
                    (SimdF32::cmple(ga, gb), pa.cmple(pb), "le"),
                    (SimdF32::cmpgt(ga, gb), pa.cmpgt(pb), "gt"),
                    (SimdF32::cmpge(ga, gb), pa.cmpge(pb), "ge"),
                    (SimdF32::is_finite_mask(ga), pa.is_finite_mask(), "finite"),
                    (SimdF32::is_nan_mask(ga), pa.is_nan_mask(), "nan"),
                ];
                for (g, p, name) in masks {
                    assert_eq!(SimdMask::bitmask(g), p.bitmask(), "{name} {a:?} {b:?}");
                    assert_eq!(SimdMask::bitmask(g & !m), (p & !pm).bitmask(), "{name} and not");
                    assert_eq!(SimdMask::bitmask(g | m), (p | pm).bitmask(), "{name} or");
                    assert_eq!((SimdMask::any(g), SimdMask::all(g)), (p.any(), p.all()), "{name}");
                }
                assert_eq!(SimdF32::is_negative_bitmask(ga), pa.is_negative_bitmask(), "{a:?}");
                for l in 0..4 {
                    assert_eq!(ga[l].to_bits(), pa[l].to_bits(), "lane {l}");
                }
            }
        }
    }

    #[test]
    fn constructors_and_axes_agree() {
        let points = [Vec3::new(1.0, -2.0, 3.0), Vec3::new(-0.0, 5.0, 1e-40), Vec3::X, Vec3::new(7.0, 8.0, -9.0)];
        let (g, p) = (<Vec4 as SimdF32>::axes(points), PortableF32::<4>::axes(points));
        for axis in 0..4 {
            assert_eq!(bits4(g[axis]), bits_p(p[axis]), "axis {axis}");
        }
        assert_eq!(g[3], Vec4::ZERO);
        let f = |l: usize| l as f32 * 1.5 - 2.0;
        assert_eq!(bits4(<Vec4 as SimdF32>::from_fn(f)), bits_p(PortableF32::from_fn(f)));
        assert_eq!(SimdF32::to_array(<Vec4 as SimdF32>::splat(2.5)), PortableF32::<4>::splat(2.5).0);
        let lanes = |l: usize| l.is_multiple_of(3);
        assert_eq!(
            SimdMask::bitmask(<BVec4A as SimdMask>::from_fn(lanes)),
            PortableMask::<4>::from_fn(lanes).bitmask()
        );
        assert_eq!(PortableMask::<16>::splat(true).bitmask(), 0xffff);
        assert_eq!(PortableMask::<8>::from_fn(|l| l == 7).bitmask(), 0x80);
        assert!(!PortableMask::<8>::splat(false).any() && PortableMask::<8>::splat(true).all());
        let wide = PortableF32::<16>::from_fn(|l| if l % 2 == 0 { -(l as f32) } else { l as f32 });
        assert_eq!(wide.is_negative_bitmask(), 0x5555, "lane 0 is -0.0");
        // `strided`: one load at stride 1, every `stride`-th entry otherwise, and the glam
        // lanes are the portable ones.
        let values: Vec<f32> = (0..20).map(|i| i as f32 * 0.5 - 3.0).collect();
        for (start, stride) in [(0, 1), (3, 1), (1, 2), (2, 5), (16, 1)] {
            let g = <Vec4 as SimdF32>::strided(&values, start, stride);
            assert_eq!(g.to_array(), std::array::from_fn(|l| values[start + l * stride]));
            assert_eq!(bits4(g), bits_p(PortableF32::<4>::strided(&values, start, stride)));
        }
    }

    /// A strided read past the end, or with no stride, panics before reading anything.
    #[test]
    fn strided_reads_are_checked() {
        let values = [1.0f32; 10];
        for (start, stride) in [(7, 1), (0, 4), (3, 0), (11, 1)] {
            let read = std::panic::catch_unwind(|| <Vec4 as SimdF32>::strided(&values, start, stride));
            assert!(read.is_err(), "start {start} stride {stride}");
            assert!(std::panic::catch_unwind(|| PortableF32::<4>::strided(&values, start, stride)).is_err());
        }
    }
}
