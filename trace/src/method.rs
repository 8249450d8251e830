//! The tracing interface: the queries every traversal method answers.
//!
//! The model is pbrt-v4's `Intersect` / `IntersectP` pair (`primitive.h`), asked of groups of
//! rays as well as single ones:
//! - [`Tracer`] is the single-ray query, closest hit and any hit: the scalar twin every group
//!   method must agree with (our kd-tree, Embree's `rtcIntersect1`, a BVH crate);
//! - [`Method`] is the group query: a tile of primary rays, the hard shadow rays of a tile's
//!   hits, the 16 soft-shadow rays of one point and an arbitrary stream of rays. Our kd-tree
//!   methods implement it as compositions of typed kernels, one per pass
//!   (`crate::kernel::Composed`); the baselines implement it whole (crate `baselines`).
//!
//! A method's per-thread scratch space (packet buffers, Embree ray packets) is made once per
//! rayon task by [`Method::scratch`], so no query allocates. Every query takes a counters
//! argument `C: TileCounters`: with [`kdtree::NoCounters`] the counting compiles away, with
//! [`kdtree::Counts`] it gives the thesis's N and I; baselines count nothing.
//!
//! The frame driver (`crate::frame`) runs a `Method` over whole frames; the registry
//! (`crate::registry`) makes one from a name.

use cones::Cone;
use cones::shadows::{SAMPLES, light_samples, shadow_rays};
use glam::Vec3;
use kdtree::surface::Surfaces;
use kdtree::{Counters, Hit, KdTree, NoCounters, Ray};
use scenes::camera::ROW_LANES;
use scenes::{Camera, Scene, SphereLight, Tile};

use crate::{shade, soft};

/// The counters a frame pass sums over tiles on several threads: any [`Counters`] that is
/// `Send` ([`NoCounters`] for timed frames, where counting compiles away; [`Counts`] for
/// `--counters` and the thesis's tables). A bound alias, not a second counters trait.
pub trait TileCounters: Counters + Send {}

impl<C: Counters + Send> TileCounters for C {}

/// A single-ray tracer: the two queries every acceleration structure answers (thesis 2.2.1).
pub trait Tracer: Sync {
    /// The closest hit of `ray` in `[t_min, t_max]`, `prim` being our triangle index,
    /// counting traversal steps and tests into `counters` where the tracer can.
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit>;
    /// Whether anything is hit in `[t_min, t_max]`, counting like
    /// [`Tracer::intersect_counted`].
    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> bool;

    /// The closest hit of `ray`, uncounted.
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_counted(ray, &mut NoCounters)
    }

    /// Whether anything blocks `ray`, uncounted.
    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_counted(ray, &mut NoCounters)
    }
}

impl<T: Tracer> Tracer for &T {
    #[inline]
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        (**self).intersect_counted(ray, counters)
    }

    #[inline]
    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> bool {
        (**self).occluded_counted(ray, counters)
    }
}

impl Tracer for KdTree {
    #[inline]
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        KdTree::intersect_counted(self, ray, counters)
    }

    #[inline]
    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> bool {
        KdTree::occluded_counted(self, ray, counters)
    }
}

/// The group queries of one traversal method: what the frame driver asks per tile, per
/// soft-shadow point and per chunk of a ray stream.
///
/// Every answer equals the single-ray answer of the method's structure under the oracle's
/// equivalence rules (`kdtree::BruteForce::equivalent_hits`); `conformance/tests/ours.rs`
/// checks it for every registered method.
pub trait Method: Sync {
    /// Per-thread scratch space (packets, frusta), made once per rayon task.
    type Scratch: Send;

    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;

    /// The closest hits of the primary rays of `tile`'s pixels ([`primary_ray`]) into `out`,
    /// row-major inside the tile.
    fn primary_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    );

    /// The hard shadow rays of one tile ([`ShadowJob`]: rays from [`hard_shadow_segment`] at its
    /// primary hits) into `out`: `true` where blocked, `false` where lit or where no ray is
    /// cast. Returns (rays traced, rays blocked).
    fn shadow_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64);

    /// The 16-sample soft shadows of one tile ([`SoftJob`]: the rays of [`SoftJob::point`] at
    /// its primary hits): the visible fraction per pixel into `visible` (1 minus the share of
    /// blocked rays; 0 where no ray is cast). The default traces each point's rays with
    /// [`Method::soft_point`]; a method that bounds several points' rays together (Benthin &
    /// Wald's multi-frusta) overrides it.
    fn soft_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        soft_by_points(self, scratch, job, visible, counters)
    }

    /// Which of the 16 soft-shadow `rays` of one point are blocked, bit `i` for ray `i`;
    /// `cone` holds all of them (thesis 4.1.9, Table 4.6).
    fn soft_point<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        counters: &mut C,
    ) -> u16;

    /// The closest hits of an arbitrary run of rays (a chunk of a ray file), in order.
    fn stream<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    );

    /// Whether each ray of an arbitrary run is blocked, in order.
    fn stream_occluded<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    );
}

/// A [`Tracer`] traced one ray at a time: every group query as a loop of single rays.
#[derive(Debug)]
pub struct SingleRays<T>(pub T);

impl<T: Tracer> Method for SingleRays<T> {
    type Scratch = ();

    fn scratch(&self) {}

    fn primary_tile<C: TileCounters>(
        &self,
        _: &mut (),
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        for ((x, y), slot) in tile.pixels().zip(out) {
            counters.generation_start();
            let ray = primary_ray(camera, x, y);
            counters.generation_end();
            *slot = self.0.intersect_counted(&ray, counters);
        }
    }

    fn shadow_tile<C: TileCounters>(
        &self,
        _: &mut (),
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64) {
        let (mut rays, mut blocked) = (0, 0);
        let mut segments = [None; ROW_LANES];
        let w = job.tile.width();
        for (ly, row) in out.chunks_mut(w.max(1) as usize).enumerate() {
            for (c, slots) in row.chunks_mut(ROW_LANES).enumerate() {
                let segments = &mut segments[..slots.len()];
                job.row_segments((c * ROW_LANES) as u32, ly as u32, segments);
                for (slot, segment) in slots.iter_mut().zip(&*segments) {
                    *slot = false;
                    let Some((start, end)) = *segment else { continue };
                    rays += 1;
                    *slot = self.0.occluded_counted(&Ray::segment(start, end), counters);
                    blocked += u64::from(*slot);
                }
            }
        }
        (rays, blocked)
    }

    fn soft_point<C: TileCounters>(&self, _: &mut (), rays: &[Ray; SAMPLES], _cone: &Cone, counters: &mut C) -> u16 {
        let mut mask = 0u16;
        for (i, ray) in rays.iter().enumerate() {
            mask |= u16::from(self.0.occluded_counted(ray, counters)) << i;
        }
        mask
    }

    fn stream<C: TileCounters>(&self, _: &mut (), rays: &[Ray], out: &mut [Option<Hit>], counters: &mut C) {
        for (ray, slot) in rays.iter().zip(out) {
            *slot = self.0.intersect_counted(ray, counters);
        }
    }

    fn stream_occluded<C: TileCounters>(&self, _: &mut (), rays: &[Ray], out: &mut [bool], counters: &mut C) {
        for (ray, slot) in rays.iter().zip(out) {
            *slot = self.0.occluded_counted(ray, counters);
        }
    }
}

/// The hard-shadow work of one tile: the scene and camera its rays come from, the tile, and
/// the tile's primary hits (row-major inside the tile) that the shadow rays start at.
#[derive(Clone, Copy, Debug)]
pub struct ShadowJob<'a> {
    /// The scene (its mesh and point light).
    pub scene: &'a Scene,
    /// The scene's surface records ([`shade::surfaces`]), which the shadow rays start from.
    pub surfaces: &'a Surfaces,
    /// The camera of the primary rays.
    pub camera: &'a Camera,
    /// The tile.
    pub tile: &'a Tile,
    /// The tile's primary hits, row-major inside the tile.
    pub hits: &'a [Option<Hit>],
}

impl ShadowJob<'_> {
    /// Each pixel of the tile with its primary hit: `(x, y, hit)`.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32, &Option<Hit>)> {
        self.tile.pixels().zip(self.hits).map(|((x, y), h)| (x, y, h))
    }

    /// The hard shadow ray of pixel `(x, y)` with primary hit `hit`, as its ends (the ray is
    /// `Ray::segment(start, end)`): [`hard_shadow_segment`]'s, one pixel at a time. The
    /// kernels take a row's at once ([`ShadowJob::row_segments`]).
    #[inline]
    pub fn segment(&self, x: u32, y: u32, hit: &Option<Hit>) -> Option<(Vec3, Vec3)> {
        hard_shadow_segment(self.scene, self.surfaces, self.camera, x, y, hit)
    }

    /// The segments ([`ShadowJob::segment`]'s, bit for bit) of the tile's pixels
    /// `lx..lx + out.len()` of tile row `ly` (tile coordinates, inside the tile) into `out`.
    /// Four pixels at a time in SIMD lanes: their primary directions (which side of the
    /// surface is lit) by [`Camera::lane_directions`], whose lanes take the divisions and
    /// square roots that are otherwise the longest chain of each pixel's setup, and the rest
    /// by [`shade::shadow_starts4`], without a branch. Every shadow kernel, ours and
    /// Embree's, starts from these.
    pub fn row_segments(&self, lx: u32, ly: u32, out: &mut [Option<(Vec3, Vec3)>]) {
        let row = ly as usize * self.tile.width() as usize + lx as usize;
        let light = &self.scene.point_light;
        for (c, chunk) in out.chunks_mut(4).enumerate() {
            let x = lx + 4 * c as u32;
            let dir = self.camera.lane_directions(self.tile.x0 + x, self.tile.y0 + ly);
            let hits = &self.hits[row + 4 * c..][..chunk.len()];
            let lanes = std::array::from_fn(|l| hits.get(l).unwrap_or(&None));
            let (start, lit) = shade::shadow_starts4(self.surfaces, light, &dir, lanes);
            let [sx, sy, sz] = start.map(|v| v.to_array());
            for (l, slot) in chunk.iter_mut().enumerate() {
                *slot = (lit >> l & 1 != 0).then(|| (Vec3::new(sx[l], sy[l], sz[l]), light.position));
            }
        }
    }

    /// Every pixel's segment ([`ShadowJob::row_segments`]), row-major inside the tile, into
    /// `out` (resized to the tile).
    pub fn segments(&self, out: &mut Vec<Option<(Vec3, Vec3)>>) {
        let w = self.tile.width() as usize;
        out.clear();
        out.resize(w * self.tile.height() as usize, None);
        for (ly, row) in out.chunks_mut(w.max(1)).enumerate() {
            self.row_segments(0, ly as u32, row);
        }
    }
}

/// What a soft-shadow pass traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SoftStats {
    /// Points that traced shadow rays (hits facing the light, outside it).
    pub points: u64,
    /// Shadow rays traced (16 per point).
    pub rays: u64,
    /// Shadow rays blocked.
    pub blocked: u64,
}

impl SoftStats {
    /// Counts a point whose 16 rays gave the blocked mask `mask`; returns its visible
    /// fraction.
    #[inline]
    pub fn add_point(&mut self, mask: u16) -> f32 {
        let n = u64::from(mask.count_ones());
        self.points += 1;
        self.rays += SAMPLES as u64;
        self.blocked += n;
        1.0 - n as f32 / SAMPLES as f32
    }
}

/// [`Method::soft_tile`] point by point: each point's 16 rays through
/// [`Method::soft_point`].
pub fn soft_by_points<M: Method + ?Sized, C: TileCounters>(
    method: &M,
    scratch: &mut M::Scratch,
    job: &SoftJob<'_>,
    visible: &mut [f32],
    counters: &mut C,
) -> SoftStats {
    soft_points(job, visible, |rays, cone| method.soft_point(scratch, rays, cone, counters))
}

/// The soft shadows of `job` point by point: `point` answers each point's 16 rays
/// ([`SoftJob::point`]) as a blocked mask, bit `i` for ray `i`; the visible fraction per pixel
/// into `visible` (0 where no ray is cast).
#[inline]
pub fn soft_points(
    job: &SoftJob<'_>,
    visible: &mut [f32],
    mut point: impl FnMut(&[Ray; SAMPLES], &Cone) -> u16,
) -> SoftStats {
    let mut stats = SoftStats::default();
    for (i, slot) in visible.iter_mut().enumerate() {
        *slot = 0.0;
        let Some((rays, cone)) = job.point(i) else { continue };
        *slot = stats.add_point(point(&rays, &cone));
    }
    stats
}

/// The 16-sample soft shadows of one tile: its primary hits (as for hard shadows) and the
/// spherical light.
#[derive(Clone, Copy, Debug)]
pub struct SoftJob<'a> {
    /// The scene, camera, tile and the tile's primary hits.
    pub hits: ShadowJob<'a>,
    /// The light.
    pub light: &'a SphereLight,
}

impl SoftJob<'_> {
    /// The 16 shadow rays of the tile's `i`-th pixel (row-major) and the cone that holds
    /// them: from [`soft::shadow_start`] to `cones::shadows::light_samples`, over `t` in
    /// `[0, 1]`. `None` for misses, surfaces facing away from the light and points inside
    /// it. Every method traces exactly these rays.
    #[inline]
    pub fn point(&self, i: usize) -> Option<([Ray; SAMPLES], Cone)> {
        let (start, samples, cone) = self.samples(i)?;
        Some((shadow_rays(start, &samples), cone))
    }

    /// What [`SoftJob::point`] makes its rays from: the rays' origin, the 16 light samples
    /// (ray `k` is `cones::shadows::shadow_ray(origin, samples[k])`) and the cone. A fifth of
    /// the bytes of the rays, for kernels that keep a tile's points before tracing them.
    #[inline]
    pub fn samples(&self, i: usize) -> Option<(Vec3, [Vec3; SAMPLES], Cone)> {
        let ShadowJob { surfaces, camera, tile, hits, .. } = self.hits;
        let hit = hits.get(i)?.as_ref()?;
        let (x, y) = (tile.x0 + i as u32 % tile.width(), tile.y0 + i as u32 / tile.width());
        let dir = camera.pixel_ray(x, y).1;
        let (start, cone) = soft::shadow_start(surfaces, self.light, hit, dir)?;
        Some((start, light_samples(start, self.light)?, cone))
    }
}

/// The primary ray of pixel `(x, y)`: from the eye, unbounded (the camera convention of
/// `scenes::Camera::pixel_ray`).
#[inline]
pub fn primary_ray(camera: &Camera, x: u32, y: u32) -> Ray {
    let (origin, dir) = camera.pixel_ray(x, y);
    Ray::new(origin, dir, 0.0, f32::INFINITY)
}

/// The hard shadow ray of pixel `(x, y)` whose primary hit is `hit`, toward the scene's point
/// light, as its ends (the ray is `Ray::segment(start, end)`; [`shade::shadow_segment`], with
/// `surfaces` the scene's [`shade::surfaces`]): its origin moved off the surface, and the
/// light. `None` for misses and surfaces facing away from the light. Every method traces
/// exactly these rays; the packet kernels build their packets from the ends
/// (`packets::RayPacket::segments`).
#[inline]
pub fn hard_shadow_segment(
    scene: &Scene,
    surfaces: &Surfaces,
    camera: &Camera,
    x: u32,
    y: u32,
    hit: &Option<Hit>,
) -> Option<(Vec3, Vec3)> {
    let hit = hit.as_ref()?;
    shade::shadow_segment(surfaces, &scene.point_light, camera.pixel_ray(x, y).1, hit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::load_and_build;

    /// The batched segments are the per-pixel ones bit for bit, on a tile inside the image
    /// (not at its origin) whose rows are longer than the lanes and not a multiple of them,
    /// with misses, lit and unlit hits; and the row calls at any start give the same.
    #[test]
    fn row_segments_are_the_pixels_segments_bit_for_bit() {
        let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
        let camera = scene.default_view().camera(61, 40).unwrap();
        let tile = Tile { x0: 7, y0: 3, x1: 7 + 19, y1: 3 + 37 };
        let hits: Vec<_> = tile.pixels().map(|(x, y)| tree.intersect(&primary_ray(&camera, x, y))).collect();
        let surfaces = shade::surfaces(&scene.mesh);
        let job = ShadowJob { scene: &scene, surfaces: &surfaces, camera: &camera, tile: &tile, hits: &hits };
        let want: Vec<_> = job.pixels().map(|(x, y, hit)| job.segment(x, y, hit)).collect();
        assert!(want.iter().any(Option::is_some) && want.iter().any(Option::is_none));
        let bits = |s: &Option<(Vec3, Vec3)>| s.map(|(a, b)| [a.to_array(), b.to_array()].map(|v| v.map(f32::to_bits)));
        let mut got = Vec::new();
        job.segments(&mut got);
        assert_eq!(got.iter().map(bits).collect::<Vec<_>>(), want.iter().map(bits).collect::<Vec<_>>());
        let w = tile.width() as usize;
        for (lx, n) in [(0, 3), (5, 9), (10, 9), (18, 1)] {
            let mut part = vec![None; n];
            job.row_segments(lx as u32, 11, &mut part);
            let row = &want[11 * w + lx..][..n];
            assert_eq!(part.iter().map(bits).collect::<Vec<_>>(), row.iter().map(bits).collect::<Vec<_>>());
        }
    }
}
