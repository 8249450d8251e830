//! Stream kernels: arbitrary runs of rays (ray files, the incoherent workload), closest hit
//! and any hit, in order.
//!
//! - [`Single`]: each ray alone (`kd-single`);
//! - [`Packets`]: each `W` consecutive rays (4, 8, 16 by the SIMD level) as an
//!   omni-directional packet, from their common origin or each from its own
//!   (`packets::omni_lanes`, the thesis's secondary packets), a same-sign packet only where a
//!   ray starts behind its origin (`kd-omni-packets`, `-w8`, `-w16`);
//! - [`SameSign`]: each four as a same-sign packet (`kd-samesign-packets`);
//! - [`Runs`]: each run of up to [`STREAM_FRUSTUM_PACKETS`] packets of rays sharing an origin
//!   (and starting at or past it: reflections off one plane from their virtual eye, a ray
//!   file's camera rays) traced by a tile kernel at the method's width (one frustum or cone,
//!   or four quarter-runs as MFT frusta or cones; `kd-mft-runs`, ...), other rays as
//!   [`Packets`].

use std::marker::PhantomData;

use kdtree::TreeTest;
use kdtree::{Hit, KdTree, Ray};
use packets::PacketTreeTest;
use packets::simd::{SimdF32, SimdMask};
use packets::triangle4::PacketTest;
use packets::{OmniPacket, PacketHit, RayPacket, TileTracer, Width, omni, omni_lanes, samesign};

use super::primary::{TileKernel, TileScratch, TracerSlot};
use super::{FromOptions, NoOptions, Stream, TreeWith};
use crate::error::Error;
use crate::method::{Method, SingleRays, TileCounters};
use crate::registry::Options;

/// Packets per frustum run of a ray stream ([`Runs`]): up to 16 (64 rays at 4 lanes, 256 at
/// 16).
pub const STREAM_FRUSTUM_PACKETS: usize = 16;

/// Rays per chunk of the any-hit queries answered by closest hits.
const ANY_CHUNK: usize = 256;

/// Each ray alone.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Single;

impl NoOptions for Single {}

impl Stream for Single {
    type Scratch = ();

    fn name(&self) -> String {
        "kd-single".into()
    }

    fn scratch(&self) {}

    #[inline]
    fn stream<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray],
        out: &mut [Option<Hit>],
        c: &mut C,
    ) {
        SingleRays(TreeWith::<I>::new(tree)).stream(&mut (), rays, out, c);
    }

    #[inline]
    fn stream_occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray],
        out: &mut [bool],
        c: &mut C,
    ) {
        SingleRays(TreeWith::<I>::new(tree)).stream_occluded(&mut (), rays, out, c);
    }
}

/// Whether `stream` finds a hit for each ray, in chunks of 256 rays: the any-hit query of the
/// kernels without one of their own.
#[inline]
fn any_by_closest<C: TileCounters>(
    rays: &[Ray],
    out: &mut [bool],
    counters: &mut C,
    mut stream: impl FnMut(&[Ray], &mut [Option<Hit>], &mut C),
) {
    let mut hits = [None; ANY_CHUNK];
    for (rays, out) in rays.chunks(ANY_CHUNK).zip(out.chunks_mut(ANY_CHUNK)) {
        let hits = &mut hits[..rays.len()];
        stream(rays, hits, counters);
        for (slot, hit) in out.iter_mut().zip(hits.iter()) {
            *slot = hit.is_some();
        }
    }
}

/// Each `width` consecutive rays as an omni-directional packet (thesis 4.1.2), from their
/// common origin or each from its own (`packets::omni_lanes`: the secondary rays of
/// neighbouring pixels), closest and any hit; same-sign packets only for rays starting behind
/// their origin. 4 rays at the SSE level (`kd-omni-packets`), 8 with AVX2 (`-w8`), 16 with
/// AVX-512 (`-w16`), from the method's SIMD level ([`Options::simd`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Packets {
    /// Rays per packet.
    pub width: Width,
}

impl Default for Packets {
    /// The thesis's 2x2 packets.
    fn default() -> Self {
        Packets { width: Width::Four }
    }
}

impl FromOptions for Packets {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(Packets { width: options.packet_width()? })
    }
}

/// `rays` (at most `V::LANES`) as one packet of `V`'s width: omni-directional from a common
/// origin, or from each ray's own ([`packets::omni_lanes`]), or same-sign where a ray starts
/// behind its origin; closest hits, or any hits with `ANY_HIT`.
#[inline(always)]
fn group<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: TileCounters, const ANY_HIT: bool>(
    tree: &KdTree,
    rays: &[Ray],
    counters: &mut C,
) -> PacketHit<V> {
    let packet = RayPacket::<V>::from_rays(rays);
    match (OmniPacket::new(packet), ANY_HIT) {
        (Some(p), false) => omni::intersect_with::<I, V, C>(tree, &p, counters),
        (Some(p), true) => omni::occluded_with::<I, V, C>(tree, &p, counters),
        (None, false) if omni_lanes::starts_at_origins(&packet) => {
            omni_lanes::intersect_with::<I, V, C>(tree, &packet, counters)
        }
        (None, true) if omni_lanes::starts_at_origins(&packet) => {
            omni_lanes::occluded_with::<I, V, C>(tree, &packet, counters)
        }
        (None, _) => samesign::intersect_with::<I, V, C>(tree, &packet, counters),
    }
}

impl Stream for Packets {
    type Scratch = ();

    fn name(&self) -> String {
        format!("kd-omni-packets{}", self.width.suffix())
    }

    fn scratch(&self) {}

    fn stream<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray],
        out: &mut [Option<Hit>],
        c: &mut C,
    ) {
        packets::at_width!(self.width, V => {
            for (rays, out) in rays.chunks(V::LANES).zip(out.chunks_mut(V::LANES)) {
                let hits = group::<I, V, C, false>(tree, rays, c);
                for (lane, slot) in out.iter_mut().enumerate() {
                    *slot = hits.get(lane);
                }
            }
        });
    }

    fn stream_occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray],
        out: &mut [bool],
        c: &mut C,
    ) {
        packets::at_width!(self.width, V => {
            for (rays, out) in rays.chunks(V::LANES).zip(out.chunks_mut(V::LANES)) {
                let found = group::<I, V, C, true>(tree, rays, c).found.bitmask();
                for (lane, slot) in out.iter_mut().enumerate() {
                    *slot = found >> lane & 1 != 0;
                }
            }
        });
    }
}

/// Each four consecutive rays as a same-sign 2x2 packet (thesis 2.3.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SameSign;

impl NoOptions for SameSign {}

impl Stream for SameSign {
    type Scratch = ();

    fn name(&self) -> String {
        "kd-samesign-packets".into()
    }

    fn scratch(&self) {}

    fn stream<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray],
        out: &mut [Option<Hit>],
        c: &mut C,
    ) {
        for (rays, out) in rays.chunks(4).zip(out.chunks_mut(4)) {
            let hits = samesign::intersect_with::<I, _, C>(tree, &RayPacket::new(rays), c);
            for (lane, slot) in out.iter_mut().enumerate() {
                *slot = hits.get(lane);
            }
        }
    }

    fn stream_occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        s: &mut (),
        rays: &[Ray],
        out: &mut [bool],
        c: &mut C,
    ) {
        any_by_closest(rays, out, c, |rays, hits, c| self.stream::<I, C>(tree, s, rays, hits, c));
    }
}

/// Runs of rays sharing an origin traced by the tile kernel `K` (frusta, MFT, cones), loaded
/// as packets of the method's width ([`TileTracer::load_rays`]), the run cut into the
/// kernel's regions in order; other rays (the secondary rays of neighbouring pixels off
/// curved or different surfaces) as [`Packets`] at the same width.
#[derive(Debug)]
pub struct Runs<K> {
    /// The kernel of the rays outside runs.
    pub packets: Packets,
    kernel: PhantomData<fn() -> K>,
}

impl<K> Clone for Runs<K> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<K> Copy for Runs<K> {}

impl<K> Default for Runs<K> {
    fn default() -> Self {
        Runs { packets: Packets::default(), kernel: PhantomData }
    }
}

impl<K> FromOptions for Runs<K> {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(Runs { packets: Packets::from_options(options)?, kernel: PhantomData })
    }
}

/// Scratch of [`Runs`]: the tracer of the bound width, made on first use.
#[derive(Debug, Default)]
pub struct RunScratch {
    tiles: TileScratch,
}

impl<K: TileKernel> Stream for Runs<K> {
    type Scratch = RunScratch;

    fn name(&self) -> String {
        format!("kd-{}-runs", K::NAME)
    }

    fn scratch(&self) -> RunScratch {
        RunScratch::default()
    }

    fn stream<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut RunScratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        packets::at_width!(self.packets.width, V => {
            let tracer = TracerSlot::<V>::slot(&mut scratch.tiles)
                .get_or_insert_with(|| TileTracer::with_size(16).expect("16 is a valid tile size"));
            let mut start = 0;
            while start < rays.len() {
                let origin = rays[start].origin.to_array().map(f32::to_bits);
                let run = rays[start..]
                    .iter()
                    .take(STREAM_FRUSTUM_PACKETS * V::LANES)
                    .take_while(|r| r.origin.to_array().map(f32::to_bits) == origin && r.t_min >= 0.0)
                    .count();
                // More than one packet's worth: a frustum run.
                if run > V::LANES && tracer.load_rays(&rays[start..start + run]).is_some() {
                    K::trace_loaded::<I, V, C>(tree, tracer, counters);
                    for (hits, slots) in tracer.packet_hits().iter().zip(out[start..start + run].chunks_mut(V::LANES)) {
                        for (lane, slot) in slots.iter_mut().enumerate() {
                            *slot = hits.get(lane);
                        }
                    }
                    start += run;
                    continue;
                }
                // One packet of the method's width, whatever their origins.
                let end = (start + V::LANES).min(rays.len());
                let hits = group::<I, V, C, false>(tree, &rays[start..end], counters);
                for (lane, slot) in out[start..end].iter_mut().enumerate() {
                    *slot = hits.get(lane);
                }
                start = end;
            }
        });
    }

    fn stream_occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut RunScratch,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        any_by_closest(rays, out, counters, |rays, hits, c| self.stream::<I, C>(tree, scratch, rays, hits, c));
    }
}
