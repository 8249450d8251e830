//! The tile renderer: tracing as separate, timed passes over preallocated buffers.
//!
//! A frame is three passes over the image's 16 x 16 tiles, each tile handled by one rayon
//! task that owns a disjoint chunk of every per-pixel buffer (no locking, no allocation per
//! ray):
//! 1. **primary**: generate each pixel's camera ray and find its closest hit;
//! 2. **shadow** (with `--shadows hard`): from each hit facing the point light, ask whether
//!    anything blocks the segment to the light;
//! 3. **output**: shade the hits (or take their depth or primitive id) into an image.
//!
//! Passes 1 and 2 are the timed "trace" of the benchmark (ray generation, traversal and
//! intersection only); pass 3 is timed apart. The per-pixel buffers are kept in *tile order*
//! (tile after tile, each tile row-major inside), so a tile's pixels are one contiguous chunk;
//! [`TileLayout`] maps them back to the row-major image.
//!
//! The traversal [`Method`] is chosen once per frame: each pass matches on it once per tile
//! and then runs a monomorphic loop, so there is no dynamic dispatch per ray. The packet
//! methods (2x2 packets, frusta, MFT) trace each tile's primary rays with a
//! [`packets::TileTracer`], one per rayon task, so the tile's frustum is the render tile
//! (`--tile N`). Shadow rays start at different hit points, so every method traces them one
//! at a time.

use std::time::Instant;

use cones::ConeMethod;
use glam::Vec3;
use kdtree::{Counters, Hit, KdTree, NoCounters, Ray};
use packets::{PacketCounters, PacketCounts, TileMethod, TileTracer};
use rayon::prelude::*;
use scenes::{Camera, Image, ScalarImage, Scene, Tile};

use crate::shade;

/// Side of the square tiles handed to the threads, unless `--tile` says otherwise.
pub const TILE_SIZE: u32 = 16;

/// How rays are traced through the tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// One ray at a time: [`KdTree::intersect`] and [`KdTree::occluded`].
    #[default]
    Mono,
    /// Omni-directional 2x2 packets (thesis 4.1.2).
    Packet,
    /// Standard same-sign 2x2 packets, split where signs differ (thesis 2.3.1).
    Samesign,
    /// One frustum per tile with packet/leaf culling (thesis 2.3.2, 4.1.3-4.1.4).
    Frustum,
    /// Four quadrant frusta per tile in SSE lanes (thesis 4.1.5).
    Mft,
    /// One cone per tile as the proxy of its rays (thesis 4.1.6-4.1.8).
    Cone,
    /// Four quadrant cones per tile in SSE lanes (thesis 4.1.9).
    #[serde(rename = "mft-cone")]
    MftCone,
}

impl Method {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::Mono => "mono",
            Method::Packet => "packet",
            Method::Samesign => "samesign",
            Method::Frustum => "frustum",
            Method::Mft => "mft",
            Method::Cone => "cone",
            Method::MftCone => "mft-cone",
        }
    }

    /// The tile kernel behind this method (`None` for single rays).
    pub fn tile_kernel(self) -> Option<TileKernel> {
        match self {
            Method::Mono => None,
            Method::Packet => Some(TileKernel::Packets(TileMethod::Packet)),
            Method::Samesign => Some(TileKernel::Packets(TileMethod::SameSign)),
            Method::Frustum => Some(TileKernel::Packets(TileMethod::Frustum)),
            Method::Mft => Some(TileKernel::Packets(TileMethod::Mft)),
            Method::Cone => Some(TileKernel::Cones(ConeMethod::Cone)),
            Method::MftCone => Some(TileKernel::Cones(ConeMethod::MftCone)),
        }
    }
}

/// How a method traces a tile loaded in a [`TileTracer`]: a `packets` method or a `cones`
/// one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileKernel {
    /// Packets, one frustum or MFT (`packets`).
    Packets(TileMethod),
    /// One cone or MFT cones (`cones`).
    Cones(ConeMethod),
}

impl TileKernel {
    /// Traces the tile loaded in `tracer`.
    #[inline]
    pub fn trace<C: PacketCounters>(self, tree: &KdTree, tracer: &mut TileTracer, counters: &mut C) {
        match self {
            TileKernel::Packets(m) => tracer.trace(tree, m, counters),
            TileKernel::Cones(m) => cones::traverse::trace(tree, tracer, m, counters),
        }
    }

    /// Whether it bounds a whole run of rays sharing an origin (frusta and cones) rather than
    /// going packet by packet.
    pub fn bounds_runs(self) -> bool {
        !matches!(self, TileKernel::Packets(TileMethod::Packet | TileMethod::SameSign))
    }
}

/// Whether shadow rays are traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Shadows {
    /// No shadow rays: every surface facing the light is lit.
    None,
    /// One shadow ray per hit towards the point light.
    #[default]
    Hard,
}

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

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.offsets.last().copied().unwrap_or(0)
    }

    /// The tiles, in buffer order.
    pub fn tiles(&self) -> &[Tile] {
        &self.tiles
    }

    /// `buf` (one entry per pixel, tile order) cut into one chunk per tile.
    ///
    /// Panics if `buf` is shorter than [`TileLayout::pixel_count`] (a programming error: the
    /// buffers come from [`Renderer::buffers`]).
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

/// The per-pixel results of tracing one frame, in tile order (see [`TileLayout`]).
#[derive(Clone, Debug)]
pub struct FrameBuffers {
    /// The closest hit of each pixel's primary ray.
    pub hits: Vec<Option<Hit>>,
    /// Whether each hit's shadow ray found a blocker (`false` without shadows, for misses and
    /// for surfaces facing away from the light).
    pub occluded: Vec<bool>,
}

impl FrameBuffers {
    /// Buffers for `pixels` pixels.
    pub fn new(pixels: usize) -> FrameBuffers {
        FrameBuffers { hits: vec![None; pixels], occluded: vec![false; pixels] }
    }
}

/// What tracing one frame did and how long it took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Primary rays traced (one per pixel).
    pub primary_rays: u64,
    /// Shadow rays traced (one per hit facing the light, with shadows on).
    pub shadow_rays: u64,
    /// Primary rays that hit a triangle.
    pub hits: u64,
    /// Shadow rays that found a blocker.
    pub occluded: u64,
    /// Seconds for the primary pass.
    pub primary_secs: f64,
    /// Seconds for the shadow pass (0 without shadows).
    pub shadow_secs: f64,
}

impl FrameStats {
    /// All rays traced.
    pub fn rays(&self) -> u64 {
        self.primary_rays + self.shadow_rays
    }

    /// Seconds spent tracing (both passes).
    pub fn trace_secs(&self) -> f64 {
        self.primary_secs + self.shadow_secs
    }
}

/// Renders one scene through one camera with one tree: the fixed part of a frame.
#[derive(Debug)]
pub struct Renderer<'a> {
    scene: &'a Scene,
    tree: &'a KdTree,
    camera: Camera,
    layout: TileLayout,
    method: Method,
    shadows: Shadows,
    culling: bool,
    tile_size: u32,
}

impl<'a> Renderer<'a> {
    /// A renderer of `scene` (whose mesh `tree` was built over) seen by `camera`, in tiles of
    /// [`TILE_SIZE`].
    pub fn new(scene: &'a Scene, tree: &'a KdTree, camera: Camera, method: Method, shadows: Shadows) -> Self {
        let layout = TileLayout::new(camera.width, camera.height, TILE_SIZE);
        Renderer { scene, tree, camera, layout, method, shadows, culling: true, tile_size: TILE_SIZE }
    }

    /// The same renderer with `size x size` tiles: the unit of work per thread, and the
    /// frustum of the frustum methods. Packet methods need a multiple of 4 in `4..=64`.
    pub fn with_tile(mut self, size: u32) -> Result<Self, packets::tile::TileError> {
        if self.method.tile_kernel().is_some() {
            TileTracer::new(size)?;
        }
        self.layout = TileLayout::new(self.camera.width, self.camera.height, size.max(1));
        self.tile_size = size.max(1);
        Ok(self)
    }

    /// The same renderer with packet/leaf culling (thesis 4.1.4) on or off; it is on by
    /// default and only the frustum methods use it.
    pub fn with_culling(mut self, on: bool) -> Self {
        self.culling = on;
        self
    }

    /// The tile layout of the per-pixel buffers.
    pub fn layout(&self) -> &TileLayout {
        &self.layout
    }

    /// Buffers of the right size for [`Renderer::trace`].
    pub fn buffers(&self) -> FrameBuffers {
        FrameBuffers::new(self.layout.pixel_count())
    }

    /// Traces one frame into `buf`: the primary pass, then the shadow pass if shadows are on.
    /// Runs on the current rayon pool.
    pub fn trace(&self, buf: &mut FrameBuffers) -> FrameStats {
        self.trace_with::<NoCounters>(buf).0
    }

    /// [`Renderer::trace`] counting traversal steps, leaves and intersection tests, for the
    /// primary and the shadow pass apart. Slower: not for timing.
    pub fn trace_counted(&self, buf: &mut FrameBuffers) -> (FrameStats, PacketCounts, PacketCounts) {
        self.trace_with::<PacketCounts>(buf)
    }

    /// Number of 2x2 packets the primary pass of a packet method traces (the denominator of
    /// the thesis's N and I): `ceil(w/2) * ceil(h/2)` per tile.
    pub fn packet_count(&self) -> u64 {
        self.layout.tiles().iter().map(|t| u64::from(t.width().div_ceil(2)) * u64::from(t.height().div_ceil(2))).sum()
    }

    fn trace_with<C: TileCounters>(&self, buf: &mut FrameBuffers) -> (FrameStats, C, C) {
        let start = Instant::now();
        let (hits, primary_counts) = self.primary_pass::<C>(&mut buf.hits);
        let primary_secs = start.elapsed().as_secs_f64();
        let (shadow_rays, occluded, shadow_counts, shadow_secs) = match self.shadows {
            Shadows::None => {
                buf.occluded.fill(false);
                (0, 0, C::default(), 0.0)
            }
            Shadows::Hard => {
                let start = Instant::now();
                let (rays, occluded, counts) = self.shadow_pass::<C>(&buf.hits, &mut buf.occluded);
                (rays, occluded, counts, start.elapsed().as_secs_f64())
            }
        };
        let stats = FrameStats {
            primary_rays: self.layout.pixel_count() as u64,
            shadow_rays,
            hits,
            occluded,
            primary_secs,
            shadow_secs,
        };
        (stats, primary_counts, shadow_counts)
    }

    /// Pass 1: the closest hit of every pixel's primary ray. Returns the number of hits.
    fn primary_pass<C: TileCounters>(&self, hits: &mut [Option<Hit>]) -> (u64, C) {
        let chunks = self.layout.chunks_mut(hits);
        let tiles = self.layout.tiles().par_iter().zip(chunks);
        match self.method.tile_kernel() {
            None => tiles
                .map(|(tile, out)| {
                    let mut counts = C::default();
                    let hits = mono_primary_tile(self.tree, &self.camera, tile, out, &mut counts);
                    (hits, counts)
                })
                .reduce(|| (0, C::default()), |a, b| (a.0 + b.0, a.1.merge(b.1))),
            Some(method) => tiles
                .map_init(
                    || {
                        // The size was checked by `with_tile`.
                        let mut tracer = TileTracer::new(self.tile_size).expect("tile size checked");
                        tracer.set_culling(self.culling);
                        tracer
                    },
                    |tracer, (tile, out)| {
                        let mut counts = C::default();
                        let hits = packet_primary_tile(self.tree, &self.camera, tracer, method, tile, out, &mut counts);
                        (hits, counts)
                    },
                )
                .reduce(|| (0, C::default()), |a, b| (a.0 + b.0, a.1.merge(b.1))),
        }
    }

    /// Pass 2: one shadow ray per hit facing the light. Returns (rays traced, rays blocked).
    fn shadow_pass<C: TileCounters>(&self, hits: &[Option<Hit>], occluded: &mut [bool]) -> (u64, u64, C) {
        let chunks: Vec<_> = self.layout.chunks(hits).into_iter().zip(self.layout.chunks_mut(occluded)).collect();
        self.layout
            .tiles()
            .par_iter()
            .zip(chunks)
            .map(|(tile, (hits, out))| {
                let mut counts = C::default();
                let (rays, blocked) =
                    mono_shadow_tile(self.scene, self.tree, &self.camera, tile, hits, out, &mut counts);
                (rays, blocked, counts)
            })
            .reduce(|| (0, 0, C::default()), |a, b| (a.0 + b.0, a.1 + b.1, a.2.merge(b.2)))
    }

    /// Pass 3 for `--aov color`: the shaded image.
    pub fn color(&self, buf: &FrameBuffers) -> Image {
        let light = &self.scene.point_light;
        let mesh = &self.scene.mesh;
        let mut colors = vec![Vec3::ZERO; self.layout.pixel_count()];
        let chunks = self.layout.chunks_mut(&mut colors);
        let inputs = self.layout.chunks(&buf.hits).into_iter().zip(self.layout.chunks(&buf.occluded));
        self.layout.tiles().par_iter().zip(chunks).zip(inputs.collect::<Vec<_>>()).for_each(
            |((tile, out), (hits, occluded))| {
                for ((((x, y), slot), hit), &blocked) in tile.pixels().zip(out).zip(hits).zip(occluded) {
                    let (origin, dir) = self.camera.pixel_ray(x, y);
                    *slot = match hit {
                        Some(hit) => shade::shade(mesh, light, origin, dir, hit, blocked),
                        None => shade::BACKGROUND,
                    };
                }
            },
        );
        Image { width: self.camera.width, height: self.camera.height, pixels: self.layout.to_row_major(&colors) }
    }

    /// Pass 3 for `--aov depth`: the distance of each primary hit (`+inf` for misses).
    pub fn depth(&self, buf: &FrameBuffers) -> ScalarImage {
        let values: Vec<f32> = buf.hits.iter().map(|h| h.map_or(f32::INFINITY, |h| h.t)).collect();
        ScalarImage { width: self.camera.width, height: self.camera.height, values: self.layout.to_row_major(&values) }
    }

    /// Pass 3 for `--aov prim`: the hit triangle's primitive id in the source file's numbering
    /// (`Mesh::prim_ids`) as f32, `-1` for misses.
    pub fn prim(&self, buf: &FrameBuffers) -> ScalarImage {
        let ids = &self.scene.mesh.prim_ids;
        let values: Vec<f32> = buf
            .hits
            .iter()
            .map(|h| h.map_or(-1.0, |h| ids.get(h.prim as usize).map_or(-1.0, |&id| id as f32)))
            .collect();
        ScalarImage { width: self.camera.width, height: self.camera.height, values: self.layout.to_row_major(&values) }
    }
}

/// Per-tile traversal counters that can be summed over tiles: [`NoCounters`] for timed
/// frames (counting compiles away), [`PacketCounts`] for `--counters`.
pub trait TileCounters: Counters + PacketCounters + Default + Send {
    /// The sum of two tiles' counts.
    fn merge(self, other: Self) -> Self;
}

impl TileCounters for NoCounters {
    #[inline]
    fn merge(self, _other: Self) -> Self {
        self
    }
}

impl TileCounters for PacketCounts {
    #[inline]
    fn merge(mut self, other: Self) -> Self {
        self += other;
        self
    }
}

/// The primary ray of pixel `(x, y)`: from the eye, unbounded.
#[inline]
pub fn primary_ray(camera: &Camera, x: u32, y: u32) -> Ray {
    let (origin, dir) = camera.pixel_ray(x, y);
    Ray::new(origin, dir, 0.0, f32::INFINITY)
}

/// Single-ray primary kernel of one tile. Returns the number of hits.
fn mono_primary_tile<C: Counters>(
    tree: &KdTree,
    camera: &Camera,
    tile: &Tile,
    out: &mut [Option<Hit>],
    counts: &mut C,
) -> u64 {
    let mut hits = 0;
    for ((x, y), slot) in tile.pixels().zip(out) {
        *slot = tree.intersect_counted(&primary_ray(camera, x, y), counts);
        hits += u64::from(slot.is_some());
    }
    hits
}

/// Packet kernel of one tile: loads its primary rays as 2x2 packets, traces them with
/// `method` and writes the hits. Returns the number of hits.
fn packet_primary_tile<C: TileCounters>(
    tree: &KdTree,
    camera: &Camera,
    tracer: &mut TileTracer,
    method: TileKernel,
    tile: &Tile,
    out: &mut [Option<Hit>],
    counts: &mut C,
) -> u64 {
    // The layout's tiles fit the tracer (same size, inside the image).
    tracer.load_primary(camera, tile).expect("tile fits the tracer");
    method.trace(tree, tracer, counts);
    tracer.write_hits(out);
    out.iter().filter(|h| h.is_some()).count() as u64
}

/// Single-ray shadow kernel of one tile. Returns (rays traced, rays blocked).
fn mono_shadow_tile<C: Counters>(
    scene: &Scene,
    tree: &KdTree,
    camera: &Camera,
    tile: &Tile,
    hits: &[Option<Hit>],
    out: &mut [bool],
    counts: &mut C,
) -> (u64, u64) {
    let (mut rays, mut blocked) = (0, 0);
    for (((x, y), hit), slot) in tile.pixels().zip(hits).zip(out) {
        *slot = false;
        let Some(hit) = hit else { continue };
        let (origin, dir) = camera.pixel_ray(x, y);
        let Some(ray) = shade::shadow_ray(&scene.mesh, &scene.point_light, origin, dir, hit) else { continue };
        rays += 1;
        *slot = tree.occluded_counted(&ray, counts);
        blocked += u64::from(*slot);
    }
    (rays, blocked)
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

    /// The tiled, parallel passes give every pixel the answer of a plain per-pixel loop.
    #[test]
    fn frame_matches_a_per_pixel_loop() {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &Default::default()).unwrap();
        let camera = scene.default_view().camera(37, 29).unwrap();
        let renderer = Renderer::new(&scene, &tree, camera, Method::Mono, Shadows::Hard);
        let mut buf = renderer.buffers();
        let stats = renderer.trace(&mut buf);
        let depth = renderer.depth(&buf);
        let prim = renderer.prim(&buf);
        let (mut hits, mut shadow_rays, mut blocked) = (0, 0, 0);
        for y in 0..camera.height {
            for x in 0..camera.width {
                let ray = primary_ray(&camera, x, y);
                let hit = tree.intersect(&ray);
                let i = (y * camera.width + x) as usize;
                assert_eq!(depth.values[i], hit.map_or(f32::INFINITY, |h| h.t), "depth of ({x}, {y})");
                assert_eq!(prim.values[i], hit.map_or(-1.0, |h| scene.mesh.prim_ids[h.prim as usize] as f32));
                let Some(hit) = hit else { continue };
                hits += 1;
                if let Some(shadow) = shade::shadow_ray(&scene.mesh, &scene.point_light, ray.origin, ray.dir, &hit) {
                    shadow_rays += 1;
                    blocked += u64::from(tree.occluded(&shadow));
                }
            }
        }
        assert!(hits > 0 && shadow_rays > 0);
        assert_eq!((stats.hits, stats.shadow_rays, stats.occluded), (hits, shadow_rays, blocked));
        assert_eq!(stats.primary_rays, u64::from(camera.width * camera.height));
    }
}
