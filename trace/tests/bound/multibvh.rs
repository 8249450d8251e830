//! The multi-BVH bindings name their node tests ([`trace::multibvh`]).

use mbvh::{Avx2, Avx512};
use trace::SimdLevel;
use trace::multibvh::{bind8, bind8_p16, bind16, build8, build16};
use trace::setup::load_and_build;

/// Below AVX2 the 8-wide tree is traced with the scalar node test, and its kernel says so.
#[test]
fn mbvh8_names_its_node_test() {
    let (scene, tree, _) = load_and_build("cube", &Default::default()).unwrap();
    let bvh = build8(&scene).unwrap();
    let names = |simd| bind8(&bvh, &tree, simd).unwrap().kernels.map(|k| k.primary);
    assert_eq!(names(SimdLevel::Sse41).as_deref(), Some("mbvh-8-scalar-nodes"));
    if Avx2::detect().is_some() {
        assert_eq!(names(SimdLevel::Avx2), None, "named by its entry, mbvh-8");
    }
    let bvh = build16(&scene).unwrap();
    let names = |simd| bind16(&bvh, &tree, simd).unwrap().kernels.map(|k| k.primary);
    assert_eq!(names(SimdLevel::Avx2).as_deref(), Some("mbvh-16-scalar-nodes"));
    if Avx512::detect().is_some() {
        assert_eq!(names(SimdLevel::Avx512), None, "named by its entry, mbvh-16");
    }
    let bvh = build8(&scene).unwrap();
    let names = |simd| bind8_p16(&bvh, &tree, simd).unwrap().kernels.map(|k| k.primary);
    assert_eq!(names(SimdLevel::Sse41).as_deref(), Some("mbvh-8-p16-portable"));
    assert_eq!(names(SimdLevel::Scalar).as_deref(), Some("mbvh-8-p16-portable"));
    if Avx2::detect().is_some() {
        assert_eq!(names(SimdLevel::Avx2).as_deref(), Some("mbvh-8-p16-avx2"));
    }
    if Avx512::detect().is_some() {
        assert_eq!(names(SimdLevel::Avx512), None, "named by its entry, mbvh-8-p16");
    }
}
