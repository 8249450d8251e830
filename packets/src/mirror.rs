//! Mirror reflections from the virtual eye (thesis 4.1.2: "omnidirectional ray packets are
//! used for the packet traversal of secondary rays").
//!
//! Rays reflected off one plane from one eye all come, in exact arithmetic, from one point:
//! the eye mirrored in the plane (the *virtual eye*). So the reflections of a primary packet
//! off a planar mirror are a packet with a common origin, whatever their direction signs:
//! exactly what the omni-directional traversal takes without splitting, and what the frustum,
//! MFT and cone kernels bound (a run of them in a ray stream is traced as frusta,
//! `trace::kernel::stream::Runs`). A reflected ray is `virtual_eye + t * reflect(d)` for `t`
//! past the primary hit distance `t_hit` (the point where it leaves the mirror, since
//! reflection keeps lengths). `trace::secondary::spawn` starts reflections this way in runs
//! off one plane when a frame asks for it (`rttest render --virtual-eye`).
//!
//! **Where the interval starts.** Past the mirror point by as much as the workspace's one
//! spawn offset ([`kdtree::ray::offset_origin`]) would lift a ray off the surface, plus a
//! bound on the rounding of the virtual eye, of the reflected direction and of the hit
//! distance (16 ulps of the largest of the eye's, the virtual eye's and the path's
//! magnitudes), both measured along the normal and divided by the cosine to the normal: the
//! start lies that far off the plane, so neither the mirror triangle nor its coplanar
//! neighbours are hit again. A reflection flatter than [`MIN_COS`] (the divisor would carry
//! the start far along the surface) gets no virtual eye: the caller starts it on the surface.
//!
//! The plane of each lane is its triangle's, from the normal computed in `f64` from the
//! vertices ([`Surface::offset_normal`]) and vertex `a`, so lanes that hit coplanar
//! axis-aligned triangles share a virtual eye bit for bit; lanes with different virtual eyes
//! go in different packets ([`reflections`] groups them).

use glam::{DVec3, Vec3};
use kdtree::surface::Surface;
use kdtree::{Hit, KdTree, Ray};

use crate::packet::{OmniPacket, RayPacket};

/// The least cosine between a primary ray and its mirror's normal for which the reflection
/// leaves from the virtual eye: flatter ones start on the surface (the start's distance along
/// the ray grows as one over the cosine).
pub const MIN_COS: f64 = 1.0 / 16.0;

/// Ulps of the largest magnitude on the path (eye, virtual eye, path length) that the start of
/// a reflected ray keeps off the mirror's plane beyond the spawn offset.
const ROUNDING_ULPS: f64 = 16.0;

/// A mirror plane `normal . p = offset` (unit normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    /// Unit normal.
    pub normal: DVec3,
    /// Plane offset.
    pub offset: f64,
}

impl Mirror {
    /// The plane of a triangle's record: its `f64` normal ([`Surface::offset_normal`]) through
    /// vertex `a` (`None` for a degenerate or non-finite triangle).
    pub fn of_surface(surface: &Surface) -> Option<Mirror> {
        let normal = surface.offset_normal.as_dvec3().try_normalize()?;
        let offset = normal.dot(surface.a.as_dvec3());
        offset.is_finite().then_some(Mirror { normal, offset })
    }

    /// `eye` reflected in the plane: the common origin of the reflected rays.
    pub fn virtual_eye(&self, eye: Vec3) -> Vec3 {
        let e = eye.as_dvec3();
        (e - 2.0 * (self.normal.dot(e) - self.offset) * self.normal).as_vec3()
    }

    /// `dir` reflected in the plane.
    pub fn reflect(&self, dir: Vec3) -> Vec3 {
        let d = dir.as_dvec3();
        (d - 2.0 * d.dot(self.normal) * self.normal).as_vec3()
    }

    /// The reflection of the ray from `eye` along `dir` that met the mirror at `t_hit` (in
    /// units of `dir`): from the virtual eye, its interval starting past the mirror as the
    /// module documentation says, `spawn_offset` being the mirror triangle's spawn offset
    /// ([`Surface::offset`]). `None` for a reflection flatter than [`MIN_COS`], or any
    /// non-finite input or result: such a ray starts on the surface instead.
    pub fn reflected_ray(&self, eye: Vec3, dir: Vec3, t_hit: f32, spawn_offset: f32) -> Option<Ray> {
        let d = dir.as_dvec3();
        let length = d.length();
        let cos = d.dot(self.normal).abs() / length;
        if !(cos >= MIN_COS && t_hit >= 0.0 && t_hit.is_finite() && spawn_offset.is_finite()) {
            return None;
        }
        let origin = self.virtual_eye(eye);
        let path = f64::from(t_hit) * length;
        let scale = f64::from(origin.abs().max_element().max(eye.abs().max_element())) + path;
        let lift = f64::from(spawn_offset) + ROUNDING_ULPS * f64::from(f32::EPSILON) * scale;
        let t_min = (f64::from(t_hit) + lift / (cos * length)) as f32;
        Ray::try_new(origin, self.reflect(dir), t_min, f32::INFINITY).ok()
    }
}

/// The reflected rays of the `lanes` of a primary packet from `eye` (the rays `dirs`, hits
/// `hits`) whose hit triangle `is_mirror` accepts, grouped into omni-directional packets by
/// virtual eye: at most four packets, each with the lanes of one virtual eye (others
/// invalid). Lane `l` of every returned packet is lane `l` of the primary packet. A lane
/// whose reflection has no virtual eye (flatter than [`MIN_COS`], or a NaN or infinite
/// `eye`, direction or hit) is left out, like a lane that hit no mirror.
pub fn reflections(
    tree: &KdTree,
    eye: Vec3,
    dirs: &[Vec3; 4],
    hits: &[Option<Hit>; 4],
    is_mirror: impl Fn(u32) -> bool,
) -> Vec<OmniPacket> {
    let rays: [Option<Ray>; 4] = std::array::from_fn(|lane| {
        let hit = hits[lane].filter(|h| is_mirror(h.prim))?;
        let surface = Surface::new(&tree.triangle(hit.prim));
        Mirror::of_surface(&surface)?.reflected_ray(eye, dirs[lane], hit.t, surface.offset)
    });
    let mut out = Vec::new();
    let mut taken = [false; 4];
    for lane in 0..4 {
        let Some(first) = rays[lane].filter(|_| !taken[lane]) else { continue };
        let group: [Option<Ray>; 4] = std::array::from_fn(|l| {
            rays[l].filter(|r| {
                !taken[l] && r.origin.to_array().map(f32::to_bits) == first.origin.to_array().map(f32::to_bits)
            })
        });
        for (l, r) in group.iter().enumerate() {
            taken[l] |= r.is_some();
        }
        // One origin and t_min > 0 by construction.
        out.extend(OmniPacket::new(RayPacket::from_lanes(group)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::omni;
    use kdtree::{BuildConfig, NoCounters};

    #[test]
    fn the_virtual_eye_sees_the_mirror_point_at_the_hit_distance() {
        let tri = [Vec3::ZERO, Vec3::Z, Vec3::X];
        let m = Mirror::of_surface(&Surface::new(&tri)).unwrap();
        assert_eq!(m.normal, DVec3::Y);
        let eye = Vec3::new(0.3, 2.0, -1.0);
        assert_eq!(m.virtual_eye(eye), Vec3::new(0.3, -2.0, -1.0));
        let dir = Vec3::new(0.2, -1.0, 0.4).normalize();
        let t = 2.0 / -dir.y;
        let p = eye + t * dir;
        // The barycentrics of `p` on `tri`: `p = u Z + v X`.
        let ray = m.reflected_ray(eye, dir, t, Surface::new(&tri).offset).unwrap();
        assert!((ray.origin + t * ray.dir - p).length() < 1e-5);
        assert!(ray.dir.y > 0.0 && ray.t_min > t && ray.at(ray.t_min).y > 0.0);
        // Flatter than MIN_COS: no virtual eye.
        let flat = Vec3::new(1.0, -0.05, 0.0);
        assert_eq!(m.reflected_ray(eye, flat, 1.0, 1e-6), None);
    }

    #[test]
    fn non_finite_input_gives_no_mirror_and_no_reflected_lane() {
        let tri = [Vec3::ZERO, Vec3::Z, Vec3::X];
        for bad in [f32::NAN, f32::INFINITY] {
            let mut t = tri;
            t[1].y = bad;
            assert_eq!(Mirror::of_surface(&Surface::new(&t)), None);
        }
        let tree = KdTree::build_soup(&[tri], &BuildConfig::default()).unwrap();
        let eye = Vec3::new(0.3, 2.0, 0.3);
        let down = Vec3::new(0.0, -1.0, 0.1);
        let hit = tree.intersect(&Ray::new(eye, down, 0.0, f32::INFINITY));
        assert!(hit.is_some());
        let nan = Vec3::new(0.0, f32::NAN, 0.0);
        let packets = reflections(&tree, eye, &[down, nan, down, down], &[hit, hit, None, hit], |_| true);
        assert_eq!(packets.len(), 1);
        assert_eq!(packets[0].rays.valid.bitmask(), 0b1001, "the NaN and the missing lane are left out");
        for eye in [Vec3::new(f32::NAN, 2.0, 0.3), Vec3::new(0.3, f32::INFINITY, 0.3)] {
            assert!(reflections(&tree, eye, &[down; 4], &[hit; 4], |_| true).is_empty(), "{eye}");
        }
    }

    /// A floor of many coplanar triangles, flat or tilted, at every scale and far from the
    /// origin, seen from eyes near and far: no reflection from the virtual eye ever hits the
    /// floor again (the floor is the whole scene, so any hit would be the mirror itself or a
    /// coplanar neighbour), and each starts on the incoming side.
    #[test]
    fn reflections_never_hit_their_own_plane_at_any_scale() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut unit = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let planes =
            [(Vec3::X, Vec3::Z), (Vec3::new(1.0, 0.3, 0.0).normalize(), Vec3::new(0.0, 0.45, 1.0).normalize())];
        let mut checked = 0;
        for scale in [1e-30f32, 1e-3, 1.0, 1e5, 1e18] {
            for centre in [Vec3::ZERO, Vec3::new(1e5, -3e5, 2e5)] {
                for (u, v) in planes {
                    let n = u.cross(v).normalize();
                    let at = |i: f32, j: f32| (centre + u * i + v * j) * scale;
                    let mut tris = Vec::new();
                    for i in -8..8 {
                        for j in -8..8 {
                            let (i, j) = (i as f32, j as f32);
                            tris.push([at(i, j), at(i + 1.0, j), at(i + 1.0, j + 1.0)]);
                            tris.push([at(i, j), at(i + 1.0, j + 1.0), at(i, j + 1.0)]);
                        }
                    }
                    let tree = KdTree::build_soup(&tris, &BuildConfig::default()).unwrap();
                    for k in 0..200 {
                        let height = if k % 2 == 0 { 0.5 + 4.0 * unit() } else { 1e3 };
                        let eye = at(16.0 * unit() - 8.0, 16.0 * unit() - 8.0) + n * (height * scale);
                        let target = at(12.0 * unit() - 6.0, 12.0 * unit() - 6.0);
                        let dir = target - eye;
                        let Some(hit) = tree.intersect(&Ray::new(eye, dir, 0.0, f32::INFINITY)) else { continue };
                        let surface = Surface::new(&tree.triangle(hit.prim));
                        let Some(mirror) = Mirror::of_surface(&surface) else { continue };
                        let Some(ray) = mirror.reflected_ray(eye, dir, hit.t, surface.offset) else { continue };
                        let start = ray.at(ray.t_min);
                        assert!((start - target).dot(n) > 0.0, "scale {scale}: starts behind the mirror");
                        assert_eq!(tree.intersect(&ray), None, "scale {scale}, centre {centre}, eye {eye}: {ray:?}");
                        assert!(!tree.occluded(&ray));
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 3000, "{checked}");
    }

    /// Reflections off the atrium's floor tiles, traced as omni-directional packets, give the
    /// single-ray hits of the same reflected rays.
    #[test]
    fn floor_reflections_as_packets_match_single_rays() {
        let scene = scenes::load_scene("atrium").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let mirror_material = scene.mesh.materials.iter().position(|m| m.name.starts_with("floor tile")).unwrap();
        let is_mirror = |prim: u32| scene.mesh.material_ids[prim as usize] as usize == mirror_material;
        let camera = scene.default_view().camera(64, 48).unwrap();
        let (mut packets, mut lanes) = (0, 0);
        for y in (0..48).step_by(2) {
            for x in (0..64).step_by(2) {
                let pixels = [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)];
                let dirs = pixels.map(|(px, py)| camera.pixel_ray(px, py).1);
                let hits = dirs.map(|d| tree.intersect(&Ray::new(camera.eye, d, 0.0, f32::INFINITY)));
                for packet in reflections(&tree, camera.eye, &dirs, &hits, is_mirror) {
                    packets += 1;
                    let got = omni::intersect(&tree, &packet, &mut NoCounters).hits();
                    for lane in 0..4 {
                        if packet.rays.valid.bitmask() >> lane & 1 != 0 {
                            lanes += 1;
                            assert_eq!(got[lane], tree.intersect(&packet.rays.ray(lane)), "pixel {:?}", pixels[lane]);
                        }
                    }
                }
            }
        }
        assert!(packets > 20 && lanes > 80, "{packets} packets, {lanes} lanes");
    }
}
