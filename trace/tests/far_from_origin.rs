//! Numerical stability far from the origin: a closed sphere 1e3, 1e5 and 1e6 units out seen
//! from 15 units away, and a large ground plane under a camera 1e5 units out. Every method of
//! the registry, with both triangle tests, must give on every pixel off a silhouette a depth
//! within `1e-5 x distance + 4 ulps of the coordinates` of the exact one (the nearest
//! triangle in `f64`). Before vertex `a` was stored in Wald's record (see
//! `kdtree::triangle::WaldTriangle`), the default test lost the sphere 1e5 units out on
//! hundreds of pixels, up to 19 units deep.

use glam::{DVec3, Vec3};
use kdtree::{BuildConfig, Intersector, KdTree};
use scenes::builtin::shapes::{MeshBuilder, Part};
use scenes::{Camera, Mesh};
use trace::{Options, Registry, Structures, TileLayout};

/// The distance to the nearest triangle of `mesh` along the ray, in `f64` (Moller-Trumbore
/// with no tolerance; ties do not matter for a depth).
fn exact_depth(mesh: &Mesh, o: DVec3, d: DVec3) -> Option<f64> {
    let mut best: Option<f64> = None;
    for tri in &mesh.triangles {
        let [a, b, c] = tri.map(|i| mesh.positions[i as usize].as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            continue;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    }
    best
}

/// Pixels off far from the exact depth, for every registered method, on `mesh` seen by
/// `camera`: (method, intersector, pixels off, worst error).
fn errors(mesh: &Mesh, camera: &Camera) -> Vec<(String, Intersector, usize, f64)> {
    let (w, h) = (camera.width, camera.height);
    let exact: Vec<Option<f64>> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (o, d) = camera.pixel_ray(x, y);
            exact_depth(mesh, o.as_dvec3(), d.as_dvec3())
        })
        .collect();
    // Off a silhouette: the pixel and its eight neighbours all hit.
    let interior = |x: u32, y: u32| {
        (x.saturating_sub(1)..=(x + 1).min(w - 1))
            .all(|i| (y.saturating_sub(1)..=(y + 1).min(h - 1)).all(|j| exact[(j * w + i) as usize].is_some()))
    };
    let far = mesh.positions.iter().fold(camera.eye.abs().max_element(), |m, p| m.max(p.abs().max_element()));
    let ulp = f64::from(far) * f64::from(f32::EPSILON);
    let registry = Registry::ours();
    let mut out = Vec::new();
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig { intersector, ..Default::default() })
            .unwrap();
        let mut structures = Structures::new(&tree);
        let scene = scenes::Scene::from_mesh("far", mesh.clone());
        registry.build_structures(&scene, &mut structures).unwrap();
        for name in registry.names(&[8, 16]) {
            let m = registry.bind(&registry.select(&name, Options::default()).unwrap(), &structures).unwrap();
            let layout = TileLayout::new(w, h, m.options.tile);
            let mut hits = vec![None; layout.pixel_count()];
            m.tracer.primary(&layout, camera, &mut hits, None);
            let hits = layout.to_row_major(&hits);
            let (mut off, mut worst) = (0, 0.0f64);
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    let Some(want) = exact[i].filter(|_| interior(x, y)) else { continue };
                    let err = hits[i].map_or(f64::INFINITY, |h| (f64::from(h.t) - want).abs());
                    if err > 1e-5 * want + 4.0 * ulp {
                        off += 1;
                        worst = worst.max(err);
                    }
                }
            }
            out.push((name, intersector, off, worst));
        }
    }
    out
}

/// The failures of `mesh` seen by `camera`, described (empty when stable); prints a summary.
fn unstable(what: &str, mesh: &Mesh, camera: &Camera) -> Option<String> {
    let errors = errors(mesh, camera);
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let of = errors.iter().filter(|e| e.1 == intersector);
        let (off, worst) = of.fold((0, 0.0f64), |a, e| (a.0.max(e.2), a.1.max(e.3)));
        eprintln!("{what}, {intersector:?}: at most {off} pixels off per method, worst error {worst:.3e}");
    }
    let bad: Vec<_> = errors.iter().filter(|e| e.2 > 0).collect();
    (!bad.is_empty()).then(|| format!("{what}: pixels off the exact depth (method, test, pixels, worst): {bad:?}"))
}

/// A closed sphere of radius 5, 1e3, 1e5 and 1e6 units out along (1, 1, 1), seen from 15
/// units away.
#[test]
fn a_sphere_far_from_the_origin() {
    let mut failures = Vec::new();
    for offset in [1e3f32, 1e5, 1e6] {
        let centre = Vec3::splat(offset);
        let mut b = MeshBuilder::new();
        let m = b.material("sphere", Vec3::ONE);
        b.add(&Part::icosphere(5.0, 4), m);
        let mut mesh = b.finish();
        mesh.positions.iter_mut().for_each(|p| *p += centre);
        let camera = Camera::look_at(centre + Vec3::new(4.0, 3.0, 15.0), centre, 45.0, 64, 64).unwrap();
        failures.extend(unstable(&format!("sphere at {offset}"), &mesh, &camera));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A ground plane 2,000 units wide, gently sloped (no axis-aligned normal), under a camera 2
/// units above it, 1e5 units out, looking across it to the horizon.
#[test]
fn a_ground_plane_under_a_camera_far_out() {
    let c = Vec3::new(1e5, 0.0, 1e5);
    let s = 1000.0;
    let ground = |x: f32, z: f32| c + Vec3::new(x, 0.02 * x + 0.03 * z, z);
    let mesh = Mesh {
        positions: vec![ground(-s, -s), ground(s, -s), ground(s, s), ground(-s, s)],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
        normals: None,
        material_ids: vec![0, 0],
        materials: vec![scenes::Material::default()],
        prim_ids: vec![0, 1],
    };
    let eye = ground(0.3, 0.7) + Vec3::new(0.0, 2.0, 0.0);
    // Towards the horizon: grazing rays meet the plane hundreds of units away.
    let camera = Camera::look_at(eye, ground(300.0, -400.0), 60.0, 64, 48).unwrap();
    let failure = unstable("ground plane at 1e5", &mesh, &camera);
    assert!(failure.is_none(), "{failure:?}");
}
