//! Image tiles: the unit of work that the renderers hand to their threads.

/// A rectangle of pixels `[x0, x1) x [y0, y1)` of an image.
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

impl Tile {
    /// Number of columns.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    /// Number of rows.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// The pixels `(x, y)` of the tile, row by row, left to right.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + use<> {
        let (x0, x1) = (self.x0, self.x1);
        (self.y0..self.y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
    }
}

/// Splits a `width` x `height` image into `size` x `size` tiles in row-major tile order.
///
/// Tiles on the right and bottom edges are clipped to the image, so every pixel lies in
/// exactly one tile. A `size` of 0 is treated as 1; an empty image has no tiles.
pub fn tiles(width: u32, height: u32, size: u32) -> Vec<Tile> {
    let size = size.max(1);
    let mut out = Vec::with_capacity(width.div_ceil(size) as usize * height.div_ceil(size) as usize);
    for y0 in (0..height).step_by(size as usize) {
        for x0 in (0..width).step_by(size as usize) {
            out.push(Tile { x0, y0, x1: x0.saturating_add(size).min(width), y1: y0.saturating_add(size).min(height) });
        }
    }
    out
}

/// The pixels of a `w` x `h` tile (row-major indices) in Morton (Z) order: each run of 4,
/// 16, 64 of them is a 2x2, 4x4, 8x8 block.
pub fn morton_order(w: u32, h: u32) -> Vec<u32> {
    let mut order: Vec<u32> = (0..w * h).collect();
    order.sort_by_key(|&i| morton(i % w, i / w));
    order
}

/// The Morton (Z-order) code of `(x, y)` (16 bits each).
fn morton(x: u32, y: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = u64::from(v & 0xffff);
        v = (v | v << 8) & 0x00ff_00ff;
        v = (v | v << 4) & 0x0f0f_0f0f;
        v = (v | v << 2) & 0x3333_3333;
        (v | v << 1) & 0x5555_5555
    };
    spread(x) | spread(y) << 1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pixel of the image is covered exactly once.
    fn assert_exact_cover(width: u32, height: u32, size: u32) {
        let mut count = vec![0u32; width as usize * height as usize];
        for tile in tiles(width, height, size) {
            assert!(tile.width() > 0 && tile.height() > 0, "empty tile {tile:?}");
            assert_eq!(tile.pixels().count(), tile.pixel_count());
            for (x, y) in tile.pixels() {
                assert!(x < width && y < height);
                count[(y * width + x) as usize] += 1;
            }
        }
        assert!(count.iter().all(|&c| c == 1), "{width}x{height} size {size}");
    }

    #[test]
    fn morton_order_visits_blocks_together() {
        let order = morton_order(4, 4);
        // The first 2x2 block, then the one to its right, then the two below them.
        assert_eq!(order[..8], [0, 1, 4, 5, 2, 3, 6, 7]);
        assert_eq!(order[8..], [8, 9, 12, 13, 10, 11, 14, 15]);
        // A clipped tile: each index once.
        let mut sorted = morton_order(5, 3);
        sorted.sort();
        assert_eq!(sorted, (0..15).collect::<Vec<_>>());
    }

    #[test]
    fn tiles_cover_every_pixel_once() {
        for (w, h, s) in [(64, 48, 16), (65, 47, 16), (1, 1, 8), (7, 3, 1), (10, 10, 100), (5, 9, 0), (33, 17, 4)] {
            assert_exact_cover(w, h, s);
        }
    }

    #[test]
    fn tiles_are_row_major_and_clipped() {
        let t = tiles(5, 3, 2);
        assert_eq!(t.len(), 6);
        assert_eq!(t[0], Tile { x0: 0, y0: 0, x1: 2, y1: 2 });
        assert_eq!(t[1], Tile { x0: 2, y0: 0, x1: 4, y1: 2 });
        assert_eq!(t[2], Tile { x0: 4, y0: 0, x1: 5, y1: 2 });
        assert_eq!(t[5], Tile { x0: 4, y0: 2, x1: 5, y1: 3 });
        assert_eq!(t[2].pixels().collect::<Vec<_>>(), vec![(4, 0), (4, 1)]);
    }

    #[test]
    fn empty_images_and_zero_size_do_not_panic() {
        assert!(tiles(0, 10, 4).is_empty());
        assert!(tiles(10, 0, 4).is_empty());
        assert_eq!(tiles(2, 2, 0).len(), 4);
        assert_eq!(tiles(u32::MAX, 1, u32::MAX).len(), 1);
    }
}
