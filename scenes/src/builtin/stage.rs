//! The stage of the built-in scenes: their named views and their lights.
//!
//! The generators (`arena`, `atrium`, `grove`, `small`) share these helpers from here, a
//! sibling, rather than from `builtin/mod.rs`, which calls the generators: so no built-in
//! file imports the module that imports it.

use glam::{Vec2, Vec3};

use crate::{PointLight, RectLight, View};

/// A named view.
pub(super) fn view(name: &str, eye: Vec3, target: Vec3, fovy_deg: f32) -> View {
    View { name: name.to_string(), eye, target, fovy_deg }
}

/// A point light at `position` and a downward-facing square area light of side `size`
/// centred on it, both with `intensity` (inverse-square, so about `intensity / d^2` at
/// distance `d`).
pub(super) fn lights_above(position: Vec3, size: f32, intensity: f32) -> (PointLight, RectLight) {
    let half = Vec2::splat(0.5 * size);
    let point = PointLight { position, intensity: Vec3::splat(intensity) };
    let area = RectLight {
        corner: position - Vec3::new(half.x, 0.0, half.y),
        // edge_u x edge_v points down (-Y).
        edge_u: Vec3::new(size, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, size),
        intensity: Vec3::splat(intensity),
    };
    (point, area)
}
