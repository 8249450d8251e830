//! `garage`: two sports cars in a metal-clad garage, standing in for the thesis's secondary-ray
//! benchmark scene (Tsakok 2008, 6, Table 6.2 and Figure 6.1: "two Ferrari F40s within a
//! garage setting", 89 754 polygons, with perfect reflections on the metallic garage and cars,
//! glass windows and a light).
//!
//! Layout (metres, Y up, floor at y = 0): an 18 x 14 m room, 4.5 m high, closed on every side.
//! The floor and the back wall are brushed metal (`M_R`), steel beams cross under the
//! ceiling; the back wall has three glazed windows and the back right corner a glass-walled
//! office (`M_TR` panes, closed thin boxes). The two cars stand side by side, noses towards
//! the default view: each a low superellipsoid body in reflective paint, a superellipsoid
//! glass canopy, four tyres (tori) on chrome hubs, glass headlights, a rear wing. Shelves
//! with boxes, a workbench, a tool chest, oil drums and a stack of tyres are diffuse. A lamp
//! under the ceiling holds the lights.
//!
//! Most triangles (about 94 %) are in the cars' smooth curved surfaces, whose reflection and
//! refraction rays scatter incoherently: the case the benchmark measures.

use glam::{Affine3A, Quat, Vec3};

use super::shapes::{MeshBuilder, Part, Rng, wall_boxes};
use super::stage::{lights_above, view};
use crate::{Material, Scene};

/// Half the room's length (X).
const ROOM_X: f32 = 9.0;
/// Half the room's depth (Z).
const ROOM_Z: f32 = 7.0;
/// Ceiling height.
const HEIGHT: f32 = 4.5;
/// Wall, floor and ceiling thickness.
const WALL: f32 = 0.3;

/// The garage, about 90k triangles. Views `default` (both cars from the front, the glazed
/// back wall and the office behind them), `low` (between the cars, just above the metal
/// floor) and `corner` (from high in a front corner).
pub fn garage() -> Scene {
    let mut b = MeshBuilder::new();
    add_room(&mut b);
    add_office(&mut b);
    add_furniture(&mut b);
    let red = b.add_material(paint("car paint red", Vec3::new(0.7, 0.04, 0.03)));
    let yellow = b.add_material(paint("car paint yellow", Vec3::new(0.85, 0.62, 0.05)));
    let turn = |degrees: f32| Quat::from_rotation_y(degrees.to_radians());
    add_car(&mut b, Affine3A::from_rotation_translation(turn(-80.0), Vec3::new(-2.4, 0.0, -0.6)), red);
    add_car(&mut b, Affine3A::from_rotation_translation(turn(-103.0), Vec3::new(2.5, 0.0, -0.9)), yellow);
    let (point_light, area_light) = lights_above(Vec3::new(0.0, HEIGHT - 0.28, -0.5), 1.2, 40.0);
    Scene {
        name: "garage".to_string(),
        mesh: b.finish(),
        views: vec![
            view("default", Vec3::new(-0.9, 1.9, 5.6), Vec3::new(0.2, 0.7, -1.4), 60.0),
            view("low", Vec3::new(0.0, 0.45, 4.5), Vec3::new(0.0, 0.7, -3.0), 60.0),
            view("corner", Vec3::new(8.2, 4.0, 6.2), Vec3::new(0.0, 0.5, -1.0), 65.0),
        ],
        point_light,
        area_light,
    }
}

/// Reflective car paint (`M_R`).
fn paint(name: &str, diffuse: Vec3) -> Material {
    Material { specular_exponent: 80.0, specular_blend: 0.6, reflectivity: 0.35, ..Material::diffuse(name, diffuse) }
}

/// Brushed metal (`M_R`) reflecting `reflectivity` of the light.
fn metal(name: &str, diffuse: Vec3, reflectivity: f32) -> Material {
    Material { specular_exponent: 60.0, specular_blend: 0.5, reflectivity, ..Material::diffuse(name, diffuse) }
}

/// Clear glass (`M_TR`): mostly transmitting, index 1.5, a little reflection.
fn glass(name: &str) -> Material {
    Material {
        specular_exponent: 200.0,
        specular_blend: 0.8,
        reflectivity: 0.1,
        transparency: 0.8,
        ior: 1.5,
        ..Material::diffuse(name, Vec3::new(0.55, 0.65, 0.68))
    }
}

/// Floor, walls with the back windows and their panes, ceiling, beams and the lamp.
fn add_room(b: &mut MeshBuilder) {
    let floor = b.add_material(metal("garage floor", Vec3::new(0.36, 0.37, 0.4), 0.45));
    let panel = b.add_material(metal("garage wall panel", Vec3::new(0.55, 0.57, 0.6), 0.3));
    let wall = b.material("garage wall", Vec3::new(0.72, 0.72, 0.68));
    let ceiling = b.material("garage ceiling", Vec3::new(0.6, 0.6, 0.6));
    let beam = b.add_material(metal("steel beam", Vec3::new(0.3, 0.32, 0.35), 0.3));
    let line = b.material("parking line", Vec3::new(0.9, 0.75, 0.1));
    let lamp = b.material("lamp", Vec3::new(0.95, 0.95, 0.9));
    let pane = b.add_material(glass("window glass"));
    let (x1, z1) = (ROOM_X + WALL, ROOM_Z + WALL);
    b.add_box(Vec3::new(-x1, -WALL, -z1), Vec3::new(x1, 0.0, z1), floor);
    b.add_box(Vec3::new(-x1, HEIGHT, -z1), Vec3::new(x1, HEIGHT + WALL, z1), ceiling);
    // The back wall (metal panels) around three windows, each glazed with a pane in the
    // middle of the wall's thickness.
    let windows: Vec<(f32, f32, f32, f32)> = [-5.0, 0.0, 5.0].iter().map(|&x| (x - 1.3, x + 1.3, 1.4, 3.4)).collect();
    for (u0, u1, y0, y1) in wall_boxes((-ROOM_X, ROOM_X), (0.0, HEIGHT), &windows) {
        b.add_box(Vec3::new(u0, y0, -z1), Vec3::new(u1, y1, -ROOM_Z), panel);
    }
    for &(u0, u1, y0, y1) in &windows {
        let mid = -ROOM_Z - 0.5 * WALL;
        b.add_box(Vec3::new(u0, y0, mid - 0.02), Vec3::new(u1, y1, mid + 0.02), pane);
    }
    // The front wall, and the side walls (which close the corners).
    b.add_box(Vec3::new(-ROOM_X, 0.0, ROOM_Z), Vec3::new(ROOM_X, HEIGHT, z1), wall);
    for (x0, x1) in [(-x1, -ROOM_X), (ROOM_X, x1)] {
        b.add_box(Vec3::new(x0, 0.0, -z1), Vec3::new(x1, HEIGHT, z1), wall);
    }
    // Steel beams across the room under the ceiling, clear of the lamp.
    for z in [-4.2, 3.2] {
        b.add_box(Vec3::new(-ROOM_X, HEIGHT - 0.35, z - 0.12), Vec3::new(ROOM_X, HEIGHT, z + 0.12), beam);
    }
    // Parking bay lines, 5 mm high.
    for x in [-5.0, 0.0, 5.0] {
        b.add_box(Vec3::new(x - 0.06, 0.0, -3.8), Vec3::new(x + 0.06, 0.005, 2.6), line);
    }
    // The lamp: a panel on two rods from the ceiling, just above the lights.
    b.add_box(Vec3::new(-0.7, HEIGHT - 0.27, -1.1), Vec3::new(0.7, HEIGHT - 0.17, 0.1), lamp);
    for x in [-0.5, 0.5] {
        b.add_box(Vec3::new(x - 0.02, HEIGHT - 0.17, -0.52), Vec3::new(x + 0.02, HEIGHT, -0.48), beam);
    }
}

/// A glass-walled office in the back right corner, with a desk and a chair.
fn add_office(b: &mut MeshBuilder) {
    let pane = b.add_material(glass("office glass"));
    let frame = b.add_material(metal("office frame", Vec3::new(0.25, 0.25, 0.27), 0.2));
    let desk = b.material("desk", Vec3::new(0.55, 0.4, 0.25));
    let (x0, z0, top) = (5.2, -3.4, 2.6);
    // Two glass walls (the room's walls close the office), on metal sills, under a top rail.
    b.add_box(Vec3::new(x0, 0.06, z0 - 0.03), Vec3::new(ROOM_X, top, z0 + 0.03), pane);
    b.add_box(Vec3::new(x0 - 0.03, 0.06, -ROOM_Z), Vec3::new(x0 + 0.03, top, z0 - 0.03), pane);
    b.add_box(Vec3::new(x0 - 0.06, 0.0, z0 - 0.06), Vec3::new(ROOM_X, 0.06, z0 + 0.06), frame);
    b.add_box(Vec3::new(x0 - 0.06, 0.0, -ROOM_Z), Vec3::new(x0 + 0.06, 0.06, z0 - 0.06), frame);
    b.add_box(Vec3::new(x0 - 0.06, top, z0 - 0.06), Vec3::new(ROOM_X, top + 0.08, z0 + 0.06), frame);
    b.add_box(Vec3::new(x0 - 0.06, top, -ROOM_Z), Vec3::new(x0 + 0.06, top + 0.08, z0 - 0.06), frame);
    // The desk and its legs, a chair.
    b.add_box(Vec3::new(6.2, 0.72, -6.6), Vec3::new(8.6, 0.76, -5.6), desk);
    for (x, z) in [(6.3, -6.5), (8.5, -6.5), (6.3, -5.7), (8.5, -5.7)] {
        b.add_box(Vec3::new(x - 0.03, 0.0, z - 0.03), Vec3::new(x + 0.03, 0.72, z + 0.03), frame);
    }
    b.add_box(Vec3::new(7.1, 0.42, -5.3), Vec3::new(7.6, 0.47, -4.8), desk);
    b.add_box(Vec3::new(7.1, 0.47, -4.85), Vec3::new(7.6, 1.0, -4.8), desk);
    b.add(&Part::prism(0.04, 0.04, 0.0, 0.42, 8, 1).translated(Vec3::new(7.35, 0.0, -5.05)), frame);
}

/// Shelves with boxes on the left wall, a workbench and a tool chest by the back wall, oil
/// drums and a stack of tyres.
fn add_furniture(b: &mut MeshBuilder) {
    let steel = b.material("shelf steel", Vec3::new(0.35, 0.4, 0.45));
    let board = b.material("shelf board", Vec3::new(0.6, 0.5, 0.35));
    let cardboard = b.material("cardboard box", Vec3::new(0.62, 0.48, 0.3));
    let bench = b.material("workbench", Vec3::new(0.5, 0.36, 0.22));
    let chest = b.material("tool chest", Vec3::new(0.75, 0.1, 0.08));
    let handle = b.add_material(metal("chrome", Vec3::new(0.8, 0.8, 0.82), 0.8));
    let drum = b.material("oil drum", Vec3::new(0.1, 0.3, 0.55));
    let rubber = b.material("spare tyre", Vec3::new(0.06, 0.06, 0.06));
    let mut rng = Rng::new(29);
    // Two shelf units against the left wall: uprights, four boards, boxes on the boards.
    for z0 in [-5.5, -2.0] {
        let (x0, x1, z1) = (-ROOM_X, -ROOM_X + 0.6, z0 + 3.0);
        for z in [z0, z1 - 0.05] {
            b.add_box(Vec3::new(x0, 0.0, z), Vec3::new(x1, 2.4, z + 0.05), steel);
        }
        for k in 0..4 {
            let y = 0.15 + 0.7 * k as f32;
            b.add_box(Vec3::new(x0, y, z0 + 0.05), Vec3::new(x1, y + 0.04, z1 - 0.05), board);
            let mut z = z0 + 0.12;
            while z < z1 - 0.6 {
                let (w, h) = (rng.range(0.3, 0.55), rng.range(0.2, 0.5));
                let d = rng.range(0.3, 0.5);
                b.add_box(Vec3::new(x0 + 0.05, y + 0.04, z), Vec3::new(x0 + 0.05 + d, y + 0.04 + h, z + w), cardboard);
                z += w + rng.range(0.05, 0.2);
            }
        }
    }
    // The workbench at the back wall, left of the middle window, with a vice and a lamp.
    let (wx0, wx1, wz0, wz1) = (-4.2, -1.2, -ROOM_Z, -ROOM_Z + 0.8);
    b.add_box(Vec3::new(wx0, 0.86, wz0), Vec3::new(wx1, 0.92, wz1), bench);
    b.add_box(Vec3::new(wx0 + 0.1, 0.25, wz0 + 0.05), Vec3::new(wx1 - 0.1, 0.29, wz1 - 0.05), bench);
    for (x, z) in [(wx0 + 0.1, wz0 + 0.1), (wx1 - 0.1, wz0 + 0.1), (wx0 + 0.1, wz1 - 0.1), (wx1 - 0.1, wz1 - 0.1)] {
        b.add_box(Vec3::new(x - 0.04, 0.0, z - 0.04), Vec3::new(x + 0.04, 0.86, z + 0.04), steel);
    }
    b.add_box(Vec3::new(-1.8, 0.92, -6.5), Vec3::new(-1.5, 1.1, -6.3), steel);
    b.add(&Part::prism(0.02, 0.02, -0.2, 0.2, 8, 1).transformed(lying(Vec3::new(-1.65, 1.05, -6.2))), handle);
    // The tool chest: drawers are shallow boxes on its front, each with a chrome handle.
    let (cx0, cx1, cz0, cz1) = (-7.8, -6.4, -ROOM_Z, -ROOM_Z + 0.6);
    b.add_box(Vec3::new(cx0, 0.0, cz0), Vec3::new(cx1, 1.2, cz1), chest);
    for k in 0..5 {
        let y = 0.1 + 0.21 * k as f32;
        b.add_box(Vec3::new(cx0 + 0.05, y, cz1), Vec3::new(cx1 - 0.05, y + 0.18, cz1 + 0.02), chest);
        b.add_box(Vec3::new(-7.3, y + 0.07, cz1 + 0.02), Vec3::new(-6.9, y + 0.1, cz1 + 0.05), handle);
    }
    // Oil drums by the right wall in front of the office.
    for (x, z) in [(8.4, -2.6), (7.7, -2.5), (8.4, -1.9)] {
        b.add(&Part::prism(0.29, 0.29, 0.0, 0.88, 24, 3).translated(Vec3::new(x, 0.0, z)), drum);
    }
    // Spare tyres stacked in the front left corner.
    for k in 0..4 {
        let y = 0.11 + 0.21 * k as f32;
        b.add(&Part::torus(0.25, 0.1, 32, 12).translated(Vec3::new(-8.2, y, 5.8)), rubber);
    }
}

/// A placement that lays a Y-axis part on its side (axis along Z) with its centre at `at`.
fn lying(at: Vec3) -> Affine3A {
    Affine3A::from_rotation_translation(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2), at)
}

/// One car, built along +X (nose) with its width along Z on the floor at the origin, placed
/// by `placement` (a rotation about Y and a translation): body in `paint`, glass canopy and
/// headlights, tyres on chrome hubs, a rear wing, tail lights.
fn add_car(b: &mut MeshBuilder, placement: Affine3A, paint: u32) {
    let glass_m = b.add_material(glass("car glass"));
    let tyre = b.material("tyre", Vec3::new(0.05, 0.05, 0.05));
    let chrome = b.add_material(metal("chrome", Vec3::new(0.8, 0.8, 0.82), 0.8));
    let tail = b.material("tail light", Vec3::new(0.8, 0.05, 0.05));
    let mut add = |part: &Part, material: u32| b.add(&part.transformed(placement), material);
    // The body: a low rounded slab whose upper half falls from the rear deck to the nose.
    let mut body = Part::superellipsoid(Vec3::new(2.2, 0.36, 0.98), 0.6, 0.3, 160, 82);
    for p in &mut body.positions {
        if p.y > 0.0 {
            let t = (p.x / 2.2 + 1.0) * 0.5; // 0 at the tail, 1 at the nose
            p.y *= 1.0 - 0.4 * t * t;
        }
        p.y += 0.62;
    }
    add(&body, paint);
    // The canopy: a glass dome set into the body behind the middle.
    let canopy = Part::superellipsoid(Vec3::new(1.05, 0.36, 0.72), 0.7, 0.5, 96, 48);
    add(&canopy.translated(Vec3::new(-0.2, 0.9, 0.0)), glass_m);
    // Wheels: a tyre (torus) on a chrome hub (short cylinder), axles along Z.
    let tyre_part = Part::torus(0.24, 0.11, 48, 16);
    let hub = Part::prism(0.19, 0.19, -0.09, 0.09, 32, 1);
    for (x, z) in [(1.35, 0.9), (1.35, -0.9), (-1.35, 0.9), (-1.35, -0.9)] {
        let at = lying(Vec3::new(x, 0.36, z));
        add(&tyre_part.transformed(at), tyre);
        add(&hub.transformed(at), chrome);
    }
    // Headlights: glass spheres in the nose.
    for z in [-0.6, 0.6] {
        add(&Part::icosphere(0.09, 2).translated(Vec3::new(2.05, 0.6, z)), glass_m);
    }
    // The rear wing on two posts, and tail lights.
    add(&Part::cuboid(Vec3::new(-2.3, 1.02, -0.9), Vec3::new(-1.9, 1.07, 0.9)), paint);
    for z in [-0.6, 0.6] {
        add(&Part::cuboid(Vec3::new(-2.15, 0.85, z - 0.03), Vec3::new(-2.07, 1.02, z + 0.03)), paint);
        add(&Part::cuboid(Vec3::new(-2.22, 0.6, z - 0.15), Vec3::new(-2.1, 0.68, z + 0.15)), tail);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Shader;

    #[test]
    fn the_garage_has_the_benchmark_materials_and_most_triangles_in_the_cars() {
        let scene = garage();
        let mesh = &scene.mesh;
        let shader_of = |name: &str| mesh.materials.iter().find(|m| m.name == name).map(|m| m.shader());
        assert_eq!(shader_of("garage floor"), Some(Shader::Reflective));
        assert_eq!(shader_of("car paint red"), Some(Shader::Reflective));
        assert_eq!(shader_of("car glass"), Some(Shader::TransparentReflective));
        assert_eq!(shader_of("window glass"), Some(Shader::TransparentReflective));
        assert_eq!(shader_of("cardboard box"), Some(Shader::Diffuse));
        let in_car = |t: usize| {
            let name = &mesh.materials[mesh.material_ids[t] as usize].name;
            name.starts_with("car ") || name == "tyre" || name == "chrome" || name == "tail light"
        };
        let car_triangles = (0..mesh.triangle_count()).filter(|&t| in_car(t)).count();
        assert!(car_triangles * 10 > mesh.triangle_count() * 9, "{car_triangles} of {}", mesh.triangle_count());
        // The lights and every view are inside the room, below the ceiling.
        let inside = |p: Vec3| p.x.abs() < ROOM_X && p.z.abs() < ROOM_Z && p.y > 0.0 && p.y < HEIGHT;
        assert!(inside(scene.point_light.position) && inside(scene.area_light.center()));
        for v in &scene.views {
            assert!(inside(v.eye) && inside(v.target), "{}", v.name);
        }
    }

    #[test]
    fn the_default_view_sees_both_cars_and_glass() {
        let scene = garage();
        let mesh = &scene.mesh;
        let camera = scene.default_view().camera(64, 48).unwrap();
        // Project every car-paint and glass vertex: some of each car's paint and of the
        // glass fall inside the image.
        let mut seen = std::collections::HashSet::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let name = mesh.materials[mesh.material_ids[t] as usize].name.as_str();
            let p = mesh.positions[tri[0] as usize];
            let d = p - camera.eye;
            let z = d.dot(camera.forward);
            if z <= 0.0 {
                continue;
            }
            let (x, y) = (d.dot(camera.right) / z, d.dot(camera.up) / z);
            let half_h = camera.tan_half_fovy;
            if y.abs() < half_h && x.abs() < half_h * 64.0 / 48.0 {
                seen.insert(name);
            }
        }
        for name in ["car paint red", "car paint yellow", "car glass", "window glass", "office glass", "garage floor"] {
            assert!(seen.contains(name), "{name} not in the default view: {seen:?}");
        }
    }
}
