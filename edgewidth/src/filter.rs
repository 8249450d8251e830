//! The 4x4 discontinuity filter of Benthin & Wald 2009 (4.5), applied after 4x4 interleaved
//! sampling ([`crate::sampling::InterleavedSets`]).
//!
//! Each pixel's value becomes the weighted mean, over a 4x4 pixel neighbourhood centred on
//! the pixel, of the pixels on the same surface. A 4-pixel box has no centre pixel, so the
//! neighbourhood is the 5x5 block `x - 2 ..= x + 2`, `y - 2 ..= y + 2` with weight 1/2 for the
//! outer columns and rows (1/4 in the corners): its weights per axis are `1/2, 1, 1, 1, 1/2`,
//! 4 in all, and columns `x - 2` and `x + 2` use the same sample sets, so over a full
//! neighbourhood each of the 16 interleaved sets weighs exactly 1, as in a 4x4 block, while
//! the mean stays centred on the pixel (a plain `x - 1 ..= x + 2` block shifts the image by
//! half a pixel towards `+x, +y`).
//!
//! A neighbour counts when its depth is within `depth_tolerance` of the pixel's (relative) and
//! its normal within `normal_cos` of the pixel's. Background pixels (infinite depth) are left
//! as they are and never count. Non-finite input is defined too: a pixel with a NaN depth is
//! left as it is, a neighbour with a NaN depth or normal never counts, and the pixel itself
//! always counts, so NaN thresholds (or a NaN normal) leave its own value.
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
    // Weight of an offset `-2 ..= 2` from the pixel along one axis.
    let weight = |offset: u32, at: u32| if offset.abs_diff(at) == 2 { 0.5f32 } else { 1.0 };
    let (mut sum, mut total) = (0.0f32, 0.0f32);
    for yy in y.saturating_sub(2)..(y + 3).min(g.height) {
        for xx in x.saturating_sub(2)..(x + 3).min(g.width) {
            let i = yy as usize * w + xx as usize;
            let d = g.depth[i];
            if i == c
                || (d.is_finite()
                    && (d - dc).abs() <= params.depth_tolerance * dc
                    && g.normal[i].dot(nc) >= params.normal_cos)
            {
                let wt = weight(xx, x) * weight(yy, y);
                sum += wt * values[i];
                total += wt;
            }
        }
    }
    // The pixel itself always counts (weight 1), so total >= 1.
    sum / total
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Filters every pixel of `values`.
    fn filter_all(values: &[f32], g: &GBuffer, p: &FilterParams) -> Vec<f32> {
        (0..g.height)
            .flat_map(|y| (0..g.width).map(move |x| (x, y)))
            .map(|(x, y)| filter_pixel(x, y, values, g, p))
            .collect()
    }

    #[test]
    fn a_constant_image_is_left_as_it_is() {
        let (w, h) = (9u32, 7u32);
        let n = (w * h) as usize;
        // Two surfaces and a background pixel: whatever is accepted, a constant stays.
        let depth: Vec<f32> = (0..n)
            .map(|i| {
                if i == 20 {
                    f32::INFINITY
                } else if i % 9 < 4 {
                    2.0
                } else {
                    5.0
                }
            })
            .collect();
        let normal = vec![Vec3::Y; n];
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let values = vec![0.375f32; n];
        assert!(filter_all(&values, &g, &FilterParams::default()).iter().all(|&v| v == 0.375));
    }

    #[test]
    fn each_interleaved_set_weighs_the_same_and_the_mean_is_centred() {
        // One flat surface: value 1 on the pixels of set `k`, 0 elsewhere. Away from the
        // border every set must weigh 1/16 of the neighbourhood, whichever pixel is filtered.
        let (w, h) = (12u32, 12u32);
        let n = (w * h) as usize;
        let (depth, normal) = (vec![3.0f32; n], vec![Vec3::Z; n]);
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let p = FilterParams::default();
        for k in 0..16u32 {
            let values: Vec<f32> =
                (0..n as u32).map(|i| f32::from(u8::from(4 * (i / w % 4) + i % w % 4 == k))).collect();
            for (x, y) in [(4, 4), (5, 6), (7, 5)] {
                assert_eq!(filter_pixel(x, y, &values, &g, &p), 1.0 / 16.0, "set {k} at ({x}, {y})");
            }
        }
        // Centred: a step between columns 5 and 6 is blurred symmetrically about it.
        let step: Vec<f32> = (0..n as u32).map(|i| f32::from(u8::from(i % w >= 6))).collect();
        let f = filter_all(&step, &g, &p);
        let row = 6 * w as usize;
        for d in 0..3 {
            let (left, right) = (f[row + 5 - d], f[row + 6 + d]);
            assert_eq!(left, 1.0 - right, "columns {} and {}", 5 - d, 6 + d);
        }
    }

    #[test]
    fn mirroring_the_image_mirrors_the_result() {
        // Irregular values and two surfaces: filtering the mirrored image gives the mirrored
        // result (a window that is not centred fails this).
        let (w, h) = (10u32, 8u32);
        let n = (w * h) as usize;
        let values: Vec<f32> = (0..n).map(|i| ((i * 37 % 11) as f32) / 10.0).collect();
        let depth: Vec<f32> = (0..n).map(|i| if (i % 10) + (i / 10) < 9 { 1.0 } else { 4.0 }).collect();
        let normal = vec![Vec3::Z; n];
        let mirror = |v: &[f32]| -> Vec<f32> {
            (0..n)
                .map(|i| v[(h as usize - 1 - i / w as usize) * w as usize + (w as usize - 1 - i % w as usize)])
                .collect()
        };
        let p = FilterParams::default();
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let md = mirror(&depth);
        let gm = GBuffer { depth: &md, ..g };
        let a = mirror(&filter_all(&values, &g, &p));
        let b = filter_all(&mirror(&values), &gm, &p);
        for (i, (a, b)) in a.iter().zip(&b).enumerate() {
            assert!((a - b).abs() < 1e-6, "pixel {i}: {a} vs {b}");
        }
    }

    #[test]
    fn averages_one_surface_and_stops_at_discontinuities() {
        // 12x6: left half at depth 1 facing +Z, right half at depth 3 (a step).
        let (w, h) = (12u32, 6u32);
        let depth: Vec<f32> = (0..w * h).map(|i| if i % w < 6 { 1.0 } else { 3.0 }).collect();
        let normal = vec![Vec3::Z; (w * h) as usize];
        let values: Vec<f32> = (0..w * h).map(|i| if i % w < 6 { (i % 2) as f32 } else { 0.25 }).collect();
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let p = FilterParams::default();
        // Inside the left half, alternating columns of 0 and 1 average to 1/2.
        assert_eq!(filter_pixel(2, 2, &values, &g, &p), 0.5);
        // At the step, the right half's values never leak in, nor the left half's out.
        assert_eq!(filter_pixel(6, 2, &values, &g, &p), 0.25);
        assert_eq!(filter_pixel(7, 2, &values, &g, &p), 0.25);
        let left_edge = filter_pixel(5, 2, &values, &g, &p);
        assert!((0.0..=1.0).contains(&left_edge) && left_edge != 0.25);
        // The same step in depth alone (equal normals, values 0 and 1) stays a step.
        let two: Vec<f32> = (0..w * h).map(|i| f32::from(u8::from(i % w >= 6))).collect();
        assert_eq!(filter_all(&two, &g, &p), two);
        // A normal discontinuity also stops it.
        let mut tilted = normal.clone();
        for (i, n) in tilted.iter_mut().enumerate() {
            if i % w as usize == 2 {
                *n = Vec3::X;
            }
        }
        let g = GBuffer { normal: &tilted, ..g };
        assert_eq!(filter_pixel(2, 2, &values, &g, &p), 0.0);
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
        // Pixel (1, 1): columns and rows 0..=3 of the 4x4 image, weight 1/2 on column and
        // row 3 (offset 2), pixels 0 and 10 left out.
        let weight = |i: usize| if i % 4 == 3 { 0.5 } else { 1.0 } * if i / 4 == 3 { 0.5 } else { 1.0 };
        let kept: Vec<usize> = (0..16).filter(|&i| i != 0 && i != 10).collect();
        let want =
            kept.iter().map(|&i| weight(i) * values[i]).sum::<f32>() / kept.iter().map(|&i| weight(i)).sum::<f32>();
        assert!((got - want).abs() < 1e-6, "{got} vs {want}");
    }
}
