//! The 4x4 discontinuity filter of Benthin & Wald 2009 (4.5), applied after 4x4 interleaved
//! sampling ([`crate::sampling::InterleavedSets`]).
//!
//! Each pixel's value becomes the mean over the 4x4 block of pixels `x - 1 ..= x + 2`,
//! `y - 1 ..= y + 2` (which holds each of the 16 sample sets once) of the pixels on the same
//! surface: a neighbour counts when its depth is within `depth_tolerance` of the pixel's
//! (relative) and its normal within `normal_cos` of the pixel's. Background pixels (infinite
//! depth) are left as they are and never count. Non-finite input is defined too: a pixel with
//! a NaN depth is left as it is, a neighbour with a NaN depth or normal never counts, and the
//! pixel itself always counts, so NaN thresholds (or a NaN normal) leave its own value.
//!
//! The paper filters irradiance; with the shading separated (one sample at the light's centre
//! times the visible fraction, its 4.5) irradiance is a smooth shading term times the visible
//! fraction, and we filter the visible fraction, the quantity our errors are measured on.

use glam::Vec3;

/// The thresholds of the discontinuity filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterParams {
    /// Largest relative depth difference of a neighbour on the same surface.
    pub depth_tolerance: f32,
    /// Smallest cosine between the normals of a neighbour on the same surface.
    pub normal_cos: f32,
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams { depth_tolerance: 0.05, normal_cos: 0.9 }
    }
}

/// Per-pixel inputs of the filter, row-major `width * height`.
#[derive(Clone, Copy, Debug)]
pub struct GBuffer<'a> {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Primary hit distance (`+inf` for background).
    pub depth: &'a [f32],
    /// Geometric normal facing the viewer.
    pub normal: &'a [Vec3],
}

/// The filtered value of pixel `(x, y)` of `values` (row-major, like `g`); see the module
/// documentation for NaN and infinite depths, normals and thresholds. A NaN value among
/// those averaged makes the result NaN.
#[inline]
pub fn filter_pixel(x: u32, y: u32, values: &[f32], g: &GBuffer, params: &FilterParams) -> f32 {
    let w = g.width as usize;
    let c = y as usize * w + x as usize;
    let (dc, nc) = (g.depth[c], g.normal[c]);
    if !dc.is_finite() {
        return values[c];
    }
    let (mut sum, mut count) = (0.0f32, 0u32);
    for yy in y.saturating_sub(1)..(y + 3).min(g.height) {
        for xx in x.saturating_sub(1)..(x + 3).min(g.width) {
            let i = yy as usize * w + xx as usize;
            let d = g.depth[i];
            if i == c
                || (d.is_finite()
                    && (d - dc).abs() <= params.depth_tolerance * dc
                    && g.normal[i].dot(nc) >= params.normal_cos)
            {
                sum += values[i];
                count += 1;
            }
        }
    }
    // The pixel itself always counts, so count >= 1.
    sum / count as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_one_surface_and_stops_at_discontinuities() {
        // 8x4: left half at depth 1 facing +Z, right half at depth 3 (a step).
        let (w, h) = (8u32, 4u32);
        let depth: Vec<f32> = (0..w * h).map(|i| if i % w < 4 { 1.0 } else { 3.0 }).collect();
        let normal = vec![Vec3::Z; (w * h) as usize];
        let values: Vec<f32> = (0..w * h).map(|i| if i % w < 4 { (i % 2) as f32 } else { 0.25 }).collect();
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let p = FilterParams::default();
        // Inside the left half, a 4x4 block of alternating 0/1 averages to 1/2.
        assert_eq!(filter_pixel(1, 1, &values, &g, &p), 0.5);
        // At the step, the right half's values never leak in.
        assert_eq!(filter_pixel(4, 1, &values, &g, &p), 0.25);
        let left_edge = filter_pixel(3, 1, &values, &g, &p);
        assert!((0.0..=1.0).contains(&left_edge) && left_edge != 0.25);
        // A normal discontinuity also stops it.
        let mut tilted = normal.clone();
        for (i, n) in tilted.iter_mut().enumerate() {
            if i % w as usize == 2 {
                *n = Vec3::X;
            }
        }
        let g = GBuffer { normal: &tilted, ..g };
        assert_eq!(filter_pixel(2, 1, &values, &g, &p), 0.0);
    }

    #[test]
    fn non_finite_input_leaves_the_pixel_itself() {
        let (w, h) = (4u32, 4u32);
        let n = (w * h) as usize;
        let values: Vec<f32> = (0..n).map(|i| i as f32 / 16.0).collect();
        let (depth, normal) = (vec![2.0f32; n], vec![Vec3::Z; n]);
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let p = FilterParams::default();
        let mean = filter_pixel(1, 1, &values, &g, &p);
        assert!(mean != values[5] && mean.is_finite());
        // NaN thresholds, or a NaN normal at the pixel: nothing else counts, never 0 / 0.
        for params in [
            FilterParams { depth_tolerance: f32::NAN, ..p },
            FilterParams { normal_cos: f32::NAN, ..p },
            FilterParams { normal_cos: f32::INFINITY, ..p },
        ] {
            assert_eq!(filter_pixel(1, 1, &values, &g, &params), values[5], "{params:?}");
        }
        let mut bad_normal = normal.clone();
        bad_normal[5] = Vec3::NAN;
        assert_eq!(filter_pixel(1, 1, &values, &GBuffer { normal: &bad_normal, ..g }, &p), values[5]);
        // A NaN depth at the pixel leaves it; NaN neighbours never count.
        let mut bad_depth = depth.clone();
        bad_depth[5] = f32::NAN;
        assert_eq!(filter_pixel(1, 1, &values, &GBuffer { depth: &bad_depth, ..g }, &p), values[5]);
        let mut holes = depth.clone();
        let mut holes_normal = normal.clone();
        holes[0] = f32::NAN;
        holes_normal[10] = Vec3::new(f32::NAN, 0.0, 1.0);
        let got =
            filter_pixel(1, 1, &values, &GBuffer { depth: &holes, normal: &holes_normal, width: w, height: h }, &p);
        let kept: Vec<usize> = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15]
            .into_iter()
            .filter(|&i| i % 4 <= 3 && i / 4 <= 3 && i != 0 && i != 10)
            .collect();
        let want = kept.iter().map(|&i| values[i]).sum::<f32>() / kept.len() as f32;
        assert!((got - want).abs() < 1e-6, "{got} vs {want}");
    }
}
