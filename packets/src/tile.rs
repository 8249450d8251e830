//! A tile of primary rays as packets (thesis 4.1.1-4.1.5): the state a tile is traced in,
//! not the tracing (the entry points are [`TileTracer::trace_mft`] and its siblings in
//! [`crate::method`] and [`TileTracer::trace_frusta`] in [`crate::frustum`]).
//!
//! The packets are `V::LANES` rays wide ([`SimdF32`]; `Vec4`, the default, is the thesis's
//! 2x2 packet) and cover a rectangle of `pw x ph` pixels ([`TileTracer::PACKET_SHAPE`]): 2x2
//! for 4 lanes, 4 wide x 2 tall for 8, 4x4 for 16 (the thesis's 2x2 packet at the register's
//! width). A tile of `N x N` pixels (`N` a multiple of 4, the thesis uses 4 to 32; of 8 for
//! 8 and 16 lanes, so that a quadrant holds whole packets) is stored as `N^2 / W` packets
//! ([`OmniPacket`]), **quadrant by quadrant** (top-left, top-right, bottom-left,
//! bottom-right; row-major inside each), so that each of the four MFT frusta owns one
//! contiguous run of packets and the single frustum owns them all. Lane `l` of the packet
//! whose top-left pixel is `(x, y)` is pixel `(x + l % pw, y + l / pw)`. Pixels outside the
//! image (tiles clipped at its right and bottom edges) are invalid lanes.
//!
//! A [`TileTracer`] is scratch space for one thread: loading and tracing a tile reuses its
//! buffers, so tracing allocates nothing once the tracer has seen its largest tile.

use std::ops::Range;

use glam::Vec4;
use kdtree::TreeTest;
use kdtree::triangle::{Intersector, WatertightTriangle};
use kdtree::{Hit, Ray};
use scenes::{Camera, Tile};

use crate::packet::{OmniPacket, PacketHit, RayPacket, all_lanes, directions};
use crate::simd::{SimdF32, SimdMask};
use crate::triangle4::{PacketTest, ShearedPacket};

/// Why a tile could not be loaded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TileError {
    /// The tile size is not a multiple of 4 in `4..=64` (packets of up to four rays).
    #[error("tile size {0} must be a multiple of 4 from 4 to 64")]
    BadSize(u32),
    /// The tile size is not a multiple of `multiple` in `multiple..=64`, the sizes whose
    /// quadrants hold whole packets of `lanes` rays (8 for 8 and 16 lanes).
    #[error("tile size {size} must be a multiple of {multiple} from {multiple} to 64 for packets of {lanes} rays")]
    BadSizeForWidth {
        /// The size asked for.
        size: u32,
        /// The packets' width in rays.
        lanes: usize,
        /// What the size must be a multiple of.
        multiple: u32,
    },
    /// A tile is split into 4 or 16 frusta, not this many.
    #[error("a tile is split into 4 or 16 frusta, not {0}")]
    BadRegions(usize),
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

/// The most frusta a tile is split into: 4 x 4 regions ([`TileTracer::set_regions`]).
pub const MAX_REGIONS: usize = 16;

/// Scratch space and state for tracing one tile of packets of `V::LANES` rays at a time
/// (2x2 pixels for the default `Vec4`; see the module for the other shapes).
#[derive(Clone, Debug)]
pub struct TileTracer<V: SimdF32 = Vec4> {
    size: u32,
    tile: Tile,
    /// The packets, quadrant by quadrant.
    pub(crate) packets: Vec<OmniPacket<V>>,
    /// Each packet's top-left pixel.
    corners: Vec<(u32, u32)>,
    /// Each packet's hits.
    pub(crate) hits: Vec<PacketHit<V>>,
    /// Each packet's finished lanes as a lane bitmask (bit `l` for lane `l`; invalid lanes
    /// are finished from the start; a frustum finishes a lane when its hit is known to be the
    /// closest). Every lane finished is [`all_lanes`].
    pub(crate) done: Vec<u32>,
    /// The packets of each region (the four quadrants by default; [`TileTracer::set_regions`]),
    /// the unused ones empty.
    pub(crate) quadrants: [Range<usize>; MAX_REGIONS],
    /// Each region's packets as a grid on the image (primary tiles only).
    pub(crate) grids: [Grid; MAX_REGIONS],
    /// Regions per side of the tile: 2 (the four quadrants of MFT) or 4 (16 frusta).
    side: u32,
    /// The camera of a primary tile (for the screen-space candidate test at leaves).
    pub(crate) camera: Option<Camera>,
    /// The common origin of every ray, `[x, y, z, 0]`.
    pub(crate) origin: [f32; 4],
    /// Each packet's watertight shear, made once per trace for the frustum methods on a
    /// watertight tree (empty otherwise).
    pub(crate) sheared: Vec<ShearedPacket<V>>,
    /// Packet/leaf culling on (the default) or off (Table 4.2).
    pub(crate) culling: bool,
    /// Any-hit mode (shadow rays): the frustum methods finish a lane at its first hit.
    pub(crate) any_hit: bool,
}

/// The 4-wide tracer's constructors, by the names the workspace calls them (each the generic
/// function of its line at `V = Vec4`, so that `TileTracer::new(size)` needs no annotation).
impl TileTracer {
    /// Whether a tracer of 2x2 packets can take tiles of `size` pixels: a multiple of 4 in
    /// `4..=64` ([`TileTracer::check_tile_size`]).
    pub fn check_size(size: u32) -> Result<(), TileError> {
        TileTracer::<Vec4>::check_tile_size(size)
    }

    /// A tracer of 2x2 packets for tiles of `size x size` pixels (a multiple of 4 in
    /// `4..=64`; [`TileTracer::with_size`]).
    pub fn new(size: u32) -> Result<TileTracer, TileError> {
        TileTracer::<Vec4>::with_size(size)
    }
}

/// The shape `(pw, ph)` in pixels of a packet of `lanes` rays: as square as a power of two
/// allows, wider than tall (2x2 for 4, 4x2 for 8, 4x4 for 16). Only powers of two up to 32
/// tile a square (a compile-time error otherwise, where a tracer of such lanes is made).
const fn packet_shape(lanes: usize) -> (u32, u32) {
    assert!(lanes.is_power_of_two() && lanes <= 32, "a tile's packets must have a power of two of lanes, up to 32");
    let pw = 1u32 << lanes.trailing_zeros().div_ceil(2);
    (pw, lanes as u32 / pw)
}

impl<V: SimdF32> TileTracer<V> {
    /// The pixels a packet covers, `(pw, ph)`: 2x2 for 4 lanes, 4 wide x 2 tall for 8, 4x4
    /// for 16. Lane `l` of the packet whose top-left pixel is `(x, y)` is pixel
    /// `(x + l % pw, y + l / pw)`.
    pub const PACKET_SHAPE: (u32, u32) = packet_shape(V::LANES);

    /// What a tile size must be a multiple of (and the smallest size): 4, or twice the
    /// packet's width in pixels where that is more (8 for 8 and 16 lanes), so that each
    /// quadrant holds whole packets.
    pub const SIZE_MULTIPLE: u32 = if 2 * Self::PACKET_SHAPE.0 > 4 { 2 * Self::PACKET_SHAPE.0 } else { 4 };

    /// Whether a tracer of these packets can take tiles of `size` pixels: a multiple of
    /// [`TileTracer::SIZE_MULTIPLE`] from it to 64 (4 for 4 lanes, 8 for 8 and 16).
    pub fn check_tile_size(size: u32) -> Result<(), TileError> {
        let multiple = Self::SIZE_MULTIPLE;
        if (multiple..=MAX_TILE).contains(&size) && size.is_multiple_of(multiple) {
            Ok(())
        } else if multiple == 4 {
            Err(TileError::BadSize(size))
        } else {
            Err(TileError::BadSizeForWidth { size, lanes: V::LANES, multiple })
        }
    }

    /// A tracer for tiles of `size x size` pixels ([`TileTracer::check_tile_size`]) in
    /// packets of `V::LANES` rays: `TileTracer::<PortableF32<16>>::with_size(16)`.
    pub fn with_size(size: u32) -> Result<TileTracer<V>, TileError> {
        Self::check_tile_size(size)?;
        let packets = (size as usize).pow(2) / V::LANES;
        Ok(TileTracer {
            size,
            tile: Tile { x0: 0, y0: 0, x1: 0, y1: 0 },
            packets: Vec::with_capacity(packets),
            corners: Vec::with_capacity(packets),
            hits: Vec::with_capacity(packets),
            done: Vec::with_capacity(packets),
            quadrants: std::array::from_fn(|_| 0..0),
            grids: [Grid::default(); MAX_REGIONS],
            side: 2,
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

    /// Whether tiles of `size` pixels split into `regions` frusta (4 or 16: 2 x 2 or 4 x 4
    /// regions) hold whole packets of these lanes in every region: [`TileTracer::check_tile_size`],
    /// and for 16 regions a size that is a multiple of 4 packet widths (8 for 2x2 packets, 16
    /// for 4x2 and 4x4).
    pub fn check_regions(size: u32, regions: usize) -> Result<(), TileError> {
        Self::check_tile_size(size)?;
        match regions {
            4 => Ok(()),
            16 => {
                let multiple = 4 * Self::PACKET_SHAPE.0;
                if size.is_multiple_of(multiple) {
                    Ok(())
                } else {
                    Err(TileError::BadSizeForWidth { size, lanes: V::LANES, multiple })
                }
            }
            _ => Err(TileError::BadRegions(regions)),
        }
    }

    /// Splits the tiles loaded from now on into `regions` frusta: 4 (the quadrants, thesis
    /// 4.1.5; the default) or 16 (4 x 4 regions, each traced as one lane of a 16-lane
    /// frustum: [`TileTracer::trace_mft_regions_with`]). The size must hold whole packets in
    /// each region ([`TileTracer::check_regions`]).
    pub fn set_regions(&mut self, regions: usize) -> Result<(), TileError> {
        Self::check_regions(self.size, regions)?;
        self.side = if regions == 16 { 4 } else { 2 };
        Ok(())
    }

    /// The number of frusta a loaded tile is split into (4 or 16).
    pub fn region_count(&self) -> usize {
        (self.side * self.side) as usize
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

    /// Number of packets in the loaded tile (the denominator of N and I).
    pub fn packet_count(&self) -> usize {
        self.packets.len()
    }

    /// Loads the primary rays of `tile` (at most `size x size`, inside `camera`'s image):
    /// pixel `(x, y)` gets exactly the single-ray camera ray, `Camera::pixel_ray` over
    /// `[0, +inf]`. A camera with a NaN or infinite field is [`TileError::NonFiniteCamera`]
    /// naming it.
    #[inline(always)]
    pub fn load_primary(&mut self, camera: &Camera, tile: &Tile) -> Result<(), TileError> {
        self.load_primary_prefetching::<()>(camera, tile, &[])
    }

    /// [`TileTracer::load_primary`], asking for the cache lines of `out` (where
    /// [`TileTracer::write_hits`] will write the tile's hits) as it goes: after each packet
    /// its share of the lines ([`prefetch_for_write`]), so that the requests are spread over
    /// the packets' generation instead of one burst that fills the CPU's miss buffers.
    #[inline(always)]
    pub fn load_primary_prefetching<T>(&mut self, camera: &Camera, tile: &Tile, out: &[T]) -> Result<(), TileError> {
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
        let (pw, ph) = Self::PACKET_SHAPE;
        let (side, step) = (self.side, self.size / self.side);
        // Region edges: `step` apart from the tile's corner, clipped to the tile.
        let xs = |k: u32| (tile.x0 + k * step).min(tile.x1);
        let ys = |k: u32| (tile.y0 + k * step).min(tile.y1);
        let origin = camera.eye.extend(0.0).to_array();
        let rays = PrimaryRays::new(camera);
        // The tile's packets, and the share of `out` each prefetches (the last one the rest).
        let count = (tile.width().div_ceil(pw) * tile.height().div_ceil(ph)).max(1) as usize;
        let share = out.len().div_ceil(count);
        let mut ahead = out.chunks(share.max(1));
        for q in 0..MAX_REGIONS {
            let first = self.packets.len();
            let (qx0, qx1, qy0, qy1) = if (q as u32) < side * side {
                let (cx, cy) = (q as u32 % side, q as u32 / side);
                (xs(cx), xs(cx + 1), ys(cy), ys(cy + 1))
            } else {
                (0, 0, 0, 0)
            };
            let (cols, rows) = (qx1.saturating_sub(qx0).div_ceil(pw), qy1.saturating_sub(qy0).div_ceil(ph));
            for y in (qy0..qy1.max(qy0)).step_by(ph as usize) {
                for x in (qx0..qx1.max(qx0)).step_by(pw as usize) {
                    self.packets.push(OmniPacket { rays: rays.packet(x, y, tile), origin });
                    self.corners.push((x, y));
                    if let Some(lines) = ahead.next() {
                        prefetch_for_write(lines);
                    }
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
    #[inline(always)]
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
    #[inline(always)]
    pub fn load_packets(&mut self, packets: &[OmniPacket<V>]) -> Option<()> {
        let origin = packets.iter().find(|p| p.rays.valid.any()).map_or([0.0; 4], |p| p.origin);
        if packets.iter().any(|p| p.rays.valid.any() && p.origin != origin) {
            return None;
        }
        self.packets.clear();
        self.packets.extend_from_slice(packets);
        self.set_loaded(origin);
        Some(())
    }

    /// Loads a run of rays made elsewhere as [`TileTracer::load_packets`] does their packets:
    /// `V::LANES` consecutive rays a packet (the last one partial), with no buffer of the
    /// caller's. Returns `None` unless every ray starts at or past one common origin (`t_min
    /// >= 0`); a ray with NaN or infinite components is an invalid lane, with no hit.
    #[inline(always)]
    pub fn load_rays(&mut self, rays: &[Ray]) -> Option<()> {
        self.packets.clear();
        for chunk in rays.chunks(V::LANES) {
            let Some(packet) = OmniPacket::new(RayPacket::<V>::from_rays(chunk)) else {
                self.packets.clear();
                return None;
            };
            self.packets.push(packet);
        }
        let origin = self.packets.iter().find(|p| p.rays.valid.any()).map_or([0.0; 4], |p| p.origin);
        if self.packets.iter().any(|p| p.rays.valid.any() && p.origin != origin) {
            self.packets.clear();
            return None;
        }
        self.set_loaded(origin);
        Some(())
    }

    /// The rest of loading packets made elsewhere: no tile, no camera, the packets cut into
    /// the regions in order.
    #[inline(always)]
    fn set_loaded(&mut self, origin: [f32; 4]) {
        self.tile = Tile { x0: 0, y0: 0, x1: 0, y1: 0 };
        self.corners.clear();
        self.corners.resize(self.packets.len(), (0, 0));
        let (n, regions) = (self.packets.len(), self.region_count());
        let cut = |q: usize| q.min(regions) * n / regions;
        self.quadrants = std::array::from_fn(|q| cut(q)..cut(q + 1));
        self.camera = None;
        self.origin = origin;
    }

    /// Resets the hits and finished lanes before a trace, and makes the watertight shear
    /// table when a frustum method traces a watertight tree (`I`, the tree's test, chosen
    /// once by the caller: the check is a constant).
    #[inline(always)]
    pub(crate) fn reset<I: TreeTest>(&mut self, frustum: bool) {
        // Plain loops: `extend` over a `map` leaves iterator code out of line, compiled
        // without a wide caller's target features.
        self.sheared.clear();
        if frustum && I::INTERSECTOR == Intersector::Watertight {
            for p in &self.packets {
                self.sheared.push(<WatertightTriangle as PacketTest<V>>::prepare4(&p.rays));
            }
        }
        self.hits.clear();
        self.done.clear();
        for p in &self.packets {
            self.hits.push(PacketHit::new(&p.rays));
            self.done.push(!p.rays.valid.bitmask() & all_lanes::<V>());
        }
    }

    /// The camera and tile of a primary tile ([`TileTracer::load_primary`]); `None` for
    /// packets loaded with [`TileTracer::load_packets`].
    pub fn primary(&self) -> Option<(&Camera, Tile)> {
        self.camera.as_ref().map(|c| (c, self.tile))
    }

    /// The packets of quadrant `q` (0 to 3: top-left, top-right, bottom-left, bottom-right
    /// for a primary tile, quarters by packet order otherwise).
    pub fn quadrant(&self, q: usize) -> &[OmniPacket<V>] {
        &self.packets[self.quadrants[q & 3].clone()]
    }

    /// The pixels of quadrant `q` of a primary tile (`None` when the quadrant is empty, at
    /// the image's right or bottom edge, or for loaded packets).
    pub fn quadrant_tile(&self, q: usize) -> Option<Tile> {
        self.camera?;
        let g = self.grids[q & 3];
        let (pw, ph) = Self::PACKET_SHAPE;
        let (x1, y1) = ((g.x0 + pw * g.cols).min(self.tile.x1), (g.y0 + ph * g.rows).min(self.tile.y1));
        (g.cols > 0 && g.rows > 0).then_some(Tile { x0: g.x0, y0: g.y0, x1, y1 })
    }

    /// The common origin of the loaded rays.
    pub fn origin(&self) -> glam::Vec3 {
        glam::Vec3::from_slice(&self.origin[..3])
    }

    /// The hits of the packets, in packet order (after a trace, e.g. [`TileTracer::trace_mft`]).
    pub fn packet_hits(&self) -> &[PacketHit<V>] {
        &self.hits
    }

    /// The loaded packets.
    pub fn packets(&self) -> &[OmniPacket<V>] {
        &self.packets
    }

    /// Writes the traced hits into `out`, the tile's pixels row by row (`tile.width()` per
    /// row), as single-ray traversal would.
    #[inline(always)]
    pub fn write_hits(&self, out: &mut [Option<Hit>]) {
        let (t, w) = (self.tile, self.tile.width() as usize);
        let (pw, ph) = Self::PACKET_SHAPE;
        for (&(x, y), hit) in self.corners.iter().zip(&self.hits) {
            // The packet's pixels inside the tile, written as rows: its first `cols` columns of
            // its first `rows` rows (all `pw x ph` but at the tile's right and bottom edges).
            let cols = t.x1.saturating_sub(x).min(pw) as usize;
            let rows = t.y1.saturating_sub(y).min(ph) as usize;
            if cols == 0 || rows == 0 {
                continue;
            }
            let start = (y - t.y0) as usize * w + (x - t.x0) as usize;
            for (r, row) in out[start..].chunks_mut(w).take(rows).enumerate() {
                for (c, slot) in row[..cols].iter_mut().enumerate() {
                    *slot = hit.get(r * pw as usize + c);
                }
            }
        }
    }
}

/// Asks the CPU to bring the cache lines of `out` in for writing, ahead of
/// [`TileTracer::write_hits`] into it: issued while a tile's packets are made
/// ([`TileTracer::load_primary_prefetching`]), so that the lines arrive while the traversal
/// runs. A frame's hits (20 bytes a pixel) outgrow the caches
/// between frames, and the write-back otherwise waits on one store miss after another: it
/// held about a tenth of the 16-lane MFT kernel's time (`perf`, Sponza). A hint
/// only: it changes no result, and does nothing off x86-64.
#[inline(always)]
pub fn prefetch_for_write<T>(out: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_ET0, _mm_prefetch};
        // Every 64-byte line the slice touches, from the one holding its first byte.
        let (start, bytes) = (out.as_ptr().cast::<i8>(), std::mem::size_of_val(out));
        let skew = start as usize % 64;
        for offset in (0..bytes + skew).step_by(64) {
            // SAFETY: a prefetch never faults and reads nothing the program sees; the address
            // is only computed (wrapping, no dereference), so it may lie outside `out`.
            unsafe { _mm_prefetch::<_MM_HINT_ET0>(start.wrapping_sub(skew).wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = out;
}

/// A quadrant's packets as a grid: the packet in column `c`, row `r` is number
/// `r * cols + c` of the quadrant and covers pixels `(x0 + pw c, y0 + ph r)` to
/// `(x0 + pw c + pw - 1, y0 + ph r + ph - 1)` for packets of `pw x ph` pixels
/// ([`TileTracer::PACKET_SHAPE`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Grid {
    pub(crate) x0: u32,
    pub(crate) y0: u32,
    pub(crate) cols: u32,
    pub(crate) rows: u32,
}

impl Grid {
    /// The columns and rows of the packets of `(pw, ph)` pixels with a pixel centre inside
    /// `rect` (see [`TileTracer::screen_rect`]).
    #[inline]
    pub(crate) fn within(&self, rect: [f32; 4], (pw, ph): (u32, u32)) -> (Range<u32>, Range<u32>) {
        // Packet column c has centres x0 + pw c + 0.5 to x0 + pw c + pw - 0.5. The sides are
        // powers of two: `* (1 / p)` is the division, exactly.
        let span = |lo: f32, hi: f32, origin: u32, n: u32, p: u32| {
            let (last_centre, scale) = (p as f32 - 0.5, 1.0 / p as f32);
            let first = ((lo - last_centre - origin as f32) * scale).ceil();
            let end = ((hi - 0.5 - origin as f32) * scale).floor() + 1.0;
            (to_count(first, n), to_count(end, n))
        };
        let ((x0, x1), (y0, y1)) =
            (span(rect[0], rect[1], self.x0, self.cols, pw), span(rect[2], rect[3], self.y0, self.rows, ph));
        (x0..x1.max(x0), y0..y1.max(y0))
    }
}

/// `v` (a whole number, or NaN) clamped to `[0, n]` as an integer, NaN as 0. The comparisons
/// are each one `maxss`/`minss` and the conversion one instruction: `Grid::within` runs at
/// every leaf a frustum reaches, and `f32::clamp` with a saturating `as u32` made its four
/// conversions a compare-and-move chain each (about 6% of the 16-lane MFT kernel, `perf`).
#[inline(always)]
fn to_count(v: f32, n: u32) -> u32 {
    // A grid has at most `MAX_TILE` columns or rows (`TileTracer::with_size` checks the
    // tile); the bound `2^24` (exact in `f32`) only keeps the conversion below sound for any
    // `n`.
    let n_f = n.min(1 << 24) as f32;
    // `v > 0.0` is false for NaN, so NaN becomes 0.
    let v = if v > 0.0 { v } else { 0.0 };
    let v = if v < n_f { v } else { n_f };
    // SAFETY: `v` is not NaN and lies in `[0, 2^24]`, so truncated it fits a `u32`.
    unsafe { v.to_int_unchecked::<u32>() }
}

#[cfg(test)]
impl Grid {
    /// [`Grid::within`] as it was written first, with `f32::clamp` and saturating
    /// conversions: the reference its faster form is tested against.
    fn within_saturating(&self, rect: [f32; 4], (pw, ph): (u32, u32)) -> (Range<u32>, Range<u32>) {
        let span = |lo: f32, hi: f32, origin: u32, n: u32, p: u32| {
            let (last_centre, scale) = (p as f32 - 0.5, 1.0 / p as f32);
            let first = ((lo - last_centre - origin as f32) * scale).ceil().clamp(0.0, n as f32) as u32;
            let end = (((hi - 0.5 - origin as f32) * scale).floor() + 1.0).clamp(0.0, n as f32) as u32;
            first..end.max(first)
        };
        (span(rect[0], rect[1], self.x0, self.cols, pw), span(rect[2], rect[3], self.y0, self.rows, ph))
    }
}

/// Primary-ray packets of one camera, generated `V::LANES` rays at a time with exactly the
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

    /// The packet of the `pw x ph` pixels ([`TileTracer::PACKET_SHAPE`]) whose top-left
    /// pixel is `(x, y)`, lane `l` pixel `(x + l % pw, y + l / pw)`; pixels outside `tile`
    /// are invalid lanes.
    #[inline(always)]
    fn packet<V: SimdF32>(&self, x: u32, y: u32, tile: &Tile) -> RayPacket<V> {
        let c = &self.camera;
        let (w, h) = (c.width as f32, c.height as f32);
        let pw = TileTracer::<V>::PACKET_SHAPE.0;
        let px = V::from_fn(|l| (x + l as u32 % pw) as f32 + 0.5);
        let py = V::from_fn(|l| (y + l as u32 / pw) as f32 + 0.5);
        // Camera::direction, per lane (a vector times a scalar is the splat's product).
        let (tan, aspect) = (V::splat(c.tan_half_fovy), V::splat(self.aspect));
        let sx = (V::splat(2.0) * px / V::splat(w) - V::ONE) * tan * aspect;
        let sy = (V::ONE - V::splat(2.0) * py / V::splat(h)) * tan;
        let comp = |a: usize| V::splat(c.forward[a]) + sx * V::splat(c.right[a]) + sy * V::splat(c.up[a]);
        let (dx, dy, dz) = (comp(0), comp(1), comp(2));
        // Vec3::normalize: d * (1 / sqrt(d . d)).
        let squares = (dx * dx + dy * dy + dz * dz).to_array();
        let len_recip = V::ONE / V::from_fn(|l| squares[l].sqrt());
        // Ray::new: reciprocals, and components whose reciprocal overflows flushed to zeros.
        let (d, inv) = directions([dx * len_recip, dy * len_recip, dz * len_recip]);
        let inside = V::Mask::from_fn(|l| x + l as u32 % pw < tile.x1 && y + l as u32 / pw < tile.y1);
        RayPacket {
            o: [V::splat(c.eye.x), V::splat(c.eye.y), V::splat(c.eye.z), V::ZERO],
            d: [d[0], d[1], d[2], V::ZERO],
            inv: [inv[0], inv[1], inv[2], V::ZERO],
            t_min: V::select(inside, V::ZERO, V::INFINITY),
            t_max: V::select(inside, V::INFINITY, V::NEG_INFINITY),
            valid: inside,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::PortableF32;
    use kdtree::Ray;

    /// Every lane of a loaded primary tile is the single camera ray, bit for bit, and the
    /// lanes outside the image are invalid; at every packet width.
    #[test]
    fn primary_lanes_are_the_camera_rays() {
        primary_lanes::<Vec4>();
        primary_lanes::<PortableF32<4>>();
        primary_lanes::<PortableF32<8>>();
        primary_lanes::<PortableF32<16>>();
    }

    #[inline(always)]
    fn primary_lanes<V: SimdF32>() {
        let pw = TileTracer::<V>::PACKET_SHAPE.0;
        for (w, h, fovy) in [(37u32, 21u32, 70.0f32), (64, 64, 150.0), (5, 9, 1.0)] {
            let camera =
                Camera::look_at(glam::Vec3::new(1.0, 2.0, 3.0), glam::Vec3::new(-4.0, 0.5, 7.0), fovy, w, h).unwrap();
            let mut tracer = TileTracer::<V>::with_size(16).unwrap();
            for tile in scenes::tiles(w, h, 16) {
                tracer.load_primary(&camera, &tile).unwrap();
                let mut seen = 0;
                for (p, &(x, y)) in tracer.packets.iter().zip(&tracer.corners) {
                    for lane in 0..V::LANES as u32 {
                        let (px, py) = (x + lane % pw, y + lane / pw);
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
        assert_eq!(g.within([10.2, 11.0, -100.0, 100.0], (2, 2)), (1..2, 0..4));
        assert_eq!(g.within([0.0, 8.4, 0.0, 1.0], (2, 2)), (0..0, 0..1));
        assert_eq!(g.within([-1e30, 1e30, 3.4, 3.7], (2, 2)), (0..4, 1..2));
        // Between two rows of pixel centres: no packet.
        assert_eq!(g.within([-1e30, 1e30, 3.6, 3.7], (2, 2)).1.len(), 0);
        // Packets of 4x2 and 4x4 pixels: packet column c covers pixels 8 + 4c to 11 + 4c.
        let g = Grid { x0: 8, y0: 0, cols: 2, rows: 2 };
        assert_eq!(g.within([11.4, 11.6, -100.0, 100.0], (4, 2)), (0..1, 0..2));
        // Between the centres 11.5 and 12.5 of two packets: none.
        assert_eq!(g.within([11.6, 12.4, -100.0, 100.0], (4, 2)).0.len(), 0);
        assert_eq!(g.within([11.4, 12.6, 1.4, 2.6], (4, 2)), (0..2, 0..2));
        // Inside one packet's span of centres (0.5 to 3.5): that packet; between two: none.
        assert_eq!(g.within([11.4, 12.6, 1.6, 2.4], (4, 4)).1, 0..1);
        assert_eq!(g.within([11.4, 12.6, 3.6, 4.4], (4, 4)).1.len(), 0);
        assert_eq!(g.within([-1e30, 1e30, 3.4, 4.6], (4, 4)), (0..2, 0..2));
        assert_eq!(g.within([-1e30, 1e30, 4.4, 4.6], (4, 4)), (0..2, 1..2));
    }

    proptest::proptest! {
        /// The branch-free `within` gives the first form's ranges: on rectangles inside,
        /// across and far outside the grid (±1e30), reversed ones, and NaN sides.
        #[test]
        fn grid_ranges_equal_the_saturating_form(
            x0 in 0u32..1024, y0 in 0u32..1024, cols in 0u32..=32, rows in 0u32..=32,
            shape in 0usize..3, sides in proptest::array::uniform4(-2000.0f32..2000.0),
            far in proptest::array::uniform4(0u8..5),
        ) {
            let g = Grid { x0, y0, cols, rows };
            let rect = std::array::from_fn(|i| match far[i] {
                0 => -1e30,
                1 => 1e30,
                2 if i == 3 => f32::NAN,
                _ => sides[i],
            });
            let shape = [(2, 2), (4, 2), (4, 4)][shape];
            proptest::prop_assert_eq!(g.within(rect, shape), g.within_saturating(rect, shape));
        }
    }

    /// The packet shapes and the sizes each width takes, with the error naming the width.
    #[test]
    fn sizes_follow_the_packet_shape() {
        assert_eq!(TileTracer::<Vec4>::PACKET_SHAPE, (2, 2));
        assert_eq!(TileTracer::<PortableF32<8>>::PACKET_SHAPE, (4, 2));
        assert_eq!(TileTracer::<PortableF32<16>>::PACKET_SHAPE, (4, 4));
        for size in 0..80 {
            let four = size % 4 == 0 && (4..=64).contains(&size);
            let eight = size % 8 == 0 && (8..=64).contains(&size);
            assert_eq!(TileTracer::check_size(size).is_ok(), four, "{size}");
            assert_eq!(TileTracer::<PortableF32<8>>::check_tile_size(size).is_ok(), eight, "{size}");
            assert_eq!(TileTracer::<PortableF32<16>>::check_tile_size(size).is_ok(), eight, "{size}");
            assert_eq!(TileTracer::<PortableF32<16>>::with_size(size).is_ok(), eight, "{size}");
        }
        assert_eq!(TileTracer::new(6).unwrap_err().to_string(), "tile size 6 must be a multiple of 4 from 4 to 64");
        let e = TileTracer::<PortableF32<16>>::with_size(4).unwrap_err();
        assert_eq!(e, TileError::BadSizeForWidth { size: 4, lanes: 16, multiple: 8 });
        assert!(e.to_string().contains("multiple of 8") && e.to_string().contains("16 rays"), "{e}");
        // A tile of the largest size holds size^2 / W packets.
        let camera = Camera::look_at(glam::Vec3::ZERO, glam::Vec3::NEG_Z, 60.0, 64, 64).unwrap();
        let mut tracer = TileTracer::<PortableF32<16>>::with_size(64).unwrap();
        tracer.load_primary(&camera, &scenes::tiles(64, 64, 64)[0]).unwrap();
        assert_eq!(tracer.packet_count(), 64 * 64 / 16);
        assert!(
            tracer.quadrants[..4].iter().all(|q| q.len() == 64) && tracer.quadrants[4..].iter().all(|q| q.is_empty())
        );
        // Split 4 x 4: sixteen regions of 16 packets, row by row, each a 16x16 square.
        tracer.set_regions(16).unwrap();
        tracer.load_primary(&camera, &scenes::tiles(64, 64, 64)[0]).unwrap();
        assert_eq!(tracer.region_count(), 16);
        for (q, (range, grid)) in tracer.quadrants.iter().zip(&tracer.grids).enumerate() {
            assert_eq!(range.len(), 16, "region {q}");
            assert_eq!((grid.x0, grid.y0, grid.cols, grid.rows), (16 * (q as u32 % 4), 16 * (q as u32 / 4), 4, 4));
        }
        // Sixteen regions need whole packets in each: 4 packet widths.
        assert!(TileTracer::<PortableF32<16>>::check_regions(16, 16).is_ok());
        let e = TileTracer::<PortableF32<16>>::check_regions(8, 16).unwrap_err();
        assert_eq!(e, TileError::BadSizeForWidth { size: 8, lanes: 16, multiple: 16 });
        assert!(TileTracer::<Vec4>::check_regions(8, 16).is_ok());
        assert!(TileTracer::<Vec4>::check_regions(12, 16).is_err());
        assert_eq!(TileTracer::<Vec4>::check_regions(8, 9), Err(TileError::BadRegions(9)));
    }

    /// A tile split 4 x 4 at the image's edge: regions clipped to the tile, every pixel in
    /// exactly one packet of its region.
    #[test]
    fn regions_cover_clipped_tiles() {
        let camera = Camera::look_at(glam::Vec3::ZERO, glam::Vec3::NEG_Z, 60.0, 37, 21).unwrap();
        let mut tracer = TileTracer::<Vec4>::with_size(16).unwrap();
        tracer.set_regions(16).unwrap();
        for tile in scenes::tiles(37, 21, 16) {
            tracer.load_primary(&camera, &tile).unwrap();
            let valid: u32 = tracer.packets.iter().map(|p| p.rays.valid.bitmask().count_ones()).sum();
            assert_eq!(valid as usize, tile.pixel_count(), "{tile:?}");
            for (range, grid) in tracer.quadrants.iter().zip(&tracer.grids) {
                assert_eq!(range.len(), (grid.cols * grid.rows) as usize);
                for &(x, y) in &tracer.corners[range.clone()] {
                    assert!(x >= grid.x0 && x < grid.x0 + 4 && y >= grid.y0 && y < grid.y0 + 4, "{tile:?}");
                }
            }
        }
    }
}
