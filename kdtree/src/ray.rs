//! Rays and hits.

use glam::Vec3;

/// A ray `origin + t * dir` for `t` in `[t_min, t_max]`.
///
/// `inv_dir` is `1 / dir` per component, computed once; a zero component (`+0.0` or `-0.0`)
/// gives an infinity of the same sign, which the traversal handles (a ray parallel to a
/// split plane). `dir` need not be normalised; hit distances are in units of `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction.
    pub dir: Vec3,
    /// `1 / dir`, per component.
    pub inv_dir: Vec3,
    /// Start of the valid interval.
    pub t_min: f32,
    /// End of the valid interval (may be `f32::INFINITY`).
    pub t_max: f32,
}

/// Why a ray was rejected by [`Ray::try_new`].
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum RayError {
    /// The origin has a NaN or infinite component.
    #[error("ray origin {0} is not finite")]
    NonFiniteOrigin(Vec3),
    /// The direction has a NaN or infinite component, or is zero.
    #[error("ray direction {0} is not finite and non-zero")]
    BadDirection(Vec3),
    /// The interval is NaN, negative-infinite at its end, or empty (`t_min > t_max`).
    #[error("ray interval [{0}, {1}] is not a valid interval")]
    BadInterval(f32, f32),
}

impl Ray {
    /// A ray over `[t_min, t_max]`, with `inv_dir` precomputed.
    ///
    /// This does not reject its input (use [`Ray::try_new`] on user input), but gives every
    /// input a defined answer: an origin or direction with an infinite component is stored as
    /// all NaN (it names no point or no direction; left as it is, a direction of `-inf` made
    /// the triangle test report a hit at `t = 0`), and every query answers a ray with a NaN
    /// origin, direction or interval end with no hit, never a panic.
    ///
    /// A direction component so tiny that its reciprocal overflows (a denormal such as
    /// `6e-45`) is flushed to a zero of the same sign, so that traversal and the triangle
    /// tests see one consistent direction (the fuzzer found rays whose `1 / d` was infinite
    /// while `d` was not zero).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Ray {
        if !(origin.is_finite() && dir.is_finite()) {
            return Ray::non_finite(origin, dir, t_min, t_max);
        }
        let inv_dir = dir.recip();
        // Keep a component when its reciprocal is finite, or it is zero.
        let keep = inv_dir.is_finite_mask() | dir.cmpeq(Vec3::ZERO);
        let dir = if keep.all() { dir } else { Vec3::select(keep, dir, Vec3::ZERO.copysign(dir)) };
        Ray { origin, dir, inv_dir, t_min, t_max }
    }

    /// The segment from `start` to `end` as a ray over `[0, 1]`: `Ray::new(start, end -
    /// start, 0.0, 1.0)`, the form every shadow ray takes (to a point light or a light sample)
    /// and that the packet kernels rebuild from the ends (`packets::RayPacket::segments`).
    #[inline]
    pub fn segment(start: Vec3, end: Vec3) -> Ray {
        Ray::new(start, end - start, 0.0, 1.0)
    }

    /// [`Ray::new`] for an origin or direction with a NaN or infinite component: a vector
    /// with an infinite component becomes all NaN, one with only NaN stays as it is (and the
    /// direction's tiny components are flushed as for finite rays).
    #[cold]
    fn non_finite(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Ray {
        let nan_if_infinite = |v: Vec3| if (v.is_finite_mask() | v.is_nan_mask()).all() { v } else { Vec3::NAN };
        let (origin, dir) = (nan_if_infinite(origin), nan_if_infinite(dir));
        let inv_dir = dir.recip();
        let keep = inv_dir.is_finite_mask() | dir.cmpeq(Vec3::ZERO) | dir.is_nan_mask();
        let dir = if keep.all() { dir } else { Vec3::select(keep, dir, Vec3::ZERO.copysign(dir)) };
        Ray { origin, dir, inv_dir, t_min, t_max }
    }

    /// Like [`Ray::new`], but rejects non-finite origins, zero or non-finite directions and
    /// NaN or empty intervals (`t_max = +inf` is allowed).
    pub fn try_new(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Result<Ray, RayError> {
        Ray::validate(origin, dir, t_min, t_max)?;
        Ok(Ray::new(origin, dir, t_min, t_max))
    }

    /// Whether this ray passes [`Ray::try_new`]'s checks: a finite origin, a finite non-zero
    /// direction, and an interval that is neither NaN nor empty. Packets make the rays that
    /// fail them invalid lanes.
    #[inline]
    pub fn is_valid(&self) -> bool {
        Ray::validate(self.origin, self.dir, self.t_min, self.t_max).is_ok()
    }

    /// The one rule behind [`Ray::try_new`] and [`Ray::is_valid`].
    #[inline]
    fn validate(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Result<(), RayError> {
        if !origin.is_finite() {
            return Err(RayError::NonFiniteOrigin(origin));
        }
        if !dir.is_finite() || dir == Vec3::ZERO {
            return Err(RayError::BadDirection(dir));
        }
        if t_min.is_nan() || t_max.is_nan() || t_min > t_max || t_min == f32::INFINITY || t_max == f32::NEG_INFINITY {
            return Err(RayError::BadInterval(t_min, t_max));
        }
        Ok(())
    }

    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}

/// A ray-triangle hit: distance, barycentrics and the triangle.
///
/// The hit point is `(1 - u - v) * a + u * b + v * c` for the triangle's vertices `a, b, c`
/// in the order given to the build. Queries return `Option<Hit>`: `None` is "no hit".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// Barycentric weight of the second vertex.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
    /// Index of the triangle in the array given to [`crate::KdTree::build`].
    pub prim: u32,
}

/// The point of `hit` on its triangle `tri`, `a + u (b - a) + v (c - a)`, from the
/// barycentrics rather than from `origin + t dir`.
///
/// Whatever the ray, this lies within a few units in the last place of the triangle's largest
/// coordinate magnitude of the triangle's plane (any `u, v` give a point of the plane, their
/// rounding only moves it within the plane). A point computed along the ray carries the
/// rounding of the ray's own origin and length instead: a camera 8 units away from a hit near
/// the world origin puts it off the plane by more than a few ulps of the hit's coordinates.
/// A NaN or infinite vertex or barycentric gives a non-finite point (never a panic).
#[inline]
pub fn surface_point(tri: &[Vec3; 3], hit: &Hit) -> Vec3 {
    let [a, b, c] = *tri;
    a + hit.u * (b - a) + hit.v * (c - a)
}

/// The origin of a ray leaving the surface at `hit` on triangle `tri` (its vertices, as
/// given to the build) on the side that `toward` points into (any length, e.g. the vector to a
/// light), so that the new ray cannot hit the surface it starts on.
///
/// The one offset scheme of the workspace, used by every method that spawns rays (shadow
/// rays: `trace::shade::shadow_ray`):
///
/// 1. the hit point is taken from the barycentrics ([`surface_point`]), so its distance to the
///    triangle's plane is a few ulps of the triangle's largest coordinate magnitude `M`,
///    whatever the ray that found it;
/// 2. it is moved along the triangle's geometric normal (computed in `f64`, so tiny
///    triangles have one), turned to the side of `toward`, by `32 ulp(M)` (`M * 32 *
///    f32::EPSILON`, with a floor of `1e-30` for a triangle at the origin). That is above the
///    error of the point (step 1) and of any triangle test's plane distance for a ray starting
///    there (a few ulps of the coordinates involved), whatever the angle: at grazing angles
///    the distance along the ray and its error grow alike.
///
/// It is relative, so it works the same at every scene scale, and grows with the distance
/// from the world origin as the `f32` spacing does: 32 ulps, about `4e-6 M`, is 0.4% of an
/// object's size when the object sits 1000 times its size away from the origin. Features
/// thinner than that (a plate resting on a floor) let light leak under their contact.
/// Measured in `bench/tests/shadow_offset.rs`: planes and spheres, lights at 0.1 to 45
/// degrees, scales 1e-3 to 1e5, at the origin and moved 1000 times their size away, both
/// triangle tests: no self-shadowed pixel and no leak under the contacts of a plate 5% of the
/// scene's size thick and of a sphere.
///
/// Non-finite input never panics: a NaN or infinite vertex or barycentric gives a non-finite
/// origin (which [`Ray::try_new`] rejects and traversal answers with no hit), and a `toward`
/// that is NaN or perpendicular to the surface moves the point to the normal's own side.
#[inline]
pub fn offset_origin(tri: &[Vec3; 3], hit: &Hit, toward: Vec3) -> Vec3 {
    let p = surface_point(tri, hit);
    let [a, b, c] = tri.map(|v| v.as_dvec3());
    let n = (b - a).cross(c - a).normalize_or_zero().as_vec3();
    let n = if n.dot(toward) < 0.0 { -n } else { n };
    let m = tri[0].abs().max(tri[1].abs()).max(tri[2].abs()).max_element().max(1e-30);
    p + n * (m * (32.0 * f32::EPSILON))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_to_the_requested_side_by_a_relative_amount() {
        for scale in [1e-3f32, 1.0, 1e5] {
            let tri = [Vec3::new(1.0, 2.0, 3.0), Vec3::new(2.0, 2.0, 3.0), Vec3::new(1.0, 2.0, 4.0)].map(|v| v * scale);
            let hit = Hit { t: 1.0, u: 0.25, v: 0.5, prim: 0 };
            let p = surface_point(&tri, &hit);
            assert_eq!(p, Vec3::new(1.25, 2.0, 3.5) * scale);
            let o = offset_origin(&tri, &hit, -Vec3::Y);
            assert!(o.y < p.y && o.x == p.x && o.z == p.z);
            // 32 ulps of the largest coordinate, 4 * scale.
            assert!((p.y - o.y) / (4.0 * scale) < 1e-5 && (p.y - o.y) / (4.0 * scale) > 1e-6);
            assert!(offset_origin(&tri, &hit, Vec3::new(0.3, 1.0, 0.2)).y > p.y);
        }
        // A tiny triangle still has a normal.
        let tiny = [Vec3::ZERO, Vec3::new(1e-30, 0.0, 0.0), Vec3::new(0.0, 0.0, 1e-30)];
        assert!(offset_origin(&tiny, &Hit { t: 0.0, u: 0.3, v: 0.3, prim: 0 }, Vec3::Y).y > 0.0);
    }

    #[test]
    fn offset_origin_of_non_finite_input() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let hit = Hit { t: 1.0, u: 0.25, v: 0.25, prim: 0 };
        // The normal (b - a) x (c - a) is -Y: a NaN `toward` keeps its side.
        assert!(offset_origin(&tri, &hit, Vec3::NAN).y < 0.0);
        assert!(offset_origin(&tri, &hit, Vec3::new(0.0, f32::INFINITY, 0.0)).y > 0.0);
        for bad in [f32::NAN, f32::INFINITY] {
            let h = Hit { u: bad, ..hit };
            assert!(!surface_point(&tri, &h).is_finite());
            assert!(!offset_origin(&tri, &h, Vec3::Y).is_finite());
            let mut t = tri;
            t[2].z = bad;
            assert!(!offset_origin(&t, &hit, Vec3::Y).is_finite());
            assert!(Ray::try_new(offset_origin(&t, &hit, Vec3::Y), Vec3::Y, 0.0, 1.0).is_err());
        }
    }

    #[test]
    fn try_new_rejects_non_finite_input() {
        let o = Vec3::ZERO;
        let d = Vec3::X;
        assert!(Ray::try_new(o, d, 0.0, f32::INFINITY).is_ok());
        assert!(Ray::try_new(o, d, f32::NEG_INFINITY, 1.0).is_ok());
        assert!(matches!(
            Ray::try_new(Vec3::new(0.0, f32::NEG_INFINITY, 0.0), d, 0.0, 1.0),
            Err(RayError::NonFiniteOrigin(_))
        ));
        assert!(matches!(Ray::try_new(o, Vec3::new(f32::NAN, 1.0, 0.0), 0.0, 1.0), Err(RayError::BadDirection(_))));
        assert!(matches!(Ray::try_new(o, d, 0.0, f32::NAN), Err(RayError::BadInterval(..))));
        assert!(matches!(Ray::try_new(o, d, f32::INFINITY, f32::INFINITY), Err(RayError::BadInterval(..))));
        assert!(matches!(Ray::try_new(o, d, f32::NEG_INFINITY, f32::NEG_INFINITY), Err(RayError::BadInterval(..))));
        let e = Ray::try_new(Vec3::new(f32::NAN, 0.0, 0.0), d, 0.0, 1.0).unwrap_err().to_string();
        assert!(e.contains("origin") && e.contains("NaN"), "{e}");
        assert!(matches!(Ray::try_new(Vec3::new(f32::NAN, 0.0, 0.0), d, 0.0, 1.0), Err(RayError::NonFiniteOrigin(_))));
        assert!(matches!(
            Ray::try_new(o, Vec3::new(0.0, f32::INFINITY, 0.0), 0.0, 1.0),
            Err(RayError::BadDirection(_))
        ));
        assert!(matches!(Ray::try_new(o, Vec3::ZERO, 0.0, 1.0), Err(RayError::BadDirection(_))));
        assert!(matches!(Ray::try_new(o, d, f32::NAN, 1.0), Err(RayError::BadInterval(..))));
        assert!(matches!(Ray::try_new(o, d, 2.0, 1.0), Err(RayError::BadInterval(..))));
    }

    #[test]
    fn denormal_components_are_flushed_to_signed_zeros() {
        let r = Ray::new(Vec3::ZERO, Vec3::new(5.684_224_5e32, 6e-45, -6e-45), 0.0, 1.0);
        assert_eq!(r.dir.y.to_bits(), 0.0f32.to_bits());
        assert_eq!(r.dir.z.to_bits(), (-0.0f32).to_bits());
        assert_eq!((r.inv_dir.y, r.inv_dir.z), (f32::INFINITY, f32::NEG_INFINITY));
        assert_eq!(r.dir.x, 5.684_224_5e32);
    }

    #[test]
    fn infinite_origins_and_directions_become_nan() {
        let inf = f32::INFINITY;
        let r = Ray::new(Vec3::new(1.0, -inf, 2.0), Vec3::X, 0.0, 1.0);
        assert!(r.origin.x.is_nan() && r.origin.y.is_nan() && r.origin.z.is_nan() && r.dir == Vec3::X);
        let r = Ray::new(Vec3::ONE, Vec3::new(0.0, 0.0, -inf), 0.0, 1.0);
        assert!(r.dir.is_nan() && r.inv_dir.is_nan() && r.origin == Vec3::ONE);
        // NaN stays where it is; tiny components of a NaN direction are still flushed.
        let r = Ray::new(Vec3::new(f32::NAN, 1.0, 2.0), Vec3::new(f32::NAN, 6e-45, 1.0), 0.0, 1.0);
        assert_eq!((r.origin.y, r.origin.z), (1.0, 2.0));
        assert!(r.dir.x.is_nan() && r.dir.y.to_bits() == 0 && r.dir.z == 1.0);
        // Infinite intervals are meaningful and kept.
        let r = Ray::new(Vec3::ONE, Vec3::X, f32::NEG_INFINITY, inf);
        assert_eq!((r.t_min, r.t_max), (f32::NEG_INFINITY, inf));
    }

    #[test]
    fn zero_components_give_signed_infinities() {
        let r = Ray::new(Vec3::ZERO, Vec3::new(0.0, -0.0, 1.0), 0.0, 1.0);
        assert_eq!(r.inv_dir.x, f32::INFINITY);
        assert_eq!(r.inv_dir.y, f32::NEG_INFINITY);
    }
}
