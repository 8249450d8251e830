//! The 4x4 discontinuity filter of Benthin & Wald 2009 (4.5), applied after 4x4 interleaved
//! sampling ([`crate::sampling::InterleavedSets`]).
//!
//! Each pixel's value becomes the mean over the 4x4 block of pixels `x - 1 ..= x + 2`,
//! `y - 1 ..= y + 2` (which holds each of the 16 sample sets once) of the pixels on the same
//! surface: a neighbour counts when its depth is within `depth_tolerance` of the pixel's
//! (relative) and its normal within `normal_cos` of the pixel's. Background pixels (infinite
//! depth) are left as they are and never count.
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

/// The filtered value of pixel `(x, y)` of `values` (row-major, like `g`).
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
            if d.is_finite()
                && (d - dc).abs() <= params.depth_tolerance * dc
                && g.normal[i].dot(nc) >= params.normal_cos
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
}
