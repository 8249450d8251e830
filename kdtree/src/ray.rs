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
    /// This does not check its input: traversal of a ray with NaN components returns no hit
    /// and never panics, but the answer is meaningless. Use [`Ray::try_new`] on user input.
    ///
    /// A direction component so tiny that its reciprocal overflows (a denormal such as
    /// `6e-45`) is flushed to a zero of the same sign, so that traversal and the triangle
    /// tests see one consistent direction (the fuzzer found rays whose `1 / d` was infinite
    /// while `d` was not zero).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Ray {
        let inv_dir = dir.recip();
        // Keep a component when its reciprocal is finite, or it is zero, or it is NaN.
        let keep = inv_dir.is_finite_mask() | dir.cmpeq(Vec3::ZERO) | dir.is_nan_mask();
        let dir = if keep.all() { dir } else { Vec3::select(keep, dir, Vec3::ZERO.copysign(dir)) };
        Ray { origin, dir, inv_dir, t_min, t_max }
    }

    /// Like [`Ray::new`], but rejects non-finite origins, zero or non-finite directions and
    /// NaN or empty intervals (`t_max = +inf` is allowed).
    pub fn try_new(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Result<Ray, RayError> {
        if !origin.is_finite() {
            return Err(RayError::NonFiniteOrigin(origin));
        }
        if !dir.is_finite() || dir == Vec3::ZERO {
            return Err(RayError::BadDirection(dir));
        }
        if t_min.is_nan() || t_max.is_nan() || t_min > t_max || t_min == f32::INFINITY || t_max == f32::NEG_INFINITY {
            return Err(RayError::BadInterval(t_min, t_max));
        }
        Ok(Ray::new(origin, dir, t_min, t_max))
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

/// The origin of a ray leaving surface point `p` (with geometric normal `n`, any length, any
/// orientation) on the side that `toward` points into, so that the new ray cannot hit the
/// surface it starts on.
///
/// The one offset scheme of the workspace (every method that spawns rays uses it): `p` is
/// moved along the normal by a distance proportional to its own magnitude, 32 units in the
/// last place of its largest coordinate (the rounding error of computing a hit point from
/// `o + t d` or from barycentrics is a few ulps of the coordinates involved), with a floor of
/// `1e-30` for points at the origin. It is scale-aware: the same relative offset at scene
/// scales 1e-3 and 1e5 and far from the origin.
#[inline]
pub fn offset_origin(p: Vec3, n: Vec3, toward: Vec3) -> Vec3 {
    let n = n.normalize_or_zero();
    let n = if n.dot(toward) < 0.0 { -n } else { n };
    let scale = p.abs().max_element().max(1e-30);
    p + n * (scale * (32.0 * f32::EPSILON))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_to_the_requested_side_by_a_relative_amount() {
        for scale in [1e-3f32, 1.0, 1e5] {
            let p = Vec3::new(1.0, 2.0, 3.0) * scale;
            let o = offset_origin(p, Vec3::Y, -Vec3::Y);
            assert!(o.y < p.y && o.x == p.x);
            assert!((p.y - o.y) / (3.0 * scale) < 1e-5);
        }
    }

    #[test]
    fn try_new_rejects_non_finite_input() {
        let o = Vec3::ZERO;
        let d = Vec3::X;
        assert!(Ray::try_new(o, d, 0.0, f32::INFINITY).is_ok());
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
    fn zero_components_give_signed_infinities() {
        let r = Ray::new(Vec3::ZERO, Vec3::new(0.0, -0.0, 1.0), 0.0, 1.0);
        assert_eq!(r.inv_dir.x, f32::INFINITY);
        assert_eq!(r.inv_dir.y, f32::NEG_INFINITY);
    }
}
