//! Tiles.
/// A tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}
/// Tiles.
pub fn tiles(width: u32, height: u32, size: u32) -> Vec<Tile> {
    let _ = (width, height, size);
    todo!()
}
