//! The one frame driver: a [`Method`] run over whole frames, tile by tile, with rayon.
//!
//! A frame is an image split into square tiles ([`TileLayout`]); every per-pixel buffer is
//! kept in *tile order* (tile after tile, row-major inside each), so a tile's pixels are one
//! contiguous chunk that one rayon task owns: no locking, no allocation per ray. Three passes
//! run over the tiles, the same for our methods and for every baseline:
//! 1. [`primary_pass`]: each pixel's camera ray and its closest hit;
//! 2. [`shadow_pass`]: from each hit facing the point light, whether anything blocks the
//!    segment to the light (hard shadows);
//! 3. [`soft_pass`]: from each such hit, the 16 rays to a spherical light (thesis Table 4.6),
//!    the visible fraction per pixel.
//!
//! The method is generic here, so every pass is one monomorphic loop; [`FrameTracer`] is the
//! same passes behind a `dyn` (one virtual call per pass, never per ray), which is how the
//! registry hands methods out (`crate::registry`).

use kdtree::Counts;
use kdtree::surface::Surfaces;
use kdtree::{Hit, LeafClock, NoCounters, Ray};
use rayon::prelude::*;
use scenes::{Camera, Scene, SphereLight, Tile};

use crate::aov::{Attribution, PixelCost};
pub use crate::method::SoftStats;
use crate::method::{Method, ShadowJob, SoftJob, TileCounters};

/// Default tile side: the frame driver's unit of work (one rayon task), and the frustum of
/// the tiled methods.
pub const TILE_SIZE: u32 = 16;

/// An image split into tiles, with each tile's offset into tile-ordered per-pixel buffers.
#[derive(Clone, Debug)]
pub struct TileLayout {
    width: u32,
    height: u32,
    tiles: Vec<Tile>,
    /// `offsets[i]..offsets[i + 1]` is tile `i`'s chunk; one more entry than tiles.
    offsets: Vec<usize>,
}

impl TileLayout {
    /// The layout of a `width` x `height` image in `tile_size` tiles.
    pub fn new(width: u32, height: u32, tile_size: u32) -> TileLayout {
        let tiles = scenes::tiles(width, height, tile_size);
        let mut offsets = Vec::with_capacity(tiles.len() + 1);
        offsets.push(0);
        for t in &tiles {
            offsets.push(offsets.last().copied().unwrap_or(0) + t.pixel_count());
        }
        TileLayout { width, height, tiles, offsets }
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.offsets.last().copied().unwrap_or(0)
    }

    /// The tiles, in buffer order.
    pub fn tiles(&self) -> &[Tile] {
        &self.tiles
    }

    /// Number of 2x2 packets over all tiles, `ceil(w/2) * ceil(h/2)` per tile: the
    /// denominator of the thesis's N and I for packet methods.
    pub fn packet_count(&self) -> u64 {
        self.tiles.iter().map(|t| u64::from(t.width().div_ceil(2)) * u64::from(t.height().div_ceil(2))).sum()
    }

    /// `buf` (one entry per pixel, tile order) cut into one chunk per tile.
    ///
    /// Panics if `buf` is shorter than [`TileLayout::pixel_count`] (a programming error).
    pub fn chunks<'a, T>(&self, buf: &'a [T]) -> Vec<&'a [T]> {
        self.offsets.windows(2).map(|w| &buf[w[0]..w[1]]).collect()
    }

    /// `buf` (one entry per pixel, tile order) cut into one disjoint mutable chunk per tile,
    /// so that each tile's task can write its own pixels without locking. Panics like
    /// [`TileLayout::chunks`].
    pub fn chunks_mut<'a, T>(&self, mut buf: &'a mut [T]) -> Vec<&'a mut [T]> {
        let mut out = Vec::with_capacity(self.tiles.len());
        for t in &self.tiles {
            let (head, tail) = std::mem::take(&mut buf).split_at_mut(t.pixel_count());
            out.push(head);
            buf = tail;
        }
        out
    }

    /// A row-major image (`width * height` values) from a tile-ordered buffer.
    pub fn to_row_major<T: Copy + Default>(&self, buf: &[T]) -> Vec<T> {
        let mut out = vec![T::default(); self.width as usize * self.height as usize];
        for (tile, chunk) in self.tiles.iter().zip(self.chunks(buf)) {
            for ((x, y), &v) in tile.pixels().zip(chunk) {
                out[y as usize * self.width as usize + x as usize] = v;
            }
        }
        out
    }
}

/// What a tile's pass returns, summed over tiles by [`for_tiles`] (hits, ray counts,
/// soft-shadow statistics).
pub trait Sum: Default + Send {
    /// The sum of two tiles' (or groups of tiles') results.
    fn sum(self, other: Self) -> Self;
}

impl Sum for () {
    fn sum(self, _: ()) {}
}

impl Sum for u64 {
    fn sum(self, other: u64) -> u64 {
        self + other
    }
}

impl Sum for (u64, u64) {
    fn sum(self, other: (u64, u64)) -> (u64, u64) {
        (self.0 + other.0, self.1 + other.1)
    }
}

impl Sum for SoftStats {
    fn sum(self, o: SoftStats) -> SoftStats {
        SoftStats { points: self.points + o.points, rays: self.rays + o.rays, blocked: self.blocked + o.blocked }
    }
}

/// The frame driver's tile loop: runs `pass` on every tile of `layout` with its chunk of
/// `chunks`, in parallel over the current rayon pool with one `scratch()` per rayon task, and
/// sums what the tiles return: the frame driver's loop (the frame's own passes run the same
/// loop with their counts, `over_tiles`), for the experiments' own per-tile passes
/// (`experiments::shadows`).
pub fn for_tiles<S, I: Send, R: Sum>(
    layout: &TileLayout,
    chunks: Vec<I>,
    scratch: impl Fn() -> S + Sync + Send,
    pass: impl Fn(&mut S, &Tile, I) -> R + Sync + Send,
) -> R {
    layout
        .tiles()
        .par_iter()
        .zip(chunks)
        .map_init(scratch, |scratch, (tile, chunk)| pass(scratch, tile, chunk))
        .reduce(R::default, R::sum)
}

/// Runs `pass` on every tile of `layout` with its chunk of `chunks`, in parallel over the
/// current rayon pool with one scratch per rayon task, and sums what the tiles return and
/// count: [`for_tiles`] with the method's scratch and a fresh `C` per tile, written out (the
/// frame's passes lost up to 15% of the `mbvh-8` soft-shadow pass when this went through
/// `for_tiles`, measured with `rttest compare`).
fn over_tiles<M: Method, C: TileCounters, I: Send, R: Sum>(
    method: &M,
    layout: &TileLayout,
    chunks: Vec<I>,
    pass: impl Fn(&mut M::Scratch, &Tile, I, &mut C) -> R + Sync + Send,
) -> (R, C) {
    layout
        .tiles()
        .par_iter()
        .zip(chunks)
        .map_init(
            || method.scratch(),
            |scratch, (tile, chunk)| {
                let mut counts = C::default();
                let out = pass(scratch, tile, chunk, &mut counts);
                (out, counts)
            },
        )
        .reduce(
            || (R::default(), C::default()),
            |(a, mut ca), (b, cb)| {
                ca += cb;
                (a.sum(b), ca)
            },
        )
}

/// Pass 1: the closest hit of every pixel's primary ray into `out` (tile order of `layout`).
/// Returns the number of hits and the summed counters.
pub fn primary_pass<M: Method, C: TileCounters>(
    method: &M,
    layout: &TileLayout,
    camera: &Camera,
    out: &mut [Option<Hit>],
) -> (u64, C) {
    over_tiles(method, layout, layout.chunks_mut(out), |scratch, tile, out, counts| {
        method.primary_tile(scratch, camera, tile, out, counts);
        out.iter().filter(|h| h.is_some()).count() as u64
    })
}

/// Pass 2: the hard shadow ray of every hit of `hits` (tile order of `layout`) into
/// `occluded`. Returns (rays traced, rays blocked) and the summed counters.
pub fn shadow_pass<M: Method, C: TileCounters>(
    method: &M,
    view: &View<'_>,
    hits: &[Option<Hit>],
    occluded: &mut [bool],
) -> (u64, u64, C) {
    let View { layout, scene, surfaces, camera } = *view;
    let chunks: Vec<_> = layout.chunks(hits).into_iter().zip(layout.chunks_mut(occluded)).collect();
    let ((rays, blocked), counts) = over_tiles(method, layout, chunks, |scratch, tile, (hits, out), counts| {
        method.shadow_tile(scratch, &ShadowJob { scene, surfaces, camera, tile, hits }, out, counts)
    });
    (rays, blocked, counts)
}

/// Pass 3: the 16 shadow rays of every hit of `hits` (tile order of `layout`) to `light`
/// ([`soft::shadow_start`], `cones::shadows::light_samples`), the visible fraction of the
/// light per pixel into `visible` (0 for pixels without a lit hit).
pub fn soft_pass<M: Method, C: TileCounters>(
    method: &M,
    view: &View<'_>,
    hits: &[Option<Hit>],
    light: &SphereLight,
    visible: &mut [f32],
) -> (SoftStats, C) {
    let View { layout, scene, surfaces, camera } = *view;
    let chunks: Vec<_> = layout.chunks(hits).into_iter().zip(layout.chunks_mut(visible)).collect();
    over_tiles(method, layout, chunks, |scratch, tile, (hits, out), counts| {
        let hits = ShadowJob { scene, surfaces, camera, tile, hits };
        method.soft_tile(scratch, &SoftJob { hits, light }, out, counts)
    })
}

/// The primary pass counted for cost images ([`crate::aov`]): the closest hits into `out` as
/// [`primary_pass`], and each pixel's share of the counts into `costs` (both in tile order of
/// `layout`). With [`Attribution::Ray`] each pixel is traced as a 1x1 tile and keeps its own
/// ray's counts (only for methods that trace rays one by one); with [`Attribution::Tile`]
/// each tile's counts are divided by its pixels. Returns the frame's summed counts, equal to
/// those of a counted [`primary_pass`]. Not timed, and never run by a timed frame.
pub fn cost_pass<M: Method>(
    method: &M,
    layout: &TileLayout,
    camera: &Camera,
    attribution: Attribution,
    out: &mut [Option<Hit>],
    costs: &mut [PixelCost],
) -> Counts {
    let chunks: Vec<_> = layout.chunks_mut(out).into_iter().zip(layout.chunks_mut(costs)).collect();
    let ((), counts) =
        over_tiles(method, layout, chunks, |scratch, tile, (out, costs), total: &mut Counts| match attribution {
            Attribution::Tile => {
                let mut c = Counts::default();
                method.primary_tile(scratch, camera, tile, out, &mut c);
                costs.fill(PixelCost::share(&c, tile.pixel_count()));
                *total += c;
            }
            Attribution::Ray => {
                for (i, (x, y)) in tile.pixels().enumerate() {
                    let pixel = Tile { x0: x, y0: y, x1: x + 1, y1: y + 1 };
                    let mut c = Counts::default();
                    method.primary_tile(scratch, camera, &pixel, &mut out[i..=i], &mut c);
                    costs[i] = PixelCost::share(&c, 1);
                    *total += c;
                }
            }
        });
    counts
}

/// Rays per parallel chunk of a ray stream.
pub const STREAM_CHUNK: usize = 4096;

/// The closest hits of an arbitrary list of rays, in order, in parallel over chunks of
/// [`STREAM_CHUNK`] rays.
pub fn stream_pass<M: Method>(method: &M, rays: &[Ray], out: &mut [Option<Hit>]) {
    out.par_chunks_mut(STREAM_CHUNK)
        .zip(rays.par_chunks(STREAM_CHUNK))
        .for_each_init(|| method.scratch(), |s, (out, rays)| method.stream(s, rays, out, &mut NoCounters));
}

/// [`stream_pass`] with counters `C`, summed over the chunks.
pub fn stream_pass_counted<M: Method, C: TileCounters>(method: &M, rays: &[Ray], out: &mut [Option<Hit>]) -> C {
    out.par_chunks_mut(STREAM_CHUNK)
        .zip(rays.par_chunks(STREAM_CHUNK))
        .map_init(
            || method.scratch(),
            |s, (out, rays)| {
                let mut c = C::default();
                method.stream(s, rays, out, &mut c);
                c
            },
        )
        .reduce(C::default, |mut a, b| {
            a += b;
            a
        })
}

/// Whether each ray of an arbitrary list is blocked, in order, in parallel like
/// [`stream_pass`].
pub fn stream_occluded_pass<M: Method>(method: &M, rays: &[Ray], out: &mut [bool]) {
    out.par_chunks_mut(STREAM_CHUNK)
        .zip(rays.par_chunks(STREAM_CHUNK))
        .for_each_init(|| method.scratch(), |s, (out, rays)| method.stream_occluded(s, rays, out, &mut NoCounters));
}

/// One view of a scene in tiles: what the shadow passes trace over.
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    /// The tiles of the image and of its tile-ordered buffers.
    pub layout: &'a TileLayout,
    /// The scene (mesh and point light).
    pub scene: &'a Scene,
    /// The scene's surface records ([`crate::shade::surfaces`]), made once per scene.
    pub surfaces: &'a Surfaces,
    /// The camera of the primary rays.
    pub camera: &'a Camera,
}

/// The passes of one method behind a `dyn`: what the registry hands out. One virtual call per
/// pass; inside, the generic passes above run monomorphic. Each pass counts into `counts`
/// when given one (slower: not for timing), and with `None` counting compiles away.
pub trait FrameTracer: Sync {
    /// [`primary_pass`]: the number of hits.
    fn primary(
        &self,
        layout: &TileLayout,
        camera: &Camera,
        out: &mut [Option<Hit>],
        counts: Option<&mut Counts>,
    ) -> u64;
    /// [`shadow_pass`] from `hits`: (rays traced, rays blocked).
    fn shadow(
        &self,
        view: &View<'_>,
        hits: &[Option<Hit>],
        out: &mut [bool],
        counts: Option<&mut Counts>,
    ) -> (u64, u64);
    /// [`soft_pass`] from `hits` to `light`.
    fn soft(
        &self,
        view: &View<'_>,
        hits: &[Option<Hit>],
        light: &SphereLight,
        out: &mut [f32],
        counts: Option<&mut Counts>,
    ) -> SoftStats;
    /// [`cost_pass`]: the primary pass with each pixel's share of the counts (cost images).
    fn primary_costs(
        &self,
        layout: &TileLayout,
        camera: &Camera,
        attribution: Attribution,
        out: &mut [Option<Hit>],
        costs: &mut [PixelCost],
    ) -> Counts;
    /// [`stream_pass`].
    fn stream(&self, rays: &[Ray], out: &mut [Option<Hit>]);
    /// [`primary_pass`] with its leaf visits clocked ([`LeafClock`], Table 3.1's split of
    /// traversal and intersection): the number of hits and the clock. Not for timing.
    fn primary_clocked(&self, layout: &TileLayout, camera: &Camera, out: &mut [Option<Hit>]) -> (u64, LeafClock);
    /// [`stream_pass`] with its leaf visits clocked, as [`FrameTracer::primary_clocked`].
    fn stream_clocked(&self, rays: &[Ray], out: &mut [Option<Hit>]) -> LeafClock;
    /// [`stream_occluded_pass`].
    fn stream_occluded(&self, rays: &[Ray], out: &mut [bool]);
}

/// A [`Method`] as a [`FrameTracer`].
#[derive(Debug)]
pub struct Driven<M>(pub M);

impl<M: Method> FrameTracer for Driven<M> {
    fn primary(
        &self,
        layout: &TileLayout,
        camera: &Camera,
        out: &mut [Option<Hit>],
        counts: Option<&mut Counts>,
    ) -> u64 {
        match counts {
            None => primary_pass::<M, NoCounters>(&self.0, layout, camera, out).0,
            Some(c) => {
                let (hits, k) = primary_pass::<M, Counts>(&self.0, layout, camera, out);
                *c += k;
                hits
            }
        }
    }

    fn shadow(&self, v: &View<'_>, hits: &[Option<Hit>], out: &mut [bool], counts: Option<&mut Counts>) -> (u64, u64) {
        let m = &self.0;
        match counts {
            None => {
                let (rays, blocked, NoCounters) = shadow_pass(m, v, hits, out);
                (rays, blocked)
            }
            Some(c) => {
                let (rays, blocked, k) = shadow_pass::<M, Counts>(m, v, hits, out);
                *c += k;
                (rays, blocked)
            }
        }
    }

    fn soft(
        &self,
        v: &View<'_>,
        hits: &[Option<Hit>],
        light: &SphereLight,
        out: &mut [f32],
        counts: Option<&mut Counts>,
    ) -> SoftStats {
        let m = &self.0;
        match counts {
            None => soft_pass::<M, NoCounters>(m, v, hits, light, out).0,
            Some(c) => {
                let (stats, k) = soft_pass::<M, Counts>(m, v, hits, light, out);
                *c += k;
                stats
            }
        }
    }

    fn primary_costs(
        &self,
        layout: &TileLayout,
        camera: &Camera,
        attribution: Attribution,
        out: &mut [Option<Hit>],
        costs: &mut [PixelCost],
    ) -> Counts {
        cost_pass(&self.0, layout, camera, attribution, out, costs)
    }

    fn stream(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        stream_pass(&self.0, rays, out);
    }

    fn primary_clocked(&self, layout: &TileLayout, camera: &Camera, out: &mut [Option<Hit>]) -> (u64, LeafClock) {
        primary_pass::<M, LeafClock>(&self.0, layout, camera, out)
    }

    fn stream_clocked(&self, rays: &[Ray], out: &mut [Option<Hit>]) -> LeafClock {
        stream_pass_counted::<M, LeafClock>(&self.0, rays, out)
    }

    fn stream_occluded(&self, rays: &[Ray], out: &mut [bool]) {
        stream_occluded_pass(&self.0, rays, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_layout_round_trips_row_major() {
        let layout = TileLayout::new(37, 21, 16);
        assert_eq!(layout.pixel_count(), 37 * 21);
        let mut buf = vec![0u32; layout.pixel_count()];
        for (tile, chunk) in layout.tiles().iter().zip(layout.chunks_mut(&mut buf)) {
            for ((x, y), v) in tile.pixels().zip(chunk) {
                *v = y * 37 + x;
            }
        }
        let image = layout.to_row_major(&buf);
        assert!(image.iter().enumerate().all(|(i, &v)| v as usize == i));
    }
}
