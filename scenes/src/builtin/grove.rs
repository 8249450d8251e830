//! `grove`: a garden of many small details, like the thesis's "Fairy" scene (174k triangles,
//! Figure 4.1): about 240 stylised plants (curved tapering stems as thin prisms, drooping
//! leaves as thin closed slabs) and 40 rocks (perturbed geodesic spheres) on a rolling ground.
//!
//! Unlike `atrium` and `arena`, most triangles are tiny and densely clustered, with large
//! empty space above them: the case where the surface area heuristic's empty-space cut-offs
//! matter most (thesis 3.2).

use glam::{Vec2, Vec3};

use super::shapes::{Frame, MeshBuilder, Part, Rng};
use super::stage::{lights_above, view};
use crate::Scene;

/// Half the side of the ground square.
const HALF: f32 = 20.0;
/// Grid cells per side of the ground.
const CELLS: u32 = 80;
/// Number of plants.
const PLANTS: u32 = 240;
/// Leaves per plant.
const LEAVES: u32 = 12;
/// Number of rocks.
const ROCKS: u32 = 40;

/// The grove, about 175k triangles. Views `default` (across the garden), `close` (among the
/// plants) and `top`.
pub fn grove() -> Scene {
    let mut b = MeshBuilder::new();
    let mut rng = Rng::new(174);
    let ground = b.material("ground", Vec3::new(0.35, 0.3, 0.18));
    b.add(&ground_part(), ground);
    let rock = b.material("rock", Vec3::new(0.5, 0.5, 0.48));
    for _ in 0..ROCKS {
        let (x, z) = (rng.range(-HALF + 2.0, HALF - 2.0), rng.range(-HALF + 2.0, HALF - 2.0));
        let size = rng.range(0.3, 1.2);
        b.add(&rock_part(&mut rng, Vec3::new(x, height(x, z) - 0.2 * size, z), size), rock);
    }
    let stem = b.material("stem", Vec3::new(0.2, 0.35, 0.1));
    let leaf_colours = [
        b.material("leaf light", Vec3::new(0.35, 0.65, 0.2)),
        b.material("leaf dark", Vec3::new(0.15, 0.45, 0.12)),
        b.material("leaf yellow", Vec3::new(0.6, 0.65, 0.2)),
    ];
    for i in 0..PLANTS {
        let (x, z) = (rng.range(-HALF + 1.0, HALF - 1.0), rng.range(-HALF + 1.0, HALF - 1.0));
        let leaf = leaf_colours[i as usize % leaf_colours.len()];
        add_plant(&mut b, &mut rng, Vec3::new(x, height(x, z) - 0.05, z), stem, leaf);
    }
    let (point_light, area_light) = lights_above(Vec3::new(4.0, 12.0, -3.0), 4.0, 200.0);
    Scene {
        name: "grove".to_string(),
        mesh: b.finish(),
        views: vec![
            view("default", Vec3::new(-10.0, 2.2, -9.0), Vec3::new(0.0, 0.5, 0.0), 60.0),
            view("close", Vec3::new(-3.0, 1.1, -3.5), Vec3::new(0.0, 0.6, 0.0), 60.0),
            view("top", Vec3::new(5.0, 32.0, 12.0), Vec3::ZERO, 60.0),
        ],
        point_light,
        area_light,
    }
}

/// The most copies [`grove_grid`] makes: 64 groves, 11.3 million triangles.
pub const MAX_GROVES: u32 = 64;

/// `grove-xN`: `n` copies of the [`grove`] side by side in a grid (`ceil(sqrt(n))` columns,
/// 44 m apart), flattened into one mesh of `n` x 176,320 triangles: a large scene for build
/// time and memory (issue 7: several million to ten million triangles). Copies share
/// nothing; triangle `i` of copy `c` is triangle `c * 176320 + i`. Views `default` (across
/// the grid from a corner), `close` (the grove's close view, in the first copy) and `top`.
/// `None` unless `1 <= n <= MAX_GROVES`.
pub fn grove_grid(n: u32) -> Option<Scene> {
    if !(1..=MAX_GROVES).contains(&n) {
        return None;
    }
    let one = grove();
    let cols = (n as f32).sqrt().ceil() as u32;
    let rows = n.div_ceil(cols);
    let spacing = 2.0 * HALF + 4.0;
    let m = &one.mesh;
    let (nv, nt) = (m.positions.len(), m.triangles.len());
    let mut mesh = crate::Mesh {
        positions: Vec::with_capacity(nv * n as usize),
        triangles: Vec::with_capacity(nt * n as usize),
        normals: None,
        material_ids: Vec::with_capacity(nt * n as usize),
        materials: m.materials.clone(),
        prim_ids: Vec::new(),
    };
    for c in 0..n {
        let offset = Vec3::new(spacing * (c % cols) as f32, 0.0, spacing * (c / cols) as f32);
        // At most 64 copies of ~100k vertices: far below 2^32, checked anyway.
        let base = u32::try_from(mesh.positions.len()).ok()?;
        mesh.positions.extend(m.positions.iter().map(|&p| p + offset));
        for t in &m.triangles {
            mesh.triangles.push([t[0].checked_add(base)?, t[1].checked_add(base)?, t[2].checked_add(base)?]);
        }
        mesh.material_ids.extend_from_slice(&m.material_ids);
    }
    mesh.prim_ids = (0..u32::try_from(mesh.triangles.len()).ok()?).collect();
    let far = Vec3::new(spacing * (cols as f32 - 0.5), 0.0, spacing * (rows as f32 - 0.5));
    let centre = 0.5 * far - Vec3::new(0.25 * spacing, 0.0, 0.25 * spacing);
    let size = far.length().max(spacing);
    let (point_light, area_light) =
        lights_above(centre + Vec3::new(4.0, 0.3 * size + 12.0, -3.0), 4.0, 200.0 * n as f32);
    let close = one.views.iter().find(|v| v.name == "close").cloned()?;
    Some(Scene {
        name: format!("grove-x{n}"),
        mesh,
        views: vec![
            view("default", Vec3::new(-0.5 * HALF, 0.08 * size + 2.0, -0.5 * HALF), centre, 60.0),
            close,
            view("top", centre + Vec3::new(5.0, 0.9 * size + 30.0, 12.0), centre, 60.0),
        ],
        point_light,
        area_light,
    })
}

/// The rolling ground's height at `(x, z)`.
fn height(x: f32, z: f32) -> f32 {
    0.4 * (0.3 * x).sin() * (0.25 * z).cos() + 0.2 * (0.7 * x + 0.4 * z).sin()
}

/// The ground: a `CELLS` x `CELLS` height-field grid closed into a 2 m deep solid.
fn ground_part() -> Part {
    let n = CELLS;
    let step = 2.0 * HALF / n as f32;
    let mut grid = Part::default();
    for i in 0..=n {
        for k in 0..=n {
            let (x, z) = (-HALF + step * i as f32, -HALF + step * k as f32);
            grid.positions.push(Vec3::new(x, height(x, z), z));
        }
    }
    let at = |i: u32, k: u32| i * (n + 1) + k;
    for i in 0..n {
        for k in 0..n {
            // Counter-clockwise seen from above.
            grid.triangles.push([at(i, k), at(i + 1, k + 1), at(i + 1, k)]);
            grid.triangles.push([at(i, k), at(i, k + 1), at(i + 1, k + 1)]);
        }
    }
    Part::close_downwards(&grid, -2.0)
}

/// A rock: a geodesic sphere with each vertex moved radially by up to 25%, flattened, sitting
/// at `at`.
fn rock_part(rng: &mut Rng, at: Vec3, size: f32) -> Part {
    let mut rock = Part::icosphere(1.0, 2);
    let squash = Vec3::new(size * rng.range(0.8, 1.2), size * rng.range(0.4, 0.7), size * rng.range(0.8, 1.2));
    for p in &mut rock.positions {
        *p = at + *p * rng.range(0.85, 1.1) * squash;
    }
    rock
}

/// A plant rooted at `root`: a curved tapering hexagonal stem and `LEAVES` drooping leaves
/// arranged in a spiral up it.
fn add_plant(b: &mut MeshBuilder, rng: &mut Rng, root: Vec3, stem_m: u32, leaf_m: u32) {
    let tall = rng.range(0.6, 1.6);
    let lean = Vec3::new(rng.range(-0.25, 0.25), 0.0, rng.range(-0.25, 0.25));
    let stem_at = |s: f32| root + Vec3::Y * (tall * s) + lean * (s * s);
    let stem_dir = |s: f32| Vec3::Y * tall + lean * (2.0 * s);
    let frames: Vec<Frame> = (0..=7)
        .map(|k| {
            let s = k as f32 / 7.0;
            let r = 0.03 - 0.018 * s;
            Frame::oriented(stem_at(s), stem_dir(s), Vec3::X, Vec2::splat(r))
        })
        .collect();
    b.add(&Part::sweep(&Part::circle(6), &frames), stem_m);

    let leaf_section = [Vec2::new(-0.5, -0.005), Vec2::new(0.5, -0.005), Vec2::new(0.5, 0.005), Vec2::new(-0.5, 0.005)];
    let phase = rng.range(0.0, std::f32::consts::TAU);
    for j in 0..LEAVES {
        let s = 0.25 + 0.7 * j as f32 / LEAVES as f32;
        let azimuth = phase + 2.4 * j as f32;
        let out = Vec3::new(azimuth.cos(), 0.0, azimuth.sin());
        let length = rng.range(0.2, 0.4) * (1.2 - 0.5 * s);
        let width = length * rng.range(0.25, 0.4);
        let base = stem_at(s) + out * 0.015;
        let frames: Vec<Frame> = (0..=5)
            .map(|k| {
                let t = k as f32 / 5.0;
                // Out and slightly up, then drooping.
                let origin = base + out * (length * t) + Vec3::Y * (length * (0.4 * t - 0.6 * t * t));
                let tangent = out + Vec3::Y * (0.4 - 1.2 * t);
                let w = width * (0.2 + 0.8 * (std::f32::consts::PI * (0.1 + 0.8 * t)).sin());
                Frame::oriented(origin, tangent, Vec3::Y, Vec2::new(w, 1.0))
            })
            .collect();
        b.add(&Part::sweep(&leaf_section, &frames), leaf_m);
    }
}
