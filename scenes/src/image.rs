//! Floating-point images.
use glam::Vec3;

/// An RGB f32 image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Row-major pixels, row 0 at the top.
    pub pixels: Vec<Vec3>,
}

/// A one-channel f32 image.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarImage {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Row-major values, row 0 at the top.
    pub values: Vec<f32>,
}
