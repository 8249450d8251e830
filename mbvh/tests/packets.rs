//! The 16-ray packets through the 8-wide tree (`mbvh::packet`) against single rays through the
//! same tree, both intersectors: every lane's closest distance equal bit for bit, the same
//! triangle (with the same `u`, `v`) but where another triangle is hit at exactly that
//! distance (a tie the brute-force oracle accepts), the same any-hit answer; the AVX-512
//! and the AVX2 packets (where the CPU runs them) equal to the portable twin bit for bit,
//! triangles included. Streams of every length (partial packets), hybrid thresholds 0 (packets to the
//! leaves), the default and 16 (single rays from the root); built-in scenes with rays from
//! surfaces and axis-parallel rays (zero direction components), random soups with degenerate
//! triangles, rays that miss everything, rays that cannot hit (non-finite), and no NaN.

use glam::Vec3;
use kdtree::{BruteForce, Counts, Hit, Intersector, NoCounters, Ray};
use mbvh::{
    Avx2, Avx512, BoxTest, HYBRID_THRESHOLD, HYBRID_THRESHOLD_ANY, HYBRID_THRESHOLD_ANY_AVX2, LeafBlock, Mbvh8, Node8,
    PacketLanes, Portable16, Traversal,
};
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;
use scenes::builtin::shapes::Rng;

fn bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim))
}

/// The packets' answers for `rays` in the lanes `lanes` at `threshold`, every stream split at
/// `split` (so packets of every fill level are traced).
fn packets<B: LeafBlock, K: BoxTest<Node = Node8>, L: PacketLanes>(
    tr: Traversal<'_, B, K>,
    lanes: L,
    threshold: u32,
    rays: &[Ray],
    split: usize,
) -> (Vec<Option<Hit>>, Vec<bool>) {
    // Wald leaves over the 16 lanes from one lane on at even splits, lane by lane at odd ones.
    let leaf_lanes = if split.is_multiple_of(2) { 1 } else { 17 };
    let p = tr.packets(lanes).with_threshold(threshold).with_leaf_lanes(leaf_lanes);
    assert_eq!(p.thresholds(), (threshold, threshold));
    let (mut hits, mut blocked) = (vec![None; rays.len()], vec![false; rays.len()]);
    let split = split.min(rays.len());
    let (ra, rb) = rays.split_at(split);
    let (ha, hb) = hits.split_at_mut(split);
    p.intersect_stream(ra, ha, &mut NoCounters);
    p.intersect_stream(rb, hb, &mut NoCounters);
    let (ba, bb) = blocked.split_at_mut(split);
    p.occluded_stream(ra, ba, &mut NoCounters);
    p.occluded_stream(rb, bb, &mut NoCounters);
    (hits, blocked)
}

/// Every lane against the single ray; returns the packet answers of the portable lanes.
fn check<B: LeafBlock, K: BoxTest<Node = Node8>>(
    what: &str,
    tr: Traversal<'_, B, K>,
    oracle: &BruteForce,
    rays: &[Ray],
) -> usize {
    let single: Vec<Option<Hit>> = rays.iter().map(|r| tr.intersect_counted(r, &mut NoCounters)).collect();
    let single_any: Vec<bool> = rays.iter().map(|r| tr.occluded_counted(r, &mut NoCounters)).collect();
    let mut hits = 0;
    for threshold in [0, HYBRID_THRESHOLD_ANY, HYBRID_THRESHOLD, 16] {
        for split in [0, 1, 7, 16, 21, 32] {
            let (got, blocked) = packets(tr, Portable16, threshold, rays, split);
            for (i, ray) in rays.iter().enumerate() {
                let at = || format!("{what}: threshold {threshold} split {split} ray {i} {ray:?}");
                assert_eq!(blocked[i], single_any[i], "{}: any hit", at());
                match (got[i], single[i]) {
                    (Some(g), Some(s)) => {
                        assert!(!g.t.is_nan() && !g.u.is_nan() && !g.v.is_nan(), "{}: NaN", at());
                        if g.prim == s.prim {
                            assert_eq!(bits(Some(g)), bits(Some(s)), "{}", at());
                        } else if g.t != s.t {
                            // Another triangle only at the same distance (a tie: at t = 0
                            // one triangle may give -0.0 and the other +0.0).
                            panic!("{}: another triangle at another distance: {g:?}, single {s:?}", at());
                        } else if let Err(e) = oracle.check(ray, Some(g), blocked[i]) {
                            panic!("{}: another triangle, not a tie: {e}", at());
                        }
                    }
                    (g, s) => assert_eq!(bits(g), bits(s), "{}", at()),
                }
            }
            let portable: Vec<_> = got.iter().map(|&h| bits(h)).collect();
            let same_as_portable = |lanes: &str, (h, b): (Vec<Option<Hit>>, Vec<bool>)| {
                assert_eq!(b, blocked, "{what}: threshold {threshold} split {split}: {lanes} any hit");
                let h: Vec<_> = h.into_iter().map(bits).collect();
                assert_eq!(
                    h, portable,
                    "{what}: threshold {threshold} split {split}: {lanes} against the portable lanes"
                );
            };
            if let Some(avx) = Avx512::detect() {
                same_as_portable("AVX-512", packets(tr, avx, threshold, rays, split));
            }
            if let Some(avx) = Avx2::detect() {
                same_as_portable("AVX2", packets(tr, avx, threshold, rays, split));
            }
            hits = got.iter().filter(|h| h.is_some()).count();
        }
    }
    hits
}

/// Both intersectors, the scalar and (where present) AVX2 single-ray node tests.
fn both(what: &str, positions: &[Vec3], triangles: &[[u32; 3]], rays: &[Ray]) -> usize {
    let bvh = Mbvh8::build(positions, triangles).unwrap();
    let tris: Vec<[Vec3; 3]> = triangles.iter().map(|t| t.map(|v| positions[v as usize])).collect();
    let (w, wt) = (BruteForce::new(&tris, Intersector::Wald), BruteForce::new(&tris, Intersector::Watertight));
    let hits = check(&format!("{what} wald"), bvh.wald(), &w, rays);
    check(&format!("{what} watertight"), bvh.watertight(), &wt, rays);
    if let Some(avx) = Avx2::detect() {
        check(&format!("{what} avx2 wald"), bvh.wald().with_test(avx), &w, rays);
        check(&format!("{what} avx2 watertight"), bvh.watertight().with_test(avx), &wt, rays);
    }
    if Avx512::detect().is_none() {
        eprintln!("note: no AVX-512 on this CPU (or the SIMD cap): the AVX2 and portable packets only");
    }
    if Avx2::detect().is_none() {
        eprintln!("note: no AVX2 on this CPU (or the SIMD cap): the portable packets only");
    }
    hits
}

/// Primary rays of every view, rays between random points and from surface points (on
/// surfaces, axis-parallel: zero direction components), AO-like short rays from surfaces,
/// rays away from the scene and rays that cannot hit.
fn rays(scene: &scenes::Scene, seed: u64) -> Vec<Ray> {
    let mut out = Vec::new();
    for view in &scene.views {
        let camera = view.camera(12, 8).unwrap();
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
    for _ in 0..150 {
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
        out.push(Ray::new(on, Vec3::new(0.0, -0.0, 1.0) * axis.x + axis, 1e-4, 0.1 * (hi - lo).length()));
        if on != b {
            out.push(Ray::new(on, b - on, 1e-4, 1.0));
        }
    }
    // Away from everything, and untraceable.
    out.push(Ray::new(hi + Vec3::ONE, Vec3::ONE, 0.0, f32::INFINITY));
    out.push(Ray::new(Vec3::splat(f32::NAN), Vec3::X, 0.0, f32::INFINITY));
    out.push(Ray::new(lo, Vec3::X, f32::NAN, f32::INFINITY));
    out.push(Ray::new(lo - Vec3::ONE, Vec3::ONE, 0.0, f32::NAN));
    out
}

#[test]
fn builtin_scenes_packets_equal_single_rays() {
    for name in ["cube", "sphere", "touching-boxes", "axis-plane-triangle", "triangle", "arena"] {
        let scene = scenes::load_scene(name).unwrap();
        let rays = rays(&scene, 11);
        let hits = both(name, &scene.mesh.positions, &scene.mesh.triangles, &rays);
        assert!(hits > 0, "{name}: no ray hit anything");
    }
}

/// Each lane type starts from its own any-hit threshold (AVX2's two halves switch to single
/// rays from more lanes on); the closest-hit threshold is shared.
#[test]
fn lane_types_take_their_default_thresholds() {
    let scene = scenes::load_scene("cube").unwrap();
    let bvh = Mbvh8::build(&scene.mesh.positions, &scene.mesh.triangles).unwrap();
    assert_eq!(bvh.wald().packets(Portable16).thresholds(), (HYBRID_THRESHOLD, HYBRID_THRESHOLD_ANY));
    if let Some(avx) = Avx512::detect() {
        assert_eq!(bvh.wald().packets(avx).thresholds(), (HYBRID_THRESHOLD, HYBRID_THRESHOLD_ANY));
    }
    if let Some(avx) = Avx2::detect() {
        assert_eq!(bvh.wald().packets(avx).thresholds(), (HYBRID_THRESHOLD, HYBRID_THRESHOLD_ANY_AVX2));
    }
}

#[test]
fn all_miss_and_empty_packets() {
    let scene = scenes::load_scene("cube").unwrap();
    let bvh = Mbvh8::build(&scene.mesh.positions, &scene.mesh.triangles).unwrap();
    // Sixteen rays away from the cube, then a stream of none.
    let rays: Vec<Ray> = (0..16)
        .map(|i| Ray::new(Vec3::splat(10.0 + i as f32), Vec3::new(1.0, 0.5, i as f32), 0.0, f32::INFINITY))
        .collect();
    for threshold in [0, 16] {
        let (h, b) = packets(bvh.wald(), Portable16, threshold, &rays, 16);
        assert!(h.iter().all(Option::is_none) && b.iter().all(|&b| !b));
        if let Some(avx) = Avx512::detect() {
            let (h, b) = packets(bvh.watertight(), avx, threshold, &rays, 16);
            assert!(h.iter().all(Option::is_none) && b.iter().all(|&b| !b));
        }
        if let Some(avx) = Avx2::detect() {
            let (h, b) = packets(bvh.watertight(), avx, threshold, &rays, 16);
            assert!(h.iter().all(Option::is_none) && b.iter().all(|&b| !b));
        }
    }
    let p = bvh.wald().packets(Portable16);
    p.intersect_stream(&[], &mut [], &mut NoCounters);
    p.occluded_stream(&[], &mut [], &mut NoCounters);
    // An empty tree.
    let empty = Mbvh8::build(&[], &[]).unwrap();
    let (h, b) = packets(empty.wald(), Portable16, 0, &rays, 3);
    assert!(h.iter().all(Option::is_none) && b.iter().all(|&b| !b));
}

#[test]
fn packets_count_their_steps() {
    let scene = scenes::load_scene("arena").unwrap();
    let bvh = Mbvh8::build(&scene.mesh.positions, &scene.mesh.triangles).unwrap();
    let rays = rays(&scene, 3);
    let p = bvh.wald().packets(Portable16).with_threshold(0);
    let mut counts = Counts::default();
    let mut hits = vec![None; rays.len()];
    p.intersect_stream(&rays, &mut hits, &mut counts);
    assert!(counts.nodes > 0 && counts.leaves > 0 && counts.tests > 0, "{counts:?}");
    // Below the threshold every lane is a single ray: the single rays' counts.
    let mut packet = Counts::default();
    bvh.wald().packets(Portable16).with_threshold(16).intersect_stream(&rays, &mut hits, &mut packet);
    let mut single = Counts::default();
    for ray in &rays {
        bvh.wald().intersect_counted(ray, &mut single);
    }
    assert_eq!(packet, single);
}

fn vertex() -> impl Strategy<Value = Vec3> {
    // Shared coordinates (on a coarse grid) make shared vertices, edges, axis planes and
    // degenerate triangles.
    let c = prop_oneof![(-3i32..4).prop_map(|i| i as f32 * 0.5), -2.0f32..2.0];
    (c.clone(), c.clone(), c).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    // The saved failures (`tests/packets.proptest-regressions`, read from the package root,
    // where `cargo test` runs) are replayed first: one is a tie at t = 0 between triangles
    // whose distances are -0.0 and +0.0.
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct("tests/packets.proptest-regressions"))),
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_soups_packets_equal_single_rays(
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
