//! A tile of primary rays as 2x2 packets (thesis 4.1.1-4.1.5): the state a tile is traced
//! in, not the tracing (the entry points are [`TileTracer::trace`] in [`crate::method`] and
//! [`TileTracer::trace_frusta`] in [`crate::frustum`]).
//!
//! A tile of `N x N` pixels (`N` a multiple of 4, the thesis uses 4 to 32) is stored as
//! `(N/2)^2` [`OmniPacket`]s, **quadrant by quadrant** (top-left, top-right, bottom-left,
//! bottom-right; row-major inside each), so that each of the four MFT frusta owns one
//! contiguous run of packets and the single frustum owns them all. Lane `l` of the packet
//! whose top-left pixel is `(x, y)` is pixel `(x + (l & 1), y + (l >> 1))`. Pixels outside the
//! image (tiles clipped at its right and bottom edges) are invalid lanes.
//!
//! A [`TileTracer`] is scratch space for one thread: loading and tracing a tile reuses its
//! buffers, so tracing allocates nothing once the tracer has seen its largest tile.

use std::ops::Range;

use glam::{BVec4A, Vec4};
use kdtree::Hit;
use kdtree::TreeTest;
use kdtree::triangle::{Intersector, WatertightTriangle};
use scenes::{Camera, Tile};

use crate::packet::{OmniPacket, PacketHit, RayPacket, directions};
use crate::triangle4::{PacketTest, ShearedPacket};

/// Why a tile could not be loaded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TileError {
    /// The tile size is not a multiple of 4 in `4..=64`.
    #[error("tile size {0} must be a multiple of 4 from 4 to 64")]
    BadSize(u32),
    /// The tile is larger than the tile size, or lies outside the camera's image.
    #[error("tile {0:?} does not fit a {1} x {1} tile of the image")]
    BadTile(Tile, u32),
    /// The camera has a NaN or infinite field (only a hand-made one can:
    /// `Camera::look_at` refuses non-finite input).
    #[error("the camera's {0} is not finite")]
    NonFiniteCamera(&'static str),
}

/// The largest tile side.
pub const MAX_TILE: u32 = 64;

/// Scratch space and state for tracing one tile of 2x2 packets at a time.
#[derive(Clone, Debug)]
pub struct TileTracer {
    size: u32,
    tile: Tile,
    /// The packets, quadrant by quadrant.
    pub(crate) packets: Vec<OmniPacket>,
    /// Each packet's top-left pixel.
    corners: Vec<(u32, u32)>,
    /// Each packet's hits.
    pub(crate) hits: Vec<PacketHit>,
    /// Each packet's finished lanes as a 4-bit mask (invalid lanes are finished from the
    /// start; a frustum finishes a lane when its hit is known to be the closest).
    pub(crate) done: Vec<u8>,
    /// The packets of each quadrant.
    pub(crate) quadrants: [Range<usize>; 4],
    /// Each quadrant's packets as a grid on the image (primary tiles only).
    pub(crate) grids: [Grid; 4],
    /// The camera of a primary tile (for the screen-space candidate test at leaves).
    pub(crate) camera: Option<Camera>,
    /// The common origin of every ray, `[x, y, z, 0]`.
    pub(crate) origin: [f32; 4],
    /// Each packet's watertight shear, made once per trace for the frustum methods on a
    /// watertight tree (empty otherwise).
    pub(crate) sheared: Vec<ShearedPacket>,
    /// Packet/leaf culling on (the default) or off (Table 4.2).
    pub(crate) culling: bool,
    /// Any-hit mode (shadow rays): the frustum methods finish a lane at its first hit.
    pub(crate) any_hit: bool,
}

impl TileTracer {
    /// Whether a tracer can take tiles of `size` pixels: a multiple of 4 in `4..=64`.
    pub fn check_size(size: u32) -> Result<(), TileError> {
        if (4..=MAX_TILE).contains(&size) && size.is_multiple_of(4) { Ok(()) } else { Err(TileError::BadSize(size)) }
    }

    /// A tracer for tiles of `size x size` pixels (a multiple of 4 in `4..=64`).
    pub fn new(size: u32) -> Result<TileTracer, TileError> {
        TileTracer::check_size(size)?;
        let packets = (size as usize / 2).pow(2);
        Ok(TileTracer {
            size,
            tile: Tile { x0: 0, y0: 0, x1: 0, y1: 0 },
            packets: Vec::with_capacity(packets),
            corners: Vec::with_capacity(packets),
            hits: Vec::with_capacity(packets),
            done: Vec::with_capacity(packets),
            quadrants: [0..0, 0..0, 0..0, 0..0],
            grids: [Grid::default(); 4],
            camera: None,
            sheared: Vec::with_capacity(packets),
            origin: [0.0; 4],
            culling: true,
            any_hit: false,
        })
    }

    /// The tile side.
    pub fn size(&self) -> u32 {
        self.size
    }

    /// Turns packet/leaf culling (4.1.4) on or off for the frustum methods.
    pub fn set_culling(&mut self, on: bool) {
        self.culling = on;
    }

    /// Any-hit mode on or off for the frustum methods (off by default): with it on, a lane is
    /// finished at its first hit, so the hits are *some* hit in the ray's interval, the
    /// answer shadow rays need, not the closest.
    pub fn set_any_hit(&mut self, on: bool) {
        self.any_hit = on;
    }

    /// Number of 2x2 packets in the loaded tile (the denominator of N and I).
    pub fn packet_count(&self) -> usize {
        self.packets.len()
    }

    /// Loads the primary rays of `tile` (at most `size x size`, inside `camera`'s image):
    /// pixel `(x, y)` gets exactly the single-ray camera ray, `Camera::pixel_ray` over
    /// `[0, +inf]`. A camera with a NaN or infinite field is [`TileError::NonFiniteCamera`]
    /// naming it.
    pub fn load_primary(&mut self, camera: &Camera, tile: &Tile) -> Result<(), TileError> {
        if tile.width() > self.size || tile.height() > self.size || tile.x1 > camera.width || tile.y1 > camera.height {
            return Err(TileError::BadTile(*tile, self.size));
        }
        for (name, finite) in [
            ("eye", camera.eye.is_finite()),
            ("forward vector", camera.forward.is_finite()),
            ("right vector", camera.right.is_finite()),
            ("up vector", camera.up.is_finite()),
            ("field of view", camera.tan_half_fovy.is_finite()),
        ] {
            if !finite {
                return Err(TileError::NonFiniteCamera(name));
            }
        }
        self.tile = *tile;
        self.packets.clear();
        self.corners.clear();
        let half = self.size / 2;
        let (xm, ym) = ((tile.x0 + half).min(tile.x1), (tile.y0 + half).min(tile.y1));
        let quads = [
            (tile.x0, xm, tile.y0, ym),
            (xm, tile.x1, tile.y0, ym),
            (tile.x0, xm, ym, tile.y1),
            (xm, tile.x1, ym, tile.y1),
        ];
        let origin = camera.eye.extend(0.0).to_array();
        let rays = PrimaryRays::new(camera);
        for (q, &(qx0, qx1, qy0, qy1)) in quads.iter().enumerate() {
            let first = self.packets.len();
            let (cols, rows) = (qx1.saturating_sub(qx0).div_ceil(2), qy1.saturating_sub(qy0).div_ceil(2));
            for y in (qy0..qy1.max(qy0)).step_by(2) {
                for x in (qx0..qx1.max(qx0)).step_by(2) {
                    self.packets.push(OmniPacket { rays: rays.packet(x, y, tile), origin });
                    self.corners.push((x, y));
                }
            }
            self.quadrants[q] = first..self.packets.len();
            self.grids[q] = Grid { x0: qx0, y0: qy0, cols, rows };
        }
        self.origin = origin;
        self.camera = Some(*camera);
        Ok(())
    }

    /// The rectangle of pixel-centre coordinates (`x + 0.5` for column `x`) whose camera
    /// rays can meet the box `[lo, hi]`: the box's corners projected onto the image, grown by
    /// a pixel for rounding, as `[x_min, x_max, y_min, y_max]`. `None` (every pixel a
    /// candidate) without a camera, or when a corner is not in front of the eye.
    #[inline]
    pub(crate) fn screen_rect(&self, lo: [f32; 4], hi: [f32; 4]) -> Option<[f32; 4]> {
        let cam = self.camera.as_ref()?;
        let (w, h) = (cam.width as f32, cam.height as f32);
        let (sx_scale, sy_scale) = (1.0 / (cam.tan_half_fovy * (w / h)), 1.0 / cam.tan_half_fovy);
        // Corner i takes hi on axis a where bit a of i is set. A camera coordinate is a sum
        // over axes, so the eight corners' coordinates are sums of per-axis pairs: lanes
        // 0-3 hold corners 0-3 (z = lo), the second vector corners 4-7 (z = hi).
        let rel_lo = glam::Vec3::from_slice(&lo[..3]) - cam.eye;
        let rel_hi = glam::Vec3::from_slice(&hi[..3]) - cam.eye;
        let coord = |axis: glam::Vec3| {
            let (x0, x1) = (rel_lo.x * axis.x, rel_hi.x * axis.x);
            let (y0, y1) = (rel_lo.y * axis.y, rel_hi.y * axis.y);
            let xy = Vec4::new(x0 + y0, x1 + y0, x0 + y1, x1 + y1);
            (xy + rel_lo.z * axis.z, xy + rel_hi.z * axis.z)
        };
        let (z0, z1) = coord(cam.forward);
        if !(z0.cmpgt(Vec4::ZERO) & z1.cmpgt(Vec4::ZERO)).all() {
            return None;
        }
        let ((x0, x1), (y0, y1)) = (coord(cam.right), coord(cam.up));
        let px = |x: Vec4, z: Vec4| (x / z * sx_scale + Vec4::ONE) * (0.5 * w);
        let py = |y: Vec4, z: Vec4| (Vec4::ONE - y / z * sy_scale) * (0.5 * h);
        let (xa, xb, ya, yb) = (px(x0, z0), px(x1, z1), py(y0, z0), py(y1, z1));
        let r =
            [xa.min(xb).min_element(), xa.max(xb).max_element(), ya.min(yb).min_element(), ya.max(yb).max_element()];
        (r.iter().all(|v| v.is_finite())).then(|| [r[0] - 1.0, r[1] + 1.0, r[2] - 1.0, r[3] + 1.0])
    }

    /// Loads packets made elsewhere (any rays with one common origin, e.g. mirror reflections
    /// seen from the mirrored eye, or a run of a ray file) as one "tile", its four quarters
    /// (by packet order) being the MFT frusta. The frustum methods bound rays by their
    /// per-axis direction extremes, so any set of directions works. Returns `None` if the
    /// packets do not share one origin. Only valid lanes count: a packet with none (e.g. of
    /// rays with NaN or infinite components, see [`RayPacket::new`]) may have any origin and
    /// gets no hit.
    pub fn load_packets(&mut self, packets: &[OmniPacket]) -> Option<()> {
        let origin = packets.iter().find(|p| p.rays.valid.any()).map_or([0.0; 4], |p| p.origin);
        if packets.iter().any(|p| p.rays.valid.any() && p.origin != origin) {
            return None;
        }
        self.tile = Tile { x0: 0, y0: 0, x1: 0, y1: 0 };
        self.packets.clear();
        self.packets.extend_from_slice(packets);
        self.corners.clear();
        self.corners.resize(packets.len(), (0, 0));
        let n = packets.len();
        let cut = |q: usize| q * n / 4;
        self.quadrants = [0..cut(1), cut(1)..cut(2), cut(2)..cut(3), cut(3)..n];
        self.camera = None;
        self.origin = origin;
        Some(())
    }

    /// Resets the hits and finished lanes before a trace, and makes the watertight shear
    /// table when a frustum method traces a watertight tree (`I`, the tree's test, chosen
    /// once by the caller: the check is a constant).
    pub(crate) fn reset<I: TreeTest>(&mut self, frustum: bool) {
        self.sheared.clear();
        if frustum && I::INTERSECTOR == Intersector::Watertight {
            self.sheared.extend(self.packets.iter().map(|p| WatertightTriangle::prepare4(&p.rays)));
        }
        self.hits.clear();
        self.hits.extend(self.packets.iter().map(|p| PacketHit::new(&p.rays)));
        self.done.clear();
        self.done.extend(self.packets.iter().map(|p| (!p.rays.valid.bitmask() & 0xF) as u8));
    }

    /// The camera and tile of a primary tile ([`TileTracer::load_primary`]); `None` for
    /// packets loaded with [`TileTracer::load_packets`].
    pub fn primary(&self) -> Option<(&Camera, Tile)> {
        self.camera.as_ref().map(|c| (c, self.tile))
    }

    /// The packets of quadrant `q` (0 to 3: top-left, top-right, bottom-left, bottom-right
    /// for a primary tile, quarters by packet order otherwise).
    pub fn quadrant(&self, q: usize) -> &[OmniPacket] {
        &self.packets[self.quadrants[q & 3].clone()]
    }

    /// The pixels of quadrant `q` of a primary tile (`None` when the quadrant is empty, at
    /// the image's right or bottom edge, or for loaded packets).
    pub fn quadrant_tile(&self, q: usize) -> Option<Tile> {
        self.camera?;
        let g = self.grids[q & 3];
        let (x1, y1) = ((g.x0 + 2 * g.cols).min(self.tile.x1), (g.y0 + 2 * g.rows).min(self.tile.y1));
        (g.cols > 0 && g.rows > 0).then_some(Tile { x0: g.x0, y0: g.y0, x1, y1 })
    }

    /// The common origin of the loaded rays.
    pub fn origin(&self) -> glam::Vec3 {
        glam::Vec3::from_slice(&self.origin[..3])
    }

    /// The hits of the packets, in packet order (after [`TileTracer::trace`]).
    pub fn packet_hits(&self) -> &[PacketHit] {
        &self.hits
    }

    /// The loaded packets.
    pub fn packets(&self) -> &[OmniPacket] {
        &self.packets
    }

    /// Writes the traced hits into `out`, the tile's pixels row by row (`tile.width()` per
    /// row), as single-ray traversal would.
    pub fn write_hits(&self, out: &mut [Option<Hit>]) {
        let (t, w) = (self.tile, self.tile.width() as usize);
        for (&(x, y), hit) in self.corners.iter().zip(&self.hits) {
            for lane in 0..4u32 {
                let (px, py) = (x + (lane & 1), y + (lane >> 1));
                if px < t.x1 && py < t.y1 {
                    out[(py - t.y0) as usize * w + (px - t.x0) as usize] = hit.get(lane as usize);
                }
            }
        }
    }
}

/// A quadrant's packets as a grid: the packet in column `c`, row `r` is number
/// `r * cols + c` of the quadrant and covers pixels `(x0 + 2c, y0 + 2r)` to
/// `(x0 + 2c + 1, y0 + 2r + 1)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Grid {
    pub(crate) x0: u32,
    pub(crate) y0: u32,
    pub(crate) cols: u32,
    pub(crate) rows: u32,
}

impl Grid {
    /// The columns and rows of the packets with a pixel centre inside `rect` (see
    /// [`TileTracer::screen_rect`]).
    #[inline]
    pub(crate) fn within(&self, rect: [f32; 4]) -> (Range<u32>, Range<u32>) {
        // Packet column c has centres x0 + 2c + 0.5 and x0 + 2c + 1.5.
        let span = |lo: f32, hi: f32, origin: u32, n: u32| {
            let first = ((lo - 1.5 - origin as f32) * 0.5).ceil().clamp(0.0, n as f32) as u32;
            let end = (((hi - 0.5 - origin as f32) * 0.5).floor() + 1.0).clamp(0.0, n as f32) as u32;
            first..end.max(first)
        };
        (span(rect[0], rect[1], self.x0, self.cols), span(rect[2], rect[3], self.y0, self.rows))
    }
}

/// Primary-ray packets of one camera, generated four rays at a time with exactly the
/// operations of [`Camera::pixel_ray`] and [`Ray::new`] (so every lane equals the single
/// ray bit for bit, which the tests check).
struct PrimaryRays {
    camera: Camera,
    aspect: f32,
}

impl PrimaryRays {
    fn new(camera: &Camera) -> PrimaryRays {
        PrimaryRays { camera: *camera, aspect: camera.width as f32 / camera.height as f32 }
    }

    /// The packet of the 2x2 pixels whose top-left pixel is `(x, y)`; pixels outside `tile`
    /// are invalid lanes.
    #[inline]
    fn packet(&self, x: u32, y: u32, tile: &Tile) -> RayPacket {
        let c = &self.camera;
        let (w, h) = (c.width as f32, c.height as f32);
        let px = Vec4::new(x as f32 + 0.5, (x + 1) as f32 + 0.5, x as f32 + 0.5, (x + 1) as f32 + 0.5);
        let py = Vec4::new(y as f32 + 0.5, y as f32 + 0.5, (y + 1) as f32 + 0.5, (y + 1) as f32 + 0.5);
        // Camera::direction, per lane.
        let sx = (Vec4::splat(2.0) * px / Vec4::splat(w) - Vec4::ONE) * c.tan_half_fovy * self.aspect;
        let sy = (Vec4::ONE - Vec4::splat(2.0) * py / Vec4::splat(h)) * c.tan_half_fovy;
        let comp = |a: usize| Vec4::splat(c.forward[a]) + sx * c.right[a] + sy * c.up[a];
        let (dx, dy, dz) = (comp(0), comp(1), comp(2));
        // Vec3::normalize: d * (1 / sqrt(d . d)).
        let len_recip = Vec4::ONE / Vec4::from_array((dx * dx + dy * dy + dz * dz).to_array().map(f32::sqrt));
        // Ray::new: reciprocals, and components whose reciprocal overflows flushed to zeros.
        let (d, inv) = directions([dx * len_recip, dy * len_recip, dz * len_recip]);
        let inside = BVec4A::new(true, x + 1 < tile.x1, y + 1 < tile.y1, x + 1 < tile.x1 && y + 1 < tile.y1);
        RayPacket {
            o: [Vec4::splat(c.eye.x), Vec4::splat(c.eye.y), Vec4::splat(c.eye.z), Vec4::ZERO],
            d: [d[0], d[1], d[2], Vec4::ZERO],
            inv: [inv[0], inv[1], inv[2], Vec4::ZERO],
            t_min: Vec4::select(inside, Vec4::ZERO, Vec4::INFINITY),
            t_max: Vec4::select(inside, Vec4::INFINITY, Vec4::NEG_INFINITY),
            valid: inside,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::Ray;

    /// Every lane of a loaded primary tile is the single camera ray, bit for bit, and the
    /// lanes outside the image are invalid.
    #[test]
    fn primary_lanes_are_the_camera_rays() {
        for (w, h, fovy) in [(37u32, 21u32, 70.0f32), (64, 64, 150.0), (5, 9, 1.0)] {
            let camera =
                Camera::look_at(glam::Vec3::new(1.0, 2.0, 3.0), glam::Vec3::new(-4.0, 0.5, 7.0), fovy, w, h).unwrap();
            let mut tracer = TileTracer::new(16).unwrap();
            for tile in scenes::tiles(w, h, 16) {
                tracer.load_primary(&camera, &tile).unwrap();
                let mut seen = 0;
                for (p, &(x, y)) in tracer.packets.iter().zip(&tracer.corners) {
                    for lane in 0..4u32 {
                        let (px, py) = (x + (lane & 1), y + (lane >> 1));
                        let valid = p.rays.valid.bitmask() >> lane & 1 != 0;
                        assert_eq!(valid, px < tile.x1 && py < tile.y1);
                        if valid {
                            let (o, d) = camera.pixel_ray(px, py);
                            let want = Ray::new(o, d, 0.0, f32::INFINITY);
                            let got = p.rays.ray(lane as usize);
                            let bits = |r: &Ray| (r.origin.to_array(), r.dir.to_array().map(f32::to_bits));
                            assert_eq!(bits(&got), bits(&want), "pixel ({px}, {py})");
                            seen += 1;
                        }
                    }
                }
                assert_eq!(seen, tile.pixel_count());
            }
        }
    }

    #[test]
    fn grid_ranges_cover_the_rectangle() {
        let g = Grid { x0: 8, y0: 0, cols: 4, rows: 4 };
        // Centres 8.5 .. 15.5; a rectangle over 10.2 .. 11.0 touches columns 10 and 11
        // (packet 1 covers columns 10 and 11).
        assert_eq!(g.within([10.2, 11.0, -100.0, 100.0]), (1..2, 0..4));
        assert_eq!(g.within([0.0, 8.4, 0.0, 1.0]), (0..0, 0..1));
        assert_eq!(g.within([-1e30, 1e30, 3.4, 3.7]), (0..4, 1..2));
        // Between two rows of pixel centres: no packet.
        assert_eq!(g.within([-1e30, 1e30, 3.6, 3.7]).1.len(), 0);
    }
}
