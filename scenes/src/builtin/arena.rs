//! `arena`: a Quake III-like level of large polygons (the thesis's "Quake III" scene, 12.8k
//! triangles, Figure 4.1): a central hall with a raised platform, ramps, pillars, jump pads and
//! a ledge, four corridors to four side rooms with stairs up to balconies, crates and lamps.
//!
//! Most of its area is in a few big boxes (floors, walls, ceilings), which is what makes such
//! levels easy for kd-trees: large empty cells bounded by large polygons.

use glam::{Affine3A, Quat, Vec3};

use super::shapes::{MeshBuilder, Part, Rng, wall_boxes};
use super::stage::{lights_above, view};
use crate::Scene;

/// Half the width of the central hall.
const HALL: f32 = 16.0;
/// Hall height (floor at 0).
const HALL_HEIGHT: f32 = 12.0;
/// Wall thickness.
const WALL: f32 = 1.0;
/// Corridor length between the hall and a side room.
const CORRIDOR: f32 = 8.0;
/// Half the width of a corridor and of its doorways.
const DOOR: f32 = 2.0;
/// Doorway height.
const DOOR_HEIGHT: f32 = 5.0;
/// Half the size of a side room.
const ROOM: f32 = 8.0;
/// Side room height.
const ROOM_HEIGHT: f32 = 9.0;

/// The arena, about 12k triangles. Views `default` (from a corner of the hall), `platform`
/// (over the central platform) and `corridor` (from a side room through a corridor).
pub fn arena() -> Scene {
    let mut b = MeshBuilder::new();
    let mut rng = Rng::new(3);
    add_hall(&mut b);
    // The four corridors and side rooms, one per direction: the same layout rotated about Y.
    for quarter in 0..4 {
        let turn = Affine3A::from_quat(Quat::from_rotation_y(quarter as f32 * std::f32::consts::FRAC_PI_2));
        add_wing(&mut b, turn, &mut rng);
    }
    add_platform_and_ramps(&mut b);
    add_pillars_pads_and_lamps(&mut b);
    let (point_light, area_light) = lights_above(Vec3::new(0.0, 10.5, 0.0), 4.0, 160.0);
    Scene {
        name: "arena".to_string(),
        mesh: b.finish(),
        views: vec![
            view("default", Vec3::new(-14.0, 3.5, -5.0), Vec3::new(0.0, 2.0, 3.0), 75.0),
            view("platform", Vec3::new(2.0, 9.0, 12.0), Vec3::new(0.0, 1.5, 0.0), 70.0),
            view("corridor", Vec3::new(HALL + WALL + CORRIDOR + ROOM, 2.5, 0.5), Vec3::new(0.0, 3.0, 0.0), 60.0),
        ],
        point_light,
        area_light,
    }
}

/// Adds `part` moved by `m` (a rotation about Y, which keeps it outward).
fn add_at(b: &mut MeshBuilder, m: Affine3A, part: &Part, material: u32) {
    b.add(&part.transformed(m), material);
}

/// The hall: floor, walls with a doorway in each side, a ceiling with a skylight, a ledge.
fn add_hall(b: &mut MeshBuilder) {
    let floor = b.material("hall floor", Vec3::new(0.4, 0.38, 0.36));
    let wall = b.material("hall wall", Vec3::new(0.55, 0.45, 0.35));
    let ceiling = b.material("ceiling", Vec3::new(0.35, 0.35, 0.4));
    let ledge = b.material("ledge", Vec3::new(0.5, 0.5, 0.55));
    let outer = HALL + WALL;
    b.add_box(Vec3::new(-outer, -1.0, -outer), Vec3::new(outer, 0.0, outer), floor);
    // Ceiling around a 8 x 8 m skylight opening (the same splitter as walls, in the XZ plane).
    for (x0, x1, z0, z1) in wall_boxes((-outer, outer), (-outer, outer), &[(-4.0, 4.0, -4.0, 4.0)]) {
        b.add_box(Vec3::new(x0, HALL_HEIGHT, z0), Vec3::new(x1, HALL_HEIGHT + 1.0, z1), ceiling);
    }
    let doorway = [(-DOOR, DOOR, 0.0, DOOR_HEIGHT)];
    for quarter in 0..4 {
        let m = Affine3A::from_quat(Quat::from_rotation_y(quarter as f32 * std::f32::consts::FRAC_PI_2));
        // The +X wall, rotated into place; it spans z in [-HALL, HALL] (corners are filled by
        // the next wall's extra thickness).
        for (z0, z1, y0, y1) in wall_boxes((-HALL, HALL + WALL), (0.0, HALL_HEIGHT), &doorway) {
            add_at(b, m, &Part::cuboid(Vec3::new(HALL, y0, z0), Vec3::new(outer, y1, z1)), wall);
        }
        // A ledge along the wall at 5 m with a trim strip at the floor.
        add_at(b, m, &Part::cuboid(Vec3::new(HALL - 2.0, 5.0, DOOR + 1.0), Vec3::new(HALL, 5.4, HALL)), ledge);
        add_at(b, m, &Part::cuboid(Vec3::new(HALL - 0.2, 0.0, -HALL), Vec3::new(HALL, 0.4, -DOOR)), ledge);
    }
}

/// One corridor and side room on the +X side (to be rotated into place by `m`): corridor
/// floor, walls and ceiling, the room with a doorway, stairs to a balcony, and crates.
fn add_wing(b: &mut MeshBuilder, m: Affine3A, rng: &mut Rng) {
    let floor = b.material("corridor floor", Vec3::new(0.35, 0.33, 0.3));
    let wall = b.material("room wall", Vec3::new(0.45, 0.5, 0.6));
    let step = b.material("stairs", Vec3::new(0.6, 0.55, 0.45));
    let crate_m = b.material("crate", Vec3::new(0.6, 0.42, 0.2));
    let x0 = HALL + WALL;
    let x1 = x0 + CORRIDOR;
    // Corridor.
    add_at(b, m, &Part::cuboid(Vec3::new(x0, -1.0, -DOOR), Vec3::new(x1, 0.0, DOOR)), floor);
    add_at(
        b,
        m,
        &Part::cuboid(Vec3::new(x0, DOOR_HEIGHT, -DOOR - WALL), Vec3::new(x1, DOOR_HEIGHT + 1.0, DOOR + WALL)),
        wall,
    );
    for z in [-DOOR - WALL, DOOR] {
        add_at(b, m, &Part::cuboid(Vec3::new(x0, 0.0, z), Vec3::new(x1, DOOR_HEIGHT, z + WALL)), wall);
    }
    // Side room: floor, ceiling, three full walls and the wall with the doorway.
    let (r0, r1) = (x1, x1 + 2.0 * ROOM);
    add_at(b, m, &Part::cuboid(Vec3::new(r0, -1.0, -ROOM), Vec3::new(r1, 0.0, ROOM)), floor);
    add_at(b, m, &Part::cuboid(Vec3::new(r0, ROOM_HEIGHT, -ROOM), Vec3::new(r1, ROOM_HEIGHT + 1.0, ROOM)), wall);
    add_at(b, m, &Part::cuboid(Vec3::new(r1, 0.0, -ROOM), Vec3::new(r1 + WALL, ROOM_HEIGHT, ROOM)), wall);
    for z in [-ROOM - WALL, ROOM] {
        add_at(b, m, &Part::cuboid(Vec3::new(r0, 0.0, z), Vec3::new(r1 + WALL, ROOM_HEIGHT, z + WALL)), wall);
    }
    for (z0, z1, y0, y1) in wall_boxes((-ROOM, ROOM), (0.0, ROOM_HEIGHT), &[(-DOOR, DOOR, 0.0, DOOR_HEIGHT)]) {
        add_at(b, m, &Part::cuboid(Vec3::new(r0 - WALL, y0, z0), Vec3::new(r0, y1, z1)), wall);
    }
    // Stairs along the far wall up to a balcony at 4.5 m.
    let steps = 18;
    for i in 0..steps {
        let rise = 4.5 * (i + 1) as f32 / steps as f32;
        let z = -ROOM + 2.0 + 0.6 * i as f32;
        add_at(b, m, &Part::cuboid(Vec3::new(r1 - 2.5, 0.0, z), Vec3::new(r1, rise, z + 0.6)), step);
    }
    let balcony_z = -ROOM + 2.0 + 0.6 * steps as f32;
    add_at(b, m, &Part::cuboid(Vec3::new(r1 - 5.0, 4.2, balcony_z), Vec3::new(r1, 4.5, ROOM)), step);
    // Balcony railing posts.
    for i in 0..8 {
        let z = balcony_z + 0.2 + (ROOM - balcony_z - 0.6) * i as f32 / 7.0;
        add_at(b, m, &Part::prism(0.08, 0.08, 4.5, 5.5, 8, 1).translated(Vec3::new(r1 - 4.9, 0.0, z)), step);
    }
    // A ramp from the corridor floor up to a low dais in the room centre.
    let dais = Vec3::new(r0 + ROOM, 0.0, 2.0);
    add_at(b, m, &Part::prism(2.5, 2.5, 0.0, 0.8, 12, 1).translated(dais), step);
    add_at(
        b,
        m,
        &Part::wedge(3.0, 0.8, -1.0, 1.0).transformed(Affine3A::from_rotation_translation(
            Quat::from_rotation_y(std::f32::consts::PI),
            dais + Vec3::new(-2.4, 0.0, 0.0),
        )),
        step,
    );
    // Crates stacked in a corner, with deterministic jitter.
    for i in 0..6 {
        let size = rng.range(0.8, 1.4);
        let x = r0 + 1.0 + rng.range(0.0, 4.0);
        let z = ROOM - 1.0 - size - rng.range(0.0, 3.0);
        let y = if i >= 4 { 1.4 } else { 0.0 };
        add_at(b, m, &Part::cuboid(Vec3::new(x, y, z), Vec3::new(x + size, y + size, z + size)), crate_m);
    }
}

/// The central octagonal platform with four ramps up to it.
fn add_platform_and_ramps(b: &mut MeshBuilder) {
    let plat = b.material("platform", Vec3::new(0.5, 0.3, 0.25));
    let ramp = b.material("ramp", Vec3::new(0.55, 0.5, 0.3));
    b.add(&Part::prism(5.0, 4.6, 0.0, 1.5, 8, 1), plat);
    b.add(&Part::prism(2.0, 1.6, 1.5, 1.8, 24, 1), plat);
    // The wedges rise to 1.5 m at their x = 0 end, which is set just inside the middle of an
    // octagon edge, and run 5 m outwards.
    for quarter in 0..4 {
        let turn = Quat::from_rotation_y(quarter as f32 * std::f32::consts::FRAC_PI_2 + std::f32::consts::FRAC_PI_8);
        let m = Affine3A::from_rotation_translation(turn, turn * Vec3::new(4.3, 0.0, 0.0));
        add_at(b, m, &Part::wedge(5.0, 1.5, -1.2, 1.2), ramp);
    }
}

/// Pillars around the hall, jump pads and lamps on brackets.
fn add_pillars_pads_and_lamps(b: &mut MeshBuilder) {
    let pillar = b.material("pillar", Vec3::new(0.65, 0.6, 0.55));
    let pad = b.material("jump pad", Vec3::new(0.2, 0.5, 0.8));
    let lamp = b.material("lamp", Vec3::new(0.95, 0.85, 0.5));
    let bracket = b.material("bracket", Vec3::new(0.3, 0.3, 0.3));
    for (x, z) in [
        (-10.0, -10.0),
        (10.0, -10.0),
        (-10.0, 10.0),
        (10.0, 10.0),
        (-10.0, 0.0),
        (10.0, 0.0),
        (0.0, -10.0),
        (0.0, 10.0),
    ] {
        let at = Vec3::new(x, 0.0, z);
        b.add(&Part::cuboid(Vec3::new(x - 1.0, 0.0, z - 1.0), Vec3::new(x + 1.0, 0.6, z + 1.0)), pillar);
        b.add(&Part::prism(0.7, 0.6, 0.6, HALL_HEIGHT - 0.8, 24, 8).translated(at), pillar);
        b.add(&Part::prism(0.6, 0.95, HALL_HEIGHT - 0.8, HALL_HEIGHT, 24, 2).translated(at), pillar);
    }
    for (x, z) in [(-6.0, -6.0), (6.0, -6.0), (-6.0, 6.0), (6.0, 6.0)] {
        b.add(&Part::prism(1.2, 1.0, 0.0, 0.25, 32, 1).translated(Vec3::new(x, 0.0, z)), pad);
    }
    // Two lamps on each hall wall, each a sphere on a bracket.
    for quarter in 0..4 {
        let m = Affine3A::from_quat(Quat::from_rotation_y(quarter as f32 * std::f32::consts::FRAC_PI_2));
        for z in [-8.0, 8.0] {
            add_at(b, m, &Part::cuboid(Vec3::new(HALL - 1.0, 7.8, z - 0.15), Vec3::new(HALL, 8.1, z + 0.15)), bracket);
            add_at(b, m, &Part::icosphere(0.35, 2).translated(Vec3::new(HALL - 1.0, 8.4, z)), lamp);
        }
    }
}
