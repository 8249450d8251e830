//! Small test scenes: a lone triangle, a cube, a sphere, two touching boxes and a triangle in
//! an axis plane (the flat case that a kd-tree split plane can coincide with, thesis 3.2).

use glam::Vec3;

use super::shapes::{MeshBuilder, Part};
use super::stage::{lights_above, view};
use crate::{Mesh, Scene};

/// A scene of `mesh` seen from `eye`, lit from above its bounds.
fn small_scene(name: &str, mesh: Mesh, eye: Vec3, target: Vec3) -> Scene {
    let (point_light, area_light) = lights_above(Vec3::new(0.8, 3.0, 1.5), 1.0, 12.0);
    Scene { name: name.to_string(), mesh, views: vec![view("default", eye, target, 45.0)], point_light, area_light }
}

/// One triangle facing +Z (not closed).
pub fn triangle() -> Scene {
    let mut b = MeshBuilder::new();
    let m = b.material("triangle", Vec3::new(0.8, 0.3, 0.2));
    let part = Part {
        positions: vec![Vec3::new(-1.0, -0.8, 0.0), Vec3::new(1.0, -0.8, 0.0), Vec3::new(0.0, 1.0, 0.0)],
        triangles: vec![[0, 1, 2]],
    };
    b.add(&part, m);
    small_scene("triangle", b.finish(), Vec3::new(0.6, 0.4, 3.5), Vec3::ZERO)
}

/// The cube `[-1, 1]^3` (12 triangles).
pub fn cube() -> Scene {
    let mut b = MeshBuilder::new();
    let m = b.material("cube", Vec3::new(0.3, 0.5, 0.8));
    b.add_box(Vec3::splat(-1.0), Vec3::splat(1.0), m);
    small_scene("cube", b.finish(), Vec3::new(3.0, 2.5, 4.0), Vec3::ZERO)
}

/// A unit geodesic sphere (1,280 triangles).
pub fn sphere() -> Scene {
    let mut b = MeshBuilder::new();
    let m = b.material("sphere", Vec3::new(0.8, 0.7, 0.3));
    b.add(&Part::icosphere(1.0, 3), m);
    small_scene("sphere", b.finish(), Vec3::new(0.5, 1.0, 3.5), Vec3::ZERO)
}

/// Two boxes touching along the plane x = 0, on a floor slab they also touch.
pub fn touching_boxes() -> Scene {
    let mut b = MeshBuilder::new();
    let left = b.material("left box", Vec3::new(0.8, 0.25, 0.2));
    let right = b.material("right box", Vec3::new(0.2, 0.6, 0.3));
    let floor = b.material("floor", Vec3::splat(0.7));
    b.add_box(Vec3::new(-1.0, 0.0, -0.5), Vec3::new(0.0, 1.0, 0.5), left);
    b.add_box(Vec3::new(0.0, 0.0, -0.4), Vec3::new(0.8, 0.7, 0.6), right);
    b.add_box(Vec3::new(-3.0, -0.2, -3.0), Vec3::new(3.0, 0.0, 3.0), floor);
    small_scene("touching-boxes", b.finish(), Vec3::new(1.5, 2.0, 3.5), Vec3::new(0.0, 0.4, 0.0))
}

/// A single triangle lying in the plane y = 0, facing +Y (not closed).
pub fn axis_plane_triangle() -> Scene {
    let mut b = MeshBuilder::new();
    let m = b.material("triangle", Vec3::new(0.3, 0.7, 0.4));
    let part = Part {
        positions: vec![Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0)],
        triangles: vec![[0, 1, 2]],
    };
    b.add(&part, m);
    small_scene("axis-plane-triangle", b.finish(), Vec3::new(0.5, 2.0, 2.5), Vec3::ZERO)
}
