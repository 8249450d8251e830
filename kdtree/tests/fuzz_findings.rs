//! Regression tests for the inputs the cargo-fuzz targets found (`fuzz/`): each is the
//! finding's input, decoded with `cargo fuzz fmt`, and the property the target checks.
//! The findings that involve the cone methods are in `cones/tests/fuzz_findings.rs`.

use glam::Vec3;
use kdtree::oracle::segment_meets_triangle;
use kdtree::triangle::{TriangleTest, WaldTriangle, WatertightTriangle};
use kdtree::{BruteForce, BuildConfig, Intersector, KdTree, Ray};

// The findings were made on trees of the thesis's SAH terms (the default before
// `docs/results/sah-terms.md`); they keep those terms so that each one rebuilds its tree.

fn tri(a: [f32; 9]) -> [Vec3; 3] {
    [Vec3::new(a[0], a[1], a[2]), Vec3::new(a[3], a[4], a[5]), Vec3::new(a[6], a[7], a[8])]
}

/// With both triangle tests: the tree over `soup` reports no hit for `ray`, the oracle finds
/// triangle `prim` unreachable (`why`) and accepts the tree's answers.
fn tree_misses_an_unreachable_triangle(soup: &[[Vec3; 3]], ray: &Ray, prim: u32, why: &str) {
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = KdTree::build_soup(soup, &BuildConfig { intersector, ..BuildConfig::thesis() }).unwrap();
        let oracle = BruteForce::for_tree(&tree);
        assert!(oracle.unreachable(ray, prim), "{why}");
        assert_eq!(tree.intersect(ray), None);
        oracle.check(ray, tree.intersect(ray), tree.occluded(ray)).unwrap_or_else(|e| panic!("{intersector:?}: {e}"));
    }
}

/// `build_soup`: a soup mixing 1e29 and denormal coordinates. The clip of the 1e29 triangle
/// to a 1e9 node lost most of its part in the node (see `build/clip.rs`), so the tree left
/// it out of a leaf it enters, and rays into that leaf missed it.
#[test]
fn huge_triangle_reaches_every_leaf_it_enters() {
    let soup = [
        tri([
            865320900.0,
            2012718800.0,
            865309600.0,
            2.809e-41,
            865304600.0,
            865309600.0,
            865309600.0,
            -1.4812316e29,
            -6.404351e28,
        ]),
        tri([-1.4787274e-30, -1.4812468e29, 1.174918e-38, 4.5894e-41, 0.0, 0.0, 0.0, 0.0, 0.0]),
    ];
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = KdTree::build_soup(&soup, &BuildConfig { intersector, ..BuildConfig::thesis() }).unwrap();
        tree.validate().unwrap_or_else(|e| panic!("{intersector:?}: {e}"));
        // Rays straight down (-z) onto the part of triangle 0 at y > 0, 0 < z < 3.1e8, which
        // lies near its vertex a: points a + s (c - a) + r (b - a), computed from `a`.
        let oracle = BruteForce::for_tree(&tree);
        let [a, b, c] = soup[0].map(|p| p.as_dvec3());
        let mut hits = 0;
        for i in 1..68 {
            for j in 1..20 {
                let p = a + (f64::from(i) * 2e-22) * (c - a) + (f64::from(j) / 20.0) * (b - a);
                if !(p.y > 0.0 && p.z > 0.0 && p.z < 3.1e8) {
                    continue;
                }
                let ray = Ray::new(Vec3::new(p.x as f32, p.y as f32, 1e9), -Vec3::Z, 0.0, f32::INFINITY);
                let got = tree.intersect(&ray);
                hits += usize::from(got.is_some());
                oracle.check(&ray, got, tree.occluded(&ray)).unwrap_or_else(|e| panic!("{intersector:?}: {e}"));
            }
        }
        // The watertight test's f32 edge functions overflow here (1e29 x 1e9 products), so it
        // reports no hit, in the tree and the oracle alike; Wald's test finds them.
        if intersector == Intersector::Wald {
            assert!(hits > 50, "the rays reach the triangle ({hits} hits)");
        }
    }
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
    tree_misses_an_unreachable_triangle(&[t], &ray, 0, "z = 1.8e-43 is above the triangle's z range [-3e33, 0]");
}

/// `traversal`: a ray with a huge y component (-4e31) and a tiny x component (2e-38) that
/// crosses the plane of a 2e37-wide sliver triangle at t = 5.9e-42, at x = -7.7e-37, outside
/// the triangle's x range [2.35e-38, 2.2e37] (the ray reaches that range only at t = 34, far
/// past its t_max = 4.7e-41). Wald's test reports a hit there: the triangle's edge
/// coefficient `c_nu` (exactly -8e-53) rounds to -0.0 in `f32`, and `c_nv * hv` (exactly
/// -3.6e-74) underflows to zero, so the third barycentric is 0 instead of slightly negative.
/// The tree culls the ray at the root box exactly and reports none; the oracle excused such
/// artefacts only for zero direction components. It now excuses every triangle whose box the
/// ray's segment surely misses (`BruteForce::unreachable`).
#[test]
fn ray_with_a_tiny_direction_component_beside_a_sliver_triangle() {
    let t = tri([
        2.3691403e-38,
        2.3418052e-38,
        1.01376515e-25,
        2.3510604e-38,
        9.19e-41,
        -1.5028658e-36,
        2.1851257e37,
        -7.729682e-37,
        -7.065031e24,
    ]);
    let ray = Ray::try_new(
        Vec3::new(-7.729682e-37, 2.3944935e-10, 1.7578e-41),
        Vec3::new(2.3476166e-38, -4.0658027e31, -2.9818803e-8),
        -2.729787e24,
        4.725e-41,
    )
    .unwrap();
    assert_ne!(ray.dir.x, 0.0, "the tiny component is kept: its reciprocal is finite");
    let record = WaldTriangle::new(&t);
    let artefact = record.intersect(&ray, &WaldTriangle::prepare(&ray), ray.t_max);
    assert_eq!(artefact.map(|h| h.0), Some(5.89e-42), "Wald's test reports the hit outside the triangle");
    tree_misses_an_unreachable_triangle(&[t], &ray, 0, "x < 0 over the whole segment, the triangle has x > 2.3e-38");
}

/// `traversal`: a ray along -x whose interval is the single point `t = 0`, its origin at
/// x = 1.5e-39, beside triangle 1, whose x range ends at 1.076e-42. The plane distance to the
/// root split x = 1.076e-42, 8.9e-78, underflows to 0, so the tree visits both children and
/// reports Wald's rounding hit on triangle 1 at `t = -0.0`; the cone methods measure the
/// plane along their axis (1.5e-39), cull that child and report none, which the target took
/// for a disagreement. Either answer is right: `BruteForce::equivalent_hits` and
/// `equivalent_occlusion` accept them (the cone side is in `cones/tests/fuzz_findings.rs`).
#[test]
fn plane_distance_underflow_finds_an_artefact_that_exact_culling_skips() {
    let soup = [
        tri([
            -7.729682e-37,
            -7.729682e-37,
            6.938894e-18,
            8.843688e-18,
            8.843688e-18,
            8.843688e-18,
            1.2605e-41,
            9.723689e-35,
            -1.0909784e-18,
        ]),
        tri([
            -1.0952567e-18,
            5.167039e-29,
            1.37753e-40,
            1.076e-42,
            3.345292e-30,
            -7.729725e-37,
            -5.09907e-37,
            6.762284e-23,
            1.0858565e-19,
        ]),
    ];
    let ray =
        Ray::try_new(Vec3::new(1.516545e-39, 3.22545e-40, 1.3591833e-38), Vec3::new(-1.7023464e38, 0.0, 0.0), 0.0, 0.0)
            .unwrap();
    let tree = KdTree::build_soup(&soup, &BuildConfig::thesis()).unwrap();
    let (root, oracle) = (tree.nodes()[0], BruteForce::for_tree(&tree));
    assert_eq!((root.axis(), root.split()), (0, 1.076e-42));
    assert_eq!((root.split() - ray.origin.x) * ray.inv_dir.x, 0.0, "8.9e-78 underflows");
    let single = tree.intersect(&ray);
    assert_eq!(single.map(|h| (h.t, h.prim)), Some((-0.0, 1)));
    assert!(oracle.unreachable(&ray, 1), "the ray's one point lies at x = 1.5e-39 > 1.076e-42");
    oracle.check(&ray, single, tree.occluded(&ray)).unwrap();
    oracle.check(&ray, None, false).unwrap();
    assert!(oracle.equivalent_hits(&ray, None, single));
    assert!(oracle.equivalent_occlusion(&ray, false, tree.occluded(&ray)));
}

/// `traversal` (Wald's test): a ray starting on the root split plane z = 0 with dz > 0 (so
/// the tree visits only the z > 0 side) crosses the plane of triangle 1 at t = 1.5e-9, where,
/// in exact arithmetic, its third barycentric `1 - u - v` is -1.13e-29: just outside an edge,
/// and below z = 0 near the ray. Wald's test rounds it to a hit; the tree, right, reports
/// none. The exact crossing point, (1.2e-38, 5.17e-29, 5.6e-46), lies in the triangle's box
/// (the edge functions' ratios are 5.2e-26, -1.13e-29 and 1), so the oracle's old box test
/// could not excuse the artefact; `BruteForce::unreachable` now decides exactly
/// (`kdtree::oracle::segment_meets_triangle`, big-integer arithmetic).
#[test]
fn wald_rounds_a_ray_just_outside_an_edge_into_a_hit() {
    let soup = [
        tri([
            -7.729682e-37,
            -7.729682e-37,
            1.2306499e-38,
            9.629911e-35,
            2.342128e-38,
            2.3073668e-38,
            2.524355e-29,
            3.22684e-40,
            -0.0,
        ]),
        tri([
            -7.740702e-37,
            -7.729682e-37,
            -3.318156e-8,
            5.42e-43,
            5.167039e-29,
            -3.761585e-37,
            2.3361182e-13,
            1.39013e-40,
            1.7578e-41,
        ]),
    ];
    let ray = Ray::try_new(
        Vec3::new(1.203171e-38, 0.0, 0.0),
        Vec3::new(-7.699488e-37, 3.4624963e-20, 3.761582e-37),
        3.7619277e-37,
        0.032061588,
    )
    .unwrap();
    let record = WaldTriangle::new(&soup[1]);
    let artefact = record.intersect(&ray, &WaldTriangle::prepare(&ray), ray.t_max);
    assert_eq!(artefact.map(|h| h.0), Some(1.4922872e-9), "Wald's test reports the hit outside the triangle");
    assert!(!kdtree::oracle::segment_meets_triangle(&soup[1], ray.origin, ray.dir, ray.t_min, ray.t_max));
    tree_misses_an_unreachable_triangle(&soup, &ray, 1, "the segment misses triangle 1 in exact arithmetic");
}

/// `traversal` (Wald's test): every triangle but one has a vertex exactly at the ray's
/// origin, and the ray (direction of length 3.9e31, interval from -1.5e31) meets them all at
/// exactly `t = 0`. Triangle 3, 3.9e31 wide, is reported at `t = -3.6e-8`, rounded below its
/// exact crossing by the test's error at that scale; triangle 2 (unreachable) gives a rounding
/// hit at `t = -3.5e-25`. The tree, visiting leaves in exact order, finds triangle 2 first and
/// then drops the leaves beyond it, triangle 3's among them. The oracle took the f32 distance
/// -3.6e-8 for "a reachable hit before the reported one"; it now asks exactly whether the ray
/// meets that triangle before the reported distance (`BruteForce::check`). Since Wald's record
/// stores vertex `a` instead of the plane offset, triangle 3 is reported at its exact
/// crossing, t = 0; the oracle's rules are checked on the new answers.
#[test]
fn huge_triangle_through_the_origin_is_reported_before_its_exact_crossing() {
    let soup = [
        tri([
            3.8500897e-37,
            3.8207024e-37,
            3.8500897e-37,
            3.8500897e-37,
            3.8500897e-37,
            3.8500897e-37,
            3.877748e-37,
            3.8500897e-37,
            3.8500897e-37,
        ]),
        tri([
            3.8500897e-37,
            3.8500897e-37,
            3.8500897e-37,
            -3.850675e31,
            -3.8655884e31,
            0.072267435,
            5.113515e-37,
            9.953485e17,
            9.96938e17,
        ]),
        tri([
            9.96938e17,
            9.96938e17,
            2321374500.0,
            6.81e-43,
            -6.0375343e23,
            -0.09230613,
            1.2053782e-38,
            9.1817e-41,
            13362867.0,
        ]),
        tri([
            3.8500897e-37,
            3.8500897e-37,
            -3.850675e31,
            -1.0380112e31,
            -1.4811937e31,
            1.4338264e-36,
            3.8500897e-37,
            3.8500897e-37,
            3.8500897e-37,
        ]),
    ];
    let ray = Ray::try_new(
        Vec3::splat(3.8500897e-37),
        Vec3::new(3.8500897e-37, 1.4282948e-36, -3.8655304e31),
        -1.4811937e31,
        1.4338264e-36,
    )
    .unwrap();
    let tree =
        KdTree::build_soup(&soup, &BuildConfig { intersector: Intersector::Wald, ..BuildConfig::thesis() }).unwrap();
    let oracle = BruteForce::for_tree(&tree);
    // Wald's test with the plane offset stored (n_d) reported triangle 3 at t = -3.640144e-8
    // and triangle 2 at -3.4569297e-25; with vertex `a` stored (subtracted from the origin
    // first) triangle 3 is reported at its exact crossing, t = 0.
    assert_eq!(oracle.all_hits(&ray), vec![(-0.0, 1), (-3.4568777e-25, 2), (-0.0, 3)]);
    assert!(oracle.unreachable(&ray, 2) && !oracle.unreachable(&ray, 3));
    assert!(segment_meets_triangle(&soup[3], ray.origin, ray.dir, 0.0, 0.0), "the origin is its vertex");
    assert!(!segment_meets_triangle(&soup[3], ray.origin, ray.dir, ray.t_min, -3.4568777e-25));
    let single = tree.intersect(&ray);
    assert_eq!(single.map(|h| (h.t, h.prim)), Some((-3.4568777e-25, 2)));
    oracle.check(&ray, single, tree.occluded(&ray)).unwrap();
    assert!(oracle.equivalent_hits(&ray, single, oracle.intersect(&ray)));
    // Still caught: a hit on triangle 0 or 3 where the ray does not meet it, and an answer
    // that contradicts itself (a hit, yet not occluded). (No hit at all is an answer the
    // oracle accepts here: every hit lies within the origin's rounding.)
    for prim in [0, 3] {
        let wrong = kdtree::Hit { t: -1.0e30, u: 0.25, v: 0.25, prim };
        assert!(oracle.check(&ray, Some(wrong), true).is_err(), "prim {prim}");
    }
    assert!(oracle.check(&ray, single, false).is_err());
    let tree =
        KdTree::build_soup(&soup, &BuildConfig { intersector: Intersector::Watertight, ..BuildConfig::thesis() })
            .unwrap();
    BruteForce::for_tree(&tree).check(&ray, tree.intersect(&ray), tree.occluded(&ray)).unwrap();
}
