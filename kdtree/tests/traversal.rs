//! Single-ray traversal against the brute-force oracle: random soups, snapped soups (shared
//! edges, vertices and axis planes), axis-parallel rays, rays in and starting on split planes,
//! rays through vertices and edges, both intersectors, the SAH tree and a median-split tree.

mod common;

use common::{check_rays, median_tree, rays_for, triangle, vertex};
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, BuildStrategy, Intersector, KdTree, Ray};
use proptest::prelude::*;

/// The exact build with Wald's test, and a binned build (binned down to 8 triangles, so the
/// soups here have binned nodes) with the watertight test: the strategy only moves planes,
/// the intersector only the records, so each pairing covers both.
/// The third: SIMD-group leaf costs with bad refines and their collapse, exact build.
fn configs() -> [BuildConfig; 3] {
    [
        BuildConfig { strategy: BuildStrategy::Exact, ..BuildConfig::default() },
        BuildConfig {
            intersector: Intersector::Watertight,
            strategy: BuildStrategy::Binned { bins: 8, min_tris: 8 },
            ..BuildConfig::default()
        },
        BuildConfig {
            strategy: BuildStrategy::Exact,
            leaf_width: 4,
            max_bad_refines: 3,
            collapse: true,
            ..BuildConfig::default()
        },
    ]
}

/// Checks `rays` against the oracle on the SAH tree and the median-split tree of `tris`, with
/// both intersectors.
fn check_trees(tris: &[[Vec3; 3]], rays: &[Ray]) -> Result<(), String> {
    for config in configs() {
        let sah = KdTree::build_soup(tris, &config).map_err(|e| e.to_string())?;
        check_rays(&sah, rays).map_err(|e| format!("SAH tree: {e}"))?;
        let median = median_tree(tris, 2, &config);
        check_rays(&median, rays).map_err(|e| format!("median tree: {e}"))?;
    }
    Ok(())
}

fn check_soup(tris: &[[Vec3; 3]], seeds: &[(Vec3, Vec3, usize, u8)], scale: f32) -> Result<(), TestCaseError> {
    check_trees(tris, &rays_for(tris, scale, seeds)).map_err(TestCaseError::fail)
}

fn seeds(scale: f32) -> impl Strategy<Value = Vec<(Vec3, Vec3, usize, u8)>> {
    prop::collection::vec((vertex(scale), common::direction(), any::<usize>(), any::<u8>()), 1..40)
}

// 64 cases per property keeps the suite fast on two cores; PROPTEST_CASES=N runs more.
proptest! {
    #![proptest_config(ProptestConfig { cases: common::cases(64), ..ProptestConfig::default() })]

    #[test]
    fn random_soups_match_the_oracle(
        tris in prop::collection::vec(triangle(1.0), 1..80),
        rays in seeds(1.0),
    ) {
        check_soup(&tris, &rays, 1.0)?;
    }

    #[test]
    fn tiny_and_huge_scales_match_the_oracle(
        exp in prop_oneof![Just(-12i32), Just(-6), Just(6), Just(12)],
        tris in prop::collection::vec(triangle(1.0), 1..40),
        rays in seeds(1.0),
    ) {
        let s = 10f32.powi(exp);
        let tris: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(|p| p * s)).collect();
        let rays: Vec<_> = rays.iter().map(|&(o, d, i, k)| (o * s, d, i, k)).collect();
        check_soup(&tris, &rays, s)?;
    }

    #[test]
    fn far_translated_soups_match_the_oracle(
        tris in prop::collection::vec(triangle(1.0), 1..40),
        rays in seeds(1.0),
    ) {
        let off = Vec3::new(1e4, -3e4, 2e4);
        let tris: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(|p| p + off)).collect();
        let rays: Vec<_> = rays.iter().map(|&(o, d, i, k)| (o + off * 0.5, d, i, k)).collect();
        check_soup(&tris, &rays, 1.0)?;
    }
}

/// A grid of unit squares in the plane z = 0 (two triangles each, shared edges and vertices).
fn planar_grid(n: usize) -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (i as f32, j as f32);
            let (a, b, c, d) = (
                Vec3::new(x, y, 0.0),
                Vec3::new(x + 1.0, y, 0.0),
                Vec3::new(x + 1.0, y + 1.0, 0.0),
                Vec3::new(x, y + 1.0, 0.0),
            );
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

#[test]
fn planar_scene_rays_through_every_vertex_and_edge() {
    let tris = planar_grid(8);
    let mut rays = Vec::new();
    for i in 0..=16 {
        for j in 0..=16 {
            // Points on vertices, edge midpoints and diagonals.
            let p = Vec3::new(i as f32 * 0.5, j as f32 * 0.5, 0.0);
            for d in [Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.3, -0.2, -1.0), Vec3::new(-0.0, 0.0, 1.0)] {
                rays.push(Ray::new(p - 2.0 * d, d, 0.0, f32::INFINITY));
            }
            // Rays lying in the plane of the grid, along and across it.
            for d in [Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 0.5, -0.0)] {
                rays.push(Ray::new(p, d, 0.0, f32::INFINITY));
            }
        }
    }
    check_trees(&tris, &rays).unwrap();
}

#[test]
fn watertight_grid_never_leaks_through_shared_edges() {
    let tris = planar_grid(8);
    let tree =
        KdTree::build_soup(&tris, &BuildConfig { intersector: Intersector::Watertight, ..Default::default() }).unwrap();
    let mut leaks = 0;
    for i in 1..16 {
        for j in 1..16 {
            let p = Vec3::new(i as f32 * 0.5, j as f32 * 0.5, 0.0);
            let d = Vec3::new(0.137, -0.071, -1.0);
            if tree.intersect(&Ray::new(p - 3.0 * d, d, 0.0, f32::INFINITY)).is_none() {
                leaks += 1;
            }
        }
    }
    assert_eq!(leaks, 0);
}

#[test]
fn axis_parallel_rays_with_signed_zeros_in_a_box_of_boxes() {
    // A 4x4x4 lattice of small cubes: split planes fall between and on cube faces.
    let mut tris = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            for k in 0..4 {
                let lo = Vec3::new(i as f32, j as f32, k as f32);
                tris.extend(cube(lo, lo + Vec3::splat(0.5)));
            }
        }
    }
    let mut rays = Vec::new();
    for a in 0..3 {
        for s in [1.0f32, -1.0] {
            for zero in [0.0f32, -0.0] {
                let mut d = Vec3::splat(zero);
                d[a] = s;
                for u in 0..=16 {
                    for v in 0..=16 {
                        let mut o = Vec3::splat(-1.0 + 6.0 * (s < 0.0) as u8 as f32);
                        o[(a + 1) % 3] = u as f32 * 0.25;
                        o[(a + 2) % 3] = v as f32 * 0.25;
                        o[a] = if s > 0.0 { -1.0 } else { 5.0 };
                        rays.push(Ray::new(o, d, 0.0, f32::INFINITY));
                    }
                }
            }
        }
    }
    check_trees(&tris, &rays).unwrap();
}

#[test]
fn origins_on_surfaces_and_split_planes() {
    let mut tris = Vec::new();
    for k in 0..5 {
        let lo = Vec3::new(k as f32, 0.0, 0.0);
        tris.extend(cube(lo, lo + Vec3::ONE));
    }
    let tree = KdTree::build_soup(&tris, &BuildConfig::default()).unwrap();
    let mut rays = Vec::new();
    // Origins on the shared faces x = 1, 2, 3, 4 (split plane candidates), going both ways.
    for k in 1..5 {
        for d in [Vec3::X, -Vec3::X, Vec3::new(0.5, 0.1, 0.2), Vec3::Y, Vec3::new(0.0, -0.0, 1.0)] {
            for t_min in [0.0, 1e-4] {
                rays.push(Ray::new(Vec3::new(k as f32, 0.5, 0.5), d, t_min, f32::INFINITY));
            }
        }
    }
    check_rays(&tree, &rays).unwrap();
    // A ray starting on a face with t_min = 0 hits that face at t = 0.
    let hit = tree.intersect(&Ray::new(Vec3::new(2.0, 0.5, 0.5), Vec3::X, 0.0, f32::INFINITY)).unwrap();
    assert_eq!(hit.t, 0.0);
}

#[test]
fn nan_rays_return_no_hit_and_never_panic() {
    let tris = planar_grid(2);
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = KdTree::build_soup(&tris, &BuildConfig { intersector, ..BuildConfig::default() }).unwrap();
        let oracle = BruteForce::for_tree(&tree);
        for (o, d) in [
            (Vec3::new(nan, 0.0, 1.0), Vec3::NEG_Z),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::new(0.0, nan, -1.0)),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::ZERO),
            (Vec3::new(0.5, 0.5, inf), Vec3::NEG_Z),
            (Vec3::new(-inf, 0.5, 0.0), Vec3::X),
            (Vec3::new(0.5, 0.5, -inf), Vec3::new(0.1, 0.1, 1.0)),
            // An infinite direction: the triangle test would report a hit at t = 0.
            (Vec3::new(0.5, 0.5, 1.0), Vec3::new(0.0, 0.0, -inf)),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::new(inf, 0.0, -1.0)),
            // NaN on an axis the ray is parallel to: the box clip cannot see it, the triangle
            // test does.
            (Vec3::new(0.5, nan, 1.0), Vec3::NEG_Z),
        ] {
            for (t_min, t_max) in [(0.0, inf), (-inf, inf), (0.0, 10.0)] {
                let ray = Ray::new(o, d, t_min, t_max);
                assert!(tree.intersect(&ray).is_none(), "{intersector:?} {ray:?}");
                assert!(!tree.occluded(&ray), "{intersector:?} {ray:?}");
                assert!(oracle.intersect(&ray).is_none(), "{intersector:?} {ray:?}");
            }
        }
        // A good ray with a NaN interval end.
        let (o, d) = (Vec3::new(0.5, 0.5, 1.0), Vec3::NEG_Z);
        assert!(tree.intersect(&Ray::new(o, d, 0.0, inf)).is_some());
        for (t_min, t_max) in [(nan, inf), (0.0, nan), (nan, nan)] {
            let ray = Ray::new(o, d, t_min, t_max);
            assert!(tree.intersect(&ray).is_none(), "{ray:?}");
            assert!(!tree.occluded(&ray), "{ray:?}");
            let mut c = kdtree::Counts::default();
            assert!(tree.intersect_counted(&ray, &mut c).is_none() && !tree.occluded_counted(&ray, &mut c));
        }
    }
}

#[test]
fn counters_count_and_agree_with_the_uncounted_query() {
    let tris = planar_grid(8);
    let tree = KdTree::build_soup(&tris, &BuildConfig::default()).unwrap();
    let ray = Ray::new(Vec3::new(3.3, 4.1, 2.0), Vec3::NEG_Z, 0.0, f32::INFINITY);
    let mut c = kdtree::Counts::default();
    assert_eq!(tree.intersect_counted(&ray, &mut c), tree.intersect(&ray));
    assert!(c.nodes >= 1 && c.leaves >= 1 && c.tests >= 1, "{c:?}");
    assert!(c.nodes >= c.leaves);
}

/// The 12 triangles of an axis-aligned box, outward facing.
fn cube(lo: Vec3, hi: Vec3) -> Vec<[Vec3; 3]> {
    let p = |i: usize| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    quads.iter().flat_map(|q| [[p(q[0]), p(q[1]), p(q[2])], [p(q[0]), p(q[2]), p(q[3])]]).collect()
}

/// Bad refines change the tree (more nodes: splits costlier than their leaf are made), the
/// collapse takes back those that did not pay (fewer nodes than without it), and every one
/// of these trees answers as the oracle.
#[test]
fn bad_refines_and_collapse_change_the_tree_and_match_the_oracle() {
    let mut r = common::Rng::new(11);
    let tris = r.triangles(3000, |r| {
        let c = r.vec3() * 10.0;
        [c, c + r.vec3() - 0.5, c + r.vec3() - 0.5]
    });
    let seeds: Vec<_> = (0..300).map(|i| (r.vec3() * 10.0, r.vec3() - 0.5, i * 7, (i % 256) as u8)).collect();
    let rays = common::rays_for(&tris, 10.0, &seeds);
    // No empty bonus, so that the statistics' SAH cost is the one the collapse minimises.
    let base = BuildConfig { leaf_width: 4, empty_bonus: 0.0, ..BuildConfig::default() };
    let build = |config: &BuildConfig| {
        let tree = KdTree::build_soup(&tris, config).unwrap();
        tree.validate().unwrap();
        check_rays(&tree, &rays).unwrap_or_else(|e| panic!("{config:?}: {e}"));
        tree
    };
    let plain = build(&base);
    let bad = build(&BuildConfig { max_bad_refines: 3, ..base.clone() });
    let both = build(&BuildConfig { max_bad_refines: 3, collapse: true, ..base.clone() });
    let (n_plain, n_bad, n_both) = (plain.nodes().len(), bad.nodes().len(), both.nodes().len());
    assert!(n_bad > n_plain, "bad refines split more: {n_bad} vs {n_plain}");
    assert!(n_both < n_bad, "the collapse takes some back: {n_both} vs {n_bad}");
    // The collapse never raises the tree's SAH cost (with the leaf width's groups).
    let (c_bad, c_both) = (bad.stats().sah_cost, both.stats().sah_cost);
    assert!(c_both <= c_bad * (1.0 + 1e-9), "{c_both} vs {c_bad}");
}
