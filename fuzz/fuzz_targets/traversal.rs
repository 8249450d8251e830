//! Arbitrary rays (zero, NaN and infinite directions included) -> traversal of a tree over an
//! arbitrary finite soup: never panics; rays accepted by `Ray::try_new` agree with the
//! brute-force oracle (`BruteForce::check`); rejected rays still traverse without a panic.
#![no_main]

use arbitrary::Arbitrary;
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Intersector, KdTree, Ray};
use libfuzzer_sys::fuzz_target;

#[derive(Arbitrary, Debug)]
struct Input {
    watertight: bool,
    soup: Vec<[[f32; 3]; 3]>,
    rays: Vec<[f32; 8]>,
}

fuzz_target!(|input: Input| {
    let tris: Vec<[Vec3; 3]> = input
        .soup
        .iter()
        .take(256)
        .map(|t| t.map(Vec3::from_array))
        .filter(|t| t.iter().all(|p| p.is_finite()))
        .collect();
    let intersector = if input.watertight { Intersector::Watertight } else { Intersector::Wald };
    let tree = KdTree::build_soup(&tris, &BuildConfig { intersector, ..BuildConfig::default() }).expect("finite soup");
    let oracle = BruteForce::for_tree(&tree);
    for r in input.rays.iter().take(64) {
        let (o, d) = (Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5]));
        match Ray::try_new(o, d, r[6], r[7]) {
            Ok(ray) => oracle.check(&ray, tree.intersect(&ray), tree.occluded(&ray)).expect("agrees with the oracle"),
            Err(_) => {
                let ray = Ray::new(o, d, r[6], r[7]);
                let _ = (tree.intersect(&ray), tree.occluded(&ray));
            }
        }
    }
});
