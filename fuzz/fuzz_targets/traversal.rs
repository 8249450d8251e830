//! Arbitrary rays (zero, NaN and infinite directions included) -> every traversal method over
//! a tree of an arbitrary finite soup: never panics; rays accepted by `Ray::try_new` agree
//! with the brute-force oracle (`BruteForce::check`) as single rays, and the packet methods
//! (omni-directional, same-sign, frustum and MFT) and the cone methods (one cone, MFT cones)
//! give the single-ray hits (or a tie at the same distance, or a difference by a rounding
//! artefact on a triangle the ray cannot reach: `BruteForce::equivalent_hits`), closest and
//! any hit; rejected rays still traverse without a panic.
#![no_main]

use arbitrary::Arbitrary;
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Hit, Intersector, KdTree, NoCounters, Ray};
use libfuzzer_sys::fuzz_target;
use cones::ConeMethod;
use packets::{OmniPacket, RayPacket, TileMethod, TileTracer, omni, samesign};

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
    let single: Vec<Option<Hit>> = accepted.iter().map(|r| tree.intersect(r)).collect();

    // Same-sign packets take any rays.
    for (rays, want) in accepted.chunks(4).zip(single.chunks(4)) {
        let hits = samesign::intersect(&tree, &RayPacket::new(rays), &mut NoCounters);
        for (lane, want) in want.iter().enumerate() {
            let got = hits.get(lane);
            assert!(oracle.equivalent_hits(&rays[lane], got, *want), "same-sign lane {lane}: {got:?}, single ray {want:?}");
        }
    }

    // The shared-origin methods: every accepted ray's direction from one accepted origin.
    let eye = accepted[input.eye as usize % accepted.len()];
    let shared: Vec<Ray> = accepted
        .iter()
        .filter_map(|r| Ray::try_new(eye.origin, r.dir, r.t_min.max(0.0), r.t_max).ok())
        .collect();
    let want: Vec<Option<Hit>> = shared.iter().map(|r| tree.intersect(r)).collect();
    let packets: Vec<OmniPacket> =
        shared.chunks(4).map(|rays| OmniPacket::new(RayPacket::new(rays)).expect("one origin, t_min >= 0")).collect();
    for ((packet, rays), want) in packets.iter().zip(shared.chunks(4)).zip(want.chunks(4)) {
        let hits = omni::intersect(&tree, packet, &mut NoCounters);
        let any = omni::occluded(&tree, packet, &mut NoCounters);
        for (lane, want) in want.iter().enumerate() {
            let got = hits.get(lane);
            assert!(oracle.equivalent_hits(&rays[lane], got, *want), "omni lane {lane}: {got:?}, single ray {want:?}");
            let (found, want) = (any.found.bitmask() >> lane & 1 != 0, tree.occluded(&rays[lane]));
            assert!(oracle.equivalent_occlusion(&rays[lane], found, want), "omni any-hit lane {lane}: {found}, single ray {want}");
        }
    }
    let mut tracer = TileTracer::new(4).expect("4 is a valid tile size");
    tracer.load_packets(&packets).expect("one origin");
    for method in [TileMethod::Packet, TileMethod::SameSign, TileMethod::Frustum, TileMethod::Mft] {
        tracer.trace(&tree, method, &mut NoCounters);
        for ((hits, want), rays) in tracer.packet_hits().iter().zip(want.chunks(4)).zip(shared.chunks(4)) {
            for (lane, want) in want.iter().enumerate() {
                let got = hits.get(lane);
                assert!(oracle.equivalent_hits(&rays[lane], got, *want), "{method:?} lane {lane}: {got:?}, single ray {want:?}");
            }
        }
    }
    for method in [ConeMethod::Cone, ConeMethod::MftCone] {
        cones::traverse::trace(&tree, &mut tracer, method, &mut NoCounters);
        for ((hits, want), rays) in tracer.packet_hits().iter().zip(want.chunks(4)).zip(shared.chunks(4)) {
            for (lane, want) in want.iter().enumerate() {
                let got = hits.get(lane);
                assert!(oracle.equivalent_hits(&rays[lane], got, *want), "{method:?} lane {lane}: {got:?}, single ray {want:?}");
            }
        }
    }
    // Any-hit mode (shadow rays): the frustum, MFT and cones find a hit exactly where the
    // single ray's occlusion query does (up to artefacts on unreachable triangles).
    tracer.set_any_hit(true);
    for method in 0..4 {
        match method {
            0 => tracer.trace(&tree, TileMethod::Frustum, &mut NoCounters),
            1 => tracer.trace(&tree, TileMethod::Mft, &mut NoCounters),
            2 => cones::traverse::trace(&tree, &mut tracer, ConeMethod::Cone, &mut NoCounters),
            _ => cones::traverse::trace(&tree, &mut tracer, ConeMethod::MftCone, &mut NoCounters),
        }
        for (hits, rays) in tracer.packet_hits().iter().zip(shared.chunks(4)) {
            for (lane, ray) in rays.iter().enumerate() {
                let found = hits.found.bitmask() >> lane & 1 != 0;
                let want = tree.occluded(ray);
                assert!(oracle.equivalent_occlusion(ray, found, want), "any-hit method {method} lane {lane}: {found}, single ray {want}");
            }
        }
    }
});
