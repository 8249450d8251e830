//! Regression tests for the inputs the cargo-fuzz targets found (`fuzz/`): each is the
//! finding's input, decoded with `cargo fuzz fmt`, and the property the target checks.

use glam::Vec3;
use kdtree::triangle::{TriangleTest, WatertightTriangle};
use kdtree::{BruteForce, BuildConfig, Intersector, KdTree, Ray};

fn tri(a: [f32; 9]) -> [Vec3; 3] {
    [Vec3::new(a[0], a[1], a[2]), Vec3::new(a[3], a[4], a[5]), Vec3::new(a[6], a[7], a[8])]
}

/// `traversal`: an axis-parallel ray passing 1e-40 beside a triangle's edge, outside its
/// box. The watertight test converted its double-precision edge functions to f32 before
/// taking their signs, flushing 1.5e-61 to zero and reporting a hit; Wald's test reports one
/// too (its rounding). The tree culls the triangle exactly and reports none. The watertight
/// test now takes exact signs; the oracle comparison accepts either answer for a triangle the
/// ray cannot reach in exact arithmetic (`BruteForce::unreachable`).
#[test]
fn ray_beside_a_triangle_outside_its_box() {
    let t =
        tri([-2.0222272e-33, 8.6016465e-19, 0.0, 1.469368e-39, 0.0, 0.0, -1.703123e38, 1.8189896e-12, -3.2653887e33]);
    let ray = Ray::try_new(
        Vec3::new(-1.2197928e-12, 9.15e-41, 1.8e-43),
        Vec3::new(5.6842245e32, 6e-45, 0.0),
        -1.4872218e-14,
        6.1923395e16,
    )
    .unwrap();
    assert_eq!(ray.dir.y, 0.0, "the denormal component is flushed");
    let record = WatertightTriangle::new(&t);
    assert_eq!(record.intersect(&ray, &WatertightTriangle::prepare(&ray), ray.t_max), None);
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = KdTree::build_soup(&[t], &BuildConfig { intersector, ..BuildConfig::default() }).unwrap();
        let oracle = BruteForce::for_tree(&tree);
        assert!(oracle.unreachable(&ray, 0), "z = 1.8e-43 is above the triangle's z range [-3e33, 0]");
        assert_eq!(tree.intersect(&ray), None);
        oracle
            .check(&ray, tree.intersect(&ray), tree.occluded(&ray))
            .unwrap_or_else(|e| panic!("{intersector:?}: {e}"));
    }
}
