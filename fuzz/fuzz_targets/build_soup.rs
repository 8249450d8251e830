//! Arbitrary triangle soups (NaN, infinities, huge and tiny coordinates, degenerate triangles)
//! -> build: never panics; a finite soup builds and passes `validate()`. The soup's length
//! picks one of four build configurations: the default, the SIMD leaf cost (`leaf_width`),
//! bad refines with collapse, and all three with a binned top down to small nodes.
#![no_main]

use glam::Vec3;
use kdtree::{BuildConfig, BuildStrategy, KdTree};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|soup: Vec<[[f32; 3]; 3]>| {
    let tris: Vec<[Vec3; 3]> = soup.iter().take(512).map(|t| t.map(Vec3::from_array)).collect();
    let finite = tris.iter().flatten().all(|p| p.is_finite());
    let config = match soup.len() % 4 {
        0 => BuildConfig::default(),
        1 => BuildConfig { leaf_width: 4, ..BuildConfig::default() },
        2 => BuildConfig { max_bad_refines: 3, collapse: true, ..BuildConfig::default() },
        _ => BuildConfig {
            leaf_width: 8,
            max_bad_refines: 2,
            collapse: true,
            strategy: BuildStrategy::Binned { bins: 16, min_tris: 8 },
            ..BuildConfig::default()
        },
    };
    match KdTree::build_soup(&tris, &config) {
        Ok(tree) => {
            assert!(finite);
            tree.validate().expect("valid tree");
        }
        Err(e) => assert!(!finite, "a finite soup was refused: {e}"),
    }
});
