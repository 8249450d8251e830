//! Animated variants of a scene for the dynamic case of pre-BVH culling (Selgrad, Müller &
//! Stamminger: a scene whose shadow structure is rebuilt every frame because objects move).
//!
//! [`animated`] takes any scene (a built-in one or a loaded file) and adds moving closed
//! objects whose placement is a function of the frame number alone, so every frame is
//! deterministic and any frame can be made without the ones before it:
//! - six *drones*, geodesic spheres (1280 triangles each) circling the point light's vertical
//!   axis at different radii, heights, speeds and directions;
//! - six *tumblers*, 32-sided columns (`Part::prism`) spinning about two axes while they slide
//!   back and forth (a triangle wave) along X or Z across the whole scene, so they pass in and
//!   out of the parts of the scene a view sees.
//!
//! Every added object is a closed, outward-wound [`Part`] under a rigid motion (rotations and
//! translations keep both), with its own vertices, so the animated mesh stays closed when the
//! base mesh is. The base scene's views and lights are kept; `name` is `BASE-animated`.
//! `by_name("arena-animated")` and `by_name("atrium-animated")` give frame 0.

use glam::{Affine3A, Quat, Vec3};

use super::shapes::Part;
use crate::{Material, Mesh, Scene};

/// Drones (spheres circling the light's axis).
pub const DRONES: u32 = 6;
/// Tumblers (spinning columns sliding across the scene).
pub const TUMBLERS: u32 = 6;

/// Frame `frame` of the animated variant of `base`: `base`'s mesh with the moving objects
/// placed as at that frame appended after its triangles (module docs). The objects are sized
/// and placed from `base`'s bounding box and point light; a base mesh with non-finite
/// positions gives non-finite positions here, for `Mesh::check` to reject.
pub fn animated(base: &Scene, frame: u32) -> Scene {
    let mut scene = base.clone();
    scene.name = format!("{}-animated", base.name);
    let mesh = &mut scene.mesh;
    let (lo, hi) =
        mesh.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let (lo, hi) = if lo.cmple(hi).all() { (lo, hi) } else { (Vec3::splat(-1.0), Vec3::ONE) };
    let light = base.point_light.position;
    let half = 0.5 * (hi.x - lo.x).max(hi.z - lo.z);
    let f = frame as f32;
    let drone = add_material(mesh, "drone", Vec3::new(0.8, 0.25, 0.2));
    let tumbler = add_material(mesh, "tumbler", Vec3::new(0.25, 0.6, 0.3));
    let sphere = Part::icosphere(0.03 * half, 3);
    for i in 0..DRONES {
        let k = i as f32;
        let radius = half * (0.1 + 0.05 * k);
        let height = lo.y + (light.y - lo.y) * (0.25 + 0.1 * k);
        let speed = 0.04 * (1.0 + (i % 3) as f32) * if i % 2 == 0 { 1.0 } else { -1.0 };
        let angle = 1.1 * k + speed * f;
        let at = Vec3::new(light.x + radius * angle.cos(), height, light.z + radius * angle.sin());
        append(mesh, &sphere.translated(at), drone);
    }
    let column = Part::prism(0.02 * half, 0.02 * half, -0.08 * half, 0.08 * half, 32, 4);
    for i in 0..TUMBLERS {
        let k = i as f32;
        // A triangle wave in [0, 1] with period 2 / speed frames, each tumbler out of phase.
        let speed = 0.01 + 0.004 * k;
        let phase = (0.17 * k + speed * f).rem_euclid(2.0);
        let s = if phase < 1.0 { phase } else { 2.0 - phase };
        let height = lo.y + (light.y - lo.y) * (0.15 + 0.12 * k);
        let across = 0.3 * (k - 2.5) / 2.5;
        let at = if i % 2 == 0 {
            Vec3::new(lo.x + (hi.x - lo.x) * (0.05 + 0.9 * s), height, light.z + half * across)
        } else {
            Vec3::new(light.x + half * across, height, lo.z + (hi.z - lo.z) * (0.05 + 0.9 * s))
        };
        let spin = Quat::from_rotation_y(0.07 * f + k) * Quat::from_rotation_x(0.05 * f + 0.5 * k);
        append(mesh, &column.transformed(Affine3A::from_rotation_translation(spin, at)), tumbler);
    }
    scene
}

/// The id of a new material `name` of colour `diffuse` in `mesh`.
fn add_material(mesh: &mut Mesh, name: &str, diffuse: Vec3) -> u32 {
    mesh.materials.push(Material::diffuse(name, diffuse));
    mesh.materials.len() as u32 - 1
}

/// Appends `part` with its own vertices, material `material` and the next `prim_ids`, with
/// vertex normals if the mesh has them (the part's smooth normals are not needed: the face's).
fn append(mesh: &mut Mesh, part: &Part, material: u32) {
    let base = mesh.positions.len() as u32;
    mesh.positions.extend_from_slice(&part.positions);
    if let Some(normals) = mesh.normals.as_mut() {
        let centre = part.positions.iter().copied().sum::<Vec3>() / part.positions.len().max(1) as f32;
        normals.extend(part.positions.iter().map(|&p| (p - centre).normalize_or(Vec3::Y)));
    }
    let next_id = mesh.prim_ids.iter().max().map_or(0, |&m| m + 1);
    for (j, &[a, b, c]) in part.triangles.iter().enumerate() {
        mesh.triangles.push([a + base, b + base, c + base]);
        mesh.material_ids.push(material);
        mesh.prim_ids.push(next_id + j as u32);
    }
}

#[cfg(test)]
mod tests {
    use super::super::shapes::checks::{degenerate, inconsistent_edge, open_edge};
    use super::*;

    #[test]
    fn every_frame_is_valid_closed_and_moves() {
        for name in ["arena", "atrium"] {
            let base = super::super::by_name(name).unwrap();
            let n = base.mesh.triangle_count();
            let frame0 = animated(&base, 0);
            assert_eq!(frame0.name, format!("{name}-animated"));
            assert_eq!(super::super::by_name(&frame0.name).unwrap().mesh, frame0.mesh);
            let added = frame0.mesh.triangle_count() - n;
            assert!(added > 6000, "{name}: {added} moving triangles");
            for k in [1, 7, 60, 250] {
                let scene = animated(&base, k);
                let mesh = &scene.mesh;
                mesh.check().unwrap_or_else(|e| panic!("{name} frame {k}: {e}"));
                assert_eq!(mesh.triangles, frame0.mesh.triangles, "the same triangles, moved");
                assert_eq!(mesh.prim_ids, (0..mesh.triangle_count() as u32).collect::<Vec<_>>());
                assert_eq!(degenerate(&mesh.positions, &mesh.triangles), None, "{name} frame {k}");
                assert_eq!(open_edge(&mesh.triangles), None, "{name} frame {k}");
                assert_eq!(inconsistent_edge(&mesh.triangles), None, "{name} frame {k}");
                let solid = Part { positions: mesh.positions.clone(), triangles: mesh.triangles.clone() };
                assert!(solid.signed_volume() > 0.0, "{name} frame {k}: inward winding");
                // The base scene is untouched; every moving object has moved.
                assert_eq!(mesh.positions[..base.mesh.positions.len()], base.mesh.positions[..]);
                let per_object: Vec<usize> = [(DRONES, 1280), (TUMBLERS, added - DRONES as usize * 1280)]
                    .iter()
                    .flat_map(|&(count, total)| std::iter::repeat_n(total / count as usize, count as usize))
                    .collect();
                let mut first = n;
                for (o, &count) in per_object.iter().enumerate() {
                    let moved = (first..first + count).any(|t| mesh.triangle(t) != frame0.mesh.triangle(t));
                    assert!(moved, "{name} frame {k}: object {o} did not move");
                    first += count;
                }
                assert_eq!(animated(&base, k).mesh, scene.mesh, "{name} frame {k} is not deterministic");
            }
        }
    }
}
