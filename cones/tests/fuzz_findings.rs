//! Regression tests for the `traversal` cargo-fuzz target's findings that involve the cone
//! methods (the others are in `kdtree/tests/fuzz_findings.rs`): each is the finding's input,
//! decoded with `cargo fuzz fmt`, and the property the target checks.

use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Intersector, KdTree, NoCounters, Ray};
use packets::{OmniPacket, PacketHit, RayPacket, TileTracer};

/// A pyramid frustum kernel's entry point (`packets`).
type PyramidKernel = fn(&mut TileTracer, &KdTree, &mut NoCounters);

/// A cone kernel's entry point.
type ConeKernel = fn(&KdTree, &mut TileTracer, &mut NoCounters);

/// A ray along -x whose interval is the single point `t = 0` (its origin, x = 1.5e-39),
/// beside triangle 1, whose x range ends at 1.076e-42. The single-ray kernel's plane distance
/// to the root split x = 1.076e-42 is 8.9e-78, which underflows to 0, so it visits both
/// children and finds Wald's rounding hit on triangle 1 at `t = -0.0`. The cone measures the
/// same plane along its axis, 1.5e-39 away, and culls the child exactly: no hit. Both answers
/// are right (the triangle is unreachable in exact arithmetic); the target required the
/// single ray's, and now accepts either (`BruteForce::equivalent_hits`). (Since the cone's
/// ends cover the underflow of the parameters, next test, its far end reaches 2.4e-7 here
/// and it visits the child too, reporting the artefact like the single ray.)
#[test]
fn cone_culls_exactly_where_the_single_ray_underflows_into_an_artefact() {
    let tris = [
        [
            Vec3::new(-7.729682e-37, -7.729682e-37, 6.938894e-18),
            Vec3::new(8.843688e-18, 8.843688e-18, 8.843688e-18),
            Vec3::new(1.2605e-41, 9.723689e-35, -1.0909784e-18),
        ],
        [
            Vec3::new(-1.0952567e-18, 5.167039e-29, 1.37753e-40),
            Vec3::new(1.076e-42, 3.345292e-30, -7.729725e-37),
            Vec3::new(-5.09907e-37, 6.762284e-23, 1.0858565e-19),
        ],
    ];
    let ray =
        Ray::try_new(Vec3::new(1.516545e-39, 3.22545e-40, 1.3591833e-38), Vec3::new(-1.7023464e38, 0.0, 0.0), 0.0, 0.0)
            .unwrap();
    let tree =
        KdTree::build_soup(&tris, &BuildConfig { intersector: Intersector::Wald, ..BuildConfig::default() }).unwrap();
    let oracle = BruteForce::for_tree(&tree);
    let single = tree.intersect(&ray);
    assert_eq!(single.map(|h| (h.t, h.prim)), Some((-0.0, 1)), "the single ray reports the artefact");
    assert!(oracle.unreachable(&ray, 1));
    oracle.check(&ray, single, tree.occluded(&ray)).unwrap();

    for (method, any_hit, hits) in cone_answers(&tree, &[ray]) {
        let got = hits.get(0);
        if any_hit {
            let found = hits.found.bitmask() & 1 != 0;
            assert!(oracle.equivalent_occlusion(&ray, found, tree.occluded(&ray)), "{method} any hit");
        } else {
            assert!(oracle.equivalent_hits(&ray, got, single), "{method}: {got:?}, single ray {single:?}");
        }
    }
    // The pyramid methods agree as well.
    let mut tracer = TileTracer::new(4).unwrap();
    tracer.load_packets(&[OmniPacket::new(RayPacket::new(&[ray])).unwrap()]).unwrap();
    let pyramids: [(&str, PyramidKernel); 2] = [("frustum", TileTracer::trace_frustum), ("mft", TileTracer::trace_mft)];
    for (method, trace) in pyramids {
        trace(&mut tracer, &tree, &mut NoCounters);
        let got = tracer.packet_hits()[0].get(0);
        assert!(oracle.equivalent_hits(&ray, got, single), "{method}: {got:?}, single ray {single:?}");
    }
}

/// The answers of both cone methods, closest hit and any hit, for `rays` (one packet with a
/// shared origin): `(method, any_hit, the packet's hits)`.
fn cone_answers(tree: &KdTree, rays: &[Ray]) -> Vec<(&'static str, bool, PacketHit)> {
    let mut tracer = TileTracer::new(4).unwrap();
    tracer.load_packets(&[OmniPacket::new(RayPacket::new(rays)).unwrap()]).unwrap();
    let mut answers = Vec::new();
    for any_hit in [false, true] {
        tracer.set_any_hit(any_hit);
        let kernels: [(&str, ConeKernel); 2] =
            [("cone", cones::traverse::trace_cone), ("mft-cone", cones::traverse::trace_mft_cone)];
        for (method, trace) in kernels {
            trace(tree, &mut tracer, &mut NoCounters);
            answers.push((method, any_hit, tracer.packet_hits()[0]));
        }
    }
    answers
}

/// A ray from y = 2.9e-14 with `d.y = -1.66e32` leaves the root box (y >= -7.7e-37) at
/// t = 1.75e-46, computed as 0, and crosses the root split y = 1.16e-38 just before, where
/// the watertight test finds triangle 1 (t = 0.0 after rounding). The single ray and the
/// pyramid compare parameters rounded alike and visit that child; the cone scaled the
/// pyramid's far end, 0, by `|d|` to a distance of 0, while its own plane distance along the
/// axis is 2.9e-14, and skipped the child. `cone_bound` now moves the ends out by the
/// underflow of the parameters (`packets::bound::T_UNDERFLOW`) before scaling them.
#[test]
fn cone_far_end_covers_an_exit_parameter_that_underflowed() {
    let tris = [
        [
            Vec3::new(3.8500897e-37, 3.8500897e-37, 2.2500777e-38),
            Vec3::new(3.053889e-39, 23461888.0, 12.062572),
            Vec3::new(4e-45, 0.0, 5.16985e-29),
        ],
        [
            Vec3::new(0.0, 1e-45, 76.6323),
            Vec3::new(-0.03753398, -7.740593e-37, -3.7751864e-37),
            Vec3::new(2.5281306e-29, 1.1571273e-38, 3.581226e-39),
        ],
    ];
    let origin = Vec3::new(3.8500897e-37, 2.9090455e-14, 3.8500897e-37);
    // The fuzz input's second ray: a denormal direction that is flushed to zero.
    let rays = [
        Ray::try_new(origin, Vec3::new(3.8500897e-37, -1.6607714e32, 6.5390944e-19), 0.0, 8.018382).unwrap(),
        Ray::try_new(origin, Vec3::new(3.4443e-41, 0.0, 0.0), 0.0, 0.0).unwrap(),
    ];
    let tree =
        KdTree::build_soup(&tris, &BuildConfig { intersector: Intersector::Watertight, ..BuildConfig::default() })
            .unwrap();
    let oracle = BruteForce::for_tree(&tree);
    let single = tree.intersect(&rays[0]);
    assert_eq!(single.map(|h| (h.t, h.prim)), Some((0.0, 1)));
    assert!(!oracle.unreachable(&rays[0], 1), "a real hit");
    for (method, any_hit, hits) in cone_answers(&tree, &rays) {
        for (lane, ray) in rays.iter().enumerate() {
            let (got, want) = (hits.get(lane), tree.intersect(ray));
            if any_hit {
                let found = hits.found.bitmask() >> lane & 1 != 0;
                assert_eq!(found, tree.occluded(ray), "{method} any hit, lane {lane}");
            } else {
                assert!(oracle.equivalent_hits(ray, got, want), "{method} lane {lane}: {got:?}, single {want:?}");
            }
        }
    }
}
