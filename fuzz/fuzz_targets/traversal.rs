//! Arbitrary rays (zero, NaN and infinite directions included) -> every traversal method over
//! a tree of an arbitrary finite soup: never panics; rays accepted by `Ray::try_new` agree
//! with the brute-force oracle (`BruteForce::check`) as single rays, and every method of
//! `trace::Registry::ours()` (streams of mixed origins and of one origin, tiles 4 and 16)
//! gives the single-ray hits (or a tie at the same distance, or a difference by a rounding
//! artefact on a triangle the ray cannot reach: `BruteForce::equivalent_hits`), closest and
//! any hit, and the shadow kernels (a shadow frustum of all the rays, same-sign any-hit
//! packets, the tile kernels' any-hit mode at 4, 8 and 16 lanes) give the single rays'
//! occlusion; rejected rays still traverse without a panic.
#![no_main]

use arbitrary::Arbitrary;
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Hit, Intersector, KdTree, NoCounters, Ray, WaldTest, WatertightTest};
use libfuzzer_sys::fuzz_target;
use packets::simd::{SimdF32, SimdMask};
use packets::triangle4::PacketTest;
use packets::{LaneFrusta, LaneWidth, OmniPacket, RayPacket, ShadowFrustum, TileTracer, Width};
use trace::{Options, Registry, Structures};

#[derive(Arbitrary, Debug)]
struct Input {
    watertight: bool,
    soup: Vec<[[f32; 3]; 3]>,
    rays: Vec<[f32; 8]>,
    /// Which accepted ray's origin the shared-origin packets use.
    eye: u8,
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
    let mut accepted = Vec::new();
    for r in input.rays.iter().take(64) {
        let (o, d) = (Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5]));
        match Ray::try_new(o, d, r[6], r[7]) {
            Ok(ray) => {
                oracle.check(&ray, tree.intersect(&ray), tree.occluded(&ray)).expect("agrees with the oracle");
                accepted.push(ray);
            }
            Err(_) => {
                let ray = Ray::new(o, d, r[6], r[7]);
                let _ = (tree.intersect(&ray), tree.occluded(&ray));
            }
        }
    }
    if accepted.is_empty() {
        return;
    }
    // Every method of the registry on the accepted rays (mixed origins: same-sign packets)
    // and on `shared`, every accepted direction from one accepted origin (omni packets,
    // frusta, cones), closest and any hit, against single rays.
    let eye = accepted[input.eye as usize % accepted.len()];
    let shared: Vec<Ray> =
        accepted.iter().filter_map(|r| Ray::try_new(eye.origin, r.dir, r.t_min.max(0.0), r.t_max).ok()).collect();
    let registry = Registry::ours();
    let mut structures = Structures::new(&tree);
    // The registry's other structures (the 4-wide BVH) over the same soup, same numbering.
    let scene = conformance::soup_scene("fuzz", &tris);
    registry.build_structures(&scene, &mut structures).expect("a finite soup builds");
    for rays in [&accepted, &shared] {
        let want: Vec<Option<Hit>> = rays.iter().map(|r| tree.intersect(r)).collect();
        let want_any: Vec<bool> = rays.iter().map(|r| tree.occluded(r)).collect();
        for name in registry.names(&[4, 16]) {
            let selected = registry.select(&name, Options::default()).expect("a registered name");
            let method = registry.bind(&selected, &structures).expect("binds on our tree");
            let (mut got, mut any) = (vec![None; rays.len()], vec![false; rays.len()]);
            method.tracer.stream(rays, &mut got);
            method.tracer.stream_occluded(rays, &mut any);
            for (i, ray) in rays.iter().enumerate() {
                assert!(
                    oracle.equivalent_hits(ray, got[i], want[i]),
                    "{name} ray {i}: {:?}, single ray {:?}",
                    got[i],
                    want[i]
                );
                assert!(
                    oracle.equivalent_occlusion(ray, any[i], want_any[i]),
                    "{name} any-hit ray {i}: {}, single ray {}",
                    any[i],
                    want_any[i]
                );
            }
        }
    }

    // The shadow kernels on the accepted rays (segments from mixed origins, finite or not,
    // the shadow rays of `trace::shadow_frusta`): Benthin & Wald's shadow frustum over all of
    // them, and 2x2 same-sign packets, each ray against its single ray's occlusion.
    let mut frustum = ShadowFrustum::new();
    for ray in &accepted {
        frustum.push(*ray);
    }
    frustum.trace(&tree, &mut NoCounters);
    for (i, (ray, &got)) in accepted.iter().zip(frustum.blocked()).enumerate() {
        let want = tree.occluded(ray);
        assert!(oracle.equivalent_occlusion(ray, got, want), "shadow frustum ray {i}: {got}, single ray {want}");
    }
    // Benthin & Wald's multi-frusta in SIMD lanes (`packets::lane_frusta`), at every width:
    // each run of up to 16 rays' segments as pushed (mostly no shared end: ray by ray), and
    // the same ends from the run's first origin (a shared apex: traced in lanes).
    let mut frusta: Vec<(Vec<Vec3>, Vec<Vec3>)> = Vec::new();
    for run in accepted.chunks(16) {
        let ends: Vec<Vec3> = run.iter().map(|r| r.origin + r.dir).collect();
        frusta.push((run.iter().map(|r| r.origin).collect(), ends.clone()));
        frusta.push((vec![run[0].origin; run.len()], ends));
    }
    for width in [LaneWidth::Scalar, LaneWidth::Four, LaneWidth::Eight, LaneWidth::Sixteen] {
        let mut lanes = LaneFrusta::new();
        for (starts, ends) in &frusta {
            lanes.push(starts, ends);
        }
        lanes.trace(&tree, width, &mut NoCounters);
        for (f, ((starts, ends), &mask)) in frusta.iter().zip(lanes.blocked()).enumerate() {
            for (k, (&a, &b)) in starts.iter().zip(ends).enumerate() {
                let ray = Ray::segment(a, b);
                let (got, want) = (mask >> k & 1 != 0, tree.occluded(&ray));
                assert!(
                    oracle.equivalent_occlusion(&ray, got, want),
                    "lane frustum {f} ray {k} ({width:?}): {got}, single ray {want}"
                );
            }
        }
    }
    for (c, four) in accepted.chunks(4).enumerate() {
        let found = packets::samesign::occluded(&tree, &RayPacket::new(four), &mut NoCounters).found.bitmask();
        for (lane, ray) in four.iter().enumerate() {
            let (got, want) = (found >> lane & 1 != 0, tree.occluded(ray));
            assert!(oracle.equivalent_occlusion(ray, got, want), "shadow packet {c} lane {lane}: {got}, single {want}");
        }
        // The same rays' ends, as the shadow kernels keep them: `RayPacket::segments` must be
        // the packet of `Ray::segment(start, end)` bit for bit.
        let starts: Vec<Vec3> = four.iter().map(|r| r.origin).collect();
        let ends: Vec<Vec3> = four.iter().map(|r| r.origin + r.dir).collect();
        let rays: Vec<Ray> = starts.iter().zip(&ends).map(|(&s, &e)| Ray::segment(s, e)).collect();
        let bits = |p: &RayPacket| {
            let v = |x: &[glam::Vec4]| x.iter().flat_map(|c| c.to_array()).map(f32::to_bits).collect::<Vec<_>>();
            (v(&p.o), v(&p.d), v(&p.inv), v(&[p.t_min, p.t_max]), p.valid.bitmask())
        };
        assert_eq!(bits(&RayPacket::segments(&starts, &ends)), bits(&RayPacket::new(&rays)), "segments {c}");
    }

    // The tile tracer's any-hit mode (shadow rays), which no registered stream uses: the
    // frustum, MFT and cones find a hit exactly where the single ray's occlusion query does.
    if shared.is_empty() {
        return;
    }
    // At every packet width: 4 lanes, 8 (AVX2), 16 in two AVX2 registers and 16 in one
    // AVX-512 register where the CPU has them, else their portable twins.
    for width in Width::ALL {
        packets::at_width!(width, V => any_hit_tiles::<V>(&tree, &oracle, &shared));
    }
});

/// The tile kernels in any-hit mode over packets of `V::LANES` rays of `shared` (one
/// origin): each lane's answer is the single ray's occlusion.
#[inline(always)]
fn any_hit_tiles<V: SimdF32>(tree: &KdTree, oracle: &BruteForce, shared: &[Ray])
where
    kdtree::triangle::WaldTriangle: PacketTest<V>,
    kdtree::triangle::WatertightTriangle: PacketTest<V>,
{
    let packets: Vec<OmniPacket<V>> = shared
        .chunks(V::LANES)
        .map(|rays| OmniPacket::new(RayPacket::from_rays(rays)).expect("one origin, t_min >= 0"))
        .collect();
    let mut tracer = TileTracer::<V>::with_size(TileTracer::<V>::SIZE_MULTIPLE).expect("a valid tile size");
    tracer.load_packets(&packets).expect("one origin");
    tracer.set_any_hit(true);
    for method in 0..4 {
        match method {
            0 => tracer.trace_frustum(tree, &mut NoCounters),
            1 => tracer.trace_mft(tree, &mut NoCounters),
            2 if tree.intersector() == Intersector::Wald => {
                cones::traverse::trace_cone_wide_with::<WaldTest, V, _>(tree, &mut tracer, &mut NoCounters)
            }
            2 => cones::traverse::trace_cone_wide_with::<WatertightTest, V, _>(tree, &mut tracer, &mut NoCounters),
            _ if tree.intersector() == Intersector::Wald => {
                cones::traverse::trace_mft_cone_wide_with::<WaldTest, V, _>(tree, &mut tracer, &mut NoCounters)
            }
            _ => cones::traverse::trace_mft_cone_wide_with::<WatertightTest, V, _>(tree, &mut tracer, &mut NoCounters),
        }
        for (hits, rays) in tracer.packet_hits().iter().zip(shared.chunks(V::LANES)) {
            for (lane, ray) in rays.iter().enumerate() {
                let found = hits.found.bitmask() >> lane & 1 != 0;
                let want = tree.occluded(ray);
                assert!(
                    oracle.equivalent_occlusion(ray, found, want),
                    "any-hit method {method} at {} lanes, lane {lane}: {found}, single ray {want}",
                    V::LANES
                );
            }
        }
    }
}
