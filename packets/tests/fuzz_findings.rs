//! Regression tests for the `traversal` cargo-fuzz target's findings that involve the packet
//! methods: each is the finding's input, decoded with `cargo fuzz fmt`, and the property the
//! target checks (the others are in `kdtree/tests/fuzz_findings.rs` and
//! `cones/tests/fuzz_findings.rs`).

use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Intersector, KdTree, NoCounters, Ray};
use packets::{OmniPacket, RayPacket, TileTracer, omni};

/// A tile kernel's entry point.
type Kernel = fn(&mut TileTracer, &KdTree, &mut NoCounters);

/// The four tile kernels by name: 2x2 packets (omni-directional, same-sign), one frustum, MFT.
const METHODS: [(&str, Kernel); 4] = [
    ("packet", TileTracer::trace_packets),
    ("samesign", TileTracer::trace_samesign),
    ("frustum", TileTracer::trace_frustum),
    ("mft", TileTracer::trace_mft),
];

/// The watertight test; a shared origin 2.3e-38 right of the root split x = 0, every ray
/// heading +x with `d_x = 3.8e15`. The plane's distance along the second ray, -2.3e-38 /
/// 3.8e15 = -6e-54, underflows to -0.0, which the omni-directional kernel's "Modification 1"
/// (negative distances, planes behind the origin, become +inf) did not catch (-0.0 is not
/// below zero): it took the plane for one at the origin, its front (x > 0) child for empty
/// and went to the back child (x < 0) only, missing the ray's hit on triangle 0 at t = 3.6e-36
/// (reachable in exact arithmetic, `BruteForce::unreachable` is false). The MFT kernel had the
/// same test. Both now decide "behind" from the signs of the distance and the direction.
#[test]
fn plane_behind_the_origin_at_an_underflowed_distance_is_behind() {
    let soup: Vec<[Vec3; 3]> = [
        [
            [2.774282e-20, 3.849744e-37, 5.786717e-39],
            [2.3552932e-38, 2251799800000000.0, 3823644300000000.0],
            [1.0541188e-36, 2.774282e-20, 0.0],
        ],
        [[1.06731134e-19, 3.849744e-37, 3.858796e-37], [9.1477e-41, 1e-45, 0.0], [0.0, 0.0, 0.0]],
        [
            [3.8500897e-37, 7647288600000000.0, 3.8600006e-37],
            [3.8500897e-37, 2.76587e-40, 1837203800.0],
            [-1.7015682e38, 9.1835e-41, 3.8500884e-37],
        ],
        [
            [3823621200000000.0, 6.3873135e-37, 3.8500897e-37],
            [3.8500897e-37, 3.8500897e-37, 4.3e-44],
            [3.8500897e-37, 3.8500897e-37, 1.1125e-41],
        ],
        [
            [6.078937e-37, 2.3418056e-38, 3.59e-43],
            [3.8500897e-37, -3823621200000000.0, 6.3873135e-37],
            [3.8500897e-37, 3.8500897e-37, -3.687652e16],
        ],
    ]
    .map(|t: [[f32; 3]; 3]| t.map(Vec3::from_array))
    .to_vec();
    let tree =
        KdTree::build_soup(&soup, &BuildConfig { intersector: Intersector::Watertight, ..BuildConfig::default() })
            .unwrap();
    let oracle = BruteForce::for_tree(&tree);
    let root = tree.nodes()[0];
    assert_eq!((root.axis(), root.split()), (0, 0.0));
    let eye = Vec3::new(2.3418056e-38, 3.59e-43, 3.8500897e-37);
    let rays = [
        Ray::try_new(eye, Vec3::new(3823621200000000.0, 6.3873135e-37, 3.8500897e-37), 3.8500897e-37, 3.8500897e-37)
            .unwrap(),
        Ray::try_new(
            eye,
            Vec3::new(3823621200000000.0, 3823644300000000.0, 3.870332e-37),
            4.6729358e-37,
            3823621200000000.0,
        )
        .unwrap(),
    ];
    assert_eq!((root.split() - eye.x) * rays[1].inv_dir.x, 0.0, "-6e-54 underflows");
    let want: Vec<_> = rays.iter().map(|r| tree.intersect(r)).collect();
    assert_eq!(want[1].map(|h| h.prim), Some(0));
    assert!(!oracle.unreachable(&rays[1], 0), "a real hit");
    for (ray, want) in rays.iter().zip(&want) {
        oracle.check(ray, *want, tree.occluded(ray)).unwrap();
    }

    let packet = OmniPacket::new(RayPacket::new(&rays)).unwrap();
    let hits = omni::intersect(&tree, &packet, &mut NoCounters);
    let any = omni::occluded(&tree, &packet, &mut NoCounters);
    for (lane, ray) in rays.iter().enumerate() {
        assert!(oracle.equivalent_hits(ray, hits.get(lane), want[lane]), "omni lane {lane}: {:?}", hits.get(lane));
        let found = any.found.bitmask() >> lane & 1 != 0;
        assert!(oracle.equivalent_occlusion(ray, found, tree.occluded(ray)), "omni any-hit lane {lane}");
    }
    let mut tracer = TileTracer::new(4).unwrap();
    tracer.load_packets(&[packet]).unwrap();
    for any_hit in [false, true] {
        tracer.set_any_hit(any_hit);
        for (method, trace) in METHODS {
            trace(&mut tracer, &tree, &mut NoCounters);
            let hits = tracer.packet_hits()[0];
            for (lane, ray) in rays.iter().enumerate() {
                if any_hit {
                    let found = hits.found.bitmask() >> lane & 1 != 0;
                    assert!(
                        oracle.equivalent_occlusion(ray, found, tree.occluded(ray)),
                        "{method} any-hit lane {lane}"
                    );
                } else {
                    let got = hits.get(lane);
                    assert!(oracle.equivalent_hits(ray, got, want[lane]), "{method} lane {lane}: {got:?}");
                }
            }
        }
    }
}

/// The `traversal` target's packet checks on a decoded input: the shared-origin rays (every
/// accepted ray's direction from the accepted ray `eye`'s origin) through the omni-directional
/// kernel and the four tile methods, closest and any hit, against the single ray.
fn check_shared_origin_packets(soup: &[[[f32; 3]; 3]], watertight: bool, rays: &[[f32; 8]], eye: usize) {
    let soup: Vec<[Vec3; 3]> = soup.iter().map(|t| t.map(Vec3::from_array)).collect();
    let intersector = if watertight { Intersector::Watertight } else { Intersector::Wald };
    let tree = KdTree::build_soup(&soup, &BuildConfig { intersector, ..BuildConfig::default() }).unwrap();
    let oracle = BruteForce::for_tree(&tree);
    let accepted: Vec<Ray> = rays
        .iter()
        .filter_map(|r| Ray::try_new(Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5]), r[6], r[7]).ok())
        .collect();
    let eye = accepted[eye % accepted.len()];
    let shared: Vec<Ray> =
        accepted.iter().filter_map(|r| Ray::try_new(eye.origin, r.dir, r.t_min.max(0.0), r.t_max).ok()).collect();
    let want: Vec<_> = shared.iter().map(|r| tree.intersect(r)).collect();
    let packets: Vec<OmniPacket> =
        shared.chunks(4).map(|rays| OmniPacket::new(RayPacket::new(rays)).unwrap()).collect();
    for ((packet, rays), want) in packets.iter().zip(shared.chunks(4)).zip(want.chunks(4)) {
        let hits = omni::intersect(&tree, packet, &mut NoCounters);
        let any = omni::occluded(&tree, packet, &mut NoCounters);
        for (lane, ray) in rays.iter().enumerate() {
            assert!(oracle.equivalent_hits(ray, hits.get(lane), want[lane]), "omni lane {lane}: {:?}", hits.get(lane));
            let found = any.found.bitmask() >> lane & 1 != 0;
            assert!(oracle.equivalent_occlusion(ray, found, tree.occluded(ray)), "omni any-hit lane {lane}");
        }
    }
    let mut tracer = TileTracer::new(4).unwrap();
    tracer.load_packets(&packets).unwrap();
    for any_hit in [false, true] {
        tracer.set_any_hit(any_hit);
        for (method, trace) in METHODS {
            if any_hit && matches!(method, "packet" | "samesign") {
                continue;
            }
            trace(&mut tracer, &tree, &mut NoCounters);
            for ((hits, rays), want) in tracer.packet_hits().iter().zip(shared.chunks(4)).zip(want.chunks(4)) {
                for (lane, ray) in rays.iter().enumerate() {
                    if any_hit {
                        let found = hits.found.bitmask() >> lane & 1 != 0;
                        let ok = oracle.equivalent_occlusion(ray, found, tree.occluded(ray));
                        assert!(ok, "{method} any-hit lane {lane}: {found}");
                    } else {
                        let got = hits.get(lane);
                        assert!(oracle.equivalent_hits(ray, got, want[lane]), "{method} lane {lane}: {got:?}");
                    }
                }
            }
        }
    }
}

/// `traversal` (Wald's test): the frustum kernel sent a ray to the far side of a plane behind
/// its origin whose distance underflowed to -0.0 (`packets::bound::plane_interval`, shared
/// with the cones), missing the single ray's hit on triangle 0 at t = 66.5.
#[test]
fn frustum_plane_behind_the_origin_at_an_underflowed_distance_wald() {
    check_shared_origin_packets(
        &[
            [
                [-7.729682e-37, 5.1198896e36, 1.2306499e-38],
                [3.2e-43, 3.526483e-38, 9.1485e-41],
                [3.8501686e-37, 3.8500897e-37, 2.5837515e-29],
            ],
            [
                [8.7975e-41, -5.316567e33, 13349707.0],
                [1.8454989e-38, 3.1552388e-33, -5.0704946e31],
                [2.584925e-29, -7.8475107e-23, 1.0353138e-23],
            ],
            [
                [-7.740593e-37, 3.7766787e-37, -0.092645764],
                [-0.092646405, -0.033871744, 1.820972e-32],
                [7.998307e35, 1.2077618e-38, 1.1571456e-38],
            ],
        ],
        false,
        &[
            [
                -7.6997095e-37,
                1.469437e-39,
                3.59e-43,
                3.7619263e-37,
                3.7900505e-37,
                3.850104e-37,
                3.8500897e-37,
                3.8500897e-37,
            ],
            [
                2.2724885e-16,
                1.2306499e-38,
                3.2e-43,
                3.526483e-38,
                3.85342e-37,
                -5.0602644e-35,
                -2.235188e37,
                7.729734e-37,
            ],
            [
                7.709248e-37,
                9.1835e-41,
                -4.4703484e-8,
                3.8500897e-37,
                3.8500897e-37,
                -1.6607714e32,
                6.5390944e-19,
                -2.9802322e-8,
            ],
            [12.062572, 2.859813e-39, -5.070498e31, 5.16985e-29, 2.65e-43, 3.59e-43, -3.860257e-29, 1.9566076e-23],
            [
                -7.740593e-37,
                -3.7766787e-37,
                -2.5280536e-29,
                1.1571273e-38,
                3.581573e-39,
                3.8500884e-37,
                3.031652e-39,
                23461888.0,
            ],
            [-2.568785e38, -1.0527823e-36, -4.9315565e-12, -1.7416521e38, 1.0854726e-27, 0.0, 0.0, 0.0],
        ],
        0,
    );
}

/// `traversal` (watertight test): the same frustum miss, a single-ray tile, hit at t = 15.8.
#[test]
fn frustum_plane_behind_the_origin_at_an_underflowed_distance_watertight() {
    check_shared_origin_packets(
        &[
            [
                [13323238.0, 6.914672e-39, -1.7058772e38],
                [-5.649315e20, -3.68197e19, 2.341805e-38],
                [-2.3418052e-38, 30238208.0, 13322571.0],
            ],
            [
                [-4.056482e31, 1.203695e-38, 0.0],
                [1.0842022e-19, 47872.0, -1.7538667e-20],
                [-2.8735182e-16, -2.8735182e-16, -2.8735182e-16],
            ],
        ],
        true,
        &[[1.9989143e-13, 7.909915e-24, -3.984662e-16, 7.0154254e-20, 0.0, -1.0484219e37, 2.3509886e-38, 4.303765e37]],
        228,
    );
}
