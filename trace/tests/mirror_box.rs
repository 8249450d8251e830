//! Secondary rays against a closed-form image: a small box seen in two parallel mirrors.
//!
//! Two mirrors face each other across `x = -1` and `x = +1`, and a diffuse marker box lies
//! between them. A ray reflected in a plane mirror is the straight ray continued into the
//! mirrored world ("unfolding"). So a pixel whose primary ray meets the mirror at `x = -1`
//! sees the marker in its reflection exactly when its straight ray meets the marker mirrored
//! in `x = -1` (x in `[-2 - hi, -2 - lo]`). After a second bounce off `x = +1`, it sees the
//! marker shifted by `-4` in `x`. The test renders with one and two generations of secondary
//! rays, with single rays and with packet, frustum and MFT methods, and checks every pixel
//! away from the marker's virtual silhouette against those boxes.

use glam::Vec3;
use kdtree::{BuildConfig, Intersector, KdTree};
use scenes::builtin::shapes::MeshBuilder;
use scenes::{Camera, Mesh, Scene};
use trace::render::{Renderer, Shadows};
use trace::{Options, Registry, Structures};

const MIRROR_A: u32 = 0;
const MIRROR_B: u32 = 1;
const MARKER: u32 = 2;
const MARKER_LO: Vec3 = Vec3::new(-0.2, -0.2, 1.8);
const MARKER_HI: Vec3 = Vec3::new(0.2, 0.2, 2.2);

fn scene() -> Scene {
    let mut b = MeshBuilder::new();
    let a = b.material("mirror-a", Vec3::splat(0.1));
    let m = b.material("mirror-b", Vec3::splat(0.1));
    let k = b.material("marker", Vec3::new(0.9, 0.2, 0.1));
    assert_eq!((a, m, k), (MIRROR_A, MIRROR_B, MARKER));
    b.add_box(Vec3::new(-1.1, -6.0, -6.0), Vec3::new(-1.0, 6.0, 6.0), a);
    b.add_box(Vec3::new(1.0, -6.0, -6.0), Vec3::new(1.1, 6.0, 6.0), m);
    b.add_box(MARKER_LO, MARKER_HI, k);
    let mut mesh: Mesh = b.finish();
    for i in [MIRROR_A, MIRROR_B] {
        mesh.materials[i as usize].reflectivity = 1.0;
    }
    mesh.check().unwrap();
    Scene::from_mesh("mirror-box", mesh)
}

/// Whether the ray `o + t d` (`t > 0`) meets the box `lo..hi` grown by `margin` on every side.
fn meets(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3, margin: f32) -> bool {
    let (lo, hi) = (lo - Vec3::splat(margin), hi + Vec3::splat(margin));
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    t0 <= t1
}

/// What the unfolded straight ray says about the marker: `Some(true)` it is seen, `Some(false)`
/// it is not, `None` too close to the virtual silhouette to tell.
fn expected(o: Vec3, d: Vec3, shift: Vec3, mirrored: bool) -> Option<bool> {
    let (mut lo, mut hi) = (MARKER_LO, MARKER_HI);
    if mirrored {
        (lo.x, hi.x) = (-2.0 - hi.x, -2.0 - lo.x);
    }
    let (lo, hi) = (lo + shift, hi + shift);
    let margin = 0.02;
    if meets(o, d, lo, hi, -margin) {
        Some(true)
    } else if !meets(o, d, lo, hi, margin) {
        Some(false)
    } else {
        None
    }
}

#[test]
fn a_box_between_two_mirrors_appears_where_the_unfolded_rays_say() {
    let scene = scene();
    let mesh = &scene.mesh;
    let camera = Camera::look_at(Vec3::new(0.6, 0.1, -2.0), Vec3::new(-1.0, 0.0, 1.0), 60.0, 96, 96).unwrap();
    let registry = Registry::ours();
    let material = |prim: u32| mesh.material_ids[prim as usize];
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig { intersector, ..Default::default() })
            .unwrap();
        let structures = Structures::new(&tree);
        for name in ["mono", "packet", "samesign", "mft-16", "frustum-8"] {
            let Ok(selected) = registry.select(name, Options::default()) else { panic!("{name}") };
            let method = registry.bind(&selected, &structures).unwrap();
            let renderer = Renderer::new(&scene, &method, camera, Shadows::Hard).with_tree(&tree).with_secondary(2);
            let mut buf = renderer.buffers();
            let stats = renderer.trace(&mut buf);
            assert!(stats.secondary_rays > 0 && buf.secondary.len() == 2, "{name}");
            let pixels: Vec<(u32, u32)> = renderer.layout().tiles().iter().flat_map(|t| t.pixels()).collect();
            let (mut seen, mut checked) = ([0usize; 2], [0usize; 2]);
            let (first, second) = (&buf.secondary[0], &buf.secondary[1]);
            // Generation 1: reflections of the mirror at x = -1 seen directly.
            for (i, (&pixel, hit)) in first.parent.iter().zip(&first.hits).enumerate() {
                let (o, d) = camera.pixel_ray(pixels[pixel as usize].0, pixels[pixel as usize].1);
                let primary = buf.hits[pixel as usize].unwrap();
                if material(primary.prim) != MIRROR_A || ((o + primary.t * d).x + 1.0).abs() > 1e-3 {
                    continue;
                }
                let got = hit.is_some_and(|h| material(h.prim) == MARKER);
                if let Some(want) = expected(o, d, Vec3::ZERO, true) {
                    assert_eq!(got, want, "{name} {intersector:?}: generation 1, pixel {:?}", pixels[pixel as usize]);
                    checked[0] += 1;
                    seen[0] += usize::from(want);
                }
                // Generation 2: those that went on to the mirror at x = +1.
                let Some(h1) = hit.filter(|h| material(h.prim) == MIRROR_B) else { continue };
                if (first.rays[i].origin + h1.t * first.rays[i].dir).x - 1.0 > 1e-3 {
                    continue;
                }
                let Some(j) = second.parent.iter().position(|&p| p as usize == i) else { continue };
                let got = second.hits[j].is_some_and(|h| material(h.prim) == MARKER);
                if let Some(want) = expected(o, d, Vec3::new(-4.0, 0.0, 0.0), false) {
                    assert_eq!(got, want, "{name} {intersector:?}: generation 2, pixel {:?}", pixels[pixel as usize]);
                    checked[1] += 1;
                    seen[1] += usize::from(want);
                }
            }
            // Not vacuous: both images of the marker cover pixels, and most pixels are judged.
            assert!(seen[0] >= 20 && seen[1] >= 10, "{name}: marker pixels {seen:?} of {checked:?}");
            assert!(checked[0] >= 1000 && checked[1] >= 500, "{name}: {checked:?}");
        }
    }
}

#[test]
fn depth_zero_traces_no_secondary_ray_and_keeps_the_image() {
    let scene = scene();
    let camera = Camera::look_at(Vec3::new(0.6, 0.1, -2.0), Vec3::new(-1.0, 0.0, 1.0), 60.0, 32, 32).unwrap();
    let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
    let structures = Structures::new(&tree);
    let registry = Registry::ours();
    let method = registry.bind(&registry.select("mono", Options::default()).unwrap(), &structures).unwrap();
    let plain = Renderer::new(&scene, &method, camera, Shadows::Hard);
    let zero = Renderer::new(&scene, &method, camera, Shadows::Hard).with_secondary(0);
    let one = Renderer::new(&scene, &method, camera, Shadows::Hard).with_secondary(1);
    let (mut a, mut b, mut c) = (plain.buffers(), zero.buffers(), one.buffers());
    plain.trace(&mut a);
    let stats = zero.trace(&mut b);
    assert_eq!((stats.secondary_rays, stats.spawn_secs, b.secondary.len()), (0, 0.0, 0));
    assert_eq!(plain.color(&a).pixels, zero.color(&b).pixels);
    // With one generation the mirrors show the marker: the image changes, stays finite.
    one.trace(&mut c);
    let (p0, p1) = (zero.color(&b).pixels, one.color(&c).pixels);
    assert!(p1.iter().all(|p| p.is_finite()));
    assert!(p0.iter().zip(&p1).filter(|(x, y)| x != y).count() > 100);
}
