//! Our kd-tree methods as [`Method`]s: single rays, and the tile kernels of `packets` and
//! `cones` (omni-directional and same-sign 2x2 packets, one frustum, MFT, one cone, MFT
//! cones; thesis 4.1.2-4.1.9).
//!
//! - [`Mono`]: single rays ([`KdTree::intersect`] / [`KdTree::occluded`]), the scalar twin;
//! - [`Tiled`]: a tile kernel. Each render tile is loaded as 2x2 packets in a
//!   [`TileTracer`], so the frustum (or cone) of `frustum`, `mft`, `cone` and `mft-cone` is
//!   the render tile. Hard shadow rays go as 2x2 packets of neighbouring pixels' rays
//!   ([`crate::shadow_frusta`]), and so do a tile's soft-shadow rays to each light stratum
//!   ([`SoftGrouping::Strata`]); with [`SoftGrouping::PerPoint`] the 16 soft-shadow rays of
//!   a point, which share an origin, go under their pyramid (packets) or their cone (cones),
//!   as in Table 4.6. With [`TileShadows::Frusta`] (method `multi-frusta`) both go as
//!   Benthin & Wald's shadow frusta. A ray stream is grouped into omni packets and frusta where consecutive rays
//!   share an origin.

use cones::shadows::SAMPLES;
use cones::{Cone, ConeMethod, ShadowMethod, SoftShadowTracer};
use kdtree::{Hit, KdTree, Ray};
use packets::{LaneWidth, OmniPacket, RayPacket, TileMethod, TileTracer, omni, samesign};
use scenes::{Camera, Tile};

use crate::method::{Method, ShadowJob, SingleRays, SoftJob, SoftStats, TileCounters, soft_by_points};
use crate::registry::SoftGrouping;
use crate::shadow_frusta::{self, Grouping, ShadowScratch};

/// Single rays through our kd-tree (thesis 2.2.1).
pub type Mono<'a> = SingleRays<&'a KdTree>;

/// How a tile of 2x2 packets is traced: a `packets` kernel or a `cones` one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Packets, one frustum or MFT (`packets`, thesis 4.1.2-4.1.5).
    Packets(TileMethod),
    /// One cone or MFT cones (`cones`, thesis 4.1.6-4.1.9).
    Cones(ConeMethod),
}

impl Kernel {
    /// Traces the tile loaded in `tracer`.
    #[inline]
    pub fn trace<C: TileCounters>(self, tree: &KdTree, tracer: &mut TileTracer, counters: &mut C) {
        match self {
            Kernel::Packets(m) => tracer.trace(tree, m, counters),
            Kernel::Cones(m) => cones::traverse::trace(tree, tracer, m, counters),
        }
    }

    /// Whether it bounds a whole run of rays sharing an origin (frusta and cones) rather than
    /// going packet by packet.
    pub fn bounds_runs(self) -> bool {
        !matches!(self, Kernel::Packets(TileMethod::Packet | TileMethod::SameSign))
    }

    /// Its per-point soft-shadow kernel ([`SoftGrouping::PerPoint`]): the cone for cones,
    /// the pyramid otherwise.
    pub fn soft_kernel(self) -> ShadowMethod {
        match self {
            Kernel::Packets(_) => ShadowMethod::Pyramid,
            Kernel::Cones(_) => ShadowMethod::Cone,
        }
    }
}

/// How a [`Tiled`] method traces shadow rays ([`crate::shadow_frusta`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileShadows {
    /// Hard shadows as 2x2 packets of neighbouring pixels' rays; soft shadows as 2x2 packets
    /// per light stratum, or per point under the thesis's pyramid or cone
    /// ([`SoftGrouping`]).
    Packets,
    /// Benthin & Wald's shadow frusta: one per tile for hard shadows, one per tile and light
    /// stratum for soft shadows.
    Frusta,
    /// Benthin & Wald's multi-frusta in SIMD lanes (`packets::lane_frusta`): each 4x4
    /// block's hard shadow rays, each point's 16 soft-shadow rays, one frustum per lane.
    Lanes(LaneWidth),
}

/// A tile kernel over our kd-tree, with its tile size, packet/leaf culling switch and shadow
/// grouping.
#[derive(Clone, Copy, Debug)]
pub struct Tiled<'a> {
    tree: &'a KdTree,
    kernel: Kernel,
    tile: u32,
    culling: bool,
    shadows: TileShadows,
    soft: SoftGrouping,
}

/// Scratch of [`Tiled`]: each part made on first use, once per rayon task.
#[derive(Debug, Default)]
pub struct TiledScratch {
    tile: Option<TileTracer>,
    stream: Option<TileTracer>,
    soft: Option<SoftShadowTracer>,
    group: Vec<OmniPacket>,
    shadows: ShadowScratch,
}

/// Rays per frustum of a ray stream: up to 16 packets.
pub const STREAM_FRUSTUM_RAYS: usize = 64;

impl<'a> Tiled<'a> {
    /// `kernel` on `tree`, tiles of `tile` pixels (a multiple of 4 in `4..=64`), with
    /// packet/leaf culling (thesis 4.1.4) on or off.
    pub fn new(tree: &'a KdTree, kernel: Kernel, tile: u32, culling: bool) -> Result<Self, packets::tile::TileError> {
        TileTracer::check_size(tile)?;
        Ok(Tiled { tree, kernel, tile, culling, shadows: TileShadows::Packets, soft: SoftGrouping::Strata })
    }

    /// The same method with its shadow rays grouped by `shadows`.
    pub fn with_shadows(self, shadows: TileShadows) -> Self {
        Tiled { shadows, ..self }
    }

    /// The same method with its soft-shadow rays grouped by `soft` (with
    /// [`TileShadows::Frusta`], soft shadows always go as shadow frusta).
    pub fn with_soft(self, soft: SoftGrouping) -> Self {
        Tiled { soft, ..self }
    }

    fn tile_tracer<'s>(&self, scratch: &'s mut TiledScratch) -> &'s mut TileTracer {
        scratch.tile.get_or_insert_with(|| {
            // The size was checked by `new`.
            let mut tracer = TileTracer::new(self.tile).expect("tile size checked");
            tracer.set_culling(self.culling);
            tracer
        })
    }
}

impl Method for Tiled<'_> {
    type Scratch = TiledScratch;

    fn scratch(&self) -> TiledScratch {
        TiledScratch::default()
    }

    fn primary_tile<C: TileCounters>(
        &self,
        scratch: &mut TiledScratch,
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        let tracer = self.tile_tracer(scratch);
        // The frame driver's tiles fit the tracer (same size, inside the image).
        tracer.load_primary(camera, tile).expect("tile fits the tracer");
        self.kernel.trace(self.tree, tracer, counters);
        tracer.write_hits(out);
    }

    /// The tile's rays as 2x2 packets of neighbours, or as one shadow frustum
    /// ([`TileShadows`]).
    fn shadow_tile<C: TileCounters>(
        &self,
        scratch: &mut TiledScratch,
        job: &ShadowJob<'_>,
        out: &mut [bool],
        c: &mut C,
    ) -> (u64, u64) {
        let grouping = match self.shadows {
            TileShadows::Packets => Grouping::Packets,
            TileShadows::Frusta => Grouping::Frusta,
            TileShadows::Lanes(width) => Grouping::Lanes(width),
        };
        shadow_frusta::hard(self.tree, grouping, &mut scratch.shadows, job, out, c)
    }

    /// Shadow frusta: one per light stratum (Benthin & Wald's multi-frusta). Packets: 2x2
    /// packets per light stratum ([`SoftGrouping::Strata`]), or each point's 16 rays under
    /// their pyramid or cone ([`SoftGrouping::PerPoint`], [`Method::soft_point`], Table 4.6).
    fn soft_tile<C: TileCounters>(
        &self,
        scratch: &mut TiledScratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        let grouping = match (self.shadows, self.soft) {
            (TileShadows::Frusta, _) => Grouping::Frusta,
            (TileShadows::Lanes(width), _) => Grouping::Lanes(width),
            (TileShadows::Packets, SoftGrouping::Strata) => Grouping::Packets,
            (TileShadows::Packets, SoftGrouping::PerPoint) => {
                return soft_by_points(self, scratch, job, visible, counters);
            }
        };
        shadow_frusta::soft(self.tree, grouping, &mut scratch.shadows, job, visible, counters)
    }

    fn soft_point<C: TileCounters>(
        &self,
        scratch: &mut TiledScratch,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        counters: &mut C,
    ) -> u16 {
        let tracer = scratch.soft.get_or_insert_with(SoftShadowTracer::new);
        tracer.occluded(self.tree, rays, cone, self.kernel.soft_kernel(), counters)
    }

    /// Consecutive rays of the stream, in order:
    /// - `packet`: each 4 as an omni-directional packet when they share an origin (and start
    ///   at it), else as a same-sign packet split by direction signs;
    /// - `samesign`: each 4 as a same-sign packet;
    /// - `frustum`, `mft`, `cone`, `mft-cone`: each run of up to [`STREAM_FRUSTUM_RAYS`]
    ///   rays sharing an origin (and starting at it) as one frustum (or cone), or four
    ///   quarter-runs as MFT frusta (or cones); other rays as `packet`.
    fn stream<C: TileCounters>(
        &self,
        scratch: &mut TiledScratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        let tracer = scratch.stream.get_or_insert_with(|| TileTracer::new(4).expect("4 is a valid tile size"));
        let group = &mut scratch.group;
        let mut start = 0;
        while start < rays.len() {
            let origin = rays[start].origin;
            let shares = |r: &Ray| r.origin.to_array().map(f32::to_bits) == origin.to_array().map(f32::to_bits);
            let run =
                rays[start..].iter().take(STREAM_FRUSTUM_RAYS).take_while(|r| shares(r) && r.t_min >= 0.0).count();
            if self.kernel.bounds_runs() && run > 4 {
                group.clear();
                for four in rays[start..start + run].chunks(4) {
                    // A shared origin and t_min >= 0 were checked for the run.
                    group.push(OmniPacket::new(RayPacket::new(four)).expect("run shares its origin"));
                }
                tracer.load_packets(group).expect("run shares its origin");
                self.kernel.trace(self.tree, tracer, counters);
                for (hits, slots) in tracer.packet_hits().iter().zip(out[start..start + run].chunks_mut(4)) {
                    for (lane, slot) in slots.iter_mut().enumerate() {
                        *slot = hits.get(lane);
                    }
                }
                start += run;
                continue;
            }
            let end = (start + 4).min(rays.len());
            let packet = RayPacket::new(&rays[start..end]);
            let hits = match (self.kernel, OmniPacket::new(packet)) {
                (Kernel::Packets(TileMethod::SameSign), _) | (_, None) => {
                    samesign::intersect(self.tree, &packet, counters)
                }
                (_, Some(omni_packet)) => omni::intersect(self.tree, &omni_packet, counters),
            };
            for (lane, slot) in out[start..end].iter_mut().enumerate() {
                *slot = hits.get(lane);
            }
            start = end;
        }
    }

    /// `packet`: omni-directional any-hit packets where 4 consecutive rays share an origin,
    /// else same-sign packets; the other kernels: whether [`Method::stream`] finds a hit.
    fn stream_occluded<C: TileCounters>(
        &self,
        scratch: &mut TiledScratch,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        if self.kernel == Kernel::Packets(TileMethod::Packet) {
            for (rays, out) in rays.chunks(4).zip(out.chunks_mut(4)) {
                let packet = RayPacket::new(rays);
                let found = match OmniPacket::new(packet) {
                    Some(p) => omni::occluded(self.tree, &p, counters).found,
                    None => samesign::intersect(self.tree, &packet, counters).found,
                };
                for (lane, slot) in out.iter_mut().enumerate() {
                    *slot = found.bitmask() >> lane & 1 != 0;
                }
            }
            return;
        }
        let mut hits = [None; STREAM_FRUSTUM_RAYS];
        for (rays, out) in rays.chunks(STREAM_FRUSTUM_RAYS).zip(out.chunks_mut(STREAM_FRUSTUM_RAYS)) {
            let hits = &mut hits[..rays.len()];
            self.stream(scratch, rays, hits, counters);
            for (slot, hit) in out.iter_mut().zip(hits.iter()) {
                *slot = hit.is_some();
            }
        }
    }
}
