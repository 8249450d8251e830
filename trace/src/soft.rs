//! The rays of 16-sample soft shadows to a spherical light (thesis Table 4.6): where a hit's
//! shadow rays start, the cone that holds them, and the light's size on a scene. The frame
//! driver's soft pass ([`crate::frame::soft_pass`]) traces them with each method's kernel, so
//! every tracer, baselines included, traces exactly these rays.

use cones::Cone;
use cones::shadows::sample_cone;
use glam::Vec3;
use kdtree::surface::Surfaces;
use kdtree::{Hit, KdTree};
use scenes::{Scene, SphereLight};

/// The diagonal of the Sponza atrium's bounding box, 41.59 units (the vertex bounds of the Dabrovic
/// model of `../shared/scenes/sponza-dabrovic.obj.gz`, whose units the thesis's light radii 1
/// and 2 are given in). A light radius `r` on another scene is `r * diagonal / SPONZA_DIAGONAL`.
pub const SPONZA_DIAGONAL: f32 = 41.59;

/// Light radius `r` in Sponza units scaled to a scene whose bounding box diagonal is `diag`.
pub fn scaled_radius(r: f32, diag: f32) -> f32 {
    r * diag / SPONZA_DIAGONAL
}

/// The shadow rays' origin and cone of the primary hit `hit`: the point moved off its
/// surface towards the light's centre. `None` when the light's centre is behind the surface
/// or the point is inside the light. Public so that other tracers (`rttest compare`) trace
/// exactly these rays.
pub fn shadow_start(surfaces: &Surfaces, light: &SphereLight, hit: &Hit, dir: Vec3) -> Option<(Vec3, Cone)> {
    let s = surfaces.get(hit.prim);
    let p = s.point(hit);
    let n = s.facing_normal(dir);
    let to_light = light.center - p;
    if n.dot(to_light) <= 0.0 {
        return None;
    }
    let start = s.offset_origin(p, to_light);
    Some((start, sample_cone(start, light)?))
}

/// The spherical light of soft shadows for `scene`: at its point light, radius `radius` in
/// Sponza units scaled by the diagonal of `tree`'s bounds ([`scaled_radius`]), as Table 4.6.
pub fn scene_light(scene: &Scene, tree: &KdTree, radius: f32) -> SphereLight {
    light_in_bounds(scene, tree.bounds().min, tree.bounds().max, radius)
}

/// The light of [`scene_light`] for a scene whose bounding box is `lo..hi`.
pub fn light_in_bounds(scene: &Scene, lo: Vec3, hi: Vec3, radius: f32) -> SphereLight {
    SphereLight {
        center: scene.point_light.position,
        radius: scaled_radius(radius, (hi - lo).length()),
        intensity: scene.point_light.intensity,
    }
}
