//! Built-in procedural scenes: generated in code, deterministic, and made of closed meshes
//! with shared vertices (every object is a closed [`shapes::Part`] with its own vertices).
//!
//! They stand in for the thesis's benchmark scenes (Tsakok 2008, Figure 4.1), which we may
//! not ship: `atrium` for Sponza (67k), `arena` for the Quake III level (12.8k),
//! `atrium-rotated` for the non-axis-aligned "Transformed Kitchen", and `grove` for Fairy
//! (174k, many small details). For the secondary rays (reflection and refraction, chapter 6),
//! `garage` stands in for the two Ferrari F40s in a garage of Table 6.2 (89 754 polygons;
//! reflective metal, car paint and glass), and `atrium-mirror` is `atrium` with a reflective
//! floor. The other scenes' materials are diffuse (`M_D`). The small scenes exercise special
//! cases. Y is up everywhere and `prim_ids[i] = i`.

use crate::Scene;

mod animated;
mod arena;
mod atrium;
mod garage;
mod grove;
pub mod shapes;
mod small;
mod stage;

pub use animated::animated;
pub use atrium::{atrium, atrium_at_detail, atrium_mirror, atrium_rotated};
pub use garage::garage;
pub use grove::{MAX_GROVES, grove_grid};

/// Names of the built-in scenes, the default first.
///
/// [`by_name`] also accepts `atrium-xN` for N = 2, 4, 8, ... (see [`atrium_at_detail`]),
/// `grove-xN` for N = 1 to 64 (see [`grove_grid`]) and `NAME-animated` (frame 0 of
/// [`animated`] over the built-in `NAME`).
pub const NAMES: &[&str] = &[
    "atrium",
    "arena",
    "atrium-rotated",
    "grove",
    "garage",
    "atrium-mirror",
    "triangle",
    "cube",
    "sphere",
    "touching-boxes",
    "axis-plane-triangle",
];

/// The names of [`NAMES`] whose geometry, triangle order, views and lights are those of another
/// name, only their materials differing (`atrium-mirror` is `atrium` with a reflective
/// floor): tests of geometry and traversal, which would repeat the other name's work, skip
/// them.
pub const MATERIAL_VARIANTS: &[&str] = &["atrium-mirror"];

/// The built-in scene called `name` (one of [`NAMES`], `atrium-xN` with N a power of two up to
/// 64: the atrium with each triangle split into N, or `grove-xN` with N from 1 to 64: N
/// groves side by side), or `None`.
pub fn by_name(name: &str) -> Option<Scene> {
    match name {
        "atrium" => Some(atrium()),
        "arena" => Some(arena::arena()),
        "atrium-rotated" => Some(atrium_rotated()),
        "grove" => Some(grove::grove()),
        "garage" => Some(garage()),
        "atrium-mirror" => Some(atrium_mirror()),
        "triangle" => Some(small::triangle()),
        "cube" => Some(small::cube()),
        "sphere" => Some(small::sphere()),
        "touching-boxes" => Some(small::touching_boxes()),
        "axis-plane-triangle" => Some(small::axis_plane_triangle()),
        _ => {
            if let Some(base) = name.strip_suffix("-animated") {
                // One level: "arena-animated-animated" is not a name.
                return (!base.ends_with("-animated")).then(|| by_name(base)).flatten().map(|s| animated(&s, 0));
            }
            if let Some(count) = name.strip_prefix("grove-x") {
                // Digits only: "+3" or " 3" would parse but are not names.
                if count.is_empty() || !count.bytes().all(|b| b.is_ascii_digit()) {
                    return None;
                }
                return grove_grid(count.parse().ok()?);
            }
            let factor: u32 = name.strip_prefix("atrium-x")?.parse().ok()?;
            (factor.is_power_of_two() && factor <= 64).then(|| atrium_at_detail(factor.trailing_zeros()))
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::shapes::checks::{degenerate, inconsistent_edge, open_edge};
    use super::*;

    /// (name, min triangles, max triangles, closed).
    const EXPECTED: &[(&str, usize, usize, bool)] = &[
        ("atrium", 60_000, 70_000, true),
        ("arena", 10_000, 15_000, true),
        ("atrium-rotated", 60_000, 70_000, true),
        ("grove", 150_000, 200_000, true),
        ("garage", 85_000, 95_000, true),
        ("atrium-mirror", 60_000, 70_000, true),
        ("triangle", 1, 1, false),
        ("cube", 12, 12, true),
        ("sphere", 1_000, 2_000, true),
        ("touching-boxes", 36, 36, true),
        ("axis-plane-triangle", 1, 1, false),
    ];

    #[test]
    fn every_name_is_tested_and_built() {
        assert_eq!(NAMES.len(), EXPECTED.len());
        for (&name, &(expected, ..)) in NAMES.iter().zip(EXPECTED) {
            assert_eq!(name, expected);
        }
        assert!(MATERIAL_VARIANTS.iter().all(|v| NAMES.contains(v)));
        assert!(by_name("no-such-scene").is_none());
        assert!(by_name("atrium-x3").is_none());
        assert!(by_name("atrium-x").is_none());
        for bad in ["grove-x0", "grove-x65", "grove-x", "grove-x+2", "grove-x 2", "grove-x99999999999"] {
            assert!(by_name(bad).is_none(), "{bad}");
        }
    }

    #[test]
    fn grove_grid_copies_the_grove_side_by_side() {
        let one = by_name("grove").unwrap().mesh;
        let scene = by_name("grove-x3").unwrap();
        assert_eq!(scene.name, "grove-x3");
        let mesh = &scene.mesh;
        mesh.check().unwrap();
        let (nv, nt) = (one.positions.len(), one.triangle_count());
        assert_eq!(mesh.triangle_count(), 3 * nt);
        assert_eq!(mesh.prim_ids, (0..3 * nt as u32).collect::<Vec<_>>());
        // Copy 2 (second row, first column): the same triangles, moved.
        for t in [0, nt / 2, nt - 1] {
            let (a, b) = (one.triangle(t), mesh.triangle(2 * nt + t));
            for k in 0..3 {
                assert!((b[k] - a[k] - Vec3::new(0.0, 0.0, 44.0)).abs().max_element() < 1e-4, "{:?}", b[k] - a[k]);
            }
            assert_eq!(mesh.triangles[2 * nt + t].map(|i| i - 2 * nv as u32), one.triangles[t]);
        }
        assert_eq!(open_edge(&mesh.triangles), None, "closed like the grove");
        for v in &scene.views {
            assert!(v.camera(64, 48).is_some(), "view {}", v.name);
        }
        assert_eq!(by_name("grove-x1").unwrap().mesh.triangles, one.triangles);
    }

    #[test]
    fn builtin_scenes_are_valid_closed_and_deterministic() {
        for &(name, lo, hi, closed) in EXPECTED {
            let scene = by_name(name).unwrap();
            let mesh = &scene.mesh;
            let n = mesh.triangle_count();
            eprintln!("{name}: {n} triangles, {} vertices", mesh.positions.len());
            assert!((lo..=hi).contains(&n), "{name}: {n} triangles, expected {lo}..={hi}");
            assert_eq!(scene.name, name);
            mesh.check().unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(mesh.prim_ids, (0..n as u32).collect::<Vec<_>>(), "{name}");
            assert_eq!(degenerate(&mesh.positions, &mesh.triangles), None, "{name}: degenerate triangle");
            assert!(
                mesh.materials.iter().all(|m| m.diffuse.cmpge(Vec3::ZERO).all() && m.diffuse.cmple(Vec3::ONE).all())
            );
            if closed {
                assert_eq!(open_edge(&mesh.triangles), None, "{name}: open edge");
                assert_eq!(inconsistent_edge(&mesh.triangles), None, "{name}: inconsistent winding");
                // Consistent winding plus positive total volume: outward (each part's sign is
                // checked in the shapes tests).
                let solid = shapes::Part { positions: mesh.positions.clone(), triangles: mesh.triangles.clone() };
                assert!(solid.signed_volume() > 0.0, "{name}: inward winding");
            }
            // Views: the first is the default and every one gives a camera.
            assert!(!scene.views.is_empty());
            assert_eq!(scene.default_view().name, "default");
            for v in &scene.views {
                assert!(v.camera(64, 48).is_some(), "{name}: view {} is degenerate", v.name);
            }
            let light = scene.area_light;
            assert!(light.edge_u.cross(light.edge_v).length() > 0.0 && scene.point_light.position.is_finite());
            assert_eq!(by_name(name).unwrap().mesh, scene.mesh, "{name} is not deterministic");
        }
    }
}
