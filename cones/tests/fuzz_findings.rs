//! Regression tests for the `traversal` cargo-fuzz target's findings that involve the cone
//! methods (the others are in `kdtree/tests/fuzz_findings.rs`): each is the finding's input,
//! decoded with `cargo fuzz fmt`, and the property the target checks.

use cones::ConeMethod;
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Intersector, KdTree, NoCounters, Ray};
use packets::{OmniPacket, RayPacket, TileMethod, TileTracer};

/// A ray along -x whose interval is the single point `t = 0` (its origin, x = 1.5e-39),
/// beside triangle 1, whose x range ends at 1.076e-42. The single-ray kernel's plane distance
/// to the root split x = 1.076e-42 is 8.9e-78, which underflows to 0, so it visits both
/// children and finds Wald's rounding hit on triangle 1 at `t = -0.0`. The cone measures the
/// same plane along its axis, 1.5e-39 away, and culls the child exactly: no hit. Both answers
/// are right (the triangle is unreachable in exact arithmetic); the target required the
/// single ray's, and now accepts either (`BruteForce::equivalent_hits`).
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

    let packets = [OmniPacket::new(RayPacket::new(&[ray])).unwrap()];
    let mut tracer = TileTracer::new(4).unwrap();
    tracer.load_packets(&packets).unwrap();
    for any_hit in [false, true] {
        tracer.set_any_hit(any_hit);
        for method in [ConeMethod::Cone, ConeMethod::MftCone] {
            cones::traverse::trace(&tree, &mut tracer, method, &mut NoCounters);
            let hits = tracer.packet_hits()[0];
            let got = hits.get(0);
            assert_eq!(got, None, "{method:?} (any hit {any_hit}) culls the child exactly");
            if any_hit {
                let found = hits.found.bitmask() & 1 != 0;
                assert!(oracle.equivalent_occlusion(&ray, found, tree.occluded(&ray)), "{method:?} any hit");
            } else {
                assert!(oracle.equivalent_hits(&ray, got, single), "{method:?}: {got:?}, single ray {single:?}");
            }
        }
        // The pyramid methods agree as well.
        for method in [TileMethod::Frustum, TileMethod::Mft] {
            tracer.trace(&tree, method, &mut NoCounters);
            let got = tracer.packet_hits()[0].get(0);
            assert!(oracle.equivalent_hits(&ray, got, single), "{method:?}: {got:?}, single ray {single:?}");
        }
    }
}
