//! TEMPORARY stand-ins for scenes-crate methods that are still being written (tile pixel
//! iteration, image output). Inherent methods win over these trait methods, so this module is
//! deleted as soon as the scenes branch is merged.

use std::path::Path;

use scenes::{Image, ScalarImage, SceneError, Tile};

/// Stand-in for `Tile::pixel_count` and `Tile::pixels`.
pub trait TileExt {
    /// Number of pixels.
    fn pixel_count(&self) -> usize;
    /// The pixels, row by row.
    fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + use<Self>;
}

impl TileExt for Tile {
    fn pixel_count(&self) -> usize {
        (self.x1 - self.x0) as usize * (self.y1 - self.y0) as usize
    }
    fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + use<> {
        let (x0, x1) = (self.x0, self.x1);
        (self.y0..self.y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
    }
}

fn unavailable(path: &Path) -> SceneError {
    SceneError::Parse { path: path.to_path_buf(), message: "image output is not available yet".into() }
}

/// Stand-in for `Image::save_png` / `save_pfm` and the `ScalarImage` ones.
pub trait SaveExt {
    /// PNG.
    fn save_png(&self, path: &Path) -> Result<(), SceneError>;
    /// PFM.
    fn save_pfm(&self, path: &Path) -> Result<(), SceneError>;
}

impl SaveExt for Image {
    fn save_png(&self, path: &Path) -> Result<(), SceneError> {
        Err(unavailable(path))
    }
    fn save_pfm(&self, path: &Path) -> Result<(), SceneError> {
        Err(unavailable(path))
    }
}

impl SaveExt for ScalarImage {
    fn save_png(&self, path: &Path) -> Result<(), SceneError> {
        Err(unavailable(path))
    }
    fn save_pfm(&self, path: &Path) -> Result<(), SceneError> {
        Err(unavailable(path))
    }
}
