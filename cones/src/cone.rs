//! A cone and where it meets an axis-aligned split plane (thesis 4.1.7, Eq. 4.1-4.8, and the
//! per-cone precomputation of Listing 4.4).
//!
//! A cone has an apex `s`, a unit axis `v` and a half-angle `α`. Its cross-section at axis
//! distance `t >= 0` is the disk of centre `s + t v` and radius `t tan α` perpendicular to `v`.
//! Seen along a plane's unit normal `n` (here a coordinate axis), that disk covers
//! `n·s + t (n·v) ± t tan α sqrt(1 - (n·v)²)`: the projection of a disk of radius `ρ` onto a
//! direction at angle `φ` to its normal has half-length `ρ sin φ`. The disk therefore meets
//! the plane `n·x = d` exactly when
//!
//! ```text
//! t (c - b) <= d - n·s <= t (c + b),   c = n·v,  b = tan α sqrt(1 - c²),
//! ```
//!
//! whose boundaries are Eq. 4.8, `t = (d - n·s) / (n·v ± tan α sqrt(1 - (n·v)²))`: the two
//! axis distances `t1 <= t2` at which the cone's outer edge touches the plane. Listing 4.4
//! precomputes the two reciprocals per axis, so that a traversal step is one subtraction
//! (`split - origin[axis]`) and two multiplications (Listing 4.3).
//!
//! The cases the formula leaves open, decided here (and tested in `tests` by name):
//! - a negative distance means the plane is met *behind* the apex, which no ray of the cone
//!   reaches: it becomes `+inf` (the "negative distance compensation" of Listing 4.5). When
//!   both are negative the cone never meets the plane in front of its apex: `(inf, inf)`;
//! - a generator parallel to the plane (`c ± b = 0`) meets it at infinity: the division by
//!   zero gives `±inf`, and the rule above keeps the side that is reached;
//! - when the cone *straddles* the plane's direction (`c - b < 0 < c + b`, some generators
//!   go up and some down), exactly one distance is positive and the interval is
//!   `[t1, +inf)`: every later cross-section still meets the plane;
//! - the apex on the plane (`d = n·s`, where the listing computes `0 * k` and would report
//!   the single point `t = 0`) is `[0, +inf)` when the cone straddles or touches the plane's
//!   direction, else just `[0, 0]`. The traversal does not use this value: it visits both
//!   children over the whole interval there, as the packet methods do.
//! - `α = 0` gives `b = 0` and both distances equal the single ray's `(d - n·s) / (n·v)`.

use glam::{DVec3, Vec3};

/// The widest half-angle a [`Cone`] may have: 89.9 degrees (`tan α` about 573). Wider sets
/// of directions are not bounded by a cone; the traversal falls back to a pyramid for them.
pub const MAX_HALF_ANGLE: f64 = 89.9 * std::f64::consts::PI / 180.0;

/// Why a cone could not be made.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ConeError {
    /// An input was NaN or infinite.
    #[error("cone {0} is not finite")]
    NotFinite(&'static str),
    /// The axis (or every direction given) has zero length.
    #[error("cone axis has zero length")]
    ZeroAxis,
    /// The half-angle is negative or not below [`MAX_HALF_ANGLE`].
    #[error("cone half-angle {0} rad is outside [0, 89.9 degrees]")]
    BadAngle(f64),
}

/// A cone of apex `apex`, unit axis `axis` and half-angle `atan(tan_alpha)`, in double
/// precision (thesis 4.1.7, Figure 4.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    /// The apex `s`.
    pub apex: DVec3,
    /// The unit axis `v`.
    pub axis: DVec3,
    /// `tan α`, `α` the angle between the axis and the outer edge.
    pub tan_alpha: f64,
}

/// Listing 4.4's per-cone values for each axis `k` (lanes `[x, y, z, 0]`):
/// `k0[k] = 1 / (v[k] + b[k])` and `k1[k] = 1 / (v[k] - b[k])`, with
/// `b[k] = tan α sqrt(1 - v[k]²)`, computed in `f64` and rounded to `f32`. A split plane
/// `dist = split - apex[k]` away is met at axis distances `dist * k0[k]` and `dist * k1[k]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeFactors {
    /// `1 / (v + b)` per axis.
    pub k0: [f32; 4],
    /// `1 / (v - b)` per axis.
    pub k1: [f32; 4],
}

/// The angle between two directions (any length, not zero) in radians, in `f64`:
/// `atan2(|a x b|, a·b)`, accurate for tiny angles too.
#[inline]
pub fn angle_between(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// `tan(alpha)` rounded up by a few ulps, so that `atan` of it is not below `alpha` and the
/// directions a cone was made to hold test as inside it.
#[inline]
fn tan_up(alpha: f64) -> f64 {
    alpha.tan() * (1.0 + 8.0 * f64::EPSILON)
}

impl Cone {
    /// A cone of apex `apex`, axis `axis` (any non-zero length) and half-angle `half_angle`
    /// radians, `0 <= half_angle <= MAX_HALF_ANGLE`. Non-finite input is an error naming it.
    pub fn new(apex: Vec3, axis: Vec3, half_angle: f64) -> Result<Cone, ConeError> {
        if !half_angle.is_finite() {
            return Err(ConeError::NotFinite("half-angle"));
        }
        if !(0.0..=MAX_HALF_ANGLE).contains(&half_angle) {
            return Err(ConeError::BadAngle(half_angle));
        }
        Cone::from_tan(apex.as_dvec3(), axis.as_dvec3(), half_angle.tan())
    }

    /// [`Cone::new`] from `tan α` in `f64`.
    pub fn from_tan(apex: DVec3, axis: DVec3, tan_alpha: f64) -> Result<Cone, ConeError> {
        if !apex.is_finite() {
            return Err(ConeError::NotFinite("apex"));
        }
        if !axis.is_finite() {
            return Err(ConeError::NotFinite("axis"));
        }
        if !tan_alpha.is_finite() {
            return Err(ConeError::NotFinite("tan of the half-angle"));
        }
        let axis = axis.normalize_or_zero();
        if axis == DVec3::ZERO {
            return Err(ConeError::ZeroAxis);
        }
        if !(0.0..=MAX_HALF_ANGLE.tan()).contains(&tan_alpha) {
            return Err(ConeError::BadAngle(tan_alpha.atan()));
        }
        Ok(Cone { apex, axis, tan_alpha })
    }

    /// The cone of apex `apex` and axis `axis` with the smallest half-angle holding every
    /// direction of `dirs`, opened by `margin` radians (for the rounding of directions that
    /// are bounded without being looked at, see [`crate::tile`]). A NaN or infinite apex,
    /// axis, direction or margin is [`ConeError::NotFinite`] naming it.
    pub fn around(apex: Vec3, axis: DVec3, dirs: &[Vec3], margin: f64) -> Result<Cone, ConeError> {
        if !margin.is_finite() {
            return Err(ConeError::NotFinite("margin"));
        }
        let mut alpha: f64 = 0.0;
        for d in dirs {
            if !d.is_finite() {
                return Err(ConeError::NotFinite("direction"));
            }
            if *d != Vec3::ZERO {
                alpha = alpha.max(angle_between(axis, d.as_dvec3()));
            }
        }
        let alpha = alpha + margin;
        if alpha.is_nan() || alpha > MAX_HALF_ANGLE {
            return Err(ConeError::BadAngle(alpha));
        }
        Cone::from_tan(apex.as_dvec3(), axis, tan_up(alpha))
    }

    /// The narrowest cone of apex `apex` holding the directions `dirs` (up to 8, e.g. the
    /// corner rays of a tile), opened by `margin` radians. The smallest enclosing cone of
    /// unit vectors is the smallest spherical cap around them, which is fixed by two of
    /// them (a diameter) or three (a circumcircle): every pair and triple is tried, and the
    /// candidate axis whose farthest direction is nearest (largest smallest cosine) is kept.
    /// For more than 8 directions the axis is their mean ([`Cone::around`]). Allocates
    /// nothing: it runs once per tile. A NaN or infinite apex, direction or margin is
    /// [`ConeError::NotFinite`] naming it.
    pub fn smallest_enclosing(apex: Vec3, dirs: &[Vec3], margin: f64) -> Result<Cone, ConeError> {
        if !margin.is_finite() {
            return Err(ConeError::NotFinite("margin"));
        }
        if dirs.len() > 8 {
            let mean: DVec3 = dirs.iter().map(|d| d.as_dvec3().normalize_or_zero()).sum();
            if !mean.is_finite() {
                return Err(ConeError::NotFinite("direction"));
            }
            return Cone::around(apex, mean.normalize_or_zero(), dirs, margin);
        }
        let mut units = [DVec3::ZERO; 8];
        let mut n = 0;
        for d in dirs {
            if !d.is_finite() {
                return Err(ConeError::NotFinite("direction"));
            }
            let u = d.as_dvec3().normalize_or_zero();
            if u != DVec3::ZERO {
                units[n] = u;
                n += 1;
            }
        }
        let units = &units[..n];
        // The cosine of the widest angle from `axis` to a direction.
        let min_cos = |axis: DVec3| units.iter().map(|u| axis.dot(*u)).fold(f64::INFINITY, f64::min);
        let mut best = (f64::NEG_INFINITY, DVec3::ZERO);
        let mut consider = |axis: DVec3| {
            if axis != DVec3::ZERO && axis.is_finite() {
                let c = min_cos(axis);
                if c > best.0 {
                    best = (c, axis);
                }
            }
        };
        consider(units.iter().sum::<DVec3>().normalize_or_zero());
        for i in 0..n {
            for j in i + 1..n {
                consider((units[i] + units[j]).normalize_or_zero());
                for k in j + 1..n {
                    let normal = (units[j] - units[i]).cross(units[k] - units[i]).normalize_or_zero();
                    consider(if normal.dot(units[i]) < 0.0 { -normal } else { normal });
                }
            }
        }
        if best.1 == DVec3::ZERO {
            return Err(ConeError::ZeroAxis);
        }
        // The half-angle from the nearest cosine, exactly as `contains` measures it: the
        // largest `atan2` angle over the directions (four of them for a tile).
        let alpha = units.iter().map(|u| angle_between(best.1, *u)).fold(0.0, f64::max) + margin;
        if alpha.is_nan() || alpha > MAX_HALF_ANGLE {
            return Err(ConeError::BadAngle(alpha));
        }
        Cone::from_tan(apex.as_dvec3(), best.1, tan_up(alpha))
    }

    /// The cone from `apex` tangent to the sphere of centre `center` and radius `radius`
    /// (Figure 4.5: every ray from the apex to a point of the sphere lies inside it),
    /// `sin α = radius / |center - apex|`. `None` when the apex is inside the sphere (or the
    /// cone would be wider than [`MAX_HALF_ANGLE`]) or the input is not finite.
    pub fn tangent_to_sphere(apex: Vec3, center: Vec3, radius: f32) -> Option<Cone> {
        let to = center.as_dvec3() - apex.as_dvec3();
        let (dist, r) = (to.length(), f64::from(radius));
        if !(r >= 0.0 && dist > r) {
            return None;
        }
        let tan_alpha = r / (dist * dist - r * r).sqrt();
        Cone::from_tan(apex.as_dvec3(), to, tan_alpha).ok()
    }

    /// The half-angle `α` in radians.
    pub fn half_angle(&self) -> f64 {
        self.tan_alpha.atan()
    }

    /// Whether the ray from the apex along `dir` lies inside the cone (the zero direction and
    /// directions with a NaN or infinite component do not).
    pub fn contains(&self, dir: Vec3) -> bool {
        dir != Vec3::ZERO && dir.is_finite() && angle_between(self.axis, dir.as_dvec3()) <= self.half_angle()
    }

    /// `b = tan α sqrt(1 - v[k]²)` for axis `k`, the square root taken as the length of the
    /// axis's other two components (no cancellation when `v[k]` is close to 1).
    #[inline]
    fn spread(&self, k: usize) -> f64 {
        let v = self.axis.to_array();
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        self.tan_alpha * v[i].hypot(v[j])
    }

    /// Eq. 4.8 with the cases of the module documentation: the axis distances `(t1, t2)`,
    /// `t1 <= t2`, between which the cone's cross-section meets the plane `x[k] = split`;
    /// `(inf, inf)` when it never does in front of the apex (and for a NaN `split`). In
    /// `f64`; the reference the single-precision traversal step is checked against.
    pub fn split_distances(&self, k: usize, split: f64) -> (f64, f64) {
        let d = split - self.apex[k];
        let c = self.axis[k];
        let b = self.spread(k);
        if d == 0.0 {
            return if c - b <= 0.0 && c + b >= 0.0 { (0.0, f64::INFINITY) } else { (0.0, 0.0) };
        }
        let fix = |t: f64| if t < 0.0 || t.is_nan() { f64::INFINITY } else { t };
        let (a, e) = (fix(d / (c + b)), fix(d / (c - b)));
        (a.min(e), a.max(e))
    }

    /// Listing 4.4: the per-axis reciprocals the traversal multiplies plane distances by.
    pub fn factors(&self) -> ConeFactors {
        let mut k0 = [0.0f32; 4];
        let mut k1 = [0.0f32; 4];
        for k in 0..3 {
            let (c, b) = (self.axis[k], self.spread(k));
            k0[k] = (1.0 / (c + b)) as f32;
            k1[k] = (1.0 / (c - b)) as f32;
        }
        ConeFactors { k0, k1 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use packets::bound::plane_interval;
    use proptest::prelude::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    /// Whether the cross-section disk at axis distance `t` meets the plane `x[k] = split`,
    /// found by sampling the disk's boundary (independent of Eq. 4.8): the disk meets the
    /// plane when its boundary has points on both sides (or on it).
    fn disk_meets_plane(cone: &Cone, k: usize, split: f64, t: f64) -> (f64, f64) {
        let v = cone.axis;
        let helper = if v.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let e1 = v.cross(helper).normalize();
        let e2 = v.cross(e1);
        let (centre, rho) = (cone.apex + t * v, t * cone.tan_alpha);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..720 {
            let phi = i as f64 * PI / 360.0;
            let p = centre + rho * (phi.cos() * e1 + phi.sin() * e2);
            lo = lo.min(p[k] - split);
            hi = hi.max(p[k] - split);
        }
        (lo, hi)
    }

    /// A random ray inside the cone: a direction at angle `frac * α` from the axis.
    fn ray_inside(cone: &Cone, frac: f64, phi: f64) -> DVec3 {
        let v = cone.axis;
        let helper = if v.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let e1 = v.cross(helper).normalize();
        let e2 = v.cross(e1);
        let a = frac * cone.half_angle();
        v * a.cos() + (phi.cos() * e1 + phi.sin() * e2) * a.sin()
    }

    fn cone(apex: [f64; 3], axis: [f64; 3], alpha: f64) -> Cone {
        Cone::from_tan(DVec3::from_array(apex), DVec3::from_array(axis), alpha.tan()).unwrap()
    }

    /// The interval agrees with the sampled disk: inside it the disk's boundary spans the
    /// plane, outside it (by a margin) the disk lies on one side.
    fn check_against_sampling(c: &Cone, k: usize, split: f64) {
        let (t1, t2) = c.split_distances(k, split);
        assert!(t1 <= t2, "t1 {t1} > t2 {t2}");
        let scale = (split - c.apex[k]).abs().max(1e-3);
        for i in 0..=40 {
            let t = scale * 10f64.powf(-3.0 + i as f64 * 0.15);
            let (lo, hi) = disk_meets_plane(c, k, split, t);
            // The sampled boundary misses the true extremes by at most 1 - cos(pi/720) of
            // the radius.
            let slack = 1e-4 * (t * c.tan_alpha) + 1e-9 * scale;
            let meets = lo <= slack && hi >= -slack;
            let clearly_meets = lo <= -slack && hi >= slack;
            let inside = t >= t1 * (1.0 - 1e-9) && t <= t2 * (1.0 + 1e-9);
            if clearly_meets {
                assert!(
                    inside,
                    "disk at t = {t} meets the plane but [{t1}, {t2}] leaves it out ({c:?}, axis {k}, split {split})"
                );
            }
            if inside && t > t1 * (1.0 + 1e-6) && t < t2 * (1.0 - 1e-6) {
                assert!(meets, "t = {t} inside [{t1}, {t2}] but the disk spans [{lo}, {hi}] ({c:?})");
            }
        }
    }

    /// Every ray inside the cone that crosses the plane does so at an axis distance inside
    /// the interval (conservative), and the single-precision traversal step's interval
    /// (Listing 4.3 with the factors of Listing 4.4, widened) holds the exact one.
    fn check_conservative(c: &Cone, k: usize, split: f64) {
        let (t1, t2) = c.split_distances(k, split);
        for i in 0..64 {
            let dir = ray_inside(c, (i % 8) as f64 / 7.0, (i / 8) as f64 * PI / 4.0 + 0.1);
            let t_ray = (split - c.apex[k]) / dir[k];
            if t_ray > 0.0 && t_ray.is_finite() {
                let tau = t_ray * dir.dot(c.axis);
                let tol = 1e-9 * tau.abs().max(1e-300);
                assert!(
                    tau >= t1 - tol && tau <= t2 + tol,
                    "ray {dir} crosses at axis distance {tau}, outside [{t1}, {t2}] ({c:?}, axis {k}, split {split})"
                );
            }
        }
        let dist = (split as f32) - (c.apex[k] as f32);
        if dist != 0.0 && dist.is_finite() && f64::from(dist) == split - c.apex[k] {
            let f = c.factors();
            let (a, b) = plane_interval(dist, f.k0[k], f.k1[k]);
            assert!(
                f64::from(a) <= t1 && f64::from(b) >= t2,
                "f32 step [{a}, {b}] does not hold the exact [{t1}, {t2}] ({c:?}, axis {k}, split {split})"
            );
        }
    }

    fn check(c: &Cone, k: usize, split: f64) {
        check_against_sampling(c, k, split);
        check_conservative(c, k, split);
    }

    #[test]
    fn axis_parallel_to_the_plane() {
        // n·v = 0: the cone straddles the plane's direction; the plane is met from
        // d / b on, forever.
        let c = cone([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.3);
        let (t1, t2) = c.split_distances(0, 2.0);
        assert!((t1 - 2.0 / 0.3f64.tan()).abs() < 1e-12 && t2 == f64::INFINITY);
        check(&c, 0, 2.0);
        check(&c, 0, -2.0);
    }

    #[test]
    fn axis_along_the_normal() {
        // n·v = ±1: the square root is 0 and both distances are the axis's.
        let c = cone([1.0, 2.0, 3.0], [1.0, 0.0, 0.0], 0.4);
        assert_eq!(c.split_distances(0, 5.0), (4.0, 4.0));
        let back = cone([1.0, 2.0, 3.0], [-1.0, 0.0, 0.0], 0.4);
        assert_eq!(back.split_distances(0, -3.0), (4.0, 4.0));
        assert_eq!(back.split_distances(0, 5.0), (f64::INFINITY, f64::INFINITY));
        check(&c, 0, 5.0);
        check(&back, 0, -3.0);
    }

    #[test]
    fn apex_on_the_plane() {
        let straddling = cone([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.5);
        assert_eq!(straddling.split_distances(0, 1.0), (0.0, f64::INFINITY));
        let away = cone([1.0, 0.0, 0.0], [1.0, 0.2, 0.0], 0.1);
        assert_eq!(away.split_distances(0, 1.0), (0.0, 0.0));
    }

    #[test]
    fn vanishing_angle_agrees_with_the_single_ray() {
        let dir = DVec3::new(0.3, -0.5, 0.8).normalize();
        for alpha in [0.0, 1e-12, 1e-9, 1e-6] {
            let c = cone([0.5, 0.25, -1.0], dir.to_array(), alpha);
            for k in 0..3 {
                let single = (2.0 - c.apex[k]) / dir[k];
                let (t1, t2) = c.split_distances(k, 2.0);
                if single > 0.0 {
                    assert!((t1 - single).abs() <= 1e-5 * single && (t2 - single).abs() <= 1e-5 * single);
                } else {
                    assert_eq!((t1, t2), (f64::INFINITY, f64::INFINITY));
                }
                if alpha == 0.0 {
                    assert_eq!(t1, t2);
                }
            }
        }
    }

    #[test]
    fn angle_near_ninety_degrees() {
        let c = Cone::new(Vec3::ZERO, Vec3::new(0.2, 1.0, 0.1), MAX_HALF_ANGLE).unwrap();
        for k in 0..3 {
            for split in [-3.0, 0.5, 7.0] {
                check(&c, k, split);
            }
        }
        assert!(matches!(Cone::new(Vec3::ZERO, Vec3::Y, FRAC_PI_2), Err(ConeError::BadAngle(_))));
    }

    #[test]
    fn generator_parallel_to_the_plane() {
        // alpha = 45 degrees with the axis at 45 degrees to x: one generator runs along the
        // plane's direction (c - b = 0) and meets it at infinity.
        let c = cone([0.0, 0.0, 0.0], [1.0, 1.0, 0.0], std::f64::consts::FRAC_PI_4);
        let (c0, b0) = (c.axis[0], c.spread(0));
        assert!((c0 - b0).abs() < 1e-15);
        let (t1, t2) = c.split_distances(0, 3.0);
        assert!(t1.is_finite() && t1 > 0.0);
        assert!(t2 > 1e14, "{t2}");
        check(&c, 0, 3.0);
        check(&c, 0, -3.0);
        // Exactly parallel generator (c + b = 0) with the split behind: never met.
        let mut exact = Cone { apex: DVec3::ZERO, axis: DVec3::new(-0.6, 0.8, 0.0), tan_alpha: 0.75 };
        // Nudge tan(alpha) by ulps until the denominator is exactly zero.
        for _ in 0..64 {
            let sum = exact.axis[0] + exact.spread(0);
            if sum == 0.0 {
                break;
            }
            exact.tan_alpha =
                f64::from_bits(if sum > 0.0 { exact.tan_alpha.to_bits() - 1 } else { exact.tan_alpha.to_bits() + 1 });
        }
        assert_eq!(exact.axis[0] + exact.spread(0), 0.0);
        assert_eq!(exact.split_distances(0, 1.0), (f64::INFINITY, f64::INFINITY));
        let (t1, t2) = exact.split_distances(0, -1.0);
        assert!(t1.is_finite() && t2 == f64::INFINITY);
    }

    #[test]
    fn planes_behind_the_apex() {
        let c = cone([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.2);
        assert_eq!(c.split_distances(2, -1.0), (f64::INFINITY, f64::INFINITY));
        let f = c.factors();
        let (a, b) = plane_interval(-1.0, f.k0[2], f.k1[2]);
        assert_eq!((a, b), (f32::INFINITY, f32::INFINITY));
    }

    #[test]
    fn negative_zero_components() {
        let c = Cone::new(Vec3::new(-0.0, 0.0, -0.0), Vec3::new(-0.0, 0.0, 1.0), 0.0).unwrap();
        // The single ray never crosses x = 1 or y = 1; the cone of angle 0 neither.
        assert_eq!(c.split_distances(0, 1.0), (f64::INFINITY, f64::INFINITY));
        assert_eq!(c.split_distances(1, -1.0), (f64::INFINITY, f64::INFINITY));
        let f = c.factors();
        assert_eq!(plane_interval(1.0, f.k0[0], f.k1[0]), (f32::INFINITY, f32::INFINITY));
        assert_eq!(plane_interval(-1.0, f.k0[0], f.k1[0]), (f32::INFINITY, f32::INFINITY));
        assert_eq!(c.split_distances(2, 3.0), (3.0, 3.0));
    }

    #[test]
    fn bad_input_is_an_error_naming_it() {
        assert_eq!(Cone::new(Vec3::NAN, Vec3::Y, 0.1), Err(ConeError::NotFinite("apex")));
        assert_eq!(Cone::new(Vec3::ZERO, Vec3::INFINITY, 0.1), Err(ConeError::NotFinite("axis")));
        assert_eq!(Cone::new(Vec3::ZERO, Vec3::ZERO, 0.1), Err(ConeError::ZeroAxis));
        assert_eq!(Cone::new(Vec3::ZERO, Vec3::Y, f64::NAN), Err(ConeError::NotFinite("half-angle")));
        assert_eq!(Cone::new(Vec3::ZERO, Vec3::Y, -0.1), Err(ConeError::BadAngle(-0.1)));
        assert!(Cone::smallest_enclosing(Vec3::ZERO, &[Vec3::X, -Vec3::X], 0.0).is_err());
        assert!(Cone::tangent_to_sphere(Vec3::ZERO, Vec3::new(0.5, 0.0, 0.0), 1.0).is_none());
    }

    #[test]
    fn non_finite_input_is_an_error_naming_it() {
        let (nan, inf) = (f64::NAN, f64::INFINITY);
        let nan3 = Vec3::new(0.0, f32::NAN, 0.0);
        assert_eq!(Cone::new(Vec3::ZERO, Vec3::Y, inf), Err(ConeError::NotFinite("half-angle")));
        assert_eq!(Cone::from_tan(DVec3::ZERO, DVec3::Y, nan), Err(ConeError::NotFinite("tan of the half-angle")));
        assert_eq!(Cone::from_tan(DVec3::ZERO, DVec3::Y, inf), Err(ConeError::NotFinite("tan of the half-angle")));
        assert_eq!(Cone::from_tan(DVec3::NEG_INFINITY, DVec3::Y, 0.1), Err(ConeError::NotFinite("apex")));
        let dirs = [Vec3::new(0.1, 0.0, 1.0), Vec3::new(-0.1, 0.0, 1.0), Vec3::new(0.0, 0.1, 1.0)];
        let many = [dirs[0]; 9];
        for m in [nan, inf, -inf] {
            assert_eq!(Cone::around(Vec3::ZERO, DVec3::Z, &dirs, m), Err(ConeError::NotFinite("margin")));
            assert_eq!(Cone::smallest_enclosing(Vec3::ZERO, &dirs, m), Err(ConeError::NotFinite("margin")));
            assert_eq!(Cone::smallest_enclosing(Vec3::ZERO, &many, m), Err(ConeError::NotFinite("margin")));
        }
        assert_eq!(Cone::around(Vec3::ZERO, DVec3::Z, &[dirs[0], nan3], 0.0), Err(ConeError::NotFinite("direction")));
        assert_eq!(Cone::around(Vec3::ZERO, DVec3::NAN, &dirs, 0.0), Err(ConeError::NotFinite("axis")));
        assert_eq!(Cone::around(nan3, DVec3::Z, &dirs, 0.0), Err(ConeError::NotFinite("apex")));
        assert_eq!(
            Cone::smallest_enclosing(Vec3::ZERO, &[dirs[0], Vec3::INFINITY], 0.0),
            Err(ConeError::NotFinite("direction"))
        );
        let mut nine = many;
        nine[8] = nan3;
        assert_eq!(Cone::smallest_enclosing(Vec3::ZERO, &nine, 0.0), Err(ConeError::NotFinite("direction")));
        assert_eq!(Cone::smallest_enclosing(nan3, &dirs, 0.0), Err(ConeError::NotFinite("apex")));
        for (apex, centre, r) in [
            (nan3, Vec3::new(0.0, 5.0, 0.0), 1.0),
            (Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 0.0), 1.0),
            (Vec3::ZERO, Vec3::new(0.0, 5.0, 0.0), f32::NAN),
            (Vec3::ZERO, Vec3::new(0.0, 5.0, 0.0), f32::INFINITY),
        ] {
            assert!(Cone::tangent_to_sphere(apex, centre, r).is_none(), "{apex} {centre} {r}");
        }
        let c = Cone::smallest_enclosing(Vec3::ZERO, &dirs, 0.0).unwrap();
        assert!(c.contains(dirs[0]) && !c.contains(nan3) && !c.contains(Vec3::new(0.0, 0.0, f32::INFINITY)));
        // A wide cone whose axis has no zero component: atan2(inf, inf) would be 45 degrees.
        let wide = Cone::new(Vec3::ZERO, Vec3::new(0.1, 0.1, 1.0), 1.2).unwrap();
        assert!(wide.contains(Vec3::Z) && !wide.contains(Vec3::new(0.0, 0.0, f32::INFINITY)));
        assert_eq!(c.split_distances(0, nan), (inf, inf));
    }

    #[test]
    fn smallest_enclosing_cone_of_corner_rays() {
        // Four directions symmetric about z: the axis is z and the angle their common one.
        let d = [
            Vec3::new(1.0, 1.0, 4.0),
            Vec3::new(-1.0, 1.0, 4.0),
            Vec3::new(1.0, -1.0, 4.0),
            Vec3::new(-1.0, -1.0, 4.0),
        ];
        let c = Cone::smallest_enclosing(Vec3::ZERO, &d, 0.0).unwrap();
        assert!((c.axis - DVec3::Z).length() < 1e-12);
        assert!((c.half_angle() - angle_between(DVec3::Z, DVec3::new(1.0, 1.0, 4.0))).abs() < 1e-12);
        assert!(d.iter().all(|&v| c.contains(v)));
        // Two directions fix a diameter; a third inside adds nothing.
        let c = Cone::smallest_enclosing(Vec3::ZERO, &[Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.1)], 0.0).unwrap();
        assert!((c.half_angle() - PI / 4.0).abs() < 1e-12);
    }

    #[test]
    fn tangent_cone_holds_the_sphere() {
        let c = Cone::tangent_to_sphere(Vec3::ZERO, Vec3::new(0.0, 10.0, 0.0), 1.0).unwrap();
        assert!((c.half_angle() - (0.1f64).asin()).abs() < 1e-12);
        for i in 0..100 {
            let phi = i as f32 * 0.37;
            let theta = i as f32 * 0.11;
            let p = Vec3::new(0.0, 10.0, 0.0)
                + Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * 0.999;
            assert!(c.contains(p));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

        /// Random cones and planes: the interval is ordered, agrees with the sampled disk and
        /// holds every crossing of a ray inside the cone; the f32 step holds it.
        #[test]
        fn random_cones_and_planes(
            apex in prop::array::uniform3(-10.0f64..10.0),
            axis in prop::array::uniform3(-1.0f64..1.0),
            alpha in 0.0f64..1.5,
            k in 0usize..3,
            split in -20.0f64..20.0,
        ) {
            prop_assume!(DVec3::from_array(axis).length() > 1e-3);
            // f32-representable apex and split, so the f32 step sees the same plane.
            let apex = apex.map(|x| f64::from(x as f32));
            let split = f64::from(split as f32);
            let c = cone(apex, axis, alpha);
            check(&c, k, split);
        }

        /// Random rays inside random cones: the crossing lies in the interval.
        #[test]
        fn rays_inside_cross_within_the_interval(
            axis in prop::array::uniform3(-1.0f64..1.0),
            alpha in 1e-6f64..1.4,
            frac in 0.0f64..1.0,
            phi in 0.0f64..6.3,
            k in 0usize..3,
            split in -5.0f64..5.0,
        ) {
            prop_assume!(DVec3::from_array(axis).length() > 1e-3);
            let c = cone([0.0; 3], axis, alpha);
            let dir = ray_inside(&c, frac, phi);
            let t_ray = split / dir[k];
            let (t1, t2) = c.split_distances(k, split);
            if t_ray > 0.0 && t_ray.is_finite() {
                let tau = t_ray * dir.dot(c.axis);
                prop_assert!(tau >= t1 * (1.0 - 1e-9) && tau <= t2 * (1.0 + 1e-9), "{tau} outside [{t1}, {t2}]");
            }
        }
    }
}
