//! Packet methods against single rays where the conformance harness
//! (`conformance/tests/ours.rs`, every registered method on the built-in and shared scenes
//! and the hard cases) does not reach: random soups and cameras (proptest) at every tile
//! size, MFT never doing more work than the single frustum of the same tile, omni packets in
//! every direction, non-finite cameras and lanes, NaN frustum bounds; and the tile kernels
//! in packets of 8 (4x2 pixels) and 16 rays (4x4) against single rays and 2x2 packets.

mod common;

use common::{arena_and_eye, build, same_hit, signed_rng, vertex};
use glam::Vec3;
use kdtree::Counts;
use kdtree::{BruteForce, BuildConfig, Hit, Intersector, KdTree, NoCounters, Ray};
use packets::simd::{PortableF32, SimdF32};
use packets::tile::TileTracer;
use proptest::prelude::*;
use rayon::prelude::*;
use scenes::{Camera, tiles};

/// A tile kernel's entry point.
type Kernel = fn(&mut TileTracer, &KdTree, &mut NoCounters);

/// The four tile kernels by name: 2x2 packets (omni-directional, same-sign), one frustum, MFT.
const METHODS: [(&str, Kernel); 4] = [
    ("packet", TileTracer::trace_packets),
    ("samesign", TileTracer::trace_samesign),
    ("frustum", TileTracer::trace_frustum),
    ("mft", TileTracer::trace_mft),
];

/// Checks per tile of `camera`'s image that MFT at `tile_size` does no more work (steps,
/// triangle tests) than the single frustum of the same tile (thesis 4.1.5).
fn mft_work(tree: &KdTree, camera: &Camera, tile_size: u32) -> Result<(), String> {
    let (mut mft, mut single) = (TileTracer::new(tile_size).unwrap(), TileTracer::new(tile_size).unwrap());
    for tile in tiles(camera.width, camera.height, tile_size) {
        let (mut m, mut f) = (Counts::default(), Counts::default());
        mft.load_primary(camera, &tile).unwrap();
        mft.trace_mft(tree, &mut m);
        single.load_primary(camera, &tile).unwrap();
        single.trace_frustum(tree, &mut f);
        if m.nodes > f.nodes || m.tests > f.tests {
            return Err(format!("tile {tile:?}: MFT {m:?} did more than the frustum {f:?}"));
        }
    }
    Ok(())
}

/// MFT never does more work than the single frustum, on every built-in scene and view.
#[test]
fn mft_never_does_more_work_than_the_frustum() {
    for name in ["atrium", "arena", "atrium-rotated", "touching-boxes", "axis-plane-triangle"] {
        let scene = scenes::load_scene(name).unwrap();
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let tree = build(&scene, intersector);
            for view in &scene.views {
                let camera = view.camera(61, 47).unwrap();
                for size in [4, 8, 16, 32] {
                    mft_work(&tree, &camera, size).unwrap_or_else(|e| panic!("{name} {}: {e}", view.name));
                }
            }
        }
    }
}

/// The tree of a random soup (each item a triangle's corners) with the given test, and a
/// `w x h` camera from `eye * 1.5` towards `target`, wide or narrow; `None` for a view too
/// short or too vertical to make a camera from (the property tests skip it).
fn soup_and_camera(
    tris: Vec<(Vec3, Vec3, Vec3)>,
    eye: Vec3,
    target: Vec3,
    wide: bool,
    watertight: bool,
    (w, h): (u32, u32),
) -> Option<(KdTree, Camera)> {
    let tris: Vec<[Vec3; 3]> = tris.into_iter().map(|(a, b, c)| [a, b, c]).collect();
    let intersector = if watertight { Intersector::Watertight } else { Intersector::Wald };
    let tree = KdTree::build_soup(&tris, &BuildConfig { intersector, ..Default::default() }).unwrap();
    let eye = eye * 1.5;
    if !((target - eye).length() > 1e-3 && (target - eye).normalize().y.abs() < 0.999) {
        return None;
    }
    Some((tree, Camera::look_at(eye, target, if wide { 150.0 } else { 40.0 }, w, h).unwrap()))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random soups (many sharing vertices and axis planes), random cameras inside and
    /// outside them: MFT never does more work than the single frustum (their hits are the
    /// conformance harness's, `conformance/tests/ours.rs`).
    #[test]
    fn mft_work_on_random_soups_and_cameras(tris in prop::collection::vec((vertex(), vertex(), vertex()), 1..120),
                                            eye in vertex(), target in vertex(), wide in any::<bool>(),
                                            watertight in any::<bool>()) {
        let view = soup_and_camera(tris, eye, target, wide, watertight, (24, 20));
        prop_assume!(view.is_some());
        let (tree, camera) = view.unwrap();
        for size in [4, 8, 16] {
            prop_assert!(mft_work(&tree, &camera, size).is_ok(), "{:?}", mft_work(&tree, &camera, size));
        }
    }
}

/// Packets of rays from the common origin in all directions (omni-directional), and their
/// any-hit query, against single rays.
#[test]
fn omni_packets_any_direction_and_any_hit() {
    use packets::{OmniPacket, RayPacket, omni};
    let (tree, origin) = arena_and_eye(Intersector::Wald);
    let mut rnd = signed_rng(12345);
    for _ in 0..2000 {
        let rays: [Ray; 4] = std::array::from_fn(|_| {
            let d = Vec3::new(rnd(), rnd(), rnd());
            Ray::new(origin, if d == Vec3::ZERO { Vec3::X } else { d }, 0.0, 1.0 + 40.0 * rnd().abs())
        });
        let packet = OmniPacket::new(RayPacket::new(&rays)).unwrap();
        let hits = omni::intersect(&tree, &packet, &mut NoCounters).hits();
        let blocked = omni::occluded(&tree, &packet, &mut NoCounters).found.bitmask();
        for (lane, ray) in rays.iter().enumerate() {
            assert!(same_hit(&tree, ray, hits[lane], tree.intersect(ray)), "{ray:?}");
            assert_eq!(blocked >> lane & 1 != 0, tree.occluded(ray), "{ray:?}");
        }
    }
}

/// A hand-made camera with a NaN or infinite field is refused, naming the field.
#[test]
fn non_finite_cameras_are_refused_by_load_primary() {
    use packets::tile::TileError;
    let good = Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, 60.0, 16, 16).unwrap();
    let tile = tiles(16, 16, 8)[0];
    let mut tracer = TileTracer::new(8).unwrap();
    tracer.load_primary(&good, &tile).unwrap();
    let nan = Vec3::new(0.0, f32::NAN, 0.0);
    for (camera, field) in [
        (Camera { eye: nan, ..good }, "eye"),
        (Camera { eye: Vec3::INFINITY, ..good }, "eye"),
        (Camera { forward: nan, ..good }, "forward"),
        (Camera { right: Vec3::NEG_INFINITY, ..good }, "right"),
        (Camera { up: nan, ..good }, "up"),
        (Camera { tan_half_fovy: f32::NAN, ..good }, "field of view"),
        (Camera { tan_half_fovy: f32::INFINITY, ..good }, "field of view"),
    ] {
        let e = tracer.load_primary(&camera, &tile).unwrap_err();
        assert!(matches!(e, TileError::NonFiniteCamera(_)) && e.to_string().contains(field), "{field}: {e}");
    }
}

/// Rays with NaN or infinite components in loaded packets (even filling the first packet)
/// get no hit from every method, and the others still get the single rays' hits.
#[test]
fn non_finite_lanes_get_no_hit_and_the_others_match_single_rays() {
    use packets::{OmniPacket, RayPacket, omni, samesign};
    let scene = scenes::load_scene("arena").unwrap();
    let origin = scene.default_view().eye;
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let bad = [
        Ray::new(Vec3::new(nan, origin.y, origin.z), Vec3::X, 0.0, inf),
        Ray::new(origin, Vec3::new(0.3, nan, -1.0), 0.0, inf),
        Ray::new(origin, Vec3::new(inf, 0.0, -1.0), 0.0, inf),
        Ray::new(origin, Vec3::NEG_Z, 0.0, nan),
        Ray::new(origin, Vec3::NEG_Z, nan, inf),
    ];
    let mut rays: Vec<Ray> = (0..64)
        .map(|i| {
            let (a, b) = (i as f32 * 0.37, i as f32 * 0.11);
            Ray::new(origin, Vec3::new(a.sin(), 0.4 * b.cos() - 0.2, -1.0), 0.0, inf)
        })
        .collect();
    // The whole first packet, and one lane in every third packet after it.
    for (i, slot) in rays.iter_mut().enumerate() {
        if i < 4 || i % 12 == 5 {
            *slot = bad[i % bad.len()];
        }
    }
    let is_bad = |i: usize| i < 4 || i % 12 == 5;
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = build(&scene, intersector);
        let packets: Vec<OmniPacket> = rays.chunks(4).map(|c| OmniPacket::new(RayPacket::new(c)).unwrap()).collect();
        let check = |what: &str, i: usize, got: Option<Hit>, any_hit: bool| {
            let ray = &rays[i];
            if is_bad(i) {
                assert_eq!(got, None, "{what}: ray {i} {ray:?}");
            } else if any_hit {
                assert_eq!(got.is_some(), tree.occluded(ray), "{what}: ray {i}");
            } else {
                assert!(same_hit(&tree, ray, got, tree.intersect(ray)), "{what}: ray {i}: {got:?}");
            }
        };
        for (p, packet) in packets.iter().enumerate() {
            let (closest, same, blocked) = (
                omni::intersect(&tree, packet, &mut NoCounters),
                samesign::intersect(&tree, &packet.rays, &mut NoCounters),
                omni::occluded(&tree, packet, &mut NoCounters),
            );
            for lane in 0..4 {
                check("omni", 4 * p + lane, closest.get(lane), false);
                check("samesign", 4 * p + lane, same.get(lane), false);
                check("omni any-hit", 4 * p + lane, blocked.get(lane), true);
            }
        }
        let mut tracer = TileTracer::new(16).unwrap();
        for any_hit in [false, true] {
            tracer.set_any_hit(any_hit);
            for (method, trace) in METHODS {
                tracer.load_packets(&packets).expect("the valid lanes share one origin");
                trace(&mut tracer, &tree, &mut NoCounters);
                let any = any_hit && matches!(method, "frustum" | "mft");
                for (p, hit) in tracer.packet_hits().iter().enumerate() {
                    for lane in 0..4 {
                        check(method, 4 * p + lane, hit.get(lane), any);
                    }
                }
            }
        }
    }
}

/// A frustum bound with a NaN field bounds nothing: `trace_frusta` traces with the pyramid
/// instead, and the hits are the single rays'.
#[test]
fn nan_frustum_bounds_fall_back_to_the_pyramid() {
    use packets::{Frusta, FrustumBound};
    let scene = scenes::load_scene("atrium").unwrap();
    let tree = build(&scene, Intersector::Wald);
    let camera = scene.default_view().camera(48, 32).unwrap();
    let nan = FrustumBound { k0: [0.0; 4], k1: [0.0; 4], near: f32::NAN, far: f32::INFINITY, hit_scale: 1.0 };
    let bounds = [
        nan,
        FrustumBound { near: 0.0, far: f32::NAN, ..nan },
        FrustumBound { near: 0.0, k0: [f32::NAN; 4], ..nan },
        FrustumBound { near: 0.0, hit_scale: f32::NAN, ..nan },
    ];
    assert!(bounds.iter().all(FrustumBound::has_nan));
    let mut tracer = TileTracer::new(16).unwrap();
    let mut checked = 0;
    for tile in tiles(camera.width, camera.height, 16) {
        let mut want = vec![None; tile.pixel_count()];
        tracer.load_primary(&camera, &tile).unwrap();
        tracer.trace_frustum(&tree, &mut NoCounters);
        tracer.write_hits(&mut want);
        for case in 0..4 {
            let pyramids = tracer.prepare(&tree);
            let frusta = match case {
                0 => Frusta::One(bounds[0]),
                1 => Frusta::One(bounds[3]),
                2 => Frusta::Four(bounds),
                _ => Frusta::Four([pyramids[0], bounds[1], pyramids[2], bounds[2]]),
            };
            let mut got = vec![None; tile.pixel_count()];
            tracer.trace_frusta(&tree, &frusta, &mut NoCounters);
            tracer.write_hits(&mut got);
            let differ = got.iter().zip(&want).filter(|(g, w)| g != w).count();
            assert_eq!(differ, 0, "tile {tile:?}, case {case}: {differ} pixels differ");
            checked += got.iter().filter(|h| h.is_some()).count();
        }
    }
    assert!(checked > 1000, "{checked} hits compared");
}

/// A tile kernel's entry point at any packet width, counting its work.
type WideKernel<V> = fn(&mut TileTracer<V>, &KdTree, &mut Counts);

/// The four tile kernels at the packet width of `V`, by name.
fn wide_methods<V: SimdF32>() -> [(&'static str, WideKernel<V>); 4] {
    [
        ("packet", TileTracer::<V>::trace_packets::<Counts>),
        ("samesign", TileTracer::<V>::trace_samesign::<Counts>),
        ("frustum", TileTracer::<V>::trace_frustum::<Counts>),
        ("mft", TileTracer::<V>::trace_mft::<Counts>),
    ]
}

/// Hits as bits (`t`, `u`, `v`, triangle), so that answers compare bit for bit.
fn bits(hits: &[Option<Hit>]) -> Vec<Option<[u32; 4]>> {
    hits.iter().map(|h| h.map(|h| [h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim])).collect()
}

/// The single rays of `camera`'s image, row by row: each pixel's closest hit and whether it
/// is blocked.
fn single_rays(tree: &KdTree, camera: &Camera) -> Vec<(Ray, Option<Hit>, bool)> {
    (0..camera.height)
        .flat_map(|y| (0..camera.width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (o, d) = camera.pixel_ray(x, y);
            let ray = Ray::new(o, d, 0.0, f32::INFINITY);
            (ray, tree.intersect(&ray), tree.occluded(&ray))
        })
        .collect()
}

/// The settings every tile is traced with: culling on and off, closest and any hit.
const SETTINGS: [(bool, bool); 4] = [(true, false), (true, true), (false, false), (false, true)];

/// What the kernels give in 2x2 packets: per tile of `camera`'s image at `tile_size`, per
/// setting ([`SETTINGS`]) and kernel ([`METHODS`]), the tile's hits row by row.
fn narrow_tiles(tree: &KdTree, camera: &Camera, tile_size: u32) -> Vec<Vec<Vec<Option<[u32; 4]>>>> {
    let mut narrow = TileTracer::new(tile_size).unwrap();
    tiles(camera.width, camera.height, tile_size)
        .iter()
        .map(|tile| {
            let mut runs = Vec::new();
            for (culling, any_hit) in SETTINGS {
                for (_, trace) in METHODS {
                    let mut got = vec![None; tile.pixel_count()];
                    narrow.set_culling(culling);
                    narrow.set_any_hit(any_hit);
                    narrow.load_primary(camera, tile).unwrap();
                    trace(&mut narrow, tree, &mut NoCounters);
                    narrow.write_hits(&mut got);
                    runs.push(bits(&got));
                }
            }
            runs
        })
        .collect()
}

/// Traces every tile of `camera`'s image at `tile_size` with the four kernels in packets of
/// `V` (culling on and off, closest and any hit) and checks each pixel against the single
/// ray `want` (by the oracle's rule; in any-hit mode the frustum methods' hits must be
/// exactly the blocked rays), each kernel against the same kernel in 2x2 packets (`narrow`,
/// from [`narrow_tiles`]) bit for bit, and MFT's work (closest hits) against the single
/// frustum's in the same packets. Returns the hits compared.
fn wide_tiles_match<V: SimdF32>(
    tree: &KdTree,
    camera: &Camera,
    tile_size: u32,
    want: &[(Ray, Option<Hit>, bool)],
    narrow: &[Vec<Vec<Option<[u32; 4]>>>],
    oracle: &BruteForce,
) -> Result<usize, String> {
    let mut wide = TileTracer::<V>::with_size(tile_size).map_err(|e| e.to_string())?;
    let mut hits = 0;
    for (tile, narrow) in tiles(camera.width, camera.height, tile_size).iter().zip(narrow) {
        let mut narrow = narrow.iter();
        for (culling, any_hit) in SETTINGS {
            let mut frustum_work = Counts::default();
            for (method, trace) in wide_methods::<V>() {
                let what =
                    format!("{method} at {} lanes, tile {tile:?}, culling {culling}, any hit {any_hit}", V::LANES);
                let mut got = vec![None; tile.pixel_count()];
                let mut work = Counts::default();
                wide.set_culling(culling);
                wide.set_any_hit(any_hit);
                wide.load_primary(camera, tile).map_err(|e| e.to_string())?;
                trace(&mut wide, tree, &mut work);
                wide.write_hits(&mut got);
                if Some(&bits(&got)) != narrow.next() {
                    return Err(format!("{what}: differs from 2x2 packets"));
                }
                let any = any_hit && matches!(method, "frustum" | "mft");
                for (i, (x, y)) in tile.pixels().enumerate() {
                    let (ray, closest, blocked) = &want[(y * camera.width + x) as usize];
                    // `same_hit`, with the oracle made once.
                    let ok =
                        if any { got[i].is_some() == *blocked } else { oracle.equivalent_hits(ray, got[i], *closest) };
                    if !ok {
                        return Err(format!("{what}: pixel ({x}, {y}) got {:?}, single ray {closest:?}", got[i]));
                    }
                    hits += usize::from(got[i].is_some());
                }
                match method {
                    "frustum" => frustum_work = work,
                    // (In any-hit mode a frustum stops at other places: no bound, as in 2x2
                    // packets.)
                    "mft" if !any_hit && (work.nodes > frustum_work.nodes || work.tests > frustum_work.tests) => {
                        return Err(format!("{what}: MFT {work:?} did more than the frustum {frustum_work:?}"));
                    }
                    _ => {}
                }
            }
        }
    }
    Ok(hits)
}

/// [`wide_tiles_match`] in packets of 8 and 16 rays.
fn wide_tiles_match_8_16(tree: &KdTree, camera: &Camera, tile_size: u32) -> Result<usize, String> {
    let (want, oracle) = (single_rays(tree, camera), BruteForce::for_tree(tree));
    let narrow = narrow_tiles(tree, camera, tile_size);
    Ok(wide_tiles_match::<PortableF32<8>>(tree, camera, tile_size, &want, &narrow, &oracle)?
        + wide_tiles_match::<PortableF32<16>>(tree, camera, tile_size, &want, &narrow, &oracle)?)
}

/// The tile kernels in packets of 8 (4x2 pixels) and 16 rays (4x4) give the single rays'
/// hits, and the 2x2 packets' bit for bit, on every built-in scene and view, with both
/// intersectors, at tile sizes 8, 16 and 32 (the image, 45 x 37, clips tiles at its right
/// and bottom edges; 16 only on the views after the first), culling on and off, closest and
/// any hit; MFT does no more work than the single frustum.
#[test]
fn wide_packets_match_single_rays_on_the_builtin_scenes() {
    let names = ["atrium", "arena", "atrium-rotated", "touching-boxes", "axis-plane-triangle"];
    let cases: Vec<_> =
        names.into_iter().flat_map(|name| [Intersector::Wald, Intersector::Watertight].map(|i| (name, i))).collect();
    // The scenes and intersectors in parallel (the test's time, on CI's two cores).
    let hits: usize = cases
        .into_par_iter()
        .map(|(name, intersector)| {
            let scene = scenes::load_scene(name).unwrap();
            let tree = build(&scene, intersector);
            let mut hits = 0;
            for (v, view) in scene.views.iter().enumerate() {
                let camera = view.camera(45, 37).unwrap();
                // Every size on the first view, the middle one on the others (time).
                for size in if v == 0 { &[8, 16, 32][..] } else { &[16] } {
                    let size = *size;
                    hits += wide_tiles_match_8_16(&tree, &camera, size)
                        .unwrap_or_else(|e| panic!("{name} {intersector:?} {} size {size}: {e}", view.name));
                }
            }
            hits
        })
        .sum();
    assert!(hits > 50_000, "{hits} hits compared");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Random soups (many sharing vertices and axis planes), random cameras inside and
    /// outside them: the tile kernels in packets of 8 and 16 rays give the single rays' hits
    /// and the 2x2 packets' bit for bit, and MFT does no more work than the frustum.
    #[test]
    fn wide_packets_on_random_soups_and_cameras(tris in prop::collection::vec((vertex(), vertex(), vertex()), 1..120),
                                                eye in vertex(), target in vertex(), wide in any::<bool>(),
                                                watertight in any::<bool>()) {
        let view = soup_and_camera(tris, eye, target, wide, watertight, (27, 21));
        prop_assume!(view.is_some());
        let (tree, camera) = view.unwrap();
        for size in [8, 16] {
            let r = wide_tiles_match_8_16(&tree, &camera, size);
            prop_assert!(r.is_ok(), "size {size}: {r:?}");
        }
    }
}

/// Rays with NaN or infinite components in loaded packets of 8 and 16 rays get no hit from
/// every kernel, closest or any hit, and the others get the single rays' hits.
#[test]
fn wide_packets_with_non_finite_lanes() {
    non_finite_lanes::<PortableF32<8>>();
    non_finite_lanes::<PortableF32<16>>();
}

fn non_finite_lanes<V: SimdF32>() {
    use packets::{OmniPacket, RayPacket};
    let scene = scenes::load_scene("arena").unwrap();
    let origin = scene.default_view().eye;
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let bad = [
        Ray::new(Vec3::new(nan, origin.y, origin.z), Vec3::X, 0.0, inf),
        Ray::new(origin, Vec3::new(0.3, nan, -1.0), 0.0, inf),
        Ray::new(origin, Vec3::new(inf, 0.0, -1.0), 0.0, inf),
        Ray::new(origin, Vec3::NEG_Z, 0.0, nan),
        Ray::new(origin, Vec3::NEG_Z, nan, inf),
    ];
    let w = V::LANES;
    let is_bad = |i: usize| i < w || i % 12 == 5;
    let rays: Vec<Ray> = (0..8 * w)
        .map(|i| {
            let (a, b) = (i as f32 * 0.37, i as f32 * 0.11);
            let good = Ray::new(origin, Vec3::new(a.sin(), 0.4 * b.cos() - 0.2, -1.0), 0.0, inf);
            if is_bad(i) { bad[i % bad.len()] } else { good }
        })
        .collect();
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = build(&scene, intersector);
        let packets: Vec<OmniPacket<V>> =
            rays.chunks(w).map(|c| OmniPacket::new(RayPacket::<V>::from_rays(c)).unwrap()).collect();
        let mut tracer = TileTracer::<V>::with_size(16).unwrap();
        let mut checked = 0;
        for culling in [true, false] {
            for any_hit in [false, true] {
                tracer.set_culling(culling);
                tracer.set_any_hit(any_hit);
                for (method, trace) in wide_methods::<V>() {
                    tracer.load_packets(&packets).expect("the valid lanes share one origin");
                    trace(&mut tracer, &tree, &mut Counts::default());
                    let any = any_hit && matches!(method, "frustum" | "mft");
                    for (p, hit) in tracer.packet_hits().iter().enumerate() {
                        for lane in 0..w {
                            let (i, got) = (w * p + lane, hit.get(lane));
                            let ray = &rays[i];
                            let what = format!("{method} {intersector:?} {w} lanes, culling {culling}: ray {i}");
                            if is_bad(i) {
                                assert_eq!(got, None, "{what} {ray:?}");
                            } else if any {
                                assert_eq!(got.is_some(), tree.occluded(ray), "{what}");
                            } else {
                                assert!(same_hit(&tree, ray, got, tree.intersect(ray)), "{what}: {got:?}");
                            }
                            checked += usize::from(got.is_some());
                        }
                    }
                }
            }
        }
        assert!(checked > 100, "{checked} hits");
    }
}

/// A NaN frustum bound falls back to the pyramid in packets of 8 and 16 rays too: the hits
/// are the single frustum's.
#[test]
fn wide_packets_with_nan_frustum_bounds() {
    nan_bounds::<PortableF32<8>>();
    nan_bounds::<PortableF32<16>>();
}

fn nan_bounds<V: SimdF32>() {
    use packets::{Frusta, FrustumBound};
    let scene = scenes::load_scene("atrium").unwrap();
    let tree = build(&scene, Intersector::Watertight);
    let camera = scene.default_view().camera(48, 36).unwrap();
    let nan = FrustumBound { k0: [0.0; 4], k1: [0.0; 4], near: f32::NAN, far: f32::INFINITY, hit_scale: 1.0 };
    let mut tracer = TileTracer::<V>::with_size(16).unwrap();
    let mut checked = 0;
    for tile in tiles(camera.width, camera.height, 16) {
        let mut want = vec![None; tile.pixel_count()];
        tracer.load_primary(&camera, &tile).unwrap();
        tracer.trace_frustum(&tree, &mut NoCounters);
        tracer.write_hits(&mut want);
        for case in 0..3 {
            let pyramids = tracer.prepare(&tree);
            let frusta = match case {
                0 => Frusta::One(nan),
                1 => Frusta::Four([nan; 4]),
                _ => Frusta::Four([pyramids[0], nan, pyramids[2], FrustumBound { near: 0.0, ..nan }]),
            };
            let mut got = vec![None; tile.pixel_count()];
            tracer.trace_frusta(&tree, &frusta, &mut NoCounters);
            tracer.write_hits(&mut got);
            assert_eq!(bits(&got), bits(&want), "{} lanes, tile {tile:?}, case {case}", V::LANES);
            checked += got.iter().filter(|h| h.is_some()).count();
        }
    }
    assert!(checked > 1000, "{checked} hits compared");
}

/// Runs of mirror reflections from their virtual eye (`packets::mirror`: one origin, every
/// interval starting past the mirror, `t_min > 0`), loaded by `load_rays` at 4, 8 and 16
/// lanes and traced by every tile kernel, closest and any hit: the single rays' answers.
#[test]
fn virtual_eye_runs_loaded_as_rays_match_single_rays() {
    reflection_runs::<glam::Vec4>();
    reflection_runs::<PortableF32<8>>();
    reflection_runs::<PortableF32<16>>();
    // The AVX2 and AVX-512 lane types, where this CPU runs them.
    #[cfg(target_arch = "x86_64")]
    {
        packets::with_avx2(reflection_runs::<packets::F32x8>);
        packets::with_avx512(reflection_runs::<packets::F32x16>);
    }
}

fn reflection_runs<V: SimdF32>() {
    use packets::mirror::Mirror;
    let scene = scenes::load_scene("atrium").unwrap();
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = build(&scene, intersector);
        let camera = scene.default_view().camera(64, 48).unwrap();
        // Each pixel's reflection off the triangle it sees, grouped by virtual eye.
        let mut runs: std::collections::HashMap<[u32; 3], Vec<Ray>> = Default::default();
        for y in 0..camera.height {
            for x in 0..camera.width {
                let (eye, dir) = camera.pixel_ray(x, y);
                let Some(hit) = tree.intersect(&Ray::new(eye, dir, 0.0, f32::INFINITY)) else { continue };
                let surface = kdtree::surface::Surface::new(&tree.triangle(hit.prim));
                let Some(mirror) = Mirror::of_surface(&surface) else { continue };
                if let Some(ray) = mirror.reflected_ray(eye, dir, hit.t, surface.offset) {
                    runs.entry(ray.origin.to_array().map(f32::to_bits)).or_default().push(ray);
                }
            }
        }
        let mut tracer = TileTracer::<V>::with_size(16).unwrap();
        let mut checked = 0;
        for rays in runs.values().filter(|r| r.len() > V::LANES) {
            for run in rays.chunks(16 * V::LANES) {
                for any_hit in [false, true] {
                    tracer.set_any_hit(any_hit);
                    for (method, trace) in wide_methods::<V>() {
                        tracer.load_rays(run).expect("one origin, t_min > 0");
                        trace(&mut tracer, &tree, &mut Counts::default());
                        let any = any_hit && matches!(method, "frustum" | "mft");
                        for (p, hits) in tracer.packet_hits().iter().enumerate() {
                            for (lane, ray) in run.iter().enumerate().skip(p * V::LANES).take(V::LANES) {
                                let got = hits.get(lane - p * V::LANES);
                                if any {
                                    assert_eq!(got.is_some(), tree.occluded(ray), "{method}, {} lanes", V::LANES);
                                } else {
                                    let want = tree.intersect(ray);
                                    assert!(
                                        same_hit(&tree, ray, got, want),
                                        "{method}, {} lanes: {got:?} {want:?}",
                                        V::LANES
                                    );
                                    checked += usize::from(got.is_some());
                                }
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 500, "{checked} hits compared at {} lanes", V::LANES);
        // A ray of another origin, or one starting behind it, is refused.
        let some = runs.values().find(|r| r.len() > 1).unwrap();
        let mut mixed = some[..2].to_vec();
        mixed[1].origin += Vec3::X;
        assert!(tracer.load_rays(&mixed).is_none());
        let behind = Ray::new(some[0].origin, some[0].dir, -1.0, f32::INFINITY);
        assert!(tracer.load_rays(&[some[0], behind]).is_none());
    }
}
