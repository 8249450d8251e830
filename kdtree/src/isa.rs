//! The SIMD instruction set the kernels may use: the widest the CPU offers this process
//! ([`SimdLevel::detect`]), capped by the user ([`SimdLevel::limit`], `rttest --simd`).
//!
//! Every kernel that has SIMD paths of several widths (the packet kernels of `packets`, the
//! lane frusta, `mbvh`'s node tests) picks its path once, when it is bound, from
//! [`SimdLevel::active`]; it never asks per ray. Capping the level is how the width ladder
//! is measured on one machine: `--simd sse4.1` runs every kernel at 4 lanes, `--simd avx2`
//! at 8, `--simd avx512` at 16 where the kernel has such a path. The cap is process-wide, as
//! Embree's `isa=` device setting is: it is set once, before any kernel is bound.
//!
//! The level lives here, in the lowest crate that has SIMD paths, so that `packets` and
//! `mbvh` read the same cap; `trace::machine` reports it.

use std::fmt;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU8, Ordering};

/// A SIMD instruction set level, ordered from narrowest to widest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum SimdLevel {
    /// No x86 SIMD (another architecture): the portable code paths.
    Scalar = 0,
    /// SSE2 only, the x86-64 baseline (glam's `Vec4` lanes).
    Sse2 = 1,
    /// SSE4.1 (4-wide `f32` lanes with blends and rounding).
    Sse41 = 2,
    /// AVX2 and FMA (8-wide `f32` lanes).
    Avx2 = 3,
    /// AVX-512 F and VL (16-wide `f32` lanes, and masks on 4- and 8-wide ones).
    Avx512 = 4,
}

/// The cap set by [`SimdLevel::limit`], as the level's `u8`; `u8::MAX` for none.
static LIMIT: AtomicU8 = AtomicU8::new(u8::MAX);

/// Why a cap could not be set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("this CPU's widest SIMD level is {detected}, so it cannot run {asked}")]
pub struct LevelError {
    /// The level asked for.
    pub asked: SimdLevel,
    /// The widest level the CPU has.
    pub detected: SimdLevel,
}

impl SimdLevel {
    /// Every level, narrowest first.
    pub const ALL: [SimdLevel; 5] =
        [SimdLevel::Scalar, SimdLevel::Sse2, SimdLevel::Sse41, SimdLevel::Avx2, SimdLevel::Avx512];

    /// The level's short name: `scalar`, `sse2`, `sse4.1`, `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Sse2 => "sse2",
            SimdLevel::Sse41 => "sse4.1",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
        }
    }

    /// The level of a [`SimdLevel::name`] (`sse` is accepted for `sse4.1`).
    pub fn from_name(name: &str) -> Option<SimdLevel> {
        match name {
            "sse" => Some(SimdLevel::Sse41),
            _ => SimdLevel::ALL.into_iter().find(|l| l.name() == name),
        }
    }

    /// The widest level this CPU runs, detected once per process: `avx512` with `avx512f`
    /// and `avx512vl` (and AVX2 and FMA, which every such CPU has: the AVX-512 kernels use
    /// them too), `avx2` with `avx2` and `fma`, `sse4.1` with `sse4.1`, else `sse2` on
    /// x86-64 and `scalar` elsewhere.
    pub fn detect() -> SimdLevel {
        static DETECTED: OnceLock<SimdLevel> = OnceLock::new();
        *DETECTED.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            {
                let avx2 = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
                if avx2 && is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512vl") {
                    SimdLevel::Avx512
                } else if avx2 {
                    SimdLevel::Avx2
                } else if is_x86_feature_detected!("sse4.1") {
                    SimdLevel::Sse41
                } else {
                    SimdLevel::Sse2
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                SimdLevel::Scalar
            }
        })
    }

    /// Caps the level every kernel bound from now on may use at `level` (`None`: no cap,
    /// the detected level). A level wider than the CPU's is an error naming both.
    pub fn limit(level: Option<SimdLevel>) -> Result<(), LevelError> {
        let detected = SimdLevel::detect();
        match level {
            Some(asked) if asked > detected => Err(LevelError { asked, detected }),
            Some(level) => {
                LIMIT.store(level as u8, Ordering::Relaxed);
                Ok(())
            }
            None => {
                LIMIT.store(u8::MAX, Ordering::Relaxed);
                Ok(())
            }
        }
    }

    /// The level kernels bind to: the detected one, capped by [`SimdLevel::limit`].
    pub fn active() -> SimdLevel {
        let cap = LIMIT.load(Ordering::Relaxed);
        let detected = SimdLevel::detect();
        SimdLevel::ALL.into_iter().find(|l| *l as u8 == cap).map_or(detected, |cap| cap.min(detected))
    }

    /// Whether the active level includes `level` (a kernel may take that path).
    pub fn allows(level: SimdLevel) -> bool {
        SimdLevel::active() >= level
    }
}

impl fmt::Display for SimdLevel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for level in SimdLevel::ALL {
            assert_eq!(SimdLevel::from_name(level.name()), Some(level));
        }
        assert_eq!(SimdLevel::from_name("sse"), Some(SimdLevel::Sse41));
        assert_eq!(SimdLevel::from_name("avx1024"), None);
    }

    #[test]
    fn detection_matches_the_feature_flags() {
        let level = SimdLevel::detect();
        #[cfg(target_arch = "x86_64")]
        {
            let avx512 = is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512vl");
            let avx2 = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
            let sse41 = is_x86_feature_detected!("sse4.1");
            assert_eq!(level == SimdLevel::Avx512, avx512 && avx2);
            assert_eq!(level >= SimdLevel::Avx2, avx512 || avx2, "{level}");
            assert_eq!(level >= SimdLevel::Sse41, avx512 || avx2 || sse41, "{level}");
            assert!(level >= SimdLevel::Sse2);
        }
        #[cfg(not(target_arch = "x86_64"))]
        assert_eq!(level, SimdLevel::Scalar);
    }

    /// The cap is process-wide, so one test sets and resets it (tests run in parallel).
    #[test]
    fn a_cap_narrows_and_cannot_widen() {
        let detected = SimdLevel::detect();
        assert_eq!(SimdLevel::active(), detected);
        SimdLevel::limit(Some(SimdLevel::Scalar)).unwrap();
        assert_eq!(SimdLevel::active(), SimdLevel::Scalar);
        assert!(!SimdLevel::allows(SimdLevel::Sse2));
        SimdLevel::limit(Some(detected)).unwrap();
        assert_eq!(SimdLevel::active(), detected);
        if detected < SimdLevel::Avx512 {
            let e = SimdLevel::limit(Some(SimdLevel::Avx512)).unwrap_err();
            assert!(e.to_string().contains("cannot run avx512"), "{e}");
        }
        SimdLevel::limit(None).unwrap();
        assert_eq!(SimdLevel::active(), detected);
    }
}
