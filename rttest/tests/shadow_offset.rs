//! Shadow rays that start on a surface (issue 7): the one offset scheme
//! (`kdtree::ray::offset_origin`, used by `trace::shade::shadow_ray`) leaves no pixel shadowed
//! by its own surface and lets no light leak under contact points, on planes and spheres at
//! grazing light angles, at scene scales from 1e-3 to 1e5, near the origin and translated a
//! thousand times the scene's size away from it, with both triangle tests.
//!
//! Each pixel of a few cameras is traced; at its hit the shadow ray is made by the scheme
//! under test and traced. The answer is judged against the exact geometry in `f64`: the
//! blockers are convex (a thin plate and a sphere resting on the ground, and the ground is
//! never between a surface and a light above it), so the segment from the hit point to the
//! light is clipped against each blocker's face planes moved out, or in, by a margin of 1% of
//! the scene's size. A segment that misses every grown blocker must be lit (an occluded one
//! is *self-shadowed*); one that passes through a shrunk blocker must be shadowed (a lit one
//! *leaks*); the few in between are not judged. The plate is 5% of the scene's size thick,
//! so light leaking under its edge or under the sphere shows.
//!
//! The harness is checked too: without an offset it finds self-shadowed pixels, and with a
//! fixed offset of 0.01 (a common choice) it finds leaks at small scales and self-shadowing
//! at large ones.

use glam::{Affine3A, DVec3, Quat, Vec3};
use kdtree::surface::Surfaces;
use kdtree::{BuildConfig, Hit, Intersector, KdTree, Ray};
use scenes::builtin::shapes::{MeshBuilder, Part};
use scenes::{Camera, Mesh, PointLight};

/// How a shadow ray is made from a primary hit (with the mesh or its surface records).
type Spawn = fn(&Mesh, &Surfaces, &PointLight, Vec3, Vec3, &Hit) -> Option<Ray>;

/// A convex blocker: the object id (material) of its triangles and its face planes
/// `n . x <= d` (unit `n`, in `f64`).
struct Blocker {
    id: u32,
    planes: Vec<(DVec3, f64)>,
}

/// One test scene: a mesh whose material ids name its objects, its convex blockers, cameras
/// and point lights, and its size (the unit of the margin).
struct Setup {
    name: String,
    mesh: Mesh,
    blockers: Vec<Blocker>,
    cameras: Vec<Camera>,
    lights: Vec<Vec3>,
    size: f64,
}

/// A flat grid of `n` x `n` cells over `[-h, h]^2` in the XZ plane at y = 0, facing +Y, with
/// shared vertices (not closed: a plane).
fn grid(h: f32, n: u32) -> Part {
    let mut part = Part::default();
    for i in 0..=n {
        for k in 0..=n {
            let (x, z) = (-h + 2.0 * h * i as f32 / n as f32, -h + 2.0 * h * k as f32 / n as f32);
            part.positions.push(Vec3::new(x, 0.0, z));
        }
    }
    let at = |i: u32, k: u32| i * (n + 1) + k;
    for i in 0..n {
        for k in 0..n {
            part.triangles.push([at(i, k), at(i + 1, k + 1), at(i + 1, k)]);
            part.triangles.push([at(i, k), at(i, k + 1), at(i + 1, k + 1)]);
        }
    }
    part
}

/// The face planes of a closed convex part (outward winding), in `f64`.
fn planes_of(part: &Part) -> Vec<(DVec3, f64)> {
    part.triangles
        .iter()
        .map(|&[a, b, c]| {
            let [a, b, c] = [a, b, c].map(|i| part.positions[i as usize].as_dvec3());
            let n = (b - a).cross(c - a).normalize();
            (n, n.dot(a))
        })
        .collect()
}

/// A point light at elevation `elev` degrees above the plane with unit normal `up` through
/// `center`, at azimuth `azim` degrees around it, `dist` away.
fn light_at(center: Vec3, up: Vec3, elev: f32, azim: f32, dist: f32) -> Vec3 {
    let (u, v) = up.any_orthonormal_pair();
    let (e, a) = (elev.to_radians(), azim.to_radians());
    center + dist * (e.cos() * (a.cos() * u + a.sin() * v) + e.sin() * up)
}

/// The contact scene at scale `s`, moved by `t`: a ground grid, a plate (5% of `s` thick)
/// and a sphere (radius `s`) resting on it; lights at 2, 10 and 45 degrees.
fn contact(s: f32, t: Vec3) -> Setup {
    let place = Affine3A::from_translation(t) * Affine3A::from_scale(Vec3::splat(s));
    let ground = grid(6.0, 12).transformed(place);
    let plate = Part::cuboid(Vec3::new(-2.0, 0.0, -1.0), Vec3::new(-0.5, 0.05, 1.0)).transformed(place);
    let unit = Part::icosphere(1.0, 2);
    let lowest = unit.positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let sphere = unit.transformed(place * Affine3A::from_translation(Vec3::new(1.5, -lowest, 0.0)));
    let mut b = MeshBuilder::new();
    for (part, name) in [(&ground, "ground"), (&plate, "plate"), (&sphere, "sphere")] {
        let m = b.material(name, Vec3::ONE);
        b.add(part, m);
    }
    let center = t + s * Vec3::new(0.0, 0.3, 0.0);
    let cameras = [Vec3::new(2.0, 4.0, 7.0), Vec3::new(-3.0, 3.5, -6.5), Vec3::new(6.0, 1.5, 1.0)]
        .map(|e| Camera::look_at(t + s * e, center, 55.0, 40, 30).expect("camera"))
        .to_vec();
    let mut lights = Vec::new();
    for elev in [2.0, 10.0, 45.0] {
        for azim in [0.0, 140.0, 250.0] {
            lights.push(light_at(center, Vec3::Y, elev, azim, 40.0 * s));
        }
    }
    Setup {
        name: format!("contact, scale {s:e}, moved {t}"),
        mesh: b.finish(),
        blockers: vec![Blocker { id: 1, planes: planes_of(&plate) }, Blocker { id: 2, planes: planes_of(&sphere) }],
        cameras,
        lights,
        size: f64::from(s),
    }
}

/// A tilted plane at scale `s`, moved by `t`, lit at 0.1, 1 and 5 degrees above it: nothing
/// may be shadowed.
fn tilted(s: f32, t: Vec3) -> Setup {
    let rot = Quat::from_rotation_x(0.3) * Quat::from_rotation_z(0.55);
    let place = Affine3A::from_translation(t) * Affine3A::from_scale(Vec3::splat(s)) * Affine3A::from_quat(rot);
    let plane = grid(5.0, 10).transformed(place);
    let mut b = MeshBuilder::new();
    let m = b.material("plane", Vec3::ONE);
    b.add(&plane, m);
    let up = rot * Vec3::Y;
    let cameras = [Vec3::new(1.0, 6.0, 5.0), Vec3::new(-4.0, 5.0, -3.0)]
        .map(|e| Camera::look_at(t + s * (rot * e), t, 50.0, 40, 30).expect("camera"))
        .to_vec();
    let mut lights = Vec::new();
    for elev in [0.1, 1.0, 5.0] {
        for azim in [20.0, 200.0] {
            lights.push(light_at(t, up, elev, azim, 30.0 * s));
        }
    }
    Setup {
        name: format!("tilted plane, scale {s:e}, moved {t}"),
        mesh: b.finish(),
        blockers: vec![],
        cameras,
        lights,
        size: f64::from(s),
    }
}

/// The parameter interval of the segment `p -> q` inside the convex body `planes`, each
/// plane moved out by `m` (in if `m` is negative), if it is not empty.
fn clip_segment(p: DVec3, q: DVec3, planes: &[(DVec3, f64)], m: f64) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let d = q - p;
    for &(n, dist) in planes {
        let (num, den) = (dist + m - n.dot(p), n.dot(d));
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else if den > 0.0 {
            t1 = t1.min(num / den);
        } else {
            t0 = t0.max(num / den);
        }
        if t0 > t1 {
            return None;
        }
    }
    Some((t0, t1))
}

/// What the exact geometry says about the segment from `p` (on object `own`) to `light`.
#[derive(Debug, PartialEq)]
enum Expect {
    Lit,
    Shadowed,
    Unsure,
}

fn expect(setup: &Setup, p: DVec3, own: u32, light: DVec3, margin: f64) -> Expect {
    let mut unsure = false;
    for b in setup.blockers.iter().filter(|b| b.id != own) {
        if clip_segment(p, light, &b.planes, -margin).is_some() {
            return Expect::Shadowed;
        }
        unsure |= clip_segment(p, light, &b.planes, margin).is_some();
    }
    if unsure { Expect::Unsure } else { Expect::Lit }
}

/// Counts over a run: pixels judged lit and shadowed, and the wrong answers among them.
#[derive(Debug, Default, Clone, Copy)]
struct Tally {
    lit: usize,
    shadowed: usize,
    self_shadowed: usize,
    leaks: usize,
}

impl std::ops::AddAssign for Tally {
    fn add_assign(&mut self, o: Tally) {
        self.lit += o.lit;
        self.shadowed += o.shadowed;
        self.self_shadowed += o.self_shadowed;
        self.leaks += o.leaks;
    }
}

/// Traces every pixel of every camera and light of `setup` with `spawn` making the shadow
/// rays, on a tree built for `intersector`. A leak must also pass the watertight tree (so a
/// ray slipping through an edge of Wald's test is not blamed on the offset).
fn run(setup: &Setup, intersector: Intersector, spawn: Spawn) -> Tally {
    let mesh = &setup.mesh;
    let build =
        |i| KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig { intersector: i, ..Default::default() });
    let tree = build(intersector).expect("build");
    let watertight = build(Intersector::Watertight).expect("build");
    let margin = 0.01 * setup.size;
    let surfaces = trace::shade::surfaces(mesh);
    let mut tally = Tally::default();
    for &position in &setup.lights {
        let light = PointLight { position, intensity: Vec3::ONE };
        for camera in &setup.cameras {
            for y in 0..camera.height {
                for x in 0..camera.width {
                    let (origin, dir) = camera.pixel_ray(x, y);
                    let Some(hit) = tree.intersect(&Ray::new(origin, dir, 0.0, f32::INFINITY)) else { continue };
                    let Some(shadow) = spawn(mesh, &surfaces, &light, origin, dir, &hit) else { continue };
                    // The exact point of the hit, from its triangle and barycentrics.
                    let [a, b, c] = mesh.triangle(hit.prim as usize).map(|v| v.as_dvec3());
                    let p = a + f64::from(hit.u) * (b - a) + f64::from(hit.v) * (c - a);
                    let own = mesh.material_ids[hit.prim as usize];
                    match expect(setup, p, own, position.as_dvec3(), margin) {
                        Expect::Lit => {
                            tally.lit += 1;
                            tally.self_shadowed += usize::from(tree.occluded(&shadow));
                        }
                        Expect::Shadowed => {
                            tally.shadowed += 1;
                            tally.leaks += usize::from(!tree.occluded(&shadow) && !watertight.occluded(&shadow));
                        }
                        Expect::Unsure => {}
                    }
                }
            }
        }
    }
    tally
}

/// Scales 1e-3 to 1e5, each near the origin and moved 1000 times its size away.
fn setups() -> Vec<Setup> {
    let mut out = Vec::new();
    for s in [1e-3f32, 1e-1, 1e1, 1e3, 1e5] {
        for t in [Vec3::ZERO, 1e3 * s * Vec3::new(0.6, 0.45, -0.66)] {
            out.push(contact(s, t));
            out.push(tilted(s, t));
        }
    }
    out
}

#[test]
fn the_offset_scheme_neither_self_shadows_nor_leaks() {
    let mut total = Tally::default();
    let mut failures = Vec::new();
    for setup in setups() {
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let t = run(&setup, intersector, the_scheme);
            if t.self_shadowed + t.leaks > 0 {
                failures.push(format!("{} ({intersector:?}): {t:?}", setup.name));
            }
            total += t;
        }
    }
    println!("offset_origin: {total:?}");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(total.lit > 100_000 && total.shadowed > 10_000, "the scenes test enough pixels: {total:?}");
}

/// The workspace's scheme: `trace::shade::shadow_ray` (`kdtree::ray::offset_origin`).
fn the_scheme(_: &Mesh, surfaces: &Surfaces, light: &PointLight, _: Vec3, dir: Vec3, hit: &Hit) -> Option<Ray> {
    trace::shade::shadow_ray(surfaces, light, dir, hit)
}

/// The shadow ray from the hit point itself, no offset.
fn no_offset(mesh: &Mesh, _: &Surfaces, light: &PointLight, origin: Vec3, dir: Vec3, hit: &Hit) -> Option<Ray> {
    let n = trace::shade::facing_normal(mesh, hit, dir);
    let p = origin + hit.t * dir;
    let to_light = light.position - p;
    (n.dot(to_light) > 0.0).then(|| Ray::new(p, to_light, 0.0, 1.0))
}

/// The shadow ray from the hit point moved 0.01 along the normal, whatever the scale.
fn fixed_offset(mesh: &Mesh, _: &Surfaces, light: &PointLight, origin: Vec3, dir: Vec3, hit: &Hit) -> Option<Ray> {
    let n = trace::shade::facing_normal(mesh, hit, dir);
    let p = origin + hit.t * dir;
    let to_light = light.position - p;
    let start = p + 0.01 * n;
    (n.dot(to_light) > 0.0).then(|| Ray::new(start, light.position - start, 0.0, 1.0))
}

#[test]
fn the_harness_finds_self_shadowing_and_leaks_of_other_schemes() {
    let (mut none, mut fixed_small, mut fixed_large) = (Tally::default(), Tally::default(), Tally::default());
    for setup in setups() {
        none += run(&setup, Intersector::Watertight, no_offset);
        if setup.size < 1.0 {
            fixed_small += run(&setup, Intersector::Watertight, fixed_offset);
        } else if setup.size > 1e3 {
            fixed_large += run(&setup, Intersector::Watertight, fixed_offset);
        }
    }
    println!("no offset: {none:?}\nfixed 0.01, scales < 1: {fixed_small:?}\nfixed 0.01, scales > 1e3: {fixed_large:?}");
    assert!(none.self_shadowed > 0, "no offset: {none:?}");
    assert!(fixed_small.leaks > 0, "fixed offset at small scales: {fixed_small:?}");
    assert!(fixed_large.self_shadowed > 0, "fixed offset at large scales: {fixed_large:?}");
}
