//! The cases the harness traces: built-in and shared scenes at their views, seeded and random
//! triangle soups, the named hard cases, and each case's ray stream.

use glam::Vec3;
use kdtree::{BuildConfig, KdTree, Ray};
use scenes::builtin::shapes::Rng;
use scenes::{Camera, Material, Mesh, Scene};
use trace::method::primary_ray;
use trace::secondary::ReflectFrom;

/// Uniform in `[-1, 1)`.
fn signed(rng: &mut Rng) -> f32 {
    rng.range(-1.0, 1.0)
}

/// A vector with components in `[-1, 1)`.
fn vec3(rng: &mut Rng) -> Vec3 {
    Vec3::new(signed(rng), signed(rng), signed(rng))
}

/// One scene with its cameras and ray stream.
#[derive(Clone, Debug)]
pub struct Case {
    /// What it is, for messages: `atrium`, `soup 3 x1e6`, ...
    pub name: String,
    /// The scene: mesh (triangle `i` is the tree's primitive `i`), point light.
    pub scene: Scene,
    /// The cameras, named.
    pub cameras: Vec<(String, Camera)>,
    /// The stream of [`ray_list`].
    pub rays: Vec<Ray>,
    /// Whether the single-ray twins are checked against the brute-force oracle here (small
    /// scenes: the oracle tests every triangle per ray).
    pub oracle: bool,
}

impl Case {
    /// A case of `scene` seen by `cameras`, its stream from the first camera
    /// ([`ray_list`], seeded by `seed`).
    pub fn new(name: impl Into<String>, scene: Scene, cameras: Vec<(String, Camera)>, oracle: bool, seed: u64) -> Case {
        let rays = ray_list(&scene, cameras.first().map(|c| &c.1), seed);
        Case { name: name.into(), scene, cameras, rays, oracle }
    }

    /// A case of `scene` at every view, `width` x `height`.
    pub fn views(name: impl Into<String>, scene: Scene, width: u32, height: u32, oracle: bool) -> Case {
        let cameras =
            scene.views.iter().filter_map(|v| Some((v.name.clone(), v.camera(width, height)?))).collect::<Vec<_>>();
        Case::new(name, scene, cameras, oracle, 7)
    }
}

/// A ray stream over `scene` (`camera`'s primary rays first, when given): every kind of ray
/// a stream may carry.
///
/// - the camera's rays, row by row: runs of one origin (packets, frusta, cones);
/// - the camera's mirror reflections, every surface taken as a mirror
///   (`trace::secondary::spawn`, the renderer's secondary rays), 2x2 blocks of pixels four
///   rays at a time: packets of neighbouring origins on surfaces (`packets::omni_lanes`);
/// - 300 rays from scattered origins in the scene's box, a third axis-parallel with `0.0` and
///   `-0.0` components, every fifth with a negative `t_min`, every seventh unbounded;
/// - 200 rays from points on triangles (origins on surfaces), in random directions;
/// - runs of 70 rays from one point (the box centre, then a point on a triangle) in the six
///   axis directions (with signed zeros) and random ones: runs longer than a frustum's 64.
pub fn ray_list(scene: &Scene, camera: Option<&Camera>, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let (lo, hi) = scene.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo).max(Vec3::splat(1e-3 * (hi - lo).max_element())));
    let diag = 2.0 * half.length();
    let mut rays: Vec<Ray> = Vec::new();
    if let Some(camera) = camera {
        for y in 0..camera.height {
            rays.extend((0..camera.width).map(|x| primary_ray(camera, x, y)));
        }
        rays.extend(reflections(scene, camera));
    }
    let nonzero = |d: Vec3| if d == Vec3::ZERO { Vec3::X } else { d };
    for i in 0..300 {
        let o = centre + vec3(&mut rng) * half * 1.2;
        let d = match i % 6 {
            0 => Vec3::new(signed(&mut rng), 0.0, -0.0),
            2 => Vec3::new(-0.0, 0.0, signed(&mut rng)),
            4 => Vec3::new(0.0, signed(&mut rng), -0.0),
            _ => vec3(&mut rng),
        };
        let t_min = if i % 5 == 0 { -0.3 * diag } else { 0.0 };
        let t_max = if i % 7 == 0 { f32::INFINITY } else { 1.5 * diag };
        rays.push(Ray::new(o, nonzero(d), t_min, t_max));
    }
    let tris = scene.mesh.triangle_count();
    let on_surface = |rng: &mut Rng| {
        if tris == 0 {
            return centre;
        }
        let t = scene.mesh.triangle((rng.next_u64() % tris as u64) as usize);
        let (u, v) = (0.5 * (signed(rng) + 1.0), 0.5 * (signed(rng) + 1.0));
        let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
        t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0])
    };
    for _ in 0..200 {
        let o = on_surface(&mut rng);
        rays.push(Ray::new(o, nonzero(vec3(&mut rng)), 0.0, f32::INFINITY));
    }
    for o in [centre, on_surface(&mut rng)] {
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::new(-0.0, 1.0, -0.0)];
        for i in 0..70 {
            let d = axes.get(i % 10).copied().unwrap_or_else(|| nonzero(vec3(&mut rng)));
            rays.push(Ray::new(o, d, 0.0, f32::INFINITY));
        }
    }
    rays
}

/// The mirror reflections of `camera`'s primary hits (single rays on a default tree), every
/// surface a perfect mirror, pixels in 2x2 blocks, alternately from the virtual eye and from
/// the surface.
fn reflections(scene: &Scene, camera: &Camera) -> Vec<Ray> {
    let mesh = &scene.mesh;
    let Ok(tree) = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig::default()) else { return Vec::new() };
    let surfaces = trace::shade::surfaces(mesh);
    let mirror = Material { reflectivity: 1.0, ..Material::default() };
    let mut out = Vec::new();
    for y0 in (0..camera.height).step_by(2) {
        for x0 in (0..camera.width).step_by(2) {
            for (x, y) in [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)] {
                if x >= camera.width || y >= camera.height {
                    continue;
                }
                let ray = primary_ray(camera, x, y);
                let Some(hit) = tree.intersect(&ray) else { continue };
                // Both starts, in blocks of 32 rays: from the virtual eye (runs of one origin
                // off flat mirrors, scattered eyes off curved ones) and from the surface.
                let from = if out.len() / 32 % 2 == 0 { ReflectFrom::VirtualEye } else { ReflectFrom::Surface };
                if let Some((r, _)) =
                    trace::secondary::spawn(surfaces.get(hit.prim), &mirror, ray.origin, ray.dir, &hit, from).reflection
                {
                    out.push(r);
                }
            }
        }
    }
    out
}

/// A scene of a triangle soup: one mesh vertex per corner, lights and a default view from
/// its bounds ([`Scene::from_mesh`]).
pub fn soup_scene(name: &str, tris: &[[Vec3; 3]]) -> Scene {
    let n = tris.len() as u32;
    let mesh = Mesh {
        positions: tris.iter().flatten().copied().collect(),
        triangles: (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
        normals: None,
        material_ids: vec![0; n as usize],
        materials: vec![Material::default()],
        prim_ids: (0..n).collect(),
    };
    Scene::from_mesh(name, mesh)
}

/// A random soup of `n` triangles in `[-1, 1]^3`: half its vertices on a grid of quarters
/// (shared vertices, triangles in axis planes), and flat triangles among them: collinear
/// corners, repeated corners, a zero-width sliver.
pub fn random_soup(seed: u64, n: usize) -> Vec<[Vec3; 3]> {
    let mut rng = Rng::new(seed);
    let vertex = |rng: &mut Rng| {
        let v = vec3(rng);
        if signed(rng) < 0.0 { (v * 4.0).round() * 0.25 } else { v }
    };
    (0..n)
        .map(|i| {
            let (a, b, c) = (vertex(&mut rng), vertex(&mut rng), vertex(&mut rng));
            match i % 11 {
                3 => [a, b, 0.5 * (a + b)],
                5 => [a, a, b],
                7 => [a, b, Vec3::new(a.x, b.y, a.z)],
                9 => [a, b, a + 1e-7 * (b - a)],
                _ => [a, b, c],
            }
        })
        .collect()
}

/// The scene moved: every position `p * scale + shift`, views and lights with it.
pub fn transformed(scene: &Scene, scale: f32, shift: Vec3) -> Scene {
    let mut out = scene.clone();
    let f = |p: Vec3| p * scale + shift;
    out.mesh.positions.iter_mut().for_each(|p| *p = f(*p));
    for v in &mut out.views {
        (v.eye, v.target) = (f(v.eye), f(v.target));
    }
    out.point_light.position = f(out.point_light.position);
    out
}

/// Every built-in scene but those of `skip`, at every view, `width` x `height`; the scenes
/// of `default_only` at their default view only.
pub fn builtin_cases(width: u32, height: u32, skip: &[&str], default_only: &[&str]) -> Vec<Case> {
    let names = scenes::builtin::NAMES.iter().filter(|n| !skip.contains(n));
    names
        .map(|&name| {
            let mut scene = scenes::load_scene(name).expect("built-in scene");
            if default_only.contains(&name) {
                scene.views.truncate(1);
            }
            let small = scene.mesh.triangle_count() <= 64;
            Case::views(name, scene, width, height, small)
        })
        .collect()
}

/// The scenes of the shared folder (`scenes::shared_scenes_dir`), each at its default view,
/// `width` x `height`; none when the folder is absent.
pub fn shared_cases(width: u32, height: u32) -> Vec<Case> {
    let files = scenes::shared_scene_files();
    files
        .iter()
        .map(|f| {
            let scene = scenes::load_scene(&f.to_string_lossy()).expect("shared scene loads");
            let camera = scene.default_view().camera(width, height).expect("finite view");
            Case::new(scene.name.clone(), scene, vec![("default".into(), camera)], false, 7)
        })
        .collect()
}

/// [`shared_cases`] for a test of the shared scenes: `None`, after a note on stderr, when the
/// folder is absent or holds no scene (the test is then skipped).
pub fn shared_cases_or_skip(width: u32, height: u32) -> Option<Vec<Case>> {
    let cases = shared_cases(width, height);
    if cases.is_empty() {
        eprintln!("no shared scenes folder: skipped");
        return None;
    }
    Some(cases)
}

/// Random soups (with flat triangles), each seen from outside and from inside with a
/// 150-degree field of view, checked against the oracle too.
pub fn soup_cases(count: u64) -> Vec<Case> {
    (0..count)
        .map(|seed| {
            let tris = random_soup(seed, 40 + 40 * seed as usize);
            let scene = soup_scene(&format!("soup {seed}"), &tris);
            let outside = scene.default_view().camera(23, 17).expect("finite soup");
            let inside = Camera::look_at(Vec3::new(0.05, 0.1, 0.02), Vec3::new(0.9, -0.2, 0.4), 150.0, 21, 15)
                .expect("a fixed camera");
            Case::new(
                format!("soup {seed}"),
                scene,
                vec![("outside".into(), outside), ("inside".into(), inside)],
                true,
                seed,
            )
        })
        .collect()
}

/// The named hard cases:
/// - the atrium seen from eyes exactly on split planes of its tree, looking along an axis
///   with an odd width so that the centre column lies in the plane (both children visited);
/// - tiny and huge coordinates: the arena scaled by 1e-3 and 1e3, a soup by 1e-6 and 1e6;
/// - far from the origin: the arena and a soup translated by 1e5 (the tree is built there).
///
/// (Rays with zero direction components, origins on surfaces and negative `t_min` are in
/// every case's stream; a camera in a triangle's axis plane is the built-in
/// `axis-plane-triangle`; flat triangles are in every soup.)
pub fn hard_cases() -> Vec<Case> {
    let mut out = Vec::new();
    let atrium = scenes::load_scene("atrium").expect("built-in scene");
    let tree = KdTree::build(&atrium.mesh.positions, &atrium.mesh.triangles, &BuildConfig::default())
        .expect("the atrium builds");
    let view = atrium.default_view();
    let mut cameras = Vec::new();
    for node in tree.nodes().iter().filter(|n| !n.is_leaf() && n.axis() != 1).take(4) {
        let axis = node.axis();
        let mut eye = view.eye;
        eye[axis] = node.split();
        let mut target = eye;
        target[2 - axis] += 10.0;
        let camera = Camera::look_at(eye, target, 70.0, 33, 21).expect("a level camera");
        assert_eq!(camera.pixel_ray(16, 10).1[axis], 0.0, "the centre ray lies in the split plane");
        cameras.push((format!("eye on split {axis} = {}", node.split()), camera));
    }
    out.push(Case::new("atrium, eyes on split planes", atrium, cameras, false, 11));
    let arena = scenes::load_scene("arena").expect("built-in scene");
    for (scale, shift) in [(1e-3, Vec3::ZERO), (1e3, Vec3::ZERO), (1.0, Vec3::splat(1e5))] {
        let scene = transformed(&arena, scale, shift);
        let camera = scene.default_view().camera(25, 19).expect("finite view");
        out.push(Case::new(format!("arena x{scale} + {shift}"), scene, vec![("default".into(), camera)], false, 12));
    }
    let soup = soup_scene("soup", &random_soup(99, 60));
    for (scale, shift) in [(1e-6, Vec3::ZERO), (1e6, Vec3::ZERO), (1.0, Vec3::new(1e5, -1e5, 1e5))] {
        let scene = transformed(&soup, scale, shift);
        let camera = scene.default_view().camera(19, 13).expect("finite view");
        out.push(Case::new(format!("soup x{scale} + {shift}"), scene, vec![("default".into(), camera)], true, 13));
    }
    out
}
