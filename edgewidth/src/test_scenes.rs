//! Scenes for the crate's tests: trees over boxes, spheres and loose triangles, built once per
//! ray-triangle test, a floor, and a square light.

use glam::Vec3;
use kdtree::{BuildConfig, Intersector, KdTree};
use scenes::RectLight;
use scenes::builtin::shapes::{MeshBuilder, Part};

use crate::sampling::AreaLight;

/// A tree over `parts` (closed boxes and spheres) and `open` (loose triangles), one per
/// ray-triangle test (Wald's, then the watertight one).
pub fn trees(parts: &[Part], open: &[[Vec3; 3]]) -> Vec<KdTree> {
    let mut b = MeshBuilder::new();
    let m = b.material("m", Vec3::ONE);
    for p in parts {
        b.add(p, m);
    }
    let mesh = b.finish();
    let mut soup: Vec<[Vec3; 3]> = mesh.triangles.iter().map(|t| t.map(|i| mesh.positions[i as usize])).collect();
    soup.extend_from_slice(open);
    [Intersector::Wald, Intersector::Watertight]
        .into_iter()
        .map(|intersector| KdTree::build_soup(&soup, &BuildConfig { intersector, ..BuildConfig::default() }).unwrap())
        .collect()
}

/// A 20 x 20 floor, its top at `y = 0`.
pub fn floor() -> Part {
    Part::cuboid(Vec3::new(-10.0, -1.0, -10.0), Vec3::new(10.0, 0.0, 10.0))
}

/// A square light facing down, `2 half` across, centred at `center`.
pub fn rect_light(center: Vec3, half: f32) -> AreaLight {
    let (u, v) = (Vec3::new(2.0 * half, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * half));
    AreaLight::Rect(RectLight { corner: center - 0.5 * (u + v), edge_u: u, edge_v: v, intensity: Vec3::ONE })
}
