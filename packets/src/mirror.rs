//! Mirror reflections as omni-directional packets (thesis 4.1.2: "omnidirectional ray packets
//! are used for the packet traversal of secondary rays").
//!
//! Rays reflected off one plane from one eye all come, in exact arithmetic, from one point:
//! the eye mirrored in the plane (the *virtual eye*). So the reflections of a primary packet
//! off a planar mirror are a packet with a common origin, whatever their direction signs:
//! exactly what the omni-directional traversal takes, without splitting. A reflected ray is
//! `virtual_eye + t * reflect(d)` for `t` past the primary hit distance `t_hit` (the point
//! where it leaves the mirror, since reflection keeps lengths). Its interval starts past the
//! mirror by the distance of the workspace's one spawn offset
//! ([`kdtree::ray::offset_origin`]) at the mirror point, so the mirror itself is never hit
//! again and the offset scales like every other spawned ray's.
//!
//! The plane of each lane is that of the triangle it hit, computed in f64 and rounded, so
//! lanes that hit coplanar triangles share a virtual eye bit for bit; lanes with different
//! virtual eyes go in different packets ([`reflections`] groups them).

use glam::{DVec3, Vec3};
use kdtree::ray::{offset_origin, surface_point};
use kdtree::{Hit, KdTree, Ray};

use crate::packet::{OmniPacket, RayPacket};

/// A mirror plane `normal . p = offset` (unit normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    /// Unit normal.
    pub normal: DVec3,
    /// Plane offset.
    pub offset: f64,
}

impl Mirror {
    /// The plane of triangle `tri` (`None` for a degenerate triangle, or one with a NaN or
    /// infinite vertex).
    pub fn of_triangle(tri: &[Vec3; 3]) -> Option<Mirror> {
        let [a, b, c] = tri.map(|p| p.as_dvec3());
        let normal = (b - a).cross(c - a).try_normalize()?;
        Some(Mirror { normal, offset: normal.dot(a) })
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

    /// The reflected ray of a primary ray `dir` from `eye` that hit the mirror triangle `tri`
    /// at `hit`: from the virtual eye, starting past the mirror by the distance
    /// [`offset_origin`] would move a ray leaving the mirror point.
    pub fn reflected_ray(&self, eye: Vec3, dir: Vec3, tri: &[Vec3; 3], hit: &Hit) -> Ray {
        let reflected = self.reflect(dir);
        let p = surface_point(tri, hit);
        let offset = (offset_origin(tri, hit, reflected) - p).length() / reflected.length();
        Ray::new(self.virtual_eye(eye), reflected, hit.t + offset, f32::INFINITY)
    }
}

/// The reflected rays of the `lanes` of a primary packet from `eye` (the rays `dirs`, hits
/// `hits`) whose hit triangle `is_mirror` accepts, grouped into omni-directional packets by
/// virtual eye: at most four packets, each with the lanes of one virtual eye (others
/// invalid). Lane `l` of every returned packet is lane `l` of the primary packet. A lane
/// whose reflected ray is not finite (a NaN or infinite `eye`, direction or hit) is left out,
/// like a lane that hit no mirror.
pub fn reflections(
    tree: &KdTree,
    eye: Vec3,
    dirs: &[Vec3; 4],
    hits: &[Option<Hit>; 4],
    is_mirror: impl Fn(u32) -> bool,
) -> Vec<OmniPacket> {
    let rays: [Option<Ray>; 4] = std::array::from_fn(|lane| {
        let hit = hits[lane].filter(|h| is_mirror(h.prim))?;
        let tri = tree.triangle(hit.prim);
        let mirror = Mirror::of_triangle(&tri)?;
        Some(mirror.reflected_ray(eye, dirs[lane], &tri, &hit)).filter(Ray::is_valid)
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
        let m = Mirror::of_triangle(&tri).unwrap();
        assert_eq!(m.normal, DVec3::Y);
        let eye = Vec3::new(0.3, 2.0, -1.0);
        assert_eq!(m.virtual_eye(eye), Vec3::new(0.3, -2.0, -1.0));
        let dir = Vec3::new(0.2, -1.0, 0.4).normalize();
        let t = 2.0 / -dir.y;
        let p = eye + t * dir;
        // The barycentrics of `p` on `tri`: `p = u Z + v X`.
        let hit = Hit { t, u: p.z, v: p.x, prim: 0 };
        let ray = m.reflected_ray(eye, dir, &tri, &hit);
        assert!((ray.origin + t * ray.dir - p).length() < 1e-5);
        assert!(ray.dir.y > 0.0 && ray.t_min > t);
    }

    #[test]
    fn non_finite_input_gives_no_mirror_and_no_reflected_lane() {
        let tri = [Vec3::ZERO, Vec3::Z, Vec3::X];
        for bad in [f32::NAN, f32::INFINITY] {
            let mut t = tri;
            t[1].y = bad;
            assert_eq!(Mirror::of_triangle(&t), None);
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
