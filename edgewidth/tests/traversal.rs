//! The edge-width traversal against its brute-force twin, and the packet variant against
//! the single-ray one: random soups of closed boxes and loose triangles on a coarse grid (so
//! faces lie on split planes and rays run along them), the named hard cases, and shadow
//! rays of the built-in scenes.

use edgewidth::brute::edge_width_brute;
use edgewidth::packet::{EdgeScratch4, edge_width4};
use edgewidth::{EdgeScratch, LeakRemedies, edge_width};
use glam::Vec3;
use kdtree::{BuildConfig, Intersector, KdTree, Ray};
use packets::RayPacket;
use proptest::prelude::*;

/// The 12 triangles of the box `[lo, hi]`, outward-facing, sharing vertex positions.
fn cuboid(lo: Vec3, hi: Vec3) -> Vec<[Vec3; 3]> {
    let c = |i: u32| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    quads.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
}

fn tree(tris: &[[Vec3; 3]], c_isect: f32, intersector: Intersector) -> KdTree {
    let config = BuildConfig { c_isect, intersector, ..BuildConfig::default() };
    let tree = KdTree::build_soup(tris, &config).unwrap();
    tree.validate().unwrap();
    tree
}

/// Compares the kernel, the brute force and the packet variant on `rays`, with each `r` and
/// each remedy setting.
fn check(tree: &KdTree, rays: &[Ray]) -> Result<(), TestCaseError> {
    let scale: Vec<f32> = (0..tree.triangle_count()).map(|i| 1.0 + (i % 3) as f32).collect();
    let settings = [
        LeakRemedies::default(),
        LeakRemedies { thickness: Some(&scale), shared_vertex: false },
        LeakRemedies { thickness: None, shared_vertex: true },
    ];
    let mut scratch = EdgeScratch::default();
    let mut scratch4 = EdgeScratch4::default();
    for remedies in &settings {
        for r in [0.05f32, 0.3, f32::INFINITY] {
            let single: Vec<f32> = rays.iter().map(|ray| edge_width(tree, ray, r, remedies, &mut scratch)).collect();
            for (ray, &w) in rays.iter().zip(&single) {
                let b = edge_width_brute(tree, ray, r, remedies);
                prop_assert!(w.to_bits() == b.to_bits(), "ray {ray:?} r {r}: traversal {w} brute {b}");
            }
            for (chunk, expect) in rays.chunks(4).zip(single.chunks(4)) {
                let packet = edge_width4(tree, &RayPacket::new(chunk), [r; 4], remedies, &mut scratch4);
                for (lane, &w) in expect.iter().enumerate() {
                    prop_assert!(
                        packet[lane].to_bits() == w.to_bits(),
                        "lane {lane} of {chunk:?}: {} vs {w}",
                        packet[lane]
                    );
                }
            }
        }
    }
    Ok(())
}

/// A value on the grid of quarter units in `[-4, 4]`.
fn grid() -> impl Strategy<Value = f32> {
    (-16i32..=16).prop_map(|i| i as f32 * 0.25)
}

fn point() -> impl Strategy<Value = Vec3> {
    (grid(), grid(), grid()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// A closed box with corners on the grid (possibly flat, then dropped as degenerate).
fn boxes() -> impl Strategy<Value = Vec<[Vec3; 3]>> {
    prop::collection::vec((point(), point()), 1..8).prop_map(|b| {
        b.into_iter()
            .filter(|(p, q)| (p - q).abs().min_element() > 0.0)
            .flat_map(|(p, q)| cuboid(p.min(q), p.max(q)))
            .collect()
    })
}

/// Segments between grid points (so many lie in split planes, with zero components).
fn segments() -> impl Strategy<Value = Vec<Ray>> {
    prop::collection::vec((point(), point()), 1..24)
        .prop_map(|s| s.into_iter().filter(|(a, b)| a != b).map(|(a, b)| Ray::new(a, b - a, 0.0, 1.0)).collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn random_boxes_match_brute_force(
        tris in boxes(),
        loose in prop::collection::vec((point(), point(), point()), 0..6),
        rays in segments(),
        c_isect in prop::sample::select(vec![1.0f32, 5.0, 80.0]),
        watertight in any::<bool>(),
    ) {
        let mut tris = tris;
        tris.extend(loose.into_iter().map(|(a, b, c)| [a, b, c]));
        prop_assume!(!tris.is_empty());
        let intersector = if watertight { Intersector::Watertight } else { Intersector::Wald };
        check(&tree(&tris, c_isect, intersector), &rays)?;
    }

    #[test]
    fn off_grid_rays_match_brute_force(
        tris in boxes(),
        rays in prop::collection::vec((any::<[i16; 3]>(), any::<[i16; 3]>()), 1..24),
    ) {
        prop_assume!(!tris.is_empty());
        let f = |v: [i16; 3]| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) / 6000.0;
        let rays: Vec<Ray> = rays.into_iter().filter(|(a, b)| a != b).map(|(a, b)| Ray::new(f(a), f(b) - f(a), 0.0, 1.0)).collect();
        check(&tree(&tris, 80.0, Intersector::Wald), &rays)?;
    }
}

/// A slab `[-2, 2] x [-0.25, 0.25] x [-2, 2]` under a 4x4 grid of small boxes whose faces
/// make split planes cut through it, so that its triangles straddle planes and sit in several
/// leaves.
fn cut_box() -> (KdTree, Vec<[Vec3; 3]>) {
    let mut tris = cuboid(Vec3::new(-2.0, -0.25, -2.0), Vec3::new(2.0, 0.25, 2.0));
    for x in [-1.5f32, -0.5, 0.5, 1.5] {
        for z in [-1.5f32, -0.5, 0.5, 1.5] {
            tris.extend(cuboid(Vec3::new(x, 1.0, z), Vec3::new(x + 0.2, 1.2, z + 0.2)));
        }
    }
    (tree(&tris, 80.0, Intersector::Wald), tris)
}

#[test]
fn triangles_in_several_leaves_count_once() {
    let (tree, _) = cut_box();
    // The slab's faces straddle the planes of the small boxes: check they do.
    let refs = tree.prim_refs().iter().filter(|&&p| p < 12).count();
    assert!(refs > 24, "the test needs triangles referenced by several leaves ({refs} references)");
    let mut scratch = EdgeScratch::default();
    let off = LeakRemedies::default();
    // Through the slab along each axis, in and off the split planes of the small boxes.
    for c in [-1.5f32, -1.4, -0.5, 0.0, 0.3, 0.5, 0.7, 1.5, 1.7] {
        for axis in 0..3 {
            for h in [-0.2f32, 0.0, 0.2] {
                let mut o = Vec3::new(c, h, c);
                o[axis] = -10.0;
                let mut d = Vec3::ZERO;
                d[axis] = 20.0;
                let ray = Ray::new(o, d, 0.0, 1.0);
                let w = edge_width(&tree, &ray, f32::INFINITY, &off, &mut scratch);
                let expect = if axis == 1 { 0.025 } else { 0.2 };
                assert!((w - expect).abs() < 1e-6, "axis {axis} at {c}, {h}: {w}");
                assert_eq!(w.to_bits(), edge_width_brute(&tree, &ray, f32::INFINITY, &off).to_bits());
            }
        }
    }
}

#[test]
fn hard_cases_match_brute_force() {
    let (tree, _) = cut_box();
    let mut rays = Vec::new();
    // Rays lying in split planes (zero components, origin on the plane).
    for s in [-2.0f32, -1.5, -1.3, -0.25, 0.25, 0.35, 1.0, 1.2, 2.0] {
        rays.push(Ray::new(Vec3::new(-10.0, s, 0.5), Vec3::new(20.0, 0.0, 0.0), 0.0, 1.0));
        rays.push(Ray::new(Vec3::new(s, -10.0, s), Vec3::new(0.0, 20.0, 0.0), 0.0, 1.0));
        rays.push(Ray::new(Vec3::new(s, s, 10.0), Vec3::new(0.0, 0.0, -20.0), 0.0, 1.0));
        // Diagonal in a plane.
        rays.push(Ray::new(Vec3::new(-6.0, s, -6.0), Vec3::new(12.0, 0.0, 12.0), 0.0, 1.0));
    }
    // Origins on surfaces: on a face, on an edge, at a corner, leaving and entering.
    for o in
        [Vec3::new(-2.0, 0.1, 0.3), Vec3::new(2.0, 0.25, 0.0), Vec3::new(2.0, 0.25, 2.0), Vec3::new(0.0, -0.25, 1.0)]
    {
        for d in [Vec3::X, -Vec3::X, Vec3::new(1.0, 1.0, 1.0), Vec3::new(-1.0, 0.5, 0.0)] {
            rays.push(Ray::new(o, 8.0 * d, 0.0, 1.0));
        }
    }
    // Through shared edges and vertices of the box.
    rays.push(Ray::new(Vec3::new(-10.0, 0.0, -10.0), Vec3::new(20.0, 0.0, 20.0), 0.0, 1.0));
    rays.push(Ray::new(Vec3::new(-4.0, -0.5, -4.0), Vec3::new(8.0, 1.0, 8.0), 0.0, 1.0));
    check(&tree, &rays).unwrap();
    // The diagonal through the slab's middle crosses it once in, once out, through the
    // edges its face diagonals share: 4 sqrt 2 of 20 sqrt 2.
    let w =
        edge_width(&tree, &rays[rays.len() - 2], f32::INFINITY, &LeakRemedies::default(), &mut EdgeScratch::default());
    assert!((w - 0.2).abs() < 1e-6, "{w}");
}

#[test]
fn open_geometry_is_a_hard_shadow_and_missing_geometry_no_shadow() {
    let tris = vec![[Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0)]];
    let tree = tree(&tris, 5.0, Intersector::Wald);
    let mut s = EdgeScratch::default();
    let off = LeakRemedies::default();
    let through = Ray::new(Vec3::new(0.0, -1.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0.0, 1.0);
    assert_eq!(edge_width(&tree, &through, 0.5, &off, &mut s), f32::INFINITY);
    let beside = Ray::new(Vec3::new(3.0, -1.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0.0, 1.0);
    assert_eq!(edge_width(&tree, &beside, 0.5, &off, &mut s), 0.0);
    let nan = Ray::new(Vec3::NAN, Vec3::Y, 0.0, 1.0);
    assert_eq!(edge_width(&tree, &nan, 0.5, &off, &mut s), 0.0);
}

#[test]
fn built_in_scene_shadow_rays_match() {
    for name in ["touching-boxes", "sphere", "arena"] {
        let scene = scenes::load_scene(name).unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(24, 24).unwrap();
        let light = scene.area_light.center();
        let mut rays = Vec::new();
        for y in 0..24 {
            for x in 0..24 {
                let (o, d) = camera.pixel_ray(x, y);
                if let Some(hit) = tree.intersect(&Ray::new(o, d, 0.0, f32::INFINITY)) {
                    let tri = tree.triangle(hit.prim);
                    let start = kdtree::ray::offset_origin(&tri, &hit, light - kdtree::ray::surface_point(&tri, &hit));
                    rays.push(Ray::new(start, light - start, 0.0, 1.0));
                }
            }
        }
        assert!(rays.len() > 100, "{name}");
        check(&tree, &rays).unwrap();
    }
}
