//! Embree as [`Method`]s of the registry: single rays (`rtcIntersect1` / `rtcOccluded1`) and packets of
//! 4, 8 and 16 rays over 2x2, 4x2 and 4x4 pixel blocks of each render tile
//! (`rtcIntersect4/8/16`, `rtcOccluded4/8/16`), with a chosen coherence hint.
//!
//! Primary rays: each block of the tile is one packet, lanes row-major in the block, lanes
//! outside the tile inactive. Hard shadows: the shadow rays of the same block's hits
//! (lanes without a shadow ray inactive). Soft shadows: the 16 rays of a point as 16 / K
//! packets (K = 1: 16 `rtcOccluded1` calls).

use std::sync::OnceLock;

use cones::Cone;
use cones::shadows::SAMPLES;
use kdtree::{Hit, Ray};
use scenes::{Camera, Scene, Tile};
use trace::method::{ShadowJob, primary_ray};
use trace::registry::{Binding, Entry, Options, StructureEntry, Structures};
use trace::{Error, Method, Registry, SingleRays, TileCounters, Tracer};

use crate::embree::{BuildQuality, Coherence, Device, DeviceInfo, EmbreeScene, Packet, Packet4, Packet8, Packet16};

/// The Embree device of this process, made on first use with the current rayon pool's
/// threads as its build threads, and its properties.
static DEVICE: OnceLock<Result<(Device, DeviceInfo), String>> = OnceLock::new();

/// The device (see [`DEVICE`]).
fn device() -> Result<&'static Device, Error> {
    let made = DEVICE.get_or_init(|| {
        let device = Device::new(Some(rayon::current_num_threads())).map_err(|e| e.to_string())?;
        let info = device.info();
        Ok((device, info))
    });
    made.as_ref().map(|(d, _)| d).map_err(|e| Error::Usage(format!("Embree: {e}")))
}

/// Embree's scene of `scene`'s mesh at `quality`, on the process's device.
fn build(scene: &Scene, quality: BuildQuality) -> Result<Box<dyn std::any::Any + Send + Sync>, Error> {
    let mesh = &scene.mesh;
    let built = EmbreeScene::build(device()?, &mesh.positions, &mesh.triangles, quality)
        .map_err(|e| Error::Usage(format!("Embree: {e}")))?;
    Ok(Box::new(built))
}

/// The structure of Embree's high-quality BVH (`RTC_BUILD_QUALITY_HIGH`, spatial splits).
pub const HIGH: &str = "embree-high";
/// The structure of Embree's medium-quality BVH.
pub const MEDIUM: &str = "embree-medium";

/// An Embree method on `structure` with `coherence`, `W` rays per packet (1: single rays).
fn bind<'s, const W: usize>(
    s: &'s Structures<'_>,
    structure: &str,
    coherence: Coherence,
) -> Result<Binding<'s>, Error> {
    let scene = s.get::<EmbreeScene>(structure)?;
    Ok(match W {
        4 => Binding::method(EmbreeBlocks::<Packet4>::new(scene, coherence)),
        8 => Binding::method(EmbreeBlocks::<Packet8>::new(scene, coherence)),
        16 => Binding::method(EmbreeBlocks::<Packet16>::new(scene, coherence)),
        _ => Binding::method(SingleRays(EmbreeSingle { scene, coherence })),
    })
}

/// An Embree entry: each traces every pass with its own kernel, named by the entry.
fn entry(name: &'static str, summary: &'static str, structure: &'static str, bind: trace::registry::Bind) -> Entry {
    Entry::whole(name, "embree", summary, structure, bind)
}

/// Registers Embree's structures and its single-ray and packet methods, with the coherent
/// context flag on the high-quality BVH, plus Embree's default incoherent flag
/// (`-incoherent`) and the medium-quality BVH (`-medium`).
pub fn register(r: &mut Registry) {
    r.add_structure(StructureEntry { name: HIGH, build: |scene| build(scene, BuildQuality::High) });
    r.add_structure(StructureEntry { name: MEDIUM, build: |scene| build(scene, BuildQuality::Medium) });
    use Coherence::{Coherent, Incoherent};
    r.add(entry("embree-1", "Embree rtcIntersect1 / rtcOccluded1, coherent flag", HIGH, |s, _: &Options| {
        bind::<1>(s, HIGH, Coherent)
    }));
    r.add(entry("embree-4", "Embree packets of 4 over 2x2 pixel blocks", HIGH, |s, _| bind::<4>(s, HIGH, Coherent)));
    r.add(entry("embree-8", "Embree packets of 8 over 4x2 pixel blocks", HIGH, |s, _| bind::<8>(s, HIGH, Coherent)));
    r.add(entry("embree-16", "Embree packets of 16 over 4x4 pixel blocks", HIGH, |s, _| bind::<16>(s, HIGH, Coherent)));
    r.add(entry("embree-1-incoherent", "Embree single rays, default (incoherent) flag", HIGH, |s, _| {
        bind::<1>(s, HIGH, Incoherent)
    }));
    r.add(entry("embree-16-incoherent", "Embree 16-packets, default (incoherent) flag", HIGH, |s, _| {
        bind::<16>(s, HIGH, Incoherent)
    }));
    r.add(entry("embree-1-medium", "Embree single rays on its medium-quality BVH", MEDIUM, |s, _| {
        bind::<1>(s, MEDIUM, Coherent)
    }));
    r.add(entry("embree-16-medium", "Embree 16-packets on its medium-quality BVH", MEDIUM, |s, _| {
        bind::<16>(s, MEDIUM, Coherent)
    }));
}

/// The device line of the text report, once a device exists.
pub fn note() -> Option<String> {
    let (_, info) = DEVICE.get()?.as_ref().ok()?;
    let yes = |b: bool| if b { "native" } else { "emulated" };
    Some(format!(
        "Embree {} ({} tasking): packets of 4 {}, of 8 {}, of 16 {}; build qualities high (embree-N) and medium (embree-N-medium); `-incoherent`: Embree's default context flag, the others coherent.",
        info.version_string(),
        match info.tasking_system {
            0 => "internal",
            1 => "TBB",
            2 => "PPL",
            _ => "unknown",
        },
        yes(info.native_ray4),
        yes(info.native_ray8),
        yes(info.native_ray16)
    ))
}

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
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> Option<Hit> {
        self.scene.intersect(ray, self.coherence)
    }

    #[inline]
    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> bool {
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

impl<P: Packet> Method for EmbreeBlocks<'_, P> {
    type Scratch = P;

    fn scratch(&self) -> P {
        P::default()
    }

    fn primary_tile<C: TileCounters>(
        &self,
        packet: &mut P,
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        _: &mut C,
    ) {
        let shape = block_shape(P::WIDTH);
        for (bx, by) in blocks(tile, shape) {
            packet.clear();
            block_pixels(tile, bx, by, shape, |lane, x, y, _| packet.set(lane, &primary_ray(camera, x, y)));
            self.scene.intersect_packet(packet, self.coherence);
            block_pixels(tile, bx, by, shape, |lane, _, _, i| out[i] = packet.hit(lane));
        }
    }

    fn shadow_tile<C: TileCounters>(
        &self,
        packet: &mut P,
        job: &ShadowJob<'_>,
        out: &mut [bool],
        _: &mut C,
    ) -> (u64, u64) {
        let tile = job.tile;
        let shape = block_shape(P::WIDTH);
        let (mut rays, mut blocked) = (0u64, 0u64);
        // One row of a block's segments (a block has at most 16 pixels).
        let mut row = [None; 16];
        for (bx, by) in blocks(tile, shape) {
            packet.clear();
            let mut any = false;
            let cols = shape.0.min(tile.width() - bx) as usize;
            for j in 0..shape.1.min(tile.height() - by) {
                job.row_segments(bx, by + j, &mut row[..cols]);
                for (i, segment) in row[..cols].iter().enumerate() {
                    if let Some((start, end)) = *segment {
                        packet.set((j * shape.0) as usize + i, &Ray::segment(start, end));
                        any = true;
                    }
                }
            }
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

    fn soft_point<C: TileCounters>(&self, packet: &mut P, rays: &[Ray; SAMPLES], _: &Cone, _: &mut C) -> u16 {
        let mut mask = 0u16;
        for (c, chunk) in rays.chunks(P::WIDTH).enumerate() {
            packet.load(chunk);
            self.scene.occluded_packet(packet, self.coherence);
            for lane in 0..chunk.len() {
                mask |= u16::from(packet.occluded(lane)) << (c * P::WIDTH + lane);
            }
        }
        mask
    }

    /// Each `P::WIDTH` consecutive rays as one packet.
    fn stream<C: TileCounters>(&self, packet: &mut P, rays: &[Ray], out: &mut [Option<Hit>], _: &mut C) {
        for (rays, out) in rays.chunks(P::WIDTH).zip(out.chunks_mut(P::WIDTH)) {
            packet.load(rays);
            self.scene.intersect_packet(packet, self.coherence);
            for (lane, slot) in out.iter_mut().enumerate() {
                *slot = packet.hit(lane);
            }
        }
    }

    /// Each `P::WIDTH` consecutive rays as one packet.
    fn stream_occluded<C: TileCounters>(&self, packet: &mut P, rays: &[Ray], out: &mut [bool], _: &mut C) {
        for (rays, out) in rays.chunks(P::WIDTH).zip(out.chunks_mut(P::WIDTH)) {
            packet.load(rays);
            self.scene.occluded_packet(packet, self.coherence);
            for (lane, slot) in out.iter_mut().enumerate() {
                *slot = packet.occluded(lane);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::NoCounters;
    use scenes::SphereLight;
    use trace::TileLayout;
    use trace::frame::{primary_pass, shadow_pass, soft_pass};
    use trace::method::SingleRays;

    /// The same triangle at the same distance, or a tie within a few ulps of the distance: a
    /// neighbour sharing a vertex (the packet kernels round `t` by an ulp differently) or a
    /// coincident coplanar face (the atrium has some; the first found of two equal `t` wins).
    fn same_or_edge_tie(scene: &Scene, got: Option<Hit>, want: Option<Hit>) -> bool {
        match (got, want) {
            (Some(g), Some(w)) if g.prim != w.prim => {
                let (a, b) = (scene.mesh.triangle(g.prim as usize), scene.mesh.triangle(w.prim as usize));
                let near = (g.t - w.t).abs() <= 4.0 * f32::EPSILON * w.t.abs();
                near && (a.iter().any(|v| b.contains(v)) || trace::ties::coplanar(&a, &b))
            }
            _ => got.map(|h| (h.prim, h.t)) == want.map(|h| (h.prim, h.t)),
        }
    }

    /// Every packet width gives the single-ray answers on every pixel, shadow ray and
    /// soft-shadow ray (Embree's packet kernels run the same triangle test), up to edge ties.
    #[test]
    fn packets_agree_with_single_rays() {
        let scene = scenes::load_scene("atrium").unwrap();
        let emb =
            EmbreeScene::build(device().unwrap(), &scene.mesh.positions, &scene.mesh.triangles, BuildQuality::High)
                .unwrap();
        // 37 x 23: blocks cut by the tile edges.
        let camera = scene.default_view().camera(37, 23).unwrap();
        let layout = TileLayout::new(37, 23, 16);
        let surfaces = trace::shade::surfaces(&scene.mesh);
        let view = trace::frame::View { layout: &layout, scene: &scene, surfaces: &surfaces, camera: &camera };
        let single = SingleRays(EmbreeSingle { scene: &emb, coherence: Coherence::Incoherent });
        let mut want = vec![None; layout.pixel_count()];
        let (hits, NoCounters) = primary_pass(&single, &layout, &camera, &mut want);
        assert!(hits > 0);
        let mut want_occ = vec![false; want.len()];
        let (rays, blocked, NoCounters) = shadow_pass(&single, &view, &want, &mut want_occ);
        let light = SphereLight { center: scene.point_light.position, radius: 0.5, intensity: glam::Vec3::ONE };
        let mut want_vis = vec![0.0; want.len()];
        let (want_soft, NoCounters) = soft_pass(&single, &view, &want, &light, &mut want_vis);
        let mut want_stream = vec![None; want.len()];
        let all: Vec<Ray> = trace::setup::primary_rays(&camera);
        single.stream(&mut (), &all, &mut want_stream, &mut NoCounters);

        #[allow(clippy::too_many_arguments, clippy::type_complexity)]
        fn check<P: Packet>(
            b: &EmbreeBlocks<'_, P>,
            scene: &Scene,
            camera: &Camera,
            layout: &TileLayout,
            want: &[Option<Hit>],
            light: &SphereLight,
            w: ((u64, u64), &[bool], trace::frame::SoftStats, &[f32], &[Ray], &[Option<Hit>]),
        ) {
            let mut got = vec![None; want.len()];
            primary_pass::<_, NoCounters>(b, layout, camera, &mut got);
            for (g, h) in got.iter().zip(want) {
                assert!(same_or_edge_tie(scene, *g, *h), "width {}: {g:?} vs {h:?}", P::WIDTH);
            }
            let surfaces = trace::shade::surfaces(&scene.mesh);
            let view = trace::frame::View { layout, scene, surfaces: &surfaces, camera };
            let mut occ = vec![false; want.len()];
            let (rays, blocked, NoCounters) = shadow_pass(b, &view, want, &mut occ);
            assert_eq!((rays, blocked), w.0);
            assert_eq!(occ, w.1);
            let mut vis = vec![0.0; want.len()];
            assert_eq!(soft_pass::<_, NoCounters>(b, &view, want, light, &mut vis).0, w.2);
            assert_eq!(vis, w.3);
            let mut stream = vec![None; w.4.len()];
            b.stream(&mut P::default(), w.4, &mut stream, &mut NoCounters);
            for (g, h) in stream.iter().zip(w.5) {
                assert!(same_or_edge_tie(scene, *g, *h), "stream, width {}: {g:?} vs {h:?}", P::WIDTH);
            }
        }
        let w = ((rays, blocked), &want_occ[..], want_soft, &want_vis[..], &all[..], &want_stream[..]);
        for coherence in [Coherence::Coherent, Coherence::Incoherent] {
            check(&EmbreeBlocks::<Packet4>::new(&emb, coherence), &scene, &camera, &layout, &want, &light, w);
            check(&EmbreeBlocks::<Packet8>::new(&emb, coherence), &scene, &camera, &layout, &want, &light, w);
            check(&EmbreeBlocks::<Packet16>::new(&emb, coherence), &scene, &camera, &layout, &want, &light, w);
        }
    }
}
