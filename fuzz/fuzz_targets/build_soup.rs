//! Arbitrary triangle soups (NaN, infinities, huge and tiny coordinates, degenerate triangles)
//! -> build: never panics; a finite soup builds and passes `validate()`.
#![no_main]

use glam::Vec3;
use kdtree::{BuildConfig, KdTree};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|soup: Vec<[[f32; 3]; 3]>| {
    let tris: Vec<[Vec3; 3]> = soup.iter().take(512).map(|t| t.map(Vec3::from_array)).collect();
    let finite = tris.iter().flatten().all(|p| p.is_finite());
    match KdTree::build_soup(&tris, &BuildConfig::default()) {
        Ok(tree) => {
            assert!(finite);
            tree.validate().expect("valid tree");
        }
        Err(e) => assert!(!finite, "a finite soup was refused: {e}"),
    }
});
