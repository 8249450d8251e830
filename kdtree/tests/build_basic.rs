//! Hand-made build cases: SAH termination, flat and degenerate configurations, huge and tiny
//! coordinates, and the statistics of a small tree.

mod common;

use common::Rng;
use glam::Vec3;
use kdtree::{BuildConfig, KdNode, KdTree};

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// The thesis's SAH terms: the expected shapes below are worked out with them.
fn build(tris: &[[Vec3; 3]]) -> KdTree {
    build_with(tris, &BuildConfig::thesis())
}

fn build_with(tris: &[[Vec3; 3]], config: &BuildConfig) -> KdTree {
    let tree = KdTree::build_soup(tris, config).expect("build");
    tree.validate().unwrap_or_else(|e| panic!("invalid tree: {e}"));
    tree
}

#[test]
fn empty_and_degenerate_inputs_give_one_empty_leaf() {
    let tree = build(&[]);
    assert_eq!(tree.nodes(), &[KdNode::leaf(0, 0)]);
    let flat = [[v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(2.0, 2.0, 2.0)]; 3];
    let tree = build(&flat);
    assert_eq!(tree.nodes(), &[KdNode::leaf(0, 0)]);
    let s = tree.stats();
    assert_eq!((s.triangles, s.triangles_in_tree, s.refs, s.empty_leaves), (3, 0, 0, 1));
    assert_eq!(s.sah_cost, 0.0);
}

#[test]
fn single_triangle_is_a_leaf() {
    let tree = build(&[[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 1.0)]]);
    assert_eq!(tree.nodes(), &[KdNode::leaf(0, 1)]);
    assert_eq!(tree.leaf_prims(tree.nodes()[0]), &[0]);
}

#[test]
fn two_far_clusters_are_split_between_them() {
    let mut rng = Rng(7);
    let mut tris = Vec::new();
    for c in [v(0.0, 0.0, 0.0), v(100.0, 0.0, 0.0)] {
        for _ in 0..50 {
            tris.push([c + rng.vec3(), c + rng.vec3(), c + rng.vec3()]);
        }
    }
    let tree = build(&tris);
    let root = tree.nodes()[0];
    assert!(!root.is_leaf());
    assert_eq!(root.axis(), 0);
    let c0_max = tris[..50].iter().flatten().map(|p| p.x).fold(f32::MIN, f32::max);
    let c1_min = tris[50..].iter().flatten().map(|p| p.x).fold(f32::MAX, f32::min);
    assert!(root.split() >= c0_max && root.split() <= c1_min, "split at {}", root.split());
    let s = tree.stats();
    assert_eq!(s.refs_per_triangle, 1.0 * s.refs as f64 / 100.0);
}

/// Root splits x = 1 (ties keep the first plane), its right child cuts the empty space off at
/// x = 9: root(x=1) -> [leaf T0, inner(x=9) -> [empty leaf, leaf T1]]. Each non-empty leaf's
/// references start at a multiple of 4 (the SIMD leaf layout of `kdtree::leaf`).
#[test]
fn stats_of_a_hand_built_tree() {
    let t0 = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
    let t1 = t0.map(|p| p + v(9.0, 0.0, 0.0));
    let tree = build(&[t0, t1]);
    assert_eq!(
        tree.nodes(),
        &[
            KdNode::inner(0, 1.0, 1),
            KdNode::leaf(0, 1),
            KdNode::inner(0, 9.0, 3),
            KdNode::leaf(4, 0),
            KdNode::leaf(4, 1)
        ]
    );
    let s = tree.stats();
    assert_eq!((s.triangles, s.triangles_in_tree, s.nodes, s.inner_nodes), (2, 2, 5, 2));
    assert_eq!((s.leaves, s.empty_leaves, s.depth, s.refs), (3, 1, 2, 2));
    assert_eq!((s.refs_per_triangle, s.avg_tris_per_nonempty_leaf), (1.0, 1.0));
    // 1 (root) + 18/20 (right inner) + 2 * 5 * 2/20 (the two triangle leaves).
    assert!((s.sah_cost - 2.9).abs() < 1e-9, "{}", s.sah_cost);
    assert_eq!(
        tree.prim_refs(),
        &[
            0,
            kdtree::leaf::GAP,
            kdtree::leaf::GAP,
            kdtree::leaf::GAP,
            1,
            kdtree::leaf::GAP,
            kdtree::leaf::GAP,
            kdtree::leaf::GAP
        ]
    );
    // Nodes, 8 reference slots, two 40-byte records and two 160-byte groups.
    assert_eq!(s.bytes, 5 * 8 + 8 * 4 + 2 * 40 + 2 * 160);
}

#[test]
fn all_triangles_in_one_plane() {
    let tris = Rng(11).triangles(2000, |r| {
        let c = r.vec3() * 10.0;
        let s = 0.05 + r.f32();
        [c, c + v(s, 0.0, 0.0), c + v(0.0, s, 0.0)].map(|p| v(p.x, p.y, 0.5))
    });
    let tree = build(&tris);
    let s = tree.stats();
    assert!(s.leaves > 50, "{s:?}");
    assert_eq!(tree.bounds().min.z, tree.bounds().max.z);
}

#[test]
fn many_identical_triangles_stay_together() {
    let t = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 1.0)];
    let mut tris = vec![t; 500];
    tris.push(t.map(|p| p + v(50.0, 0.0, 0.0)));
    let tree = build(&tris);
    let s = tree.stats();
    assert!(s.depth < 10 && s.refs < 1100, "{s:?}");
}

#[test]
fn triangles_on_split_planes_and_touching_boxes() {
    // A grid of unit cells, each with triangles lying in its faces (x = i, y = j planes), and
    // cubes' faces touching each other.
    let mut tris = Vec::new();
    for i in 0..8 {
        for j in 0..8 {
            let (x, y) = (i as f32, j as f32);
            tris.push([v(x, y, 0.0), v(x, y + 1.0, 0.0), v(x, y, 1.0)]);
            tris.push([v(x, y, 0.0), v(x + 1.0, y, 0.0), v(x, y, 1.0)]);
            tris.push([v(x, y, 0.0), v(x + 1.0, y, 0.0), v(x + 1.0, y + 1.0, 0.0)]);
            tris.push([v(x + 0.25, y + 0.25, 0.0), v(x + 0.75, y + 0.5, 0.5), v(x + 0.5, y + 0.75, 1.0)]);
        }
    }
    for config in
        [BuildConfig::thesis(), BuildConfig::default(), BuildConfig { empty_bonus: 0.8, ..BuildConfig::thesis() }]
    {
        let tree = build_with(&tris, &config);
        // At least one leaf per grid cell (the default terms give exactly the 64 cells, 4
        // triangles each; the thesis's split further).
        assert!(tree.stats().leaves >= 64, "{config:?}: {:?}", tree.stats());
    }
}

/// Coordinates of magnitude 1e30 / 1e38 and 1e-15 build normal trees. At 1e-30 the caller's
/// `f32` degeneracy test (edge cross product) underflows to zero, so the triangles count as
/// degenerate; those builds must still succeed and validate.
#[test]
fn huge_and_tiny_coordinates() {
    for scale in [1e-30f32, 1e-38] {
        let tris = Rng(3).triangles(500, |r| [r.vec3(), r.vec3(), r.vec3()].map(|p| p * scale));
        build(&tris);
    }
    // A scene mixing both: tiny triangles near the origin and huge ones around them.
    let mut rng = Rng(9);
    let mut tris = rng.triangles(300, |r| [r.vec3(), r.vec3(), r.vec3()].map(|p| p * 1e-18));
    tris.extend(rng.triangles(300, |r| [r.vec3(), r.vec3(), r.vec3()].map(|p| (p - Vec3::splat(0.5)) * 1e30)));
    build(&tris);
    for scale in [1e30f32, 1e-15, 1e38] {
        let tris = Rng(3).triangles(500, |r| {
            let c = r.vec3() * 2.0 - Vec3::ONE;
            let s = r.f32() * 0.2;
            [c, c + r.vec3() * s, c + r.vec3() * s].map(|p| p * scale)
        });
        let tree = build(&tris);
        let s = tree.stats();
        assert!(s.sah_cost.is_finite() && s.sah_cost > 0.0, "{scale}: {s:?}");
        assert!(s.leaves > 10, "{scale}: {s:?}");
        assert!(tree.nodes().iter().all(|n| n.is_leaf() || n.split().is_finite()));
    }
}

#[test]
fn depth_limit_is_respected() {
    let tris = Rng(5).triangles(3000, |r| {
        let c = r.vec3() * 10.0;
        [c, c + r.vec3() * 0.1, c + r.vec3() * 0.1]
    });
    for d in [0, 1, 5] {
        let tree = build_with(&tris, &BuildConfig { max_depth: Some(d), ..BuildConfig::default() });
        assert_eq!(tree.stats().depth, d as usize);
    }
    let tree = build_with(&tris, &BuildConfig { max_depth: Some(1000), c_trav: 0.0, ..BuildConfig::default() });
    assert!(tree.stats().depth <= kdtree::MAX_DEPTH as usize);
}

/// NaN and infinite input is an error naming where it is, never a panic.
#[test]
fn non_finite_input_is_an_error_naming_it() {
    use kdtree::{Aabb, BuildError};
    let positions = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(1.0, 1.0, 0.0)];
    let triangles = [[0, 1, 2], [1, 3, 2]];
    let config = BuildConfig::default();
    assert!(KdTree::build(&positions, &triangles, &config).is_ok());
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut p = positions;
        p[3].z = bad;
        let e = KdTree::build(&p, &triangles, &config).unwrap_err();
        assert!(matches!(e, BuildError::NonFiniteVertex { index: 3, .. }), "{e:?}");
        assert!(e.to_string().starts_with("vertex 3 is not finite"), "{e}");
        // Soups number vertices 3 * triangle + corner.
        let soup = [[p[0], p[1], p[2]], [p[1], p[3], p[2]]];
        let e = KdTree::build_soup(&soup, &config).unwrap_err();
        assert!(matches!(e, BuildError::NonFiniteVertex { index: 4, .. }), "{e:?}");
        // Configuration values.
        for (config, field) in [
            (BuildConfig { c_trav: bad, ..BuildConfig::default() }, "c_trav"),
            (BuildConfig { c_isect: bad, ..BuildConfig::default() }, "c_isect"),
            (BuildConfig { empty_bonus: bad, ..BuildConfig::default() }, "empty_bonus"),
        ] {
            let e = KdTree::build(&positions, &triangles, &config).unwrap_err();
            assert!(matches!(e, BuildError::BadConfig(_)) && e.to_string().contains(field), "{field} = {bad}: {e}");
        }
    }

    // Trees made elsewhere: vertices, bounds and split planes are checked.
    let tris = [[positions[0], positions[1], positions[2]], [positions[1], positions[3], positions[2]]];
    let bounds = Aabb::from_points(&positions);
    let nodes = vec![KdNode::inner(0, 0.5, 1), KdNode::leaf(0, 2), KdNode::leaf(0, 2)];
    let from = |tris: &[[Vec3; 3]], nodes: &[KdNode], bounds: Aabb| {
        KdTree::from_parts(tris.to_vec(), nodes.to_vec(), vec![0, 1], bounds, &config)
    };
    from(&tris, &nodes, bounds).unwrap().validate().unwrap();
    let empty = KdTree::from_parts(Vec::new(), vec![KdNode::leaf(0, 0)], Vec::new(), Aabb::EMPTY, &config);
    assert!(empty.is_ok(), "the empty box is allowed");
    for bad in [f32::NAN, f32::INFINITY] {
        let mut t = tris;
        t[1][2].y = bad;
        let e = from(&t, &nodes, bounds).unwrap_err();
        assert!(e.contains("triangle 1") && e.contains("not finite"), "{e}");
        let e = from(&tris, &[KdNode::inner(0, bad, 1), nodes[1], nodes[2]], bounds).unwrap_err();
        assert!(e.contains("node 0") && e.contains("split plane"), "{e}");
    }
    let e = from(&tris, &nodes, Aabb { max: v(1.0, f32::NAN, 0.0), ..bounds }).unwrap_err();
    assert!(e.contains("bounds") && e.contains("NaN"), "{e}");
    // Children out of range, reachable or not: the single-ray kernel reads nodes unchecked.
    let e = from(&tris, &[KdNode::inner(0, 0.5, 2), nodes[1], nodes[2]], bounds).unwrap_err();
    assert!(e.contains("node 0") && e.contains("of 3"), "{e}");
    let unreachable = [nodes[0], nodes[1], nodes[2], KdNode::inner(1, 0.5, 3)];
    let e = from(&tris, &unreachable, bounds).unwrap_err();
    assert!(e.contains("node 3") && e.contains("of 4"), "{e}");
}

/// Four small triangles at the corners of a box: priced per triangle (leaf width 1) the
/// leaf costs 4 tests and the node splits; priced by SIMD groups of 4 the leaf costs one
/// group test, less than any split (a traversal step plus a group on at least one side),
/// and the node is one leaf.
#[test]
fn four_triangles_split_per_triangle_and_make_one_leaf_of_a_group_of_four() {
    let mut tris = Vec::new();
    for c in [v(0.0, 0.0, 0.0), v(10.0, 0.0, 0.0), v(0.0, 10.0, 0.0), v(10.0, 10.0, 10.0)] {
        tris.push([c, c + v(1.0, 0.0, 0.0), c + v(0.0, 1.0, 1.0)]);
    }
    for strategy in [kdtree::BuildStrategy::Exact, kdtree::BuildStrategy::Binned { bins: 8, min_tris: 2 }] {
        let base = BuildConfig { strategy, ..BuildConfig::default() };
        let per_triangle = build_with(&tris, &BuildConfig { leaf_width: 1, ..base.clone() });
        assert!(!per_triangle.nodes()[0].is_leaf(), "{:?}", per_triangle.nodes());
        let grouped = build_with(&tris, &BuildConfig { leaf_width: 4, ..base });
        assert_eq!(grouped.nodes(), &[KdNode::leaf(0, 4)], "{strategy:?}");
    }
}

/// A leaf width and bad-refine count out of range are configuration errors naming them.
#[test]
fn leaf_width_and_bad_refines_out_of_range_are_refused() {
    let tris = [[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 1.0)]];
    for (config, field) in [
        (BuildConfig { leaf_width: 0, ..BuildConfig::default() }, "leaf_width"),
        (BuildConfig { leaf_width: BuildConfig::MAX_LEAF_WIDTH + 1, ..BuildConfig::default() }, "leaf_width"),
        (
            BuildConfig { max_bad_refines: BuildConfig::MAX_BAD_REFINES + 1, ..BuildConfig::default() },
            "max_bad_refines",
        ),
    ] {
        let e = KdTree::build_soup(&tris, &config).unwrap_err();
        assert!(matches!(&e, kdtree::BuildError::BadConfig(m) if m.contains(field)), "{e}");
    }
}
