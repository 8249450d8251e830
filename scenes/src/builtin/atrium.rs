//! `atrium`: a Sponza-like two-storey colonnaded courtyard (the thesis's "Sponza Atrium",
//! 67k triangles, Figure 4.1), its rotated variant and its subdivided versions.
//!
//! Layout (metres, Y up): the open courtyard runs along X between two arcades at z = +-4;
//! behind each arcade an ambulatory reaches the outer wall at |z| = 7.5, covered by the upper
//! gallery floor, which has its own arcade, balustrade and roof. Columns are tessellated round
//! shafts on plinths with moulded bases and capitals; arches are rectangular sections swept
//! along half circles; walls are boxes around window and door openings; banners hang from the
//! upper arches; the floor is tiled.

use glam::{Affine3A, EulerRot, Quat, Vec2, Vec3};

use super::shapes::{Frame, MeshBuilder, Part, wall_boxes};
use super::stage::{lights_above, view};
use crate::Scene;

/// Column centres along X (both arcades, both storeys).
const COLUMN_X: [f32; 8] = [-10.5, -7.5, -4.5, -1.5, 1.5, 4.5, 7.5, 10.5];
/// Half the courtyard width: the arcades stand at z = +-ARCADE_Z.
const ARCADE_Z: f32 = 4.0;
/// Inner face of the long outer walls.
const WALL_Z: f32 = 7.5;
/// Inner face of the end walls.
const WALL_X: f32 = 13.5;
/// Wall thickness.
const WALL_T: f32 = 0.5;
/// Top of the outer walls.
const WALL_TOP: f32 = 14.2;

/// Heights of one storey's column and arch.
struct Storey {
    /// Floor level.
    floor: f32,
    /// Shaft radius.
    radius: f32,
    /// Shaft height.
    shaft: f32,
}

/// The two storeys: ground floor and gallery.
const STOREYS: [Storey; 2] =
    [Storey { floor: 0.0, radius: 0.3, shaft: 3.8 }, Storey { floor: 7.6, radius: 0.22, shaft: 2.6 }];

/// The Sponza-like atrium, about 65k triangles. Views `default` (from one end of the courtyard
/// along it, like the classic Sponza view), `gallery` (from the upper gallery) and `top`.
pub fn atrium() -> Scene {
    let mut b = MeshBuilder::new();
    add_floor(&mut b);
    for storey in &STOREYS {
        for z in [-ARCADE_Z, ARCADE_Z] {
            add_arcade(&mut b, storey, z);
        }
    }
    add_gallery_floors_and_roofs(&mut b);
    add_walls(&mut b);
    add_balustrades(&mut b);
    add_banners(&mut b);
    let (point_light, mut area_light) = lights_above(Vec3::new(0.0, 9.0, 0.0), 3.0, 120.0);
    // The area light is a 6 x 3 m skylight over the courtyard.
    area_light.corner = Vec3::new(-3.0, 15.0, -1.5);
    area_light.edge_u = Vec3::new(6.0, 0.0, 0.0);
    area_light.edge_v = Vec3::new(0.0, 0.0, 3.0);
    area_light.intensity = Vec3::splat(250.0);
    Scene {
        name: "atrium".to_string(),
        mesh: b.finish(),
        views: vec![
            view("default", Vec3::new(-12.0, 2.5, 0.5), Vec3::new(0.0, 5.0, 0.0), 70.0),
            view("gallery", Vec3::new(-11.5, 9.3, 6.0), Vec3::new(4.0, 7.5, 1.0), 65.0),
            view("top", Vec3::new(3.0, 32.0, 10.0), Vec3::new(0.0, 0.0, 0.0), 60.0),
        ],
        point_light,
        area_light,
    }
}

/// The floor: a base slab under the whole building and 1 m tiles with thin joints on top.
fn add_floor(b: &mut MeshBuilder) {
    let slab = b.material("floor slab", Vec3::new(0.45, 0.42, 0.38));
    let light = b.material("floor tile light", Vec3::new(0.78, 0.74, 0.66));
    let dark = b.material("floor tile dark", Vec3::new(0.55, 0.5, 0.45));
    let outer = Vec3::new(WALL_X + WALL_T, 0.0, WALL_Z + WALL_T);
    b.add_box(Vec3::new(-outer.x, -0.5, -outer.z), Vec3::new(outer.x, -0.03, outer.z), slab);
    let (nx, nz) = (2 * WALL_X as i32, 2 * WALL_Z as i32);
    for i in 0..nx {
        for k in 0..nz {
            let x = -WALL_X + i as f32;
            let z = -WALL_Z + k as f32;
            let m = if (i + k) % 2 == 0 { light } else { dark };
            b.add_box(Vec3::new(x + 0.02, -0.03, z + 0.02), Vec3::new(x + 0.98, 0.0, z + 0.98), m);
        }
    }
}

/// One storey's row of columns at `z` with arches between them and a wall strip above.
fn add_arcade(b: &mut MeshBuilder, s: &Storey, z: f32) {
    let stone = b.material("column", Vec3::new(0.85, 0.8, 0.7));
    let trim = b.material("column base and capital", Vec3::new(0.7, 0.62, 0.5));
    let arch = b.material("arch", Vec3::new(0.8, 0.7, 0.55));
    let wall = b.material("arcade wall", Vec3::new(0.75, 0.68, 0.58));
    let r = s.radius;
    let y_base = s.floor + 0.25;
    let y_shaft = y_base + 0.3;
    let y_capital = y_shaft + s.shaft;
    let y_abacus = y_capital + 0.35;
    let spring = y_abacus + 0.18;
    for &x in &COLUMN_X {
        let at = Vec3::new(x, 0.0, z);
        let w = r * 1.6;
        b.add_box(Vec3::new(x - w, s.floor, z - w), Vec3::new(x + w, y_base, z + w), trim);
        b.add(&Part::prism(r * 1.4, r * 1.05, y_base, y_shaft, 32, 2).translated(at), trim);
        b.add(&Part::prism(r, r * 0.92, y_shaft, y_capital, 32, 12).translated(at), stone);
        b.add(&Part::prism(r * 0.92, r * 1.5, y_capital, y_abacus, 32, 2).translated(at), trim);
        let a = r * 1.7;
        b.add_box(Vec3::new(x - a, y_abacus, z - a), Vec3::new(x + a, spring, z + a), trim);
    }
    // Semicircular arches from abacus to abacus: a 0.45 x 0.7 m section swept over 24 steps.
    let radius = 0.5 * (COLUMN_X[1] - COLUMN_X[0]);
    let section = rectangle(0.45, 0.7);
    for pair in COLUMN_X.windows(2) {
        let centre = Vec3::new(0.5 * (pair[0] + pair[1]), spring, z);
        let frames: Vec<Frame> = (0..=24)
            .map(|k| {
                let a = std::f32::consts::PI * k as f32 / 24.0;
                let p = centre + radius * Vec3::new(-a.cos(), a.sin(), 0.0);
                Frame::oriented(p, Vec3::new(a.sin(), a.cos(), 0.0), Vec3::Z, Vec2::ONE)
            })
            .collect();
        b.add(&Part::sweep(&section, &frames), arch);
    }
    // The wall strip above the arches, up to the next floor (or the roof).
    let crown = spring + radius + 0.225;
    let x0 = COLUMN_X[0] - 1.0;
    let x1 = COLUMN_X[COLUMN_X.len() - 1] + 1.0;
    b.add_box(Vec3::new(x0, crown, z - 0.35), Vec3::new(x1, crown + 0.6, z + 0.35), wall);
    // Piers closing the arcade ends against the end walls.
    for (p0, p1) in [(-WALL_X, x0), (x1, WALL_X)] {
        b.add_box(Vec3::new(p0, s.floor, z - 0.35), Vec3::new(p1, crown + 0.6, z + 0.35), wall);
    }
}

/// A `width` x `depth` rectangle centred on the origin (counter-clockwise).
fn rectangle(width: f32, depth: f32) -> [Vec2; 4] {
    let (w, d) = (0.5 * width, 0.5 * depth);
    [Vec2::new(-w, -d), Vec2::new(w, -d), Vec2::new(w, d), Vec2::new(-w, d)]
}

/// The upper gallery floors over the ambulatories and the roofs over the upper galleries.
fn add_gallery_floors_and_roofs(b: &mut MeshBuilder) {
    let floor = b.material("gallery floor", Vec3::new(0.6, 0.55, 0.5));
    let roof = b.material("roof", Vec3::new(0.55, 0.35, 0.28));
    let gallery_floor = STOREYS[1].floor;
    for sign in [-1.0f32, 1.0] {
        let (z0, z1) = sorted(sign * (ARCADE_Z + 0.35), sign * WALL_Z);
        b.add_box(Vec3::new(-WALL_X, gallery_floor - 0.4, z0), Vec3::new(WALL_X, gallery_floor, z1), floor);
        b.add_box(Vec3::new(-WALL_X, 13.8, z0), Vec3::new(WALL_X, 14.2, z1), roof);
    }
}

/// `(a, b)` in increasing order.
fn sorted(a: f32, b: f32) -> (f32, f32) {
    if a <= b { (a, b) } else { (b, a) }
}

/// The outer walls with doors and windows, built from boxes around the openings.
fn add_walls(b: &mut MeshBuilder) {
    let wall = b.material("outer wall", Vec3::new(0.82, 0.76, 0.66));
    let sill = b.material("window sill", Vec3::new(0.6, 0.55, 0.5));
    // Long walls: a door or window in every ground-floor bay, a window in every upper bay.
    let mut long_openings = Vec::new();
    for (i, pair) in COLUMN_X.windows(2).enumerate() {
        let c = 0.5 * (pair[0] + pair[1]);
        if i % 3 == 0 {
            long_openings.push((c - 0.8, c + 0.8, 0.0, 3.2));
        } else {
            long_openings.push((c - 0.6, c + 0.6, 2.0, 4.4));
        }
        long_openings.push((c - 0.55, c + 0.55, 9.0, 11.6));
    }
    for sign in [-1.0f32, 1.0] {
        let (z0, z1) = sorted(sign * WALL_Z, sign * (WALL_Z + WALL_T));
        let span = (-WALL_X - WALL_T, WALL_X + WALL_T);
        for (u0, u1, y0, y1) in wall_boxes(span, (0.0, WALL_TOP), &long_openings) {
            b.add_box(Vec3::new(u0, y0, z0), Vec3::new(u1, y1, z1), wall);
        }
        for &(u0, u1, y0, _) in long_openings.iter().filter(|o| o.2 > 0.0) {
            let (s0, s1) = sorted(sign * (WALL_Z - 0.15), sign * WALL_Z);
            b.add_box(Vec3::new(u0 - 0.1, y0 - 0.12, s0), Vec3::new(u1 + 0.1, y0, s1), sill);
        }
    }
    // End walls: a central door, two ground windows and three upper windows.
    let end_openings = [
        (-1.2, 1.2, 0.0, 3.8),
        (-5.5, -4.3, 2.0, 4.5),
        (4.3, 5.5, 2.0, 4.5),
        (-5.5, -4.3, 9.0, 11.8),
        (-0.6, 0.6, 9.0, 12.0),
        (4.3, 5.5, 9.0, 11.8),
    ];
    for sign in [-1.0f32, 1.0] {
        let (x0, x1) = sorted(sign * WALL_X, sign * (WALL_X + WALL_T));
        for (u0, u1, y0, y1) in wall_boxes((-WALL_Z, WALL_Z), (0.0, WALL_TOP), &end_openings) {
            b.add_box(Vec3::new(x0, y0, u0), Vec3::new(x1, y1, u1), wall);
        }
    }
}

/// The gallery balustrades between the upper columns: base, rail and turned balusters.
fn add_balustrades(b: &mut MeshBuilder) {
    let stone = b.material("balustrade", Vec3::new(0.88, 0.85, 0.78));
    let y0 = STOREYS[1].floor;
    for z in [-ARCADE_Z, ARCADE_Z] {
        for pair in COLUMN_X.windows(2) {
            let (x0, x1) = (pair[0] + 0.45, pair[1] - 0.45);
            b.add_box(Vec3::new(x0, y0, z - 0.2), Vec3::new(x1, y0 + 0.12, z + 0.2), stone);
            b.add_box(Vec3::new(x0, y0 + 0.95, z - 0.2), Vec3::new(x1, y0 + 1.07, z + 0.2), stone);
            let count = 9;
            for i in 0..count {
                let x = x0 + (x1 - x0) * (i as f32 + 0.5) / count as f32;
                let at = Vec3::new(x, 0.0, z);
                b.add(&Part::prism(0.06, 0.09, y0 + 0.12, y0 + 0.5, 8, 2).translated(at), stone);
                b.add(&Part::prism(0.09, 0.05, y0 + 0.5, y0 + 0.95, 8, 2).translated(at), stone);
            }
        }
    }
}

/// Cloth banners hanging from the upper arches into the courtyard, gently waving.
fn add_banners(b: &mut MeshBuilder) {
    let colours = [
        ("banner red", Vec3::new(0.7, 0.12, 0.1)),
        ("banner green", Vec3::new(0.15, 0.5, 0.2)),
        ("banner blue", Vec3::new(0.15, 0.25, 0.65)),
    ];
    let top = STOREYS[1].floor + 0.25 + 0.3 + STOREYS[1].shaft + 0.35 + 0.18 + 1.2;
    let section = rectangle(1.1, 0.03);
    let mut i = 0;
    for z in [-ARCADE_Z + 0.5, ARCADE_Z - 0.5] {
        for pair in COLUMN_X.windows(2) {
            let (name, colour) = colours[i % colours.len()];
            i += 1;
            let m = b.material(name, colour);
            let x = 0.5 * (pair[0] + pair[1]);
            let inward = -z.signum();
            // Hanging down: the path runs along -Y; the cloth bulges towards the courtyard.
            let frames: Vec<Frame> = (0..=20)
                .map(|k| {
                    let t = k as f32 / 20.0;
                    let bulge = 0.25 * (t * std::f32::consts::PI).sin() + 0.05 * (t * 9.0 + x).sin();
                    let origin = Vec3::new(x, top - 4.2 * t, z + inward * bulge);
                    Frame::oriented(origin, Vec3::NEG_Y, Vec3::Z, Vec2::ONE)
                })
                .collect();
            b.add(&Part::sweep(&section, &frames), m);
        }
    }
}

/// The names of the atrium's floor tile materials, which only the tiles use (the slab under
/// them shows in the joints).
const FLOOR_TILES: [&str; 2] = ["floor tile light", "floor tile dark"];

/// `atrium-mirror`: `atrium` with polished, reflective floor tiles (`M_R`: reflectivity 0.5, a
/// specular highlight; their diffuse colours kept), for the secondary-ray pass (thesis 4.2.1,
/// chapter 6). The geometry, triangle order, material ids, views and lights are `atrium`'s;
/// only the tiles' two materials differ.
pub fn atrium_mirror() -> Scene {
    let mut scene = atrium();
    scene.name = "atrium-mirror".to_string();
    for m in scene.mesh.materials.iter_mut().filter(|m| FLOOR_TILES.contains(&m.name.as_str())) {
        m.reflectivity = 0.5;
        m.specular_blend = 0.5;
        m.specular_exponent = 80.0;
    }
    scene
}

/// The rotation of `atrium-rotated`: 17, 29 and 11 degrees about X, Y and Z, which leaves no
/// face of the atrium axis-aligned (the thesis's "Transformed Kitchen" idea, 4.1).
pub fn atrium_rotation() -> Quat {
    Quat::from_euler(EulerRot::XYZ, 17f32.to_radians(), 29f32.to_radians(), 11f32.to_radians())
}

/// `atrium` under [`atrium_rotation`] about the origin; its views and lights are rotated the
/// same way (the cameras keep +Y as their up direction).
pub fn atrium_rotated() -> Scene {
    let mut scene = atrium();
    let m = Affine3A::from_quat(atrium_rotation());
    scene.name = "atrium-rotated".to_string();
    for p in &mut scene.mesh.positions {
        *p = m.transform_point3(*p);
    }
    for v in &mut scene.views {
        v.eye = m.transform_point3(v.eye);
        v.target = m.transform_point3(v.target);
    }
    scene.point_light.position = m.transform_point3(scene.point_light.position);
    let area = &mut scene.area_light;
    area.corner = m.transform_point3(area.corner);
    area.edge_u = m.transform_vector3(area.edge_u);
    area.edge_v = m.transform_vector3(area.edge_v);
    scene
}

/// `atrium` with every triangle split `doublings` times by
/// [`Mesh::split_longest_edges`](crate::Mesh::split_longest_edges), i.e. `2^doublings` times
/// the triangles in the same shape, named `atrium-xN`, for build-scaling measurements
/// (thesis 3.3, O(N log N) builds). `doublings = 0` is `atrium` itself.
pub fn atrium_at_detail(doublings: u32) -> Scene {
    let mut scene = atrium();
    for _ in 0..doublings {
        scene.mesh = scene.mesh.split_longest_edges();
    }
    if doublings > 0 {
        scene.name = format!("atrium-x{}", 1u64 << doublings);
    }
    scene
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin::shapes::checks::open_edge;

    #[test]
    fn rotated_atrium_has_no_axis_aligned_face() {
        let scene = atrium_rotated();
        let mesh = &scene.mesh;
        let aligned =
            (0..mesh.triangle_count()).filter(|&i| mesh.geometric_normal(i).abs().max_element() > 1.0 - 1e-4).count();
        assert_eq!(aligned, 0);
        assert_eq!(scene.mesh.triangles, atrium().mesh.triangles);
        // The light stays inside the rotated courtyard: same distance to the rotated views.
        let plain = atrium();
        let d0 = plain.point_light.position.distance(plain.views[0].eye);
        let d1 = scene.point_light.position.distance(scene.views[0].eye);
        assert!((d0 - d1).abs() < 1e-4);
    }

    #[test]
    fn atrium_default_view_looks_along_the_courtyard() {
        let scene = atrium();
        let cam = scene.default_view().camera(64, 48).unwrap();
        assert!(cam.forward.x > 0.9);
        let (lo, hi) = scene.mesh.bounds().unwrap();
        assert!(cam.eye.cmpgt(lo).all() && cam.eye.cmplt(hi).all());
    }

    #[test]
    fn the_mirror_atrium_differs_only_in_its_floor_tiles() {
        use crate::Shader;
        let (plain, mirror) = (atrium(), atrium_mirror());
        assert_eq!(mirror.name, "atrium-mirror");
        let (a, b) = (&plain.mesh, &mirror.mesh);
        assert_eq!((&a.positions, &a.triangles, &a.prim_ids), (&b.positions, &b.triangles, &b.prim_ids));
        assert_eq!((&a.material_ids, &a.normals), (&b.material_ids, &b.normals));
        assert_eq!(
            (plain.views, plain.point_light, plain.area_light),
            (mirror.views, mirror.point_light, mirror.area_light)
        );
        assert_eq!(a.materials.len(), b.materials.len());
        let mut reflective = Vec::new();
        for (i, (m, n)) in a.materials.iter().zip(&b.materials).enumerate() {
            assert_eq!((&m.name, m.diffuse, m.shader()), (&n.name, n.diffuse, Shader::Diffuse));
            if n != m {
                assert_eq!(n.shader(), Shader::Reflective, "{}", n.name);
                reflective.push(i as u32);
            }
        }
        assert_eq!(reflective.len(), FLOOR_TILES.len());
        // The reflective materials are on the floor tiles alone: triangles at floor level.
        let mut tiles = 0;
        for (t, id) in b.material_ids.iter().enumerate() {
            if reflective.contains(id) {
                tiles += 1;
                assert!(b.triangle(t).iter().all(|p| (-0.031..=0.0).contains(&p.y)), "triangle {t}");
            }
        }
        assert_eq!(tiles, 12 * 2 * WALL_X as usize * 2 * WALL_Z as usize);
    }

    #[test]
    fn detail_levels_double_the_triangles() {
        let base = atrium().mesh.triangle_count();
        let x2 = atrium_at_detail(1);
        assert_eq!(x2.mesh.triangle_count(), 2 * base);
        assert_eq!(x2.name, "atrium-x2");
        x2.mesh.check().unwrap();
        assert_eq!(atrium_at_detail(0).mesh.triangle_count(), base);
        // Splitting keeps the shape: same bounds.
        assert_eq!(x2.mesh.bounds(), atrium().mesh.bounds());
        let _ = open_edge;
    }
}
