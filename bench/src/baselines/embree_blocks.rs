//! Embree as a [`BlockTracer`]: single rays (`rtcIntersect1` / `rtcOccluded1`) and packets of
//! 4, 8 and 16 rays over 2x2, 4x2 and 4x4 pixel blocks of each render tile
//! (`rtcIntersect4/8/16`, `rtcOccluded4/8/16`), with a chosen coherence hint.
//!
//! Primary rays: each block of the tile is one packet, lanes row-major in the block, lanes
//! outside the tile inactive. Hard shadows: the shadow rays of the same block's hits
//! (lanes without a shadow ray inactive). Soft shadows: the 16 rays of a point as 16 / K
//! packets (K = 1: 16 `rtcOccluded1` calls).

use cones::shadows::SAMPLES;
use kdtree::{Hit, Ray};
use scenes::{Camera, Scene, Tile};

use super::embree::{Coherence, EmbreeScene, Packet};
use super::{BlockTracer, Tracer, hard_shadow_ray};
use crate::render::primary_ray;

/// Embree single rays with a coherence hint.
#[derive(Debug)]
pub struct EmbreeSingle<'a> {
    /// The scene.
    pub scene: &'a EmbreeScene,
    /// The context flag of every call.
    pub coherence: Coherence,
}

impl Tracer for EmbreeSingle<'_> {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.scene.intersect(ray, self.coherence)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        self.scene.occluded(ray, self.coherence)
    }
}

/// Embree packets of `P::WIDTH` rays over pixel blocks.
#[derive(Debug)]
pub struct EmbreeBlocks<'a, P> {
    /// The scene.
    pub scene: &'a EmbreeScene,
    /// The context flag of every call.
    pub coherence: Coherence,
    _packet: std::marker::PhantomData<fn() -> P>,
}

impl<'a, P: Packet> EmbreeBlocks<'a, P> {
    /// Packets of `P` on `scene` with `coherence`.
    pub fn new(scene: &'a EmbreeScene, coherence: Coherence) -> Self {
        EmbreeBlocks { scene, coherence, _packet: std::marker::PhantomData }
    }
}

/// The pixel block of a packet width: (columns, rows).
pub fn block_shape(width: usize) -> (u32, u32) {
    match width {
        4 => (2, 2),
        8 => (4, 2),
        16 => (4, 4),
        w => (w as u32, 1),
    }
}

/// Calls `f(lane, x, y, index in the tile)` for the pixels of the block at `(bx, by)` (tile
/// coordinates) that lie inside `tile`.
#[inline]
fn block_pixels(tile: &Tile, bx: u32, by: u32, shape: (u32, u32), mut f: impl FnMut(usize, u32, u32, usize)) {
    let tw = tile.width();
    for j in 0..shape.1 {
        for i in 0..shape.0 {
            let (lx, ly) = (bx + i, by + j);
            if lx < tw && ly < tile.height() {
                f((j * shape.0 + i) as usize, tile.x0 + lx, tile.y0 + ly, (ly * tw + lx) as usize);
            }
        }
    }
}

/// The top-left corners of the blocks covering `tile`, in tile coordinates.
fn blocks(tile: &Tile, shape: (u32, u32)) -> impl Iterator<Item = (u32, u32)> + use<> {
    let (w, h) = (tile.width(), tile.height());
    (0..h).step_by(shape.1 as usize).flat_map(move |by| (0..w).step_by(shape.0 as usize).map(move |bx| (bx, by)))
}

impl<P: Packet> BlockTracer for EmbreeBlocks<'_, P> {
    type Scratch = P;

    fn scratch(&self) -> P {
        P::default()
    }

    fn primary_tile(&self, packet: &mut P, camera: &Camera, tile: &Tile, out: &mut [Option<Hit>]) {
        let shape = block_shape(P::WIDTH);
        for (bx, by) in blocks(tile, shape) {
            packet.clear();
            block_pixels(tile, bx, by, shape, |lane, x, y, _| packet.set(lane, &primary_ray(camera, x, y)));
            self.scene.intersect_packet(packet, self.coherence);
            block_pixels(tile, bx, by, shape, |lane, _, _, i| out[i] = packet.hit(lane));
        }
    }

    fn shadow_tile(
        &self,
        packet: &mut P,
        scene: &Scene,
        camera: &Camera,
        tile: &Tile,
        hits: &[Option<Hit>],
        out: &mut [bool],
    ) -> (u64, u64) {
        let shape = block_shape(P::WIDTH);
        let (mut rays, mut blocked) = (0u64, 0u64);
        for (bx, by) in blocks(tile, shape) {
            packet.clear();
            let mut any = false;
            block_pixels(tile, bx, by, shape, |lane, x, y, i| {
                if let Some(ray) = hard_shadow_ray(scene, camera, x, y, &hits[i]) {
                    packet.set(lane, &ray);
                    any = true;
                }
            });
            if any {
                self.scene.occluded_packet(packet, self.coherence);
            }
            block_pixels(tile, bx, by, shape, |lane, _, _, i| {
                out[i] = packet.occluded(lane);
                rays += u64::from(packet.active(lane));
                blocked += u64::from(out[i]);
            });
        }
        (rays, blocked)
    }

    fn soft_point(&self, packet: &mut P, rays: &[Ray; SAMPLES]) -> u16 {
        let mut mask = 0u16;
        for (c, chunk) in rays.chunks(P::WIDTH).enumerate() {
            packet.clear();
            for (lane, ray) in chunk.iter().enumerate() {
                packet.set(lane, ray);
            }
            self.scene.occluded_packet(packet, self.coherence);
            for lane in 0..chunk.len() {
                mask |= u16::from(packet.occluded(lane)) << (c * P::WIDTH + lane);
            }
        }
        mask
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baselines::embree::{BuildQuality, Device, Packet4, Packet8, Packet16};
    use crate::baselines::{SingleRays, primary_pass, shadow_pass, soft_pass};
    use crate::render::TileLayout;
    use scenes::SphereLight;

    /// Every packet width gives the single-ray answers on every pixel, shadow ray and
    /// soft-shadow ray (Embree's packet kernels run the same triangle test).
    #[test]
    fn packets_agree_with_single_rays() {
        let scene = scenes::load_scene("atrium").unwrap();
        let device = Device::new(Some(2)).unwrap();
        let emb =
            EmbreeScene::build(&device, &scene.mesh.positions, &scene.mesh.triangles, BuildQuality::High).unwrap();
        // 37 x 23: blocks cut by the tile edges.
        let camera = scene.default_view().camera(37, 23).unwrap();
        let layout = TileLayout::new(37, 23, 16);
        let single = SingleRays(&EmbreeSingle { scene: &emb, coherence: Coherence::Incoherent });
        let mut want = vec![None; layout.pixel_count()];
        let hits = primary_pass(&single, &camera, &layout, &mut want);
        assert!(hits > 0);
        let mut want_occ = vec![false; want.len()];
        let want_shadow = shadow_pass(&single, &scene, &camera, &layout, &want, &mut want_occ);
        let light = SphereLight { center: scene.point_light.position, radius: 0.5, intensity: glam::Vec3::ONE };
        let row_major = layout.to_row_major(&want);
        let want_soft = soft_pass(&single, &scene, &camera, &row_major, &light);

        struct Want<'a> {
            scene: &'a Scene,
            camera: Camera,
            layout: TileLayout,
            hits: Vec<Option<Hit>>,
            shadow: (u64, u64),
            occluded: Vec<bool>,
            soft: (Vec<f32>, u64, u64),
            light: SphereLight,
        }
        fn check<P: Packet>(b: &EmbreeBlocks<'_, P>, w: &Want<'_>) {
            let mut got = vec![None; w.hits.len()];
            primary_pass(b, &w.camera, &w.layout, &mut got);
            for (g, h) in got.iter().zip(&w.hits) {
                assert_eq!(g.map(|h| (h.prim, h.t)), h.map(|h| (h.prim, h.t)), "width {}", P::WIDTH);
            }
            let mut occ = vec![false; w.hits.len()];
            assert_eq!(shadow_pass(b, w.scene, &w.camera, &w.layout, &w.hits, &mut occ), w.shadow);
            assert_eq!(occ, w.occluded);
            assert_eq!(soft_pass(b, w.scene, &w.camera, &w.layout.to_row_major(&w.hits), &w.light), w.soft);
        }
        let w = Want {
            scene: &scene,
            camera,
            layout,
            hits: want,
            shadow: want_shadow,
            occluded: want_occ,
            soft: want_soft,
            light,
        };
        for coherence in [Coherence::Coherent, Coherence::Incoherent] {
            check(&EmbreeBlocks::<Packet4>::new(&emb, coherence), &w);
            check(&EmbreeBlocks::<Packet8>::new(&emb, coherence), &w);
            check(&EmbreeBlocks::<Packet16>::new(&emb, coherence), &w);
        }
    }
}
