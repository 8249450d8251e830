//! Cone and MFT-cone traversal against single rays where the conformance harness
//! (`conformance/tests/ours.rs`, every registered method on the built-in and shared scenes,
//! random soups, cameras and lights, and the hard cases) does not reach: packets loaded from
//! elsewhere in narrow and wide bundles, non-finite lanes and cameras, and cone soft shadows
//! on two light sizes against the pyramid and single rays; and the cone kernels with the
//! tile's packets 8 and 16 rays wide.

#[path = "../../packets/tests/common/mod.rs"]
mod common;

use common::{arena_and_eye, build, same_hit, signed_rng};
use cones::shadows::{SAMPLES, light_samples, sample_cone, shadow_rays};
use cones::{ShadowMethod, SoftShadowTracer, traverse};
use glam::Vec3;
use kdtree::{Intersector, KdTree, NoCounters, Ray, WaldTest, WatertightTest};
use packets::simd::{PortableF32, SimdF32};
use packets::{OmniPacket, RayPacket, TileTracer};
use rayon::prelude::*;
use scenes::{Camera, SphereLight, tiles};

/// A cone kernel's entry point.
type Kernel = fn(&KdTree, &mut TileTracer, &mut NoCounters);

/// The two cone kernels by name: one cone per tile, four quadrant cones.
const METHODS: [(&str, Kernel); 2] = [("cone", traverse::trace_cone), ("mft-cone", traverse::trace_mft_cone)];

/// Soft shadows of the primary hits of `camera` to a spherical light at `centre`: the cone,
/// the pyramid and single rays agree on every shadow ray. Returns how many points were
/// partly shadowed (so that a test can insist on penumbrae).
fn check_soft_shadows(scene: &scenes::Scene, tree: &KdTree, camera: &Camera, light: &SphereLight) -> usize {
    let mut t = SoftShadowTracer::new();
    let mut penumbra = 0;
    for y in 0..camera.height {
        for x in 0..camera.width {
            let (o, d) = camera.pixel_ray(x, y);
            let Some(hit) = tree.intersect(&Ray::new(o, d, 0.0, f32::INFINITY)) else { continue };
            let tri = scene.mesh.triangle(hit.prim as usize);
            let p = kdtree::ray::offset_origin(&tri, &hit, light.center - kdtree::ray::surface_point(&tri, &hit));
            let (Some(samples), Some(cone)) = (light_samples(p, light), sample_cone(p, light)) else {
                continue;
            };
            let rays = shadow_rays(p, &samples);
            let single = t.occluded(tree, &rays, &cone, ShadowMethod::Single, &mut NoCounters);
            for m in [ShadowMethod::Pyramid, ShadowMethod::Cone] {
                let got = t.occluded(tree, &rays, &cone, m, &mut NoCounters);
                assert_eq!(got, single, "pixel ({x}, {y}) {m:?}: {got:016b} vs single {single:016b}");
            }
            penumbra += usize::from(single != 0 && u32::from(single) != (1u32 << SAMPLES) - 1);
        }
    }
    penumbra
}

#[test]
fn cone_soft_shadows_match_single_rays_on_the_builtin_scenes() {
    let mut penumbra = 0;
    for &name in scenes::builtin::NAMES.iter().filter(|n| !scenes::builtin::MATERIAL_VARIANTS.contains(n)) {
        let scene = scenes::load_scene(name).unwrap();
        let tree = build(&scene, Intersector::Wald);
        let diag = (tree.bounds().max - tree.bounds().min).length();
        let camera = scene.default_view().camera(40, 30).unwrap();
        for radius in [0.02 * diag, 0.08 * diag] {
            let light = SphereLight { center: scene.point_light.position, radius, intensity: Vec3::ONE };
            penumbra += check_soft_shadows(&scene, &tree, &camera, &light);
        }
    }
    assert!(penumbra > 50, "only {penumbra} partly shadowed points: the test would not see a difference");
}

/// Packets loaded from elsewhere (rays from one origin in a narrow bundle, unnormalised, and
/// in every direction, where no cone holds them and the pyramid takes over): the cone
/// methods give the single rays' hits.
#[test]
fn loaded_packets_in_narrow_and_wide_bundles() {
    let (tree, origin) = arena_and_eye(Intersector::Watertight);
    let mut rnd = signed_rng(987654321);
    let mut tracer = TileTracer::new(8).unwrap();
    for spread in [0.01f32, 0.3, 3.0] {
        for round in 0..20 {
            let axis = Vec3::new(rnd(), rnd(), rnd());
            let rays: Vec<Ray> = (0..64)
                .map(|_| {
                    let d = (axis + spread * Vec3::new(rnd(), rnd(), rnd())) * (1.0 + 4.0 * rnd().abs());
                    Ray::new(origin, d, 0.0, f32::INFINITY)
                })
                .collect();
            let packets: Vec<OmniPacket> =
                rays.chunks(4).map(|r| OmniPacket::new(RayPacket::new(r)).unwrap()).collect();
            for (method, trace) in METHODS {
                tracer.load_packets(&packets).unwrap();
                trace(&tree, &mut tracer, &mut NoCounters);
                for (i, ray) in rays.iter().enumerate() {
                    let got = tracer.packet_hits()[i / 4].get(i % 4);
                    let want = tree.intersect(ray);
                    assert!(
                        same_hit(&tree, ray, got, want),
                        "spread {spread} round {round} ray {i} {method}: {got:?} vs {want:?}"
                    );
                }
            }
        }
    }
}

/// Loaded packets with NaN or infinite lanes (the whole first packet among them): the cone
/// methods give those lanes no hit and the others the single rays' hits.
#[test]
fn loaded_packets_with_non_finite_lanes() {
    let scene = scenes::load_scene("arena").unwrap();
    let origin = scene.default_view().eye;
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let bad = [
        Ray::new(Vec3::new(origin.x, nan, origin.z), Vec3::NEG_Z, 0.0, inf),
        Ray::new(origin, Vec3::new(nan, 0.1, -1.0), 0.0, inf),
        Ray::new(origin, Vec3::new(0.0, -inf, -1.0), 0.0, inf),
        Ray::new(origin, Vec3::NEG_Z, 0.0, nan),
    ];
    let is_bad = |i: usize| i < 4 || i % 7 == 3;
    let rays: Vec<Ray> = (0..64)
        .map(|i| {
            if is_bad(i) {
                return bad[i % 4];
            }
            let (a, b) = (i as f32 * 0.05, i as f32 * 0.03);
            Ray::new(origin, Vec3::new(a.sin() * 0.3, b.cos() * 0.2 - 0.3, -1.0), 0.0, inf)
        })
        .collect();
    let packets: Vec<OmniPacket> = rays.chunks(4).map(|r| OmniPacket::new(RayPacket::new(r)).unwrap()).collect();
    let mut tracer = TileTracer::new(8).unwrap();
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = build(&scene, intersector);
        for (method, trace) in METHODS {
            tracer.load_packets(&packets).expect("the valid lanes share one origin");
            trace(&tree, &mut tracer, &mut NoCounters);
            for (i, ray) in rays.iter().enumerate() {
                let got = tracer.packet_hits()[i / 4].get(i % 4);
                if is_bad(i) {
                    assert_eq!(got, None, "ray {i} {method}");
                } else {
                    assert!(same_hit(&tree, ray, got, tree.intersect(ray)), "ray {i} {method}: {got:?}");
                }
            }
        }
    }
}

/// A hand-made camera with a NaN or infinite field has no cone, and no tile to trace.
#[test]
fn non_finite_cameras_have_no_cone() {
    let good = Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, 60.0, 16, 16).unwrap();
    let tile = tiles(16, 16, 8)[0];
    assert!(traverse::primary_cone(&good, &tile).is_ok());
    for camera in [
        Camera { eye: Vec3::new(f32::NAN, 1.0, 5.0), ..good },
        Camera { forward: Vec3::new(0.0, f32::INFINITY, -1.0), ..good },
        Camera { tan_half_fovy: f32::NAN, ..good },
    ] {
        let e = traverse::primary_cone(&camera, &tile).unwrap_err();
        assert!(matches!(e, cones::ConeError::NotFinite(_)), "{e:?}");
        assert!(TileTracer::new(8).unwrap().load_primary(&camera, &tile).is_err());
    }
}

/// A cone kernel at any packet width, by the tree's test.
fn wide_cone<V: SimdF32>(mft: bool, tree: &KdTree, tracer: &mut TileTracer<V>) {
    match (tree.intersector(), mft) {
        (Intersector::Wald, false) => traverse::trace_cone_wide_with::<WaldTest, V, _>(tree, tracer, &mut NoCounters),
        (Intersector::Wald, true) => {
            traverse::trace_mft_cone_wide_with::<WaldTest, V, _>(tree, tracer, &mut NoCounters)
        }
        (Intersector::Watertight, false) => {
            traverse::trace_cone_wide_with::<WatertightTest, V, _>(tree, tracer, &mut NoCounters)
        }
        (Intersector::Watertight, true) => {
            traverse::trace_mft_cone_wide_with::<WatertightTest, V, _>(tree, tracer, &mut NoCounters)
        }
    }
}

/// Hits as bits (`t`, `u`, `v`, triangle), so that answers compare bit for bit.
fn bits(hits: &[Option<kdtree::Hit>]) -> Vec<Option<[u32; 4]>> {
    hits.iter().map(|h| h.map(|h| [h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim])).collect()
}

/// Every tile of `camera`'s image at `size` with both cone kernels in packets of `V`,
/// culling on and off, closest and any hit: the 2x2 packets' hits bit for bit, and the
/// single rays' (by the oracle's rule; in any-hit mode exactly the blocked rays).
fn wide_cones_match<V: SimdF32>(tree: &KdTree, camera: &Camera, size: u32) -> usize {
    let (mut wide, mut narrow) = (TileTracer::<V>::with_size(size).unwrap(), TileTracer::new(size).unwrap());
    let mut hits = 0;
    for tile in tiles(camera.width, camera.height, size) {
        for (culling, any_hit) in [(true, false), (true, true), (false, false), (false, true)] {
            for (mft, (method, trace)) in [false, true].into_iter().zip(METHODS) {
                let what = format!("{method} at {} lanes, tile {tile:?}, culling {culling}, any {any_hit}", V::LANES);
                let (mut got, mut got4) = (vec![None; tile.pixel_count()], vec![None; tile.pixel_count()]);
                wide.set_culling(culling);
                wide.set_any_hit(any_hit);
                wide.load_primary(camera, &tile).unwrap();
                wide_cone(mft, tree, &mut wide);
                wide.write_hits(&mut got);
                narrow.set_culling(culling);
                narrow.set_any_hit(any_hit);
                narrow.load_primary(camera, &tile).unwrap();
                trace(tree, &mut narrow, &mut NoCounters);
                narrow.write_hits(&mut got4);
                assert_eq!(bits(&got), bits(&got4), "{what}: differs from 2x2 packets");
                for (i, (x, y)) in tile.pixels().enumerate() {
                    let (o, d) = camera.pixel_ray(x, y);
                    let ray = Ray::new(o, d, 0.0, f32::INFINITY);
                    if any_hit {
                        assert_eq!(got[i].is_some(), tree.occluded(&ray), "{what}: pixel ({x}, {y})");
                    } else {
                        let want = tree.intersect(&ray);
                        assert!(
                            same_hit(tree, &ray, got[i], want),
                            "{what}: pixel ({x}, {y}) {:?} vs {want:?}",
                            got[i]
                        );
                    }
                    hits += usize::from(got[i].is_some());
                }
            }
        }
    }
    hits
}

/// The cone kernels with the tile's packets 8 (4x2 pixels) and 16 rays (4x4) wide give the
/// 2x2 packets' hits bit for bit and the single rays', on built-in scenes with both
/// intersectors, at tile sizes 8, 16 and 32 (the image, 45 x 37, clips tiles at its right
/// and bottom edges), culling on and off, closest and any hit.
#[test]
fn wide_packets_under_cones_match_single_rays() {
    let cases: Vec<_> = ["atrium", "arena", "touching-boxes"]
        .into_iter()
        .flat_map(|name| [Intersector::Wald, Intersector::Watertight].map(|i| (name, i)))
        .collect();
    // The scenes and intersectors in parallel (the test's time, on CI's two cores).
    let hits: usize = cases
        .into_par_iter()
        .map(|(name, intersector)| {
            let scene = scenes::load_scene(name).unwrap();
            let tree = build(&scene, intersector);
            let camera = scene.default_view().camera(45, 37).unwrap();
            let mut hits = 0;
            for size in [8, 16, 32] {
                hits += wide_cones_match::<PortableF32<8>>(&tree, &camera, size);
                hits += wide_cones_match::<PortableF32<16>>(&tree, &camera, size);
            }
            hits
        })
        .sum();
    assert!(hits > 10_000, "{hits} hits compared");
}

/// Packets of 16 rays loaded from elsewhere in narrow and wide bundles (the cone of the
/// loaded rays, or the pyramid where none holds them), with non-finite lanes among them:
/// the cone kernels give those no hit and the others the single rays' hits.
#[test]
fn wide_loaded_packets_under_cones() {
    let (tree, origin) = arena_and_eye(Intersector::Watertight);
    let mut rnd = signed_rng(24681357);
    let mut tracer = TileTracer::<PortableF32<16>>::with_size(8).unwrap();
    let is_bad = |i: usize| i % 11 == 4;
    let mut checked = 0;
    for spread in [0.01f32, 0.3, 3.0] {
        for round in 0..8 {
            let axis = Vec3::new(rnd(), rnd(), rnd());
            let rays: Vec<Ray> = (0..64)
                .map(|i| {
                    let d = (axis + spread * Vec3::new(rnd(), rnd(), rnd())) * (1.0 + 4.0 * rnd().abs());
                    let d = if is_bad(i) { Vec3::new(f32::NAN, d.y, d.z) } else { d };
                    Ray::new(origin, d, 0.0, f32::INFINITY)
                })
                .collect();
            let packets: Vec<OmniPacket<PortableF32<16>>> =
                rays.chunks(16).map(|r| OmniPacket::new(RayPacket::from_rays(r)).unwrap()).collect();
            for mft in [false, true] {
                tracer.load_packets(&packets).unwrap();
                wide_cone(mft, &tree, &mut tracer);
                for (i, ray) in rays.iter().enumerate() {
                    let got = tracer.packet_hits()[i / 16].get(i % 16);
                    let what = format!("spread {spread} round {round} ray {i} mft {mft}");
                    if is_bad(i) {
                        assert_eq!(got, None, "{what}");
                    } else {
                        let want = tree.intersect(ray);
                        assert!(same_hit(&tree, ray, got, want), "{what}: {got:?} vs {want:?}");
                        checked += usize::from(want.is_some());
                    }
                }
            }
        }
    }
    assert!(checked > 500, "{checked} hits compared");
}
