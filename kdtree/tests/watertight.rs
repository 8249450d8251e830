//! Rays aimed exactly at shared edges and vertices of closed meshes must hit something: the
//! watertight test never lets one through; Wald's test may (its count is printed, and the
//! README quotes it).

use glam::Vec3;
use kdtree::{BuildConfig, Intersector, KdTree, Ray};

/// Rays from outside the mesh's bounds aimed at every edge midpoint, at the edge's 1/3 and
/// 2/3 points and at every vertex, from `dirs` directions each (meshes that are convex or
/// unions of convex parts). Returns (rays, misses); the tree must agree with the oracle.
fn leaks(mesh: &scenes::Mesh, intersector: Intersector, dirs: usize) -> (usize, usize) {
    let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig { intersector, ..BuildConfig::default() })
        .unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let radius = (hi - lo).length();
    let center = 0.5 * (lo + hi);
    let mut targets = Vec::new();
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (mesh.positions[tri[k] as usize], mesh.positions[tri[(k + 1) % 3] as usize]);
            targets.extend([a, 0.5 * (a + b), a + (b - a) / 3.0, a + (b - a) * (2.0 / 3.0)]);
        }
    }
    let (mut rays, mut misses, mut traversal_misses) = (0, 0, 0);
    let oracle = kdtree::BruteForce::for_tree(&tree);
    for (i, &p) in targets.iter().enumerate() {
        for j in 0..dirs {
            // Directions within 30 degrees of the inward direction (towards the centre), spread
            // by a golden-angle spiral. A ray grazing a convex mesh may legitimately touch it
            // only at the rounded target point, so tangent directions are left out.
            let inward = (center - p).normalize_or(Vec3::Z);
            let (u, v) = inward.any_orthonormal_pair();
            let k = (i * dirs + j) as f32;
            let spread = 0.5 * ((k * 0.618_034) % 1.0).sqrt();
            let phi = k * 2.399_963;
            let d = (inward + spread * (phi.cos() * u + phi.sin() * v)).normalize();
            let origin = p - d * (2.0 * radius);
            rays += 1;
            let ray = Ray::new(origin, d, 0.0, f32::INFINITY);
            if tree.intersect(&ray).is_none() {
                misses += 1;
                if oracle.intersect(&ray).is_some() {
                    traversal_misses += 1;
                }
            }
        }
    }
    assert_eq!(traversal_misses, 0, "the tree missed hits the oracle found");
    (rays, misses)
}

#[test]
fn watertight_test_never_leaks_on_closed_meshes() {
    for name in ["sphere", "cube"] {
        let scene = scenes::builtin::by_name(name).unwrap();
        let (rays, wald) = leaks(&scene.mesh, Intersector::Wald, 8);
        let (_, watertight) = leaks(&scene.mesh, Intersector::Watertight, 8);
        println!("{name}: {rays} rays at shared edges and vertices: wald {wald} leaks, watertight {watertight}");
        assert_eq!(watertight, 0, "{name}");
    }
}
