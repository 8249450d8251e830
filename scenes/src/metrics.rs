//! Error metrics between two images of the same size: RMSE, PSNR and maximum absolute
//! difference, over every channel of every pixel.
//!
//! They compare renders of the same view made by different tracers or kd-tree builders
//! (identical trees must give identical images; thesis 4.1 compares speed only, so these
//! are our own correctness checks). Computations are done in f64.

use crate::{Image, ScalarImage, SceneError};

/// Anything that is a width x height grid of f32 samples (one or more channels per pixel).
pub trait Samples {
    /// `(width, height)` in pixels; images of different sizes cannot be compared.
    fn dims(&self) -> (usize, usize);
    /// Every channel of every pixel, in a fixed order.
    fn samples(&self) -> impl Iterator<Item = f32> + '_;
}

impl Samples for Image {
    fn dims(&self) -> (usize, usize) {
        (self.width as usize, self.height as usize)
    }
    fn samples(&self) -> impl Iterator<Item = f32> + '_ {
        self.pixels.iter().flat_map(|p| p.to_array())
    }
}

impl Samples for ScalarImage {
    fn dims(&self) -> (usize, usize) {
        (self.width as usize, self.height as usize)
    }
    fn samples(&self) -> impl Iterator<Item = f32> + '_ {
        self.values.iter().copied()
    }
}

impl Samples for [f32] {
    fn dims(&self) -> (usize, usize) {
        (self.len(), 1)
    }
    fn samples(&self) -> impl Iterator<Item = f32> + '_ {
        self.iter().copied()
    }
}

/// The pairs of samples of `a` and `b`, or an error if their sizes differ.
fn pairs<'a, T: Samples + ?Sized>(a: &'a T, b: &'a T) -> Result<impl Iterator<Item = (f64, f64)> + 'a, SceneError> {
    let (da, db) = (a.dims(), b.dims());
    if da != db {
        return Err(SceneError::SizeMismatch { a: da, b: db });
    }
    Ok(a.samples().zip(b.samples()).map(|(x, y)| (f64::from(x), f64::from(y))))
}

/// Mean squared difference over all samples (0 for empty images).
fn mse<T: Samples + ?Sized>(a: &T, b: &T) -> Result<f64, SceneError> {
    let (sum, n) = pairs(a, b)?.fold((0.0, 0usize), |(s, n), (x, y)| (s + (x - y) * (x - y), n + 1));
    Ok(if n == 0 { 0.0 } else { sum / n as f64 })
}

/// Root-mean-square difference over every channel of every pixel.
///
/// A NaN sample makes the result NaN, an infinite difference `+inf` (two infinities of the
/// same sign differ by NaN). Errors if the sizes differ.
pub fn rmse<T: Samples + ?Sized>(a: &T, b: &T) -> Result<f64, SceneError> {
    Ok(mse(a, b)?.sqrt())
}

/// Peak signal-to-noise ratio in dB with peak 1.0: `10 log10(1 / mse)`; `+inf` for identical
/// images. A NaN sample makes it NaN, an infinite difference `-inf`. Errors if the sizes
/// differ.
pub fn psnr<T: Samples + ?Sized>(a: &T, b: &T) -> Result<f64, SceneError> {
    let mse = mse(a, b)?;
    Ok(if mse == 0.0 { f64::INFINITY } else { -10.0 * mse.log10() })
}

/// The largest absolute difference of any sample (0 for empty images; NaN if any difference
/// is NaN, `+inf` if one is infinite and none NaN). Errors if the sizes differ.
pub fn max_abs<T: Samples + ?Sized>(a: &T, b: &T) -> Result<f64, SceneError> {
    let nan_aware_max = |m: f64, d: f64| if m.is_nan() || d.is_nan() { f64::NAN } else { m.max(d) };
    Ok(pairs(a, b)?.map(|(x, y)| (x - y).abs()).fold(0.0, nan_aware_max))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use glam::Vec3;

    #[test]
    fn slice_metrics_match_hand_computed_values() {
        let a = [0.0f32, 0.5, 1.0, 1.0];
        let b = [0.0f32, 0.0, 1.0, 0.0];
        // Squared differences 0, 0.25, 0, 1: mean 0.3125.
        assert_relative_eq!(rmse(&a[..], &b[..]).unwrap(), 0.3125f64.sqrt(), epsilon = 1e-12);
        assert_relative_eq!(psnr(&a[..], &b[..]).unwrap(), -10.0 * 0.3125f64.log10(), epsilon = 1e-12);
        assert_relative_eq!(max_abs(&a[..], &b[..]).unwrap(), 1.0);
    }

    #[test]
    fn identical_images_have_zero_error_and_infinite_psnr() {
        let mut img = Image::new(3, 2);
        img.set(1, 1, Vec3::new(0.2, 0.4, 0.6));
        assert_eq!(rmse(&img, &img).unwrap(), 0.0);
        assert_eq!(max_abs(&img, &img).unwrap(), 0.0);
        assert_eq!(psnr(&img, &img).unwrap(), f64::INFINITY);
    }

    #[test]
    fn rgb_images_compare_every_channel() {
        let a = Image::new(2, 1);
        let mut b = Image::new(2, 1);
        b.set(1, 0, Vec3::new(0.1, 0.0, 0.0));
        // One of six samples differs by 0.1 (f32 0.1 widened to f64).
        let d = f64::from(0.1f32);
        assert_relative_eq!(rmse(&a, &b).unwrap(), (d * d / 6.0).sqrt(), epsilon = 1e-12);
        assert_relative_eq!(psnr(&a, &b).unwrap(), -10.0 * (d * d / 6.0).log10(), epsilon = 1e-9);
        assert_relative_eq!(max_abs(&a, &b).unwrap(), d);
    }

    #[test]
    fn scalar_images_and_nan() {
        let mut a = ScalarImage::new(2, 2);
        let b = ScalarImage::new(2, 2);
        a.set(0, 1, -2.0);
        assert_relative_eq!(rmse(&a, &b).unwrap(), 1.0);
        assert_relative_eq!(max_abs(&a, &b).unwrap(), 2.0);
        a.set(1, 1, f32::NAN);
        assert!(rmse(&a, &b).unwrap().is_nan());
        assert!(max_abs(&a, &b).unwrap().is_nan());
        assert!(psnr(&a, &b).unwrap().is_nan());
    }

    #[test]
    fn infinite_samples() {
        let a = [0.0f32, f32::INFINITY, 0.5];
        let b = [0.0f32, 1.0, 0.5];
        assert_eq!(rmse(&a[..], &b[..]).unwrap(), f64::INFINITY);
        assert_eq!(max_abs(&a[..], &b[..]).unwrap(), f64::INFINITY);
        assert_eq!(psnr(&a[..], &b[..]).unwrap(), f64::NEG_INFINITY);
        // The same infinity in both differs by NaN, not 0.
        assert!(rmse(&a[..], &a[..]).unwrap().is_nan());
        assert!(max_abs(&a[..], &a[..]).unwrap().is_nan());
        assert!(psnr(&a[..], &a[..]).unwrap().is_nan());
    }

    #[test]
    fn size_mismatch_is_an_error() {
        assert!(rmse(&Image::new(2, 3), &Image::new(3, 2)).is_err());
        assert!(psnr(&ScalarImage::new(1, 1), &ScalarImage::new(1, 2)).is_err());
        assert!(max_abs(&[0.0f32][..], &[][..]).is_err());
    }
}
