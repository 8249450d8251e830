//! Shadow rays and the diffuse shading of the thesis's benchmark renders.
//!
//! The model (Tsakok 2008, 4.1): Lambertian surfaces lit by one point light with
//! inverse-square attenuation, plus a small ambient term so that shadowed and back-facing
//! surfaces are not pitch black. The surface normal is the triangle's geometric normal, or the
//! interpolated vertex normal where the mesh has normals, turned to face the viewer.

use glam::{Vec3, Vec4};
use kdtree::surface::{Lanes3, Surface, SurfaceLanes, Surfaces, dot4};
use kdtree::{Hit, Ray};
use scenes::{Mesh, PointLight};

/// The [`Surface`] records of `mesh`'s triangles, made once per scene: what
/// [`shadow_ray`] and [`crate::soft::shadow_start`] read.
pub fn surfaces(mesh: &Mesh) -> Surfaces {
    Surfaces::new(&mesh.positions, &mesh.triangles)
}

/// The ambient term: the fraction of the material's diffuse colour seen without any light.
pub const AMBIENT: f32 = 0.08;

/// The colour of pixels whose primary ray hits nothing.
pub const BACKGROUND: Vec3 = Vec3::new(0.02, 0.02, 0.03);

/// The geometric normal of the hit triangle, turned to face the incoming ray `dir`.
#[inline]
pub fn facing_normal(mesh: &Mesh, hit: &Hit, dir: Vec3) -> Vec3 {
    let n = mesh.geometric_normal(hit.prim as usize);
    if n.dot(dir) > 0.0 { -n } else { n }
}

/// The shadow ray from the primary hit `hit` of a ray with direction `dir` towards `light`,
/// or `None` when the surface faces away from the light (it is unlit whatever lies between).
///
/// The origin comes from [`kdtree::ray::offset_origin`], the workspace's one scheme: the hit
/// point from its barycentrics, moved off the surface by 32 ulps of the triangle's
/// coordinates, here read from the triangle's precomputed [`Surface`] record (the same
/// values bit for bit, one cache line instead of the mesh's index and three vertices). The
/// direction is unnormalised and reaches the light at `t = 1`.
#[inline]
pub fn shadow_ray(surfaces: &Surfaces, light: &PointLight, dir: Vec3, hit: &Hit) -> Option<Ray> {
    let (start, end) = shadow_segment(surfaces, light, dir, hit)?;
    Some(Ray::segment(start, end))
}

/// The ends of [`shadow_ray`]: its origin and the light (the ray is
/// `Ray::segment(start, end)`), for kernels that build their packets from the
/// ends (`packets::RayPacket::segments`).
#[inline(always)]
pub fn shadow_segment(surfaces: &Surfaces, light: &PointLight, dir: Vec3, hit: &Hit) -> Option<(Vec3, Vec3)> {
    let s: &Surface = surfaces.get(hit.prim);
    let n = s.facing_normal(dir);
    let p = s.point(hit);
    let to_light = light.position - p;
    if n.dot(to_light) <= 0.0 {
        return None;
    }
    Some((s.offset_origin(p, to_light), light.position))
}

/// What a lane without a hit reads in [`shadow_starts4`] (its answers are discarded).
static NO_SURFACE: Surface = Surface {
    a: Vec3::ZERO,
    e1: Vec3::ZERO,
    e2: Vec3::ZERO,
    normal: Vec3::ZERO,
    offset_normal: Vec3::ZERO,
    offset: 0.0,
};

/// [`shadow_segment`] of four primary hits in SIMD lanes: lane `l` is the hit `hits[l]` of
/// the primary ray with direction lane `l` of `dir` (`None`: a pixel whose ray hit nothing).
/// Returns the shadow rays' starts in lanes and the lanes that cast a ray as bits (bit `l`
/// set where [`shadow_segment`] gives `Some`); each such lane's start is
/// [`shadow_segment`]'s bit for bit (the same operations lane by lane,
/// [`SurfaceLanes`]), and every ray ends at the light. Four pixels' setup takes one
/// instruction per operation and no branch.
#[inline(always)]
pub fn shadow_starts4(surfaces: &Surfaces, light: &PointLight, dir: &Lanes3, hits: [&Option<Hit>; 4]) -> (Lanes3, u32) {
    let records = hits.map(|hit| hit.as_ref().map_or(&NO_SURFACE, |hit| surfaces.get(hit.prim)));
    let found = hits.iter().enumerate().fold(0, |bits, (l, hit)| bits | u32::from(hit.is_some()) << l);
    let s = SurfaceLanes::gather(records);
    let n = s.facing_normal(dir);
    let p = s.point(
        Vec4::from_array(hits.map(|h| h.map_or(0.0, |h| h.u))),
        Vec4::from_array(hits.map(|h| h.map_or(0.0, |h| h.v))),
    );
    let to_light: Lanes3 = std::array::from_fn(|i| Vec4::splat(light.position[i]) - p[i]);
    // `shadow_segment` gives `None` where `n . to_light <= 0` (and so `Some` for NaN).
    let lit = found & !dot4(&n, &to_light).cmple(Vec4::ZERO).bitmask();
    (s.offset_origin(&p, &to_light), lit)
}

/// The colour of the hit `hit` of the ray `origin + t * dir` (a primary or a secondary
/// ray): the thesis's fixed-function shading (4.2.1, steps 4 and 5) of its material.
///
/// - An ambient term.
/// - Lambert's `N . L` with the point light's inverse-square attenuation.
/// - For specular materials (`specular_blend > 0`), Phong's highlight
///   `blend (R . V)^exp`, white and attenuated like the diffuse term.
///
/// `visible` is the fraction of the light the point sees: 1 lit, 0 blocked (hard shadows:
/// whether the shadow ray found a blocker; always 1 without shadows), the fraction of
/// unblocked sample rays for soft shadows. A surface facing away from the light gets only the
/// ambient term either way. Reflection and refraction are not here: they are the weighted
/// colours of the secondary rays ([`crate::secondary`]) that [`crate::render`] adds.
pub fn shade(mesh: &Mesh, light: &PointLight, origin: Vec3, dir: Vec3, hit: &Hit, visible: f32) -> Vec3 {
    let prim = hit.prim as usize;
    let material = mesh.material_ids.get(prim).and_then(|&m| mesh.materials.get(m as usize));
    let diffuse = material.map_or(Vec3::splat(0.75), |m| m.diffuse);
    let mut color = AMBIENT * diffuse;
    if visible <= 0.0 {
        return color;
    }
    let geometric = facing_normal(mesh, hit, dir);
    let p = origin + hit.t * dir;
    let to_light = light.position - p;
    let dist2 = to_light.length_squared();
    if geometric.dot(to_light) <= 0.0 || dist2 <= 0.0 {
        return color;
    }
    let normal = shading_normal(mesh, hit).map_or(geometric, |n| if n.dot(geometric) < 0.0 { -n } else { n });
    let cos = normal.dot(to_light) / dist2.sqrt();
    if cos > 0.0 {
        color += diffuse * light.intensity * (cos / dist2) * visible;
        if let Some(m) = material.filter(|m| m.specular_blend > 0.0) {
            // Phong: the light's mirror direction against the direction to the viewer.
            let l = to_light / dist2.sqrt();
            let r = crate::secondary::reflect(-l, normal);
            let v = -dir.normalize_or_zero();
            let rv = r.dot(v).max(0.0);
            if rv > 0.0 {
                color += light.intensity * (m.specular_blend * rv.powf(m.specular_exponent) / dist2 * visible);
            }
        }
    }
    color
}

/// The interpolated vertex normal at the hit, where the mesh has normals and they do not
/// cancel out.
fn shading_normal(mesh: &Mesh, hit: &Hit) -> Option<Vec3> {
    let normals = mesh.normals.as_ref()?;
    let [a, b, c] = *mesh.triangles.get(hit.prim as usize)?;
    let w = 1.0 - hit.u - hit.v;
    let n = w * *normals.get(a as usize)? + hit.u * *normals.get(b as usize)? + hit.v * *normals.get(c as usize)?;
    n.try_normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenes::Material;

    fn floor() -> Mesh {
        Mesh {
            positions: vec![Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0)],
            triangles: vec![[0, 2, 1]],
            normals: None,
            material_ids: vec![0],
            materials: vec![Material::diffuse("m", Vec3::ONE)],
            prim_ids: vec![0],
        }
    }

    #[test]
    fn shadow_ray_leaves_the_surface_towards_the_light() {
        let mesh = floor();
        let light = PointLight { position: Vec3::new(0.0, 2.0, 0.0), intensity: Vec3::ONE };
        let hit = Hit { t: 1.0, u: 0.3, v: 0.3, prim: 0 };
        let surfaces = surfaces(&mesh);
        let ray = shadow_ray(&surfaces, &light, -Vec3::Y, &hit).unwrap();
        assert!(ray.origin.y > 0.0);
        assert!((ray.at(1.0) - light.position).length() < 1e-6);
        // A light below the floor, seen from above: the surface faces away, no ray.
        let below = PointLight { position: Vec3::new(0.0, -2.0, 0.0), intensity: Vec3::ONE };
        assert!(shadow_ray(&surfaces, &below, -Vec3::Y, &hit).is_none());
    }

    #[test]
    fn lit_is_brighter_than_shadowed_and_follows_inverse_square() {
        let mesh = floor();
        let hit = Hit { t: 1.0, u: 0.3, v: 0.3, prim: 0 };
        let near = PointLight { position: Vec3::new(0.0, 1.0, 0.0), intensity: Vec3::ONE };
        let far = PointLight { position: Vec3::new(0.0, 2.0, 0.0), intensity: Vec3::ONE };
        let o = Vec3::new(0.0, 1.0, 0.0);
        let lit = shade(&mesh, &near, o, -Vec3::Y, &hit, 1.0);
        let dark = shade(&mesh, &near, o, -Vec3::Y, &hit, 0.0);
        assert!(lit.x > dark.x);
        assert!((dark.x - AMBIENT).abs() < 1e-6);
        let lit_far = shade(&mesh, &far, o, -Vec3::Y, &hit, 1.0);
        assert!(((lit.x - AMBIENT) / (lit_far.x - AMBIENT) - 4.0).abs() < 1e-3);
    }

    #[test]
    fn phong_highlight_peaks_in_the_mirror_direction() {
        let mut mesh = floor();
        let diffuse_only = mesh.clone();
        mesh.materials[0].specular_blend = 0.5;
        mesh.materials[0].specular_exponent = 50.0;
        let hit = Hit { t: 1.0, u: 1.0 / 3.0, v: 1.0 / 3.0, prim: 0 };
        let p = Vec3::new(0.0, 0.0, -1.0 / 3.0);
        let light = PointLight { position: p + Vec3::new(-1.0, 1.0, 0.0), intensity: Vec3::ONE };
        // Seen from the mirror direction of the light: diffuse plus blend / dist2 (R . V = 1).
        let eye = p + Vec3::new(1.0, 1.0, 0.0);
        let at = |eye: Vec3, mesh: &Mesh| {
            let d = p - eye;
            shade(mesh, &light, eye, d, &Hit { t: 1.0, ..hit }, 1.0)
        };
        let peak = at(eye, &mesh) - at(eye, &diffuse_only);
        assert!((peak.x - 0.5 / 2.0).abs() < 1e-4, "{peak}");
        // Away from it the highlight falls off; in shadow there is none.
        let off = at(p + Vec3::new(0.3, 1.0, 0.0), &mesh) - at(p + Vec3::new(0.3, 1.0, 0.0), &diffuse_only);
        assert!(off.x < 0.1 * peak.x, "{off}");
        let d = p - eye;
        assert_eq!(shade(&mesh, &light, eye, d, &hit, 0.0), shade(&diffuse_only, &light, eye, d, &hit, 0.0));
    }
}
