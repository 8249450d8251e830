//! The width of a packet kernel: how many rays one instruction serves, 4 (SSE), 8 (AVX2) or
//! 16 (AVX-512), chosen once when a kernel is bound ([`Width::for_level`]), and
//! [`at_width!`](crate::at_width), which runs a kernel's code at it.
//!
//! The packet code is written once, generic over its lane type ([`crate::simd::SimdF32`]);
//! a width names the lane type it runs with:
//! - [`Width::Four`]: glam's `Vec4` (SSE), the thesis's 2x2 packet;
//! - [`Width::Eight`]: [`F32x8`](crate::simd_x86::F32x8) (AVX2), compiled inside the
//!   8-lane runner `simd_x86::run_avx2` (`#[target_feature(enable = "avx2,fma")]`);
//! - [`Width::SixteenInPairs`]: [`F32x8x2`](crate::simd_x86::F32x8x2), 16 lanes in two
//!   AVX2 registers, compiled inside `simd_x86::run_avx2`: the 16-ray packets of a CPU (or
//!   a SIMD cap) without AVX-512;
//! - [`Width::Sixteen`]: [`F32x16`](crate::simd_x86::F32x16) (AVX-512 F/VL), compiled
//!   inside the 16-lane runner `simd_x86::run_avx512`.
//!
//! Those are the runners `simd_x86::with_avx2` / `with_avx512` use too, with the features
//! the lane types' `available()` checks. The wide lane types use their instructions
//! unconditionally, so [`at_width!`] checks `available()` first (cached feature bits, per
//! call) and runs the portable twin of the same width
//! ([`PortableF32<8>`](crate::simd::PortableF32), `<16>`) on a CPU without them: the answer
//! is the same bit for bit either way (the lane types are tested against each other), only
//! the speed differs. Everything the kernel calls must inline into the `target_feature`
//! function for its lane operations to become single instructions (the packet kernels' hot
//! functions are `#[inline(always)]`).

use kdtree::isa::SimdLevel;

/// How many rays a packet kernel traces per instruction, and in which registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Width {
    /// 4 lanes (SSE): 2x2 pixels, the thesis's packet.
    Four,
    /// 8 lanes (AVX2): 4x2 pixels.
    Eight,
    /// 16 lanes in two AVX2 registers: 4x4 pixels on a CPU (or a SIMD cap) without AVX-512.
    SixteenInPairs,
    /// 16 lanes (AVX-512): 4x4 pixels.
    Sixteen,
}

impl Width {
    /// Every width, narrowest first.
    pub const ALL: [Width; 4] = [Width::Four, Width::Eight, Width::SixteenInPairs, Width::Sixteen];

    /// The width the packet kernels bind at `level` unless a method asks for another
    /// ([`Width::at_level`]): 16 lanes at `avx512` (one register) and at `avx2` (two
    /// registers, [`Width::SixteenInPairs`]), else 4. At `avx2` the 16-ray packets beat the
    /// 8-ray ones of one register: per ray they do the same arithmetic, and they halve the
    /// per-packet work (traversal steps, culling, the walk's decisions): 1.03-1.04x on
    /// primary rays, 1.06-1.08x on hard shadows and 1.07x on soft shadows on an AVX2 CPU
    /// (`docs/results/width-ladder.md`).
    pub fn for_level(level: SimdLevel) -> Width {
        match level {
            SimdLevel::Avx512 => Width::Sixteen,
            SimdLevel::Avx2 => Width::SixteenInPairs,
            _ => Width::Four,
        }
    }

    /// The width of `lanes` rays per instruction at `level` (a method's `NAME@w8`): 16
    /// lanes in one register at `avx512`, in two at `avx2`; 4 lanes at any level (as
    /// [`Width::for_level`] binds them below `sse4.1`); `None` for another count, or where
    /// `level` runs no such width natively (8 or 16 below `avx2`).
    pub fn at_level(lanes: usize, level: SimdLevel) -> Option<Width> {
        let width = match lanes {
            4 => return Some(Width::Four),
            8 => Width::Eight,
            16 if level >= SimdLevel::Avx512 => Width::Sixteen,
            16 => Width::SixteenInPairs,
            _ => return None,
        };
        (width.level() <= level).then_some(width)
    }

    /// The lowest SIMD level that runs the width natively (else [`at_width!`] runs its
    /// portable twin): `sse4.1` for 4 lanes, `avx2` for 8 and for 16 in pairs, `avx512`
    /// for 16 in one register.
    pub fn level(self) -> SimdLevel {
        match self {
            Width::Four => SimdLevel::Sse41,
            Width::Eight | Width::SixteenInPairs => SimdLevel::Avx2,
            Width::Sixteen => SimdLevel::Avx512,
        }
    }

    /// Rays per instruction: 4, 8 or 16.
    pub fn lanes(self) -> usize {
        match self {
            Width::Four => 4,
            Width::Eight => 8,
            Width::SixteenInPairs | Width::Sixteen => 16,
        }
    }

    /// What a kernel's name gains at this width: nothing at 4 (the thesis's packets keep
    /// their names), `-w8` and `-w16` otherwise (`kd-mft-16-w16`; the SIMD level a run
    /// prints tells one register from two).
    pub fn suffix(self) -> &'static str {
        match self {
            Width::Four => "",
            Width::Eight => "-w8",
            Width::SixteenInPairs | Width::Sixteen => "-w16",
        }
    }

    /// Whether this CPU runs the width's instructions (else [`at_width!`] runs its portable
    /// twin): the lane type's own check ([`crate::simd_x86::F32x8::available`],
    /// [`crate::simd_x86::F32x16::available`]).
    pub fn native(self) -> bool {
        match self {
            Width::Four => true,
            #[cfg(target_arch = "x86_64")]
            Width::Eight | Width::SixteenInPairs => crate::simd_x86::F32x8::available(),
            #[cfg(target_arch = "x86_64")]
            Width::Sixteen => crate::simd_x86::F32x16::available(),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }
}

/// `at_width!(width, V => body)`: evaluates `body` with the type `V` the lane type of
/// `width` ([`Width`]), compiled for its instruction set: `Vec4` at [`Width::Four`],
/// `F32x8` under AVX2 at [`Width::Eight`], `F32x8x2` under AVX2 at
/// [`Width::SixteenInPairs`], `F32x16` under AVX-512 at [`Width::Sixteen`] (the portable
/// twins `PortableF32<8>` / `<16>` where the CPU lacks them, or off x86-64).
/// The body is expanded once per lane type; it must call only `#[inline(always)]` kernel
/// code for the wide lanes to become single instructions.
#[macro_export]
macro_rules! at_width {
    ($width:expr, $V:ident => $body:expr) => {{
        match $width {
            $crate::Width::Four => {
                type $V = ::glam::Vec4;
                $body
            }
            #[cfg(target_arch = "x86_64")]
            $crate::Width::Eight if $crate::simd_x86::F32x8::available() => {
                // SAFETY: the CPU has AVX2 and FMA (just checked).
                unsafe {
                    $crate::simd_x86::run_avx2(
                        #[inline(always)]
                        || {
                            type $V = $crate::simd_x86::F32x8;
                            $body
                        },
                    )
                }
            }
            #[cfg(target_arch = "x86_64")]
            $crate::Width::Sixteen if $crate::simd_x86::F32x16::available() => {
                // SAFETY: the CPU has AVX-512F and VL, AVX2 and FMA (just checked).
                unsafe {
                    $crate::simd_x86::run_avx512(
                        #[inline(always)]
                        || {
                            type $V = $crate::simd_x86::F32x16;
                            $body
                        },
                    )
                }
            }
            #[cfg(target_arch = "x86_64")]
            $crate::Width::SixteenInPairs if $crate::simd_x86::F32x8::available() => {
                // SAFETY: the CPU has AVX2 and FMA (just checked).
                unsafe {
                    $crate::simd_x86::run_avx2(
                        #[inline(always)]
                        || {
                            type $V = $crate::simd_x86::F32x8x2;
                            $body
                        },
                    )
                }
            }
            $crate::Width::Eight => {
                type $V = $crate::simd::PortableF32<8>;
                $body
            }
            $crate::Width::Sixteen | $crate::Width::SixteenInPairs => {
                type $V = $crate::simd::PortableF32<16>;
                $body
            }
        }
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_follow_the_levels() {
        assert_eq!(Width::for_level(SimdLevel::Avx512), Width::Sixteen);
        assert_eq!(Width::for_level(SimdLevel::Avx2), Width::SixteenInPairs);
        assert_eq!(Width::for_level(SimdLevel::Sse41), Width::Four);
        assert_eq!(Width::for_level(SimdLevel::Scalar), Width::Four);
        assert_eq!(Width::ALL.map(Width::lanes), [4, 8, 16, 16]);
        for level in SimdLevel::ALL {
            assert!(Width::for_level(level).level() <= level.max(SimdLevel::Sse41), "{level}");
        }
        assert_eq!(Width::at_level(8, SimdLevel::Avx512), Some(Width::Eight));
        assert_eq!(Width::at_level(16, SimdLevel::Avx512), Some(Width::Sixteen));
        assert_eq!(Width::at_level(16, SimdLevel::Avx2), Some(Width::SixteenInPairs));
        assert_eq!(Width::at_level(4, SimdLevel::Avx2), Some(Width::Four));
        assert_eq!(Width::at_level(4, SimdLevel::Scalar), Some(Width::Four));
        assert_eq!(Width::at_level(8, SimdLevel::Sse41), None);
        assert_eq!(Width::at_level(16, SimdLevel::Sse41), None);
        assert_eq!(Width::at_level(12, SimdLevel::Avx512), None);
        let detected = SimdLevel::detect();
        assert_eq!(Width::Sixteen.native(), detected == SimdLevel::Avx512);
        assert_eq!(Width::SixteenInPairs.native(), detected >= SimdLevel::Avx2);
    }

    /// The macro gives each width its lane type, natively compiled or not.
    #[test]
    fn at_width_picks_the_lane_type() {
        use crate::simd::SimdF32;
        for width in Width::ALL {
            let lanes = at_width!(width, V => V::LANES);
            let sum = at_width!(width, V => {
                let v = V::from_fn(|l| l as f32);
                (0..V::LANES).map(|l| (v + V::ONE)[l]).sum::<f32>()
            });
            assert_eq!(lanes, width.lanes());
            let n = width.lanes() as f32;
            assert_eq!(sum, n * (n + 1.0) / 2.0);
        }
    }
}
