//! The renderer over bound methods: the frame against a per-pixel loop, soft and edge-width
//! shadows across kernels, reused buffers, cost images ([`trace::render`]).

use edgewidth::{LeakRemedies, occlusion_factor, width_from_light};
use kdtree::Counts;
use scenes::PointLight;
use trace::aov::{Attribution, Cost, PixelCost};
use trace::method::{Tracer, primary_ray};
use trace::registry::{Bound, Options, Registry, Structures};
use trace::render::{Renderer, Shadows};
use trace::setup::load_and_build;
use trace::shade;

/// The tiled, parallel passes give every pixel the answer of a plain per-pixel loop.
#[test]
fn frame_matches_a_per_pixel_loop() {
    let (scene, tree, _) = load_and_build("touching-boxes", &Default::default()).unwrap();
    let camera = scene.default_view().camera(37, 29).unwrap();
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let mono = bind(&registry, "mono", &structures);
    let renderer = Renderer::new(&scene, &mono, camera, Shadows::Hard);
    let surfaces = shade::surfaces(&scene.mesh);
    let mut buf = renderer.buffers();
    let stats = renderer.trace(&mut buf);
    let depth = renderer.depth(&buf);
    let prim = renderer.prim(&buf);
    let (mut hits, mut shadow_rays, mut blocked) = (0, 0, 0);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let ray = primary_ray(&camera, x, y);
            let hit = Tracer::intersect(&tree, &ray);
            let i = (y * camera.width + x) as usize;
            assert_eq!(depth.values[i], hit.map_or(f32::INFINITY, |h| h.t), "depth of ({x}, {y})");
            assert_eq!(prim.values[i], hit.map_or(-1.0, |h| scene.mesh.prim_ids[h.prim as usize] as f32));
            let Some(hit) = hit else { continue };
            hits += 1;
            if let Some(shadow) = shade::shadow_ray(&surfaces, &scene.point_light, ray.dir, &hit) {
                shadow_rays += 1;
                blocked += u64::from(Tracer::occluded(&tree, &shadow));
            }
        }
    }
    assert!(hits > 0 && shadow_rays > 0);
    assert_eq!((stats.hits, stats.shadow_rays, stats.occluded), (hits, shadow_rays, blocked));
    assert_eq!(stats.primary_rays, u64::from(camera.width * camera.height));
}

/// The display buffer is the shaded image as its PNG encodes it, packed.
#[test]
fn packed_colors_are_the_png_bytes() {
    let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
    let camera = scene.default_view().camera(45, 31).unwrap();
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let m = bind(&registry, "mft-8", &structures);
    let renderer = Renderer::new(&scene, &m, camera, Shadows::Hard);
    let mut buf = renderer.buffers();
    renderer.trace(&mut buf);
    let rgb = renderer.color(&buf).to_rgb8();
    let mut packed = vec![7; 3];
    renderer.color_packed(&buf, &mut packed);
    assert_eq!(packed.len(), 45 * 31);
    for (p, c) in packed.iter().zip(rgb.rgb.chunks_exact(3)) {
        assert_eq!(*p, u32::from(c[0]) << 16 | u32::from(c[1]) << 8 | u32::from(c[2]));
    }
    assert!(packed.iter().any(|&p| p != packed[0]));
}

/// Soft shadows: 16 rays per lit point, a penumbra, and the same visibility for every
/// soft-shadow kernel (single rays, pyramid, cone).
#[test]
fn soft_shadows_agree_across_kernels() {
    let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
    let camera = scene.default_view().camera(48, 32).unwrap();
    let light = trace::soft::scene_light(&scene, &tree, 2.0);
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let mut reference: Option<Vec<f32>> = None;
    for name in ["mono", "packet", "cone-8", "mft-16"] {
        let m = bind(&registry, name, &structures);
        let renderer = Renderer::new(&scene, &m, camera, Shadows::Soft16).with_light(light);
        let mut buf = renderer.buffers();
        let (stats, _, counts) = renderer.trace_counted(&mut buf);
        assert!(stats.shadow_rays > 0 && stats.shadow_rays % 16 == 0, "{name}");
        assert!(counts.nodes > 0, "{name}");
        let visible = renderer.layout().to_row_major(&buf.visible);
        assert!(visible.iter().any(|&v| v > 0.0 && v < 1.0), "{name}: no penumbra");
        match &reference {
            None => reference = Some(visible),
            Some(r) => assert_eq!(r, &visible, "{name}"),
        }
    }
}

/// Edge-width shadows: the same rays as hard shadows, so a pixel is fully lit exactly where
/// the hard shadow ray is unblocked; inside hard shadows the edge width gives a penumbra
/// (0 < visible < 1) somewhere; the same visibility whatever the primary method; and each
/// value is `1 - occlusion_factor` of the single-ray kernel's edge width.
#[test]
fn edge_width_shadows_darken_only_the_hard_shadows() {
    let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
    let camera = scene.default_view().camera(64, 48).unwrap();
    let light = trace::soft::scene_light(&scene, &tree, 2.0);
    let surfaces = shade::surfaces(&scene.mesh);
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let mut reference: Option<Vec<f32>> = None;
    for name in ["mono", "mft-8"] {
        let m = bind(&registry, name, &structures);
        let hard = Renderer::new(&scene, &m, camera, Shadows::Hard).with_light(light);
        let mut hard_buf = hard.buffers();
        let hard_stats = hard.trace(&mut hard_buf);
        let edge = Renderer::new(&scene, &m, camera, Shadows::EdgeWidth).with_light(light).with_tree(&tree);
        let mut buf = edge.buffers();
        let stats = edge.trace(&mut buf);
        assert_eq!((stats.shadow_rays, stats.occluded), (hard_stats.shadow_rays, hard_stats.occluded), "{name}");
        assert!(buf.occluded.iter().all(|&o| !o));
        let visible = edge.layout().to_row_major(&buf.visible);
        let hits = edge.layout().to_row_major(&buf.hits);
        let blocked = hard.layout().to_row_major(&hard_buf.occluded);
        let mut penumbra = 0;
        let mut scratch = edgewidth::EdgeScratch::default();
        for (i, (&v, hit)) in visible.iter().zip(&hits).enumerate() {
            let (x, y) = (i as u32 % camera.width, i as u32 / camera.width);
            let dir = camera.pixel_ray(x, y).1;
            let center = PointLight { position: light.center, intensity: light.intensity };
            let Some(ray) = hit.and_then(|h| shade::shadow_ray(&surfaces, &center, dir, &h)) else {
                assert_eq!(v, 0.0, "{name}: unlit pixel ({x}, {y})");
                continue;
            };
            let p = kdtree::ray::surface_point(&scene.mesh.triangle(hit.unwrap().prim as usize), &hit.unwrap());
            let r = width_from_light(light.radius, (light.center - p).length(), 1.0);
            let w = edgewidth::edge_width(&tree, &ray, r, &LeakRemedies::default(), &mut scratch);
            assert_eq!(v, 1.0 - occlusion_factor(w, r), "{name}: ({x}, {y})");
            assert_eq!(v == 1.0, !blocked[i], "{name}: ({x}, {y}) lit by edge widths iff by hard shadows");
            penumbra += usize::from(v > 0.0 && v < 1.0);
        }
        assert!(penumbra > 0, "{name}: no penumbra");
        match &reference {
            None => reference = Some(visible),
            Some(r) => assert_eq!(r, &visible, "{name}"),
        }
    }
}

/// Buffers reused from a frame with other shadows (as the viewer reuses them) give the
/// frame of fresh buffers: no visibility is left over from soft or edge-width shadows.
#[test]
fn reused_buffers_keep_nothing_from_other_shadows() {
    let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
    let camera = scene.default_view().camera(40, 30).unwrap();
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let m = bind(&registry, "mft-8", &structures);
    let modes = [Shadows::None, Shadows::Hard, Shadows::Soft16, Shadows::EdgeWidth];
    let renderer = |s| Renderer::new(&scene, &m, camera, s).with_tree(&tree);
    for before in modes {
        for after in modes {
            let mut reused = renderer(before).buffers();
            renderer(before).trace(&mut reused);
            renderer(after).trace(&mut reused);
            let mut fresh = renderer(after).buffers();
            renderer(after).trace(&mut fresh);
            let (a, b) = (renderer(after).color(&reused), renderer(after).color(&fresh));
            assert!(a.pixels == b.pixels, "{before:?} then {after:?}");
        }
    }
}

/// Summed over the image, each cost image gives the counters' totals of an ordinary
/// counted frame, for single rays (per pixel), 2x2 packets, frusta, MFT and cones (per
/// tile), on an image whose size is not a multiple of the tile.
#[test]
fn cost_images_sum_to_the_counters_totals() {
    let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
    let camera = scene.default_view().camera(53, 37).unwrap();
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    for name in ["mono", "packet", "samesign", "frustum-8", "mft-16", "cone-8", "mft-cone-16"] {
        let m = bind(&registry, name, &structures);
        let renderer = Renderer::new(&scene, &m, camera, Shadows::None);
        let mut buf = renderer.buffers();
        let (_, counted, _) = renderer.trace_counted(&mut buf);
        let expected_hits = buf.hits.clone();
        let frame = renderer.trace_costs(&mut buf);
        assert_eq!(buf.hits, expected_hits, "{name}: the cost pass traces the same hits");
        assert_eq!(frame.totals, counted, "{name}: the cost pass counts what a counted frame counts");
        assert!(counted.nodes > 0 && counted.tests > 0, "{name}");
        let expected = if name == "mono" { Attribution::Ray } else { Attribution::Tile };
        assert_eq!(frame.attribution, expected, "{name}");
        for cost in Cost::ALL {
            let total = cost.of(&counted) as f64;
            let sum = frame.sum(cost);
            assert!((sum - total).abs() <= 1e-6 * total.max(1.0), "{name} {}: {sum} vs {total}", cost.name());
            let image = frame.image(cost);
            assert_eq!(image.values.len(), (camera.width * camera.height) as usize);
            assert!(image.values.iter().all(|v| v.is_finite() && *v >= 0.0));
        }
        if name.starts_with("frustum") || name.starts_with("mft-16") {
            assert!(counted.culled > 0, "{name}: packet/leaf culling culls some packets");
        }
    }
}

/// Single rays: every pixel holds exactly its own ray's counts.
#[test]
fn single_ray_pixels_hold_their_own_ray() {
    let (scene, tree, _) = load_and_build("touching-boxes", &Default::default()).unwrap();
    let camera = scene.default_view().camera(19, 13).unwrap();
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let m = bind(&registry, "mono", &structures);
    let renderer = Renderer::new(&scene, &m, camera, Shadows::None);
    let frame = renderer.trace_costs(&mut renderer.buffers());
    for y in 0..camera.height {
        for x in 0..camera.width {
            let mut c = Counts::default();
            let ray = primary_ray(&camera, x, y);
            let _ = tree.intersect_counted(&ray, &mut c);
            let p = frame.pixels[(y * camera.width + x) as usize];
            assert_eq!(p, PixelCost::share(&c, 1), "({x}, {y})");
        }
    }
}

/// `name` selected with the default options and bound to `structures`.
fn bind<'s>(registry: &Registry, name: &str, structures: &'s Structures<'_>) -> Bound<'s> {
    registry.bind(&registry.select(name, Options::default()).unwrap(), structures).unwrap()
}
