//! Other tracers on exactly our rays: Intel Embree 3 (feature `embree`) and the pure-Rust BVH
//! crates `bvh` and `obvhs` (feature `bvh-crates`), for `rttest compare`.
//!
//! A baseline is a [`BlockTracer`]: it traces one render tile of primary rays, the shadow
//! rays of one tile's hits and the 16 soft-shadow rays of one point. The drivers here run it
//! over a frame exactly as our renderer runs its methods (rayon over the same 16 x 16 tiles,
//! per-pixel buffers in tile order, ray generation inside the timed pass), and with exactly
//! our rays: primary rays from [`scenes::Camera::pixel_ray`], hard shadow rays from
//! [`crate::shade::shadow_ray`] on *our* single-ray hits, soft-shadow rays from
//! [`crate::soft::shadow_start`] and `cones::shadows::{light_samples, shadow_rays}`.
//!
//! - [`SingleRays`]: any [`Tracer`] (closest hit and any hit of one ray) one ray at a time;
//! - `embree`: the FFI, and `embree_blocks`: Embree's packets of 4, 8 and 16 over 2x2, 4x2
//!   and 4x4 pixel blocks (feature `embree`);
//! - `bvh_crates`: the `bvh` and `obvhs` crates (feature `bvh-crates`).

use cones::shadows::{SAMPLES, light_samples, shadow_rays};
use kdtree::{Hit, Ray};
use rayon::prelude::*;
use scenes::{Camera, Scene, SphereLight, Tile};

use crate::render::{TileLayout, primary_ray};
use crate::{shade, soft};

#[cfg(feature = "bvh-crates")]
pub mod bvh_crates;
#[cfg(feature = "embree")]
pub mod embree;
#[cfg(feature = "embree")]
pub mod embree_blocks;

/// A single-ray tracer: the two queries every acceleration structure answers.
pub trait Tracer: Sync {
    /// The closest hit of `ray` in `[t_min, t_max]`, `prim` being our triangle index.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;
    /// Whether anything is hit in `[t_min, t_max]`.
    fn occluded(&self, ray: &Ray) -> bool;
}

impl<T: Tracer> Tracer for &T {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        (**self).intersect(ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        (**self).occluded(ray)
    }
}

impl Tracer for kdtree::KdTree {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        kdtree::KdTree::intersect(self, ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        kdtree::KdTree::occluded(self, ray)
    }
}

/// A tracer of whole tiles and soft-shadow points, with per-thread scratch space.
pub trait BlockTracer: Sync {
    /// Per-thread scratch (packets), made once per rayon task.
    type Scratch: Send;
    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;
    /// The closest hits of the primary rays of `tile`'s pixels into `out` (row-major inside
    /// the tile).
    fn primary_tile(&self, scratch: &mut Self::Scratch, camera: &Camera, tile: &Tile, out: &mut [Option<Hit>]);
    /// The shadow rays of the hits `hits` (row-major inside `tile`), written to `out`.
    /// Returns (rays traced, rays blocked).
    fn shadow_tile(
        &self,
        scratch: &mut Self::Scratch,
        scene: &Scene,
        camera: &Camera,
        tile: &Tile,
        hits: &[Option<Hit>],
        out: &mut [bool],
    ) -> (u64, u64);
    /// Which of the 16 soft-shadow `rays` of one point are blocked, bit `i` for ray `i`.
    fn soft_point(&self, scratch: &mut Self::Scratch, rays: &[Ray; SAMPLES]) -> u16;
}

/// A [`Tracer`] traced one ray at a time.
#[derive(Debug)]
pub struct SingleRays<T>(pub T);

impl<T: Tracer> BlockTracer for SingleRays<T> {
    type Scratch = ();

    fn scratch(&self) {}

    fn primary_tile(&self, _: &mut (), camera: &Camera, tile: &Tile, out: &mut [Option<Hit>]) {
        for ((x, y), slot) in tile.pixels().zip(out) {
            *slot = self.0.intersect(&primary_ray(camera, x, y));
        }
    }

    fn shadow_tile(
        &self,
        _: &mut (),
        scene: &Scene,
        camera: &Camera,
        tile: &Tile,
        hits: &[Option<Hit>],
        out: &mut [bool],
    ) -> (u64, u64) {
        let (mut rays, mut blocked) = (0, 0);
        for (((x, y), hit), slot) in tile.pixels().zip(hits).zip(out) {
            *slot = false;
            let Some(ray) = hard_shadow_ray(scene, camera, x, y, hit) else { continue };
            rays += 1;
            *slot = self.0.occluded(&ray);
            blocked += u64::from(*slot);
        }
        (rays, blocked)
    }

    fn soft_point(&self, _: &mut (), rays: &[Ray; SAMPLES]) -> u16 {
        let mut mask = 0u16;
        for (i, ray) in rays.iter().enumerate() {
            mask |= u16::from(self.0.occluded(ray)) << i;
        }
        mask
    }
}

/// The shadow ray of pixel `(x, y)` whose primary hit is `hit`, exactly as our renderer
/// makes it ([`shade::shadow_ray`]); `None` for misses and surfaces facing away.
#[inline]
pub fn hard_shadow_ray(scene: &Scene, camera: &Camera, x: u32, y: u32, hit: &Option<Hit>) -> Option<Ray> {
    let hit = hit.as_ref()?;
    let (origin, dir) = camera.pixel_ray(x, y);
    shade::shadow_ray(&scene.mesh, &scene.point_light, origin, dir, hit)
}

/// Primary pass: every pixel's closest hit into `out` (tile order of `layout`), rayon over
/// the tiles. Returns the number of hits.
pub fn primary_pass<B: BlockTracer>(b: &B, camera: &Camera, layout: &TileLayout, out: &mut [Option<Hit>]) -> u64 {
    let chunks = layout.chunks_mut(out);
    layout
        .tiles()
        .par_iter()
        .zip(chunks)
        .map_init(
            || b.scratch(),
            |s, (tile, out)| {
                b.primary_tile(s, camera, tile, out);
                out.iter().filter(|h| h.is_some()).count() as u64
            },
        )
        .sum()
}

/// Hard-shadow pass: the shadow ray of every hit of `hits` (tile order of `layout`) into
/// `occluded`. Returns (rays traced, rays blocked).
pub fn shadow_pass<B: BlockTracer>(
    b: &B,
    scene: &Scene,
    camera: &Camera,
    layout: &TileLayout,
    hits: &[Option<Hit>],
    occluded: &mut [bool],
) -> (u64, u64) {
    let chunks: Vec<_> = layout.chunks(hits).into_iter().zip(layout.chunks_mut(occluded)).collect();
    layout
        .tiles()
        .par_iter()
        .zip(chunks)
        .map_init(|| b.scratch(), |s, (tile, (hits, out))| b.shadow_tile(s, scene, camera, tile, hits, out))
        .reduce(|| (0, 0), |a, c| (a.0 + c.0, a.1 + c.1))
}

/// Soft-shadow pass: the 16 shadow rays of every hit of `hits` (row-major) to `light`, as
/// [`soft::soft_shadow_pass`] makes them, rayon over rows. Returns the visible fraction per
/// pixel, the rays traced and the rays blocked.
pub fn soft_pass<B: BlockTracer>(
    b: &B,
    scene: &Scene,
    camera: &Camera,
    hits: &[Option<Hit>],
    light: &SphereLight,
) -> (Vec<f32>, u64, u64) {
    let w = camera.width as usize;
    let mut visible = vec![0.0f32; hits.len()];
    let (rays, blocked) = visible
        .par_chunks_mut(w)
        .zip(hits.par_chunks(w))
        .enumerate()
        .map_init(
            || b.scratch(),
            |s, (y, (out, row))| {
                let (mut rays, mut blocked) = (0u64, 0u64);
                for (x, (slot, hit)) in out.iter_mut().zip(row).enumerate() {
                    let Some(hit) = hit else { continue };
                    let dir = camera.pixel_ray(x as u32, y as u32).1;
                    let Some((start, _cone)) = soft::shadow_start(scene, light, hit, dir) else { continue };
                    let Some(samples) = light_samples(start, light) else { continue };
                    let mask = b.soft_point(s, &shadow_rays(start, &samples));
                    let n = u64::from(mask.count_ones());
                    rays += SAMPLES as u64;
                    blocked += n;
                    *slot = 1.0 - n as f32 / SAMPLES as f32;
                }
                (rays, blocked)
            },
        )
        .reduce(|| (0, 0), |a, c| (a.0 + c.0, a.1 + c.1));
    (visible, rays, blocked)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::{BuildConfig, KdTree, NoCounters};

    /// The drivers over single rays of our own tree reproduce the renderer and the soft pass.
    #[test]
    fn single_ray_drivers_match_the_renderer_and_soft_pass() {
        let scene = scenes::load_scene("atrium").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(40, 24).unwrap();
        let renderer = crate::render::Renderer::new(
            &scene,
            &tree,
            camera,
            crate::render::Method::Mono,
            crate::render::Shadows::Hard,
        );
        let mut buf = renderer.buffers();
        let stats = renderer.trace(&mut buf);
        let layout = renderer.layout();
        let b = SingleRays(&tree);
        let mut hits = vec![None; layout.pixel_count()];
        assert_eq!(primary_pass(&b, &camera, layout, &mut hits), stats.hits);
        assert_eq!(hits, buf.hits);
        let mut occluded = vec![false; hits.len()];
        assert_eq!(shadow_pass(&b, &scene, &camera, layout, &hits, &mut occluded), (stats.shadow_rays, stats.occluded));
        assert_eq!(occluded, buf.occluded);

        let row_major = layout.to_row_major(&hits);
        let light = SphereLight { center: scene.point_light.position, radius: 0.5, intensity: glam::Vec3::ONE };
        let (visible, rays, blocked) = soft_pass(&b, &scene, &camera, &row_major, &light);
        let want: soft::SoftPass<NoCounters> =
            soft::soft_shadow_pass(&scene, &tree, &camera, &row_major, &light, cones::ShadowMethod::Single);
        assert_eq!((visible, rays, blocked), (want.visible, want.rays, want.blocked));
        assert!(blocked > 0);
    }
}
