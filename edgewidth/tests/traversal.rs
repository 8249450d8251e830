//! The edge-width traversal against its brute-force twin, and the packet variant against
//! the single-ray one: random soups of closed boxes and loose triangles on a coarse grid (so
//! faces lie on split planes and rays run along them), the named hard cases, and shadow
//! rays of the built-in scenes.
//!
//! The rule under test: a ray's edge width is a function of the hits the triangle test
//! reports on its segment (one per triangle, sorted by `t`, ties through shared edges merged),
//! so the kernels must equal the brute force bit for bit, degenerate rays included. A ray
//! lying in a face's plane gets no hit from that face and whatever the test reports on the
//! edges of the faces around it; the answer may be odd (a graze between two touching boxes
//! can read as a hard shadow), but it is the same answer everywhere. The grid makes such
//! rays common: most failures of this comparison were in-plane rays.

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
    for (setting, remedies) in settings.iter().enumerate() {
        for r in [0.05f32, 0.3, f32::INFINITY] {
            let single: Vec<f32> = rays.iter().map(|ray| edge_width(tree, ray, r, remedies, &mut scratch)).collect();
            for (ray, &w) in rays.iter().zip(&single) {
                let b = edge_width_brute(tree, ray, r, remedies);
                prop_assert!(
                    w.to_bits() == b.to_bits(),
                    "ray {ray:?} r {r} remedies #{setting}: traversal {w} brute {b}"
                );
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

/// NaN and infinite rays cross nothing, with the kernel, the packet kernel and the brute
/// force alike; a NaN `r` never exits early (the width of `r = +inf`).
#[test]
fn non_finite_rays_and_widths() {
    let tris = cuboid(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.5, 1.0));
    let off = LeakRemedies::default();
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = tree(&tris, 5.0, intersector);
        let mut s = EdgeScratch::default();
        let through = Ray::new(Vec3::new(0.3, -1.0, -0.2), Vec3::new(0.0, 2.0, 0.0), 0.0, 1.0);
        let full = edge_width(&tree, &through, inf, &off, &mut s);
        assert!((full - 0.25).abs() < 1e-6, "{full}");
        assert_eq!(edge_width(&tree, &through, 0.1, &off, &mut s), inf, "early exit past r");
        assert_eq!(edge_width(&tree, &through, nan, &off, &mut s), full);
        assert_eq!(edge_width_brute(&tree, &through, nan, &off), full);
        let bad = [
            Ray::new(Vec3::new(0.3, nan, -0.2), Vec3::new(0.0, 2.0, 0.0), 0.0, 1.0),
            Ray::new(Vec3::new(0.3, -inf, -0.2), Vec3::new(0.0, 2.0, 0.0), 0.0, 1.0),
            Ray::new(Vec3::new(0.3, -1.0, -0.2), Vec3::new(0.0, nan, 0.0), 0.0, 1.0),
            Ray::new(Vec3::new(0.3, -1.0, -0.2), Vec3::new(0.0, inf, 0.0), 0.0, 1.0),
            Ray::new(Vec3::new(0.3, -1.0, -0.2), Vec3::new(0.0, 2.0, 0.0), nan, 1.0),
            Ray::new(Vec3::new(0.3, -1.0, -0.2), Vec3::new(0.0, 2.0, 0.0), 0.0, nan),
        ];
        for ray in &bad {
            assert_eq!(edge_width(&tree, ray, 0.5, &off, &mut s), 0.0, "{ray:?}");
            assert_eq!(edge_width_brute(&tree, ray, 0.5, &off), 0.0, "{ray:?}");
        }
        let mut s4 = EdgeScratch4::default();
        for (i, ray) in bad.iter().enumerate() {
            let lanes = [*ray, through, bad[(i + 1) % bad.len()], through];
            let w = edge_width4(&tree, &RayPacket::new(&lanes), [0.5, nan, 0.5, inf], &off, &mut s4);
            assert_eq!(w, [0.0, full, 0.0, full], "{ray:?}");
        }
    }
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

/// The triangles of the boxes `[lo, hi]`, in order, then `loose`.
fn soup(boxes: &[(Vec3, Vec3)], loose: &[[Vec3; 3]]) -> Vec<[Vec3; 3]> {
    let mut tris: Vec<[Vec3; 3]> = boxes.iter().flat_map(|&(lo, hi)| cuboid(lo, hi)).collect();
    tris.extend_from_slice(loose);
    tris
}

/// The edge width of `ray` by the kernel, after checking it against the brute force and the
/// packet variant with every setting.
fn width(tree: &KdTree, ray: Ray, r: f32) -> f32 {
    check(tree, &[ray]).unwrap();
    let w = edge_width(tree, &ray, r, &LeakRemedies::default(), &mut EdgeScratch::default());
    assert_eq!(w.to_bits(), edge_width_brute(tree, &ray, r, &LeakRemedies::default()).to_bits());
    w
}

/// A proptest finding: a ray in the plane `y = 1` of the top face of a box, grazing the top
/// edges of its side faces, with `y = 1` a split plane. The ray in the plane visits both
/// children over its whole interval; the second child's entry sat on the stack below entries
/// pushed while the first child's subtree was traversed, and the kernel paired up to the top
/// entry's start, so the corner hits at `t = 1` were paired before the edge hit at 0.857 that
/// the second child reported (width 1 where the brute force has an entry never closed).
#[test]
fn in_plane_ray_grazing_a_box_top_matches_brute_force() {
    let v = Vec3::new;
    let tris = soup(
        &[
            (v(-3.5, -3.5, -2.5), v(3.25, -1.25, -1.25)),
            (v(0.0, -0.25, 0.75), v(0.25, 0.0, 1.0)),
            (v(-3.75, 0.0, -0.25), v(0.0, 1.0, 0.0)),
            (v(-0.25, -0.25, -0.5), v(0.0, 0.0, 1.25)),
        ],
        &[[v(0.0, 0.0, 2.5), v(1.75, -4.0, -1.5), v(-1.75, 3.75, 2.75)]],
    );
    let tree = tree(&tris, 1.0, Intersector::Wald);
    let ray = Ray::new(v(-0.5, 1.0, 1.5), v(0.5, 0.0, -1.75), 0.0, 1.0);
    // Entry on the loose triangle at 0, exit on the box's edge at 6/7, the box's far corner
    // at 1 an entry never closed.
    assert_eq!(width(&tree, ray, f32::INFINITY), f32::INFINITY);
    assert_eq!(width(&tree, ray, 0.05), f32::INFINITY);
}

/// A proptest finding: a ray in the plane `z = 0.75` where two boxes touch face to face,
/// grazing the edges of the side faces of both (Wald test). Same cause as above: the side
/// faces of one box were paired before those of the other (width 0.0084 where the brute
/// force has 0.0588, past `r = 0.05`).
#[test]
fn in_plane_ray_between_touching_boxes_matches_brute_force() {
    let v = Vec3::new;
    let tris = soup(
        &[
            (v(0.0, 0.0, -2.25), v(1.25, 0.75, 0.0)),
            (v(0.0, 0.0, 0.0), v(0.25, 0.75, 0.75)),
            (v(-0.25, 0.0, 0.75), v(0.25, 1.0, 1.0)),
        ],
        &[],
    );
    let tree = tree(&tris, 1.0, Intersector::Wald);
    let ray = Ray::new(v(-1.0, 0.25, 0.75), v(4.25, 1.75, 0.0), 0.0, 1.0);
    // Grazes at x = -0.25 (entry), x = 0 (exit), y = 0.75 (entry), x = 0.25 (exit): the
    // widest pair is 1/17, from x = -0.25 to 0 over the 4.25 of the ray.
    let w = width(&tree, ray, f32::INFINITY);
    assert!((w - 1.0 / 17.0).abs() < 1e-6, "{w}");
    assert_eq!(width(&tree, ray, 0.05), f32::INFINITY);
}

/// A proptest finding: the face `x = 0` of a box lies in the split plane `x = 0` and only
/// the leaf on its box's side holds it; the watertight test puts the ray's entry through it
/// 14 ulps before that leaf's start, beyond the plane-distance widening. The kernel used to
/// drop hits before the start of the leaf that reports them (taking them for repeats of an
/// earlier leaf's hits) and lost the entry; hits now count by triangle, whatever the leaf.
#[test]
fn hit_computed_before_its_only_leaf_counts() {
    let v = Vec3::new;
    let tris = soup(
        &[(v(0.0, -2.75, 0.25), v(0.25, 3.25, 0.5))],
        &[[v(0.0, 0.0, 0.0), v(0.0, 0.0, -0.25), v(-0.5, 0.0, 0.0)]],
    );
    let ray = Ray::new(v(-0.25, -1.75, 0.0), v(3.5, 4.25, 4.0), 0.0, 1.0);
    for c_isect in [1.0f32, 5.0, 80.0] {
        let tree = tree(&tris, c_isect, Intersector::Watertight);
        // In through x = 0 at t = 1/14, out through z = 0.5 at t = 1/8.
        let w = width(&tree, ray, 0.3);
        assert!((w - (1.0 / 8.0 - 1.0 / 14.0)).abs() < 1e-6, "c_isect {c_isect}: {w}");
        assert_eq!(width(&tree, ray, 0.05), f32::INFINITY);
    }
}
