//! The 4-, 8- and 16-wide BVHs against the brute-force oracle (`kdtree::oracle::BruteForce`, same
//! triangle test) and against their scalar twins, with both intersectors: on the small
//! built-in scenes (every view, primary rays and random rays from and to surfaces,
//! axis-parallel rays) and on random soups. Every closest hit must pass `BruteForce::check`,
//! and every traversal (4-wide SSE, 8-wide scalar, 8-wide AVX2 where the CPU has it, 16-wide
//! scalar, 16-wide AVX-512 where the CPU has it) must give its scalar twin's answers bit for
//! bit.

use glam::Vec3;
use kdtree::{BruteForce, Hit, Intersector, NoCounters, Ray};
use mbvh::{Avx2, Avx512, BoxTest, LeafBlock, Mbvh, Mbvh8, Mbvh16, Traversal};
use proptest::prelude::*;
use scenes::builtin::shapes::Rng;

fn bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim))
}

/// Checks every ray; returns the number of hits.
fn check<B: LeafBlock, K: BoxTest>(what: &str, tr: Traversal<'_, B, K>, oracle: &BruteForce, rays: &[Ray]) -> usize {
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let got = tr.intersect_counted(ray, &mut NoCounters);
        let occluded = tr.occluded_counted(ray, &mut NoCounters);
        if let Err(e) = oracle.check(ray, got, occluded) {
            panic!("{what}: ray {i} {ray:?}: {e}");
        }
        assert_eq!(bits(got), bits(tr.intersect_scalar(ray, &mut NoCounters)), "{what}: ray {i}: scalar twin");
        assert_eq!(occluded, tr.occluded_scalar(ray, &mut NoCounters), "{what}: ray {i}: scalar twin (any hit)");
        hits += usize::from(got.is_some());
    }
    hits
}

/// Every width and node test, both intersectors; returns the 4-wide Wald hits.
fn both(what: &str, positions: &[Vec3], triangles: &[[u32; 3]], rays: &[Ray]) -> usize {
    let bvh = Mbvh::build(positions, triangles).unwrap();
    bvh.validate(positions, triangles).unwrap();
    let bvh8 = Mbvh8::build(positions, triangles).unwrap();
    bvh8.validate(positions, triangles).unwrap();
    let bvh16 = Mbvh16::build(positions, triangles).unwrap();
    bvh16.validate(positions, triangles).unwrap();
    let tris: Vec<[Vec3; 3]> = triangles.iter().map(|t| t.map(|v| positions[v as usize])).collect();
    let (w, wt) = (BruteForce::new(&tris, Intersector::Wald), BruteForce::new(&tris, Intersector::Watertight));
    let hits = check(&format!("{what} wald"), bvh.wald(), &w, rays);
    check(&format!("{what} watertight"), bvh.watertight(), &wt, rays);
    check(&format!("{what} 8-wide wald"), bvh8.wald(), &w, rays);
    check(&format!("{what} 8-wide watertight"), bvh8.watertight(), &wt, rays);
    check(&format!("{what} 16-wide wald"), bvh16.wald(), &w, rays);
    check(&format!("{what} 16-wide watertight"), bvh16.watertight(), &wt, rays);
    if let Some(avx) = Avx2::detect() {
        check(&format!("{what} 8-wide avx2 wald"), bvh8.wald().with_test(avx), &w, rays);
        check(&format!("{what} 8-wide avx2 watertight"), bvh8.watertight().with_test(avx), &wt, rays);
    }
    if let Some(avx) = Avx512::detect() {
        let hits16 = check(&format!("{what} 16-wide avx512 wald"), bvh16.wald().with_test(avx), &w, rays);
        assert_eq!(hits16, hits, "{what}: hits of the 16-wide AVX-512 and the 4-wide traversals");
        check(&format!("{what} 16-wide avx512 watertight"), bvh16.watertight().with_test(avx), &wt, rays);
    } else {
        eprintln!(
            "note: no AVX-512 on this CPU (or the SIMD cap): the 16-wide tree is traced with the scalar test only"
        );
    }
    hits
}

/// Primary rays of every view, rays between random surface points (starting on surfaces),
/// random rays through the scene box, and axis-parallel ones (zero direction components).
fn rays(scene: &scenes::Scene, seed: u64) -> Vec<Ray> {
    let mut out = Vec::new();
    for view in &scene.views {
        let camera = view.camera(24, 16).unwrap();
        for y in 0..camera.height {
            for x in 0..camera.width {
                let (o, d) = camera.pixel_ray(x, y);
                out.push(Ray::new(o, d, 0.0, f32::INFINITY));
            }
        }
    }
    let mesh = &scene.mesh;
    let lo = mesh.positions.iter().fold(Vec3::INFINITY, |a, &b| a.min(b));
    let hi = mesh.positions.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
    let mut rng = Rng::new(seed);
    let point = |rng: &mut Rng| Vec3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
    let n = mesh.triangles.len();
    for _ in 0..300 {
        let (a, b) = (point(&mut rng), point(&mut rng));
        if a != b {
            out.push(Ray::new(a, b - a, 0.0, f32::INFINITY));
            out.push(Ray::new(a, b - a, 0.0, 1.0));
        }
        let t = mesh.triangle((rng.next_u64() % n as u64) as usize);
        let (u, v) = (rng.range(0.0, 0.5), rng.range(0.0, 0.5));
        let on = t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0]);
        let axis = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z][(rng.next_u64() % 6) as usize];
        out.push(Ray::new(on, axis, 0.0, f32::INFINITY));
        if on != b {
            out.push(Ray::new(on, b - on, 1e-4, 1.0));
        }
    }
    out
}

#[test]
fn builtin_scenes_against_the_oracle_and_the_scalar_twin() {
    for name in ["cube", "sphere", "touching-boxes", "axis-plane-triangle", "triangle", "arena"] {
        let scene = scenes::load_scene(name).unwrap();
        let rays = rays(&scene, 7);
        let hits = both(name, &scene.mesh.positions, &scene.mesh.triangles, &rays);
        assert!(hits > 0, "{name}: no ray hit anything");
    }
}

fn vertex() -> impl Strategy<Value = Vec3> {
    // Shared coordinates (on a coarse grid) make shared vertices, edges and axis planes.
    let c = prop_oneof![(-3i32..4).prop_map(|i| i as f32 * 0.5), -2.0f32..2.0];
    (c.clone(), c.clone(), c).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_soups_against_the_oracle(
        tris in prop::collection::vec((vertex(), vertex(), vertex()), 1..200),
        rays in prop::collection::vec((vertex(), vertex(), -0.5f32..0.5), 1..40),
    ) {
        let positions: Vec<Vec3> = tris.iter().flat_map(|&(a, b, c)| [a, b, c]).collect();
        let triangles: Vec<[u32; 3]> = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let rays: Vec<Ray> = rays
            .iter()
            .filter(|(o, t, _)| o != t)
            .flat_map(|&(o, t, tmin)| [Ray::new(o * 1.5, t - o * 1.5, tmin, f32::INFINITY), Ray::new(o, (t - o).signum() * Vec3::X, 0.0, 10.0)])
            .collect();
        both("soup", &positions, &triangles, &rays);
    }
}

/// Spatial splits (Stich et al. 2009): long crossing slivers, whose boxes overlap everywhere,
/// are cut into parts in several leaves. At scales from 1e-30 to 1e18 and 1e5 and 1e6 from the
/// origin, every part's clipped box must keep the triangle findable: the traversals against
/// the oracle on rays along the slivers, across them and from points on them.
#[test]
fn spatial_splits_keep_every_part_of_a_triangle() {
    for (scale, offset) in [(1.0f32, 0.0f32), (1e-30, 0.0), (1e18, 0.0), (1.0, 1e5), (10.0, -1e6)] {
        let mut rng = Rng::new(29);
        let mut positions = Vec::new();
        for i in 0..240 {
            // A sixth are long slivers across the whole box (their boxes fill it), the rest small.
            let a = Vec3::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0), rng.range(-4.0, 4.0));
            let c = if i % 6 == 0 { -a } else { a + Vec3::new(rng.range(-0.3, 0.3), rng.range(-0.3, 0.3), 0.3) };
            let w = Vec3::new(rng.range(-0.05, 0.05), 0.05, rng.range(-0.05, 0.05));
            positions.extend([a, c, c + w].map(|p| p * scale + Vec3::splat(offset)));
        }
        let triangles: Vec<[u32; 3]> = (0..240).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let refs = Mbvh::build(&positions, &triangles).unwrap().stats().leaf_triangles;
        assert!(refs > triangles.len() * 11 / 10, "scale {scale}, offset {offset}: only {refs} references");
        let mut rays = Vec::new();
        for (i, t) in triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            for s in [0.0f32, 0.01, 0.25, 0.5, 0.75, 0.99, 1.0] {
                let on = a + (b - a) * s + (c - b) * (0.5 * s);
                let from = on + Vec3::new(0.3, -0.7, 1.1 + (i % 5) as f32) * scale;
                rays.push(Ray::new(from, on - from, 0.0, f32::INFINITY));
                rays.push(Ray::new(on, (b - a) * (1.0 - 2.0 * (i % 2) as f32), 0.0, f32::INFINITY));
                rays.push(Ray::new(on, Vec3::Z, 0.0, f32::INFINITY));
            }
        }
        let hits = both(&format!("slivers at scale {scale}, offset {offset}"), &positions, &triangles, &rays);
        assert!(hits > rays.len() / 4, "scale {scale}, offset {offset}: {hits} hits of {}", rays.len());
    }
}
