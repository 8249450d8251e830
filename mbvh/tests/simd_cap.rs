//! The SIMD cap (`kdtree::isa::SimdLevel::limit`, `rttest --simd`) withholds the node tests'
//! tokens: capped at AVX2, [`Avx512::detect`] gives none and [`Avx2::detect`] still does;
//! capped at SSE4.1, neither. The cap is process-wide, so this file (its own test process)
//! holds one test that sets and resets it.

use kdtree::isa::SimdLevel;
use mbvh::{Avx2, Avx512};

#[test]
fn the_cap_withholds_the_wider_tokens() {
    let detected = SimdLevel::detect();
    let has512 = Avx512::detect().is_some();
    if !has512 {
        eprintln!("note: no AVX-512 on this CPU: only the narrower caps are checked");
    }
    assert!(!has512 || detected == SimdLevel::Avx512, "{detected}");
    if detected >= SimdLevel::Avx2 {
        let has2 = Avx2::detect().is_some();
        SimdLevel::limit(Some(SimdLevel::Avx2)).unwrap();
        assert!(Avx512::detect().is_none());
        assert_eq!(Avx2::detect().is_some(), has2);
        SimdLevel::limit(Some(SimdLevel::Sse41)).unwrap();
        assert!(Avx512::detect().is_none() && Avx2::detect().is_none());
    }
    SimdLevel::limit(None).unwrap();
    assert_eq!(Avx512::detect().is_some(), has512);
}
