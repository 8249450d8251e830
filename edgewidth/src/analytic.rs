//! The closed-form visible fraction of a spherical light behind a spherical occluder: the
//! case where every soft-shadow method can be measured in absolute terms.
//!
//! Seen from a point, the light and the occluder are spherical caps of angular radii `a`
//! (light, `sin a = r_l / d_l`) and `b` (occluder) whose centres are `g` apart. The occluded
//! solid angle is their overlap, which has a closed form (Tovchigrechko & Vakser 2001; a
//! textbook spherical-triangle result):
//!
//! ```text
//! g >= a + b:   0
//! g <= |a - b|: 2 pi (1 - cos(min(a, b)))
//! otherwise:    2 [pi - acos((cos g - cos a cos b) / (sin a sin b))
//!                     - acos((cos b - cos g cos a) / (sin g sin a)) cos a
//!                     - acos((cos a - cos g cos b) / (sin g sin b)) cos b]
//! ```
//!
//! and the visible fraction is `1 - overlap / (2 pi (1 - cos a))`, the quantity that
//! solid-angle-uniform samples of the light ([`crate::AreaLight::sample`]) estimate.

use glam::{DVec3, Vec3};
use std::f64::consts::PI;

/// The solid angle shared by two spherical caps of angular radii `a` and `b` whose centres
/// are `g` apart (all in radians, `a, b` in `[0, pi / 2]`). A NaN argument gives NaN.
pub fn cap_overlap(a: f64, b: f64, g: f64) -> f64 {
    if a.is_nan() || b.is_nan() || g.is_nan() {
        return f64::NAN;
    }
    if g >= a + b {
        return 0.0;
    }
    if g <= (a - b).abs() {
        return 2.0 * PI * (1.0 - a.min(b).cos());
    }
    let (ca, cb, cg) = (a.cos(), b.cos(), g.cos());
    let (sa, sb, sg) = (a.sin(), b.sin(), g.sin());
    let x = ((cg - ca * cb) / (sa * sb)).clamp(-1.0, 1.0).acos();
    let y = ((cb - cg * ca) / (sg * sa)).clamp(-1.0, 1.0).acos();
    let z = ((ca - cg * cb) / (sg * sb)).clamp(-1.0, 1.0).acos();
    (2.0 * (PI - x - y * ca - z * cb)).max(0.0)
}

/// The fraction of the spherical light (`light_center`, `light_radius`) visible from `p`
/// past the sphere (`occluder_center`, `occluder_radius`), which must lie nearer to `p` than
/// the light. `0` inside the occluder, `1` inside the light. A NaN or infinite input gives
/// NaN (the closed form has no answer to compare with), never a panic.
pub fn sphere_visible_fraction(
    p: Vec3,
    light_center: Vec3,
    light_radius: f32,
    occluder_center: Vec3,
    occluder_radius: f32,
) -> f64 {
    if !(p.is_finite()
        && light_center.is_finite()
        && light_radius.is_finite()
        && occluder_center.is_finite()
        && occluder_radius.is_finite())
    {
        return f64::NAN;
    }
    let p = p.as_dvec3();
    let (to_l, to_o): (DVec3, DVec3) = (light_center.as_dvec3() - p, occluder_center.as_dvec3() - p);
    let (dl, d_o) = (to_l.length(), to_o.length());
    if d_o <= f64::from(occluder_radius) {
        return 0.0;
    }
    if dl <= f64::from(light_radius) {
        return 1.0;
    }
    let a = (f64::from(light_radius) / dl).asin();
    let b = (f64::from(occluder_radius) / d_o).asin();
    let g = (to_l.dot(to_o) / (dl * d_o)).clamp(-1.0, 1.0).acos();
    let light_cap = 2.0 * PI * (1.0 - a.cos());
    (1.0 - cap_overlap(a, b, g) / light_cap).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// Monte Carlo estimate of the overlap of two caps: uniform directions in cap `a`
    /// (around +Z), counted inside cap `b` (around a direction `g` away).
    fn overlap_mc(a: f64, b: f64, g: f64, n: u32) -> f64 {
        let mut rng = Rng::new(5);
        let axis = DVec3::new(g.sin(), 0.0, g.cos());
        let mut inside = 0u32;
        for _ in 0..n {
            let cos = 1.0 - f64::from(rng.next_f32()) * (1.0 - a.cos());
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let phi = 2.0 * PI * f64::from(rng.next_f32());
            let d = DVec3::new(sin * phi.cos(), sin * phi.sin(), cos);
            inside += u32::from(d.dot(axis) >= b.cos());
        }
        f64::from(inside) / f64::from(n) * 2.0 * PI * (1.0 - a.cos())
    }

    #[test]
    fn overlap_matches_monte_carlo() {
        for (a, b, g) in [(0.2, 0.3, 0.25), (0.1, 0.1, 0.15), (0.3, 0.05, 0.3), (0.05, 0.4, 0.38), (0.5, 0.5, 0.9)] {
            let exact = cap_overlap(a, b, g);
            let mc = overlap_mc(a, b, g, 400_000);
            let cap = 2.0 * PI * (1.0 - f64::cos(a));
            assert!((exact - mc).abs() / cap < 0.01, "a {a} b {b} g {g}: {exact} vs {mc}");
        }
    }

    #[test]
    fn overlap_limits() {
        assert_eq!(cap_overlap(0.1, 0.2, 0.31), 0.0);
        let small = 2.0 * PI * (1.0 - f64::cos(0.1));
        assert!((cap_overlap(0.1, 0.3, 0.1) - small).abs() < 1e-12);
        // Continuous at the contained limit.
        assert!((cap_overlap(0.1, 0.3, 0.2 + 1e-9) - small).abs() < 1e-6);
        assert!(cap_overlap(0.1, 0.3, 0.4 - 1e-9) < 1e-6);
    }

    #[test]
    fn non_finite_input_gives_nan() {
        assert!(cap_overlap(f64::NAN, 0.1, 0.1).is_nan() && cap_overlap(0.1, f64::NAN, 0.1).is_nan());
        assert!(cap_overlap(0.1, 0.1, f64::NAN).is_nan());
        let (l, o) = (Vec3::new(0.0, 10.0, 0.0), Vec3::new(0.0, 2.0, 0.0));
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        assert!(sphere_visible_fraction(Vec3::ZERO, l, 0.5, o, 0.05).is_finite());
        for bad in [nan, inf] {
            for (p, lc, lr, oc, or) in [
                (Vec3::new(bad, 0.0, 0.0), l, 0.5, o, 0.05),
                (Vec3::ZERO, Vec3::new(0.0, bad, 0.0), 0.5, o, 0.05),
                (Vec3::ZERO, l, bad, o, 0.05),
                (Vec3::ZERO, l, 0.5, Vec3::new(0.0, 0.0, bad), 0.05),
                (Vec3::ZERO, l, 0.5, o, bad),
            ] {
                assert!(sphere_visible_fraction(p, lc, lr, oc, or).is_nan(), "{p} {lc} {lr} {oc} {or}");
            }
        }
    }

    #[test]
    fn visible_fraction_of_a_centred_and_a_clear_light() {
        let light = Vec3::new(0.0, 10.0, 0.0);
        // Occluder straight below the light and larger in angle: the light is hidden.
        assert_eq!(sphere_visible_fraction(Vec3::ZERO, light, 0.5, Vec3::new(0.0, 2.0, 0.0), 1.0), 0.0);
        // Occluder far to the side: all visible.
        assert_eq!(sphere_visible_fraction(Vec3::ZERO, light, 0.5, Vec3::new(5.0, 2.0, 0.0), 1.0), 1.0);
        let half = sphere_visible_fraction(Vec3::ZERO, light, 0.5, Vec3::new(0.0, 2.0, 0.0), 0.05);
        assert!(half > 0.0 && half < 1.0);
    }
}
