//! Eq. 5.1 of the thesis: the occlusion factor from an edge width, and the width `R` at which
//! a point counts as fully occluded, derived from the light's size.

/// The occlusion factor of Eq. 5.1 (Tsakok 2008, chapter 5): `0` for `edge_width <= 0`,
/// `edge_width / r` between `0` and `r`, `1` from `r` on (an infinite width, the answer for
/// an entry never closed, is `1`).
///
/// A NaN width, which the kernels of this crate never return, counts as fully occluded (the
/// hard-shadow answer), and so does any positive width with `r <= 0` or a NaN `r`.
#[inline]
pub fn occlusion_factor(edge_width: f32, r: f32) -> f32 {
    if edge_width.is_nan() {
        return 1.0;
    }
    if edge_width <= 0.0 {
        return 0.0;
    }
    if r.is_nan() || r <= 0.0 || edge_width >= r {
        return 1.0;
    }
    edge_width / r
}

/// The width `R` of Eq. 5.1 for a shadow ray of length `distance` towards a light of radius
/// `light_radius`, as a fraction of the ray (the unit of [`crate::edge_width`]).
///
/// The thesis leaves `R` as "a value proportional to the light radius". We take the chord
/// that blocks a light of diameter `2 * light_radius` seen along the ray: an occluder as
/// thick along the ray as the light is wide occludes fully. In ray units that is
/// `scale * 2 * light_radius / distance` (`scale = 1` by default, `--edge-scale` on the
/// command line). Returns `0` (hard shadows) for a point light or a degenerate distance, and
/// whenever the result would be NaN or infinite (a NaN or infinite input among them).
#[inline]
pub fn width_from_light(light_radius: f32, distance: f32, scale: f32) -> f32 {
    let r = scale * 2.0 * light_radius / distance;
    if r.is_finite() && r > 0.0 { r } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equation_5_1_is_piecewise_linear() {
        assert_eq!(occlusion_factor(0.0, 0.2), 0.0);
        assert_eq!(occlusion_factor(-1.0, 0.2), 0.0);
        assert_eq!(occlusion_factor(0.05, 0.2), 0.25);
        assert_eq!(occlusion_factor(0.2, 0.2), 1.0);
        assert_eq!(occlusion_factor(f32::INFINITY, 0.2), 1.0);
        assert_eq!(occlusion_factor(f32::NAN, 0.2), 1.0);
        // R = 0 is hard shadows: any crossing occludes fully.
        assert_eq!(occlusion_factor(1e-6, 0.0), 1.0);
        assert_eq!(occlusion_factor(0.05, f32::NAN), 1.0);
        assert_eq!(occlusion_factor(0.0, f32::NAN), 0.0);
        assert_eq!(occlusion_factor(0.05, f32::INFINITY), 0.0);
    }

    #[test]
    fn width_scales_with_the_light_and_shrinks_with_distance() {
        assert_eq!(width_from_light(0.5, 10.0, 1.0), 0.1);
        assert_eq!(width_from_light(0.5, 20.0, 1.0), 0.05);
        assert_eq!(width_from_light(0.5, 10.0, 2.0), 0.2);
        assert_eq!(width_from_light(0.0, 10.0, 1.0), 0.0);
        assert_eq!(width_from_light(0.5, 0.0, 1.0), 0.0);
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        for (radius, distance, scale) in
            [(nan, 10.0, 1.0), (0.5, nan, 1.0), (0.5, 10.0, nan), (inf, 10.0, 1.0), (0.5, 10.0, inf), (0.5, 1e-44, 1.0)]
        {
            assert_eq!(width_from_light(radius, distance, scale), 0.0, "{radius} {distance} {scale}");
        }
        // An infinite distance: an infinitely small light, hard shadows.
        assert_eq!(width_from_light(0.5, inf, 1.0), 0.0);
    }
}
