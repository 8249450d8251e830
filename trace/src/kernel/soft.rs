//! Soft-shadow kernels: the 16 rays of each primary hit to a spherical light (thesis 4.1.9,
//! Table 4.6; Benthin & Wald 2009).
//!
//! Per point, the thesis's three ([`Method::soft_point`] point by point): [`Single`] (each
//! ray alone, `kd-single`), [`Pyramid`] (the point's 16 rays as four 2x2 packets under their
//! pyramid, `kd-pyramid`) and [`Cone`] (under the cone of the light's sample disk,
//! `kd-cone`): `cones::SoftShadowTracer`. Per tile, each light stratum's rays of the tile
//! together: [`StratumPackets`] (as same-sign 2x2 packets in Morton order,
//! `kd-stratum-packets`, the default of every packet, frustum and cone method) and [`Frusta`]
//! (as one shadow frustum per tile and stratum, Benthin & Wald's multi-frusta,
//! `kd-multi-frusta-N`); and [`Lanes`] (each point's 16 rays as one frustum, several points
//! in SIMD lanes, `kd-lane-frusta`).
//!
//! `--soft-grouping per-point` binds a method's per-point kernel (pyramid or cone) in place
//! of its per-stratum one: the registry line names both.

use cones::shadows::SAMPLES;
use cones::{ShadowMethod, SoftShadowTracer};
use kdtree::{KdTree, Ray};
use packets::PacketTreeTest;
use packets::{LaneFrusta, LaneWidth, OmniPacket, RayPacket, ShadowFrustum, omni, samesign};

use super::shadow;
use super::{FromOptions, NoOptions, SoftShadow, TreeWith};
use crate::error::Error;
use crate::method::{Method, SingleRays, SoftJob, SoftStats, TileCounters, soft_by_points, soft_points};
use crate::registry::Options;
use crate::shadow_frusta::{self, ShadowScratch};

/// Each of a point's rays alone ([`KdTree::occluded`]), point by point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Single;

impl NoOptions for Single {}

impl SoftShadow for Single {
    type Scratch = ();

    fn name(&self) -> String {
        "kd-single".into()
    }

    fn scratch(&self) {}

    #[inline]
    fn soft_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        soft_by_points(&SingleRays(TreeWith::<I>::new(tree)), &mut (), job, visible, counters)
    }

    #[inline]
    fn soft_point<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray; SAMPLES],
        cone: &cones::Cone,
        counters: &mut C,
    ) -> u16 {
        SingleRays(TreeWith::<I>::new(tree)).soft_point(&mut (), rays, cone, counters)
    }
}

/// Defines a per-point kernel of `cones::SoftShadowTracer`: each point's 16 rays under
/// one bound.
macro_rules! per_point {
    ($(#[$doc:meta])* $kernel:ident, $name:literal, $method:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct $kernel;

        impl NoOptions for $kernel {}

        impl SoftShadow for $kernel {
            type Scratch = Option<SoftShadowTracer>;

            fn name(&self) -> String {
                $name.into()
            }

            fn scratch(&self) -> Option<SoftShadowTracer> {
                None
            }

            #[inline]
            fn soft_tile<I: PacketTreeTest, C: TileCounters>(
                &self,
                tree: &KdTree,
                scratch: &mut Option<SoftShadowTracer>,
                job: &SoftJob<'_>,
                visible: &mut [f32],
                counters: &mut C,
            ) -> SoftStats {
                soft_points(job, visible, |rays, cone| self.soft_point::<I, C>(tree, scratch, rays, cone, counters))
            }

            #[inline]
            fn soft_point<I: PacketTreeTest, C: TileCounters>(
                &self,
                tree: &KdTree,
                scratch: &mut Option<SoftShadowTracer>,
                rays: &[Ray; SAMPLES],
                cone: &cones::Cone,
                counters: &mut C,
            ) -> u16 {
                let tracer = scratch.get_or_insert_with(SoftShadowTracer::new);
                tracer.occluded_with::<I, C>(tree, rays, cone, $method, counters)
            }
        }
    };
}

per_point!(
    /// A point's 16 rays as four 2x2 packets under their pyramid frustum (the per-axis
    /// extremes of their directions; thesis Table 4.6).
    Pyramid, "kd-pyramid", ShadowMethod::Pyramid
);

per_point!(
    /// A point's 16 rays as four 2x2 packets under the cone of the light's sample disk
    /// (`cones::shadows::sample_cone`; thesis 4.1.9, Table 4.6).
    Cone, "kd-cone", ShadowMethod::Cone
);

/// A point's 16 rays as four same-sign 2x2 packets (rays `4i .. 4i + 4` the packet `i`):
/// the per-point query of the kernels that group rays across points.
fn four_packets<I: PacketTreeTest, C: TileCounters>(tree: &KdTree, rays: &[Ray; SAMPLES], counters: &mut C) -> u16 {
    let mut mask = 0u16;
    for (i, four) in rays.chunks(4).enumerate() {
        let found = samesign::occluded_with::<I, _, C>(tree, &RayPacket::new(four), counters).found.bitmask() as u16;
        mask |= (found & 0xF) << (4 * i);
    }
    mask
}

/// A point's 16 rays as four omni-directional 2x2 packets from the point (thesis 4.1.2: rays
/// with a common origin and any mix of direction signs go down the tree together, without
/// the pyramid or cone that [`Pyramid`] and [`Cone`] bound them by first). The per-point
/// kernel in between single rays and the thesis's bounded ones: what the bound buys is
/// `kd-pyramid` or `kd-cone` against this. Rays that do not share their origin (never the
/// case for a point's rays) go as same-sign packets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OmniPoints;

impl NoOptions for OmniPoints {}

impl SoftShadow for OmniPoints {
    type Scratch = ();

    fn name(&self) -> String {
        "kd-omni-points".into()
    }

    fn scratch(&self) {}

    #[inline]
    fn soft_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        soft_points(job, visible, |rays, cone| self.soft_point::<I, C>(tree, &mut (), rays, cone, counters))
    }

    #[inline]
    fn soft_point<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        rays: &[Ray; SAMPLES],
        _: &cones::Cone,
        counters: &mut C,
    ) -> u16 {
        let mut mask = 0u16;
        for (i, four) in rays.chunks(4).enumerate() {
            let packet = RayPacket::new(four);
            let found = match OmniPacket::new(packet) {
                Some(omni_packet) => omni::occluded_with::<I, _, C>(tree, &omni_packet, counters).found,
                None => samesign::occluded_with::<I, _, C>(tree, &packet, counters).found,
            };
            mask |= (found.bitmask() as u16 & 0xF) << (4 * i);
        }
        mask
    }
}

/// Each tile's rays to each light stratum as same-sign 2x2 packets of neighbouring points'
/// rays, in Morton order (Benthin & Wald 2009): `shadow_frusta::soft_strata` with
/// [`shadow::Packets`]. The default of every packet, frustum and cone method: 1.3-1.5x
/// single rays on Sponza, kitchen and atrium (`docs/results/coherent-shadows.md`). One
/// point's rays alone go as four 2x2 packets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StratumPackets {
    /// The packets: same-sign packets of `width` rays ([`shadow::Packets`]).
    pub packets: shadow::Packets,
}

impl FromOptions for StratumPackets {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(StratumPackets { packets: shadow::Packets::from_options(options)? })
    }
}

impl SoftShadow for StratumPackets {
    type Scratch = ShadowScratch<()>;

    fn name(&self) -> String {
        format!("kd-stratum-packets{}", self.packets.width.suffix())
    }

    fn scratch(&self) -> Self::Scratch {
        ShadowScratch::default()
    }

    #[inline]
    fn soft_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        shadow_frusta::soft_strata::<I, _, C>(tree, &self.packets, scratch, job, visible, counters)
    }

    #[inline]
    fn soft_point<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        _: &cones::Cone,
        counters: &mut C,
    ) -> u16 {
        four_packets::<I, C>(tree, rays, counters)
    }
}

/// Each tile's rays to each light stratum as one of Benthin & Wald's shadow frusta (their
/// multi-frusta): `shadow_frusta::soft_strata` with [`shadow::Frusta`]. One point's rays
/// alone go as one frustum.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frusta {
    /// The tile, which is the frustum: part of the kernel's name (`kd-multi-frusta-16`).
    pub tile: u32,
}

impl FromOptions for Frusta {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(Frusta { tile: options.tile })
    }
}

impl SoftShadow for Frusta {
    type Scratch = ShadowScratch<ShadowFrustum>;

    fn name(&self) -> String {
        format!("kd-multi-frusta-{}", self.tile)
    }

    fn scratch(&self) -> Self::Scratch {
        ShadowScratch::default()
    }

    #[inline]
    fn soft_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        shadow_frusta::soft_strata::<I, _, C>(
            tree,
            &shadow::Frusta { tile: self.tile },
            scratch,
            job,
            visible,
            counters,
        )
    }

    fn soft_point<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        _: &cones::Cone,
        counters: &mut C,
    ) -> u16 {
        let frustum = scratch.group();
        frustum.clear();
        for &ray in rays {
            frustum.push(ray);
        }
        frustum.trace_with::<I, C>(tree, counters);
        frustum.blocked().iter().enumerate().fold(0, |mask, (i, &b)| mask | u16::from(b) << i)
    }
}

/// Each point's 16 rays, which share its origin, as one of Benthin & Wald's multi-frusta,
/// `width` points at once in SIMD lanes (`shadow_frusta::soft_lanes`). One point's rays alone
/// fill one lane of several; they go as four 2x2 packets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lanes {
    /// How many frusta go down the tree together (`--lanes`).
    pub width: LaneWidth,
}

impl FromOptions for Lanes {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(Lanes { width: super::lane_width(options) })
    }
}

impl SoftShadow for Lanes {
    type Scratch = ShadowScratch<LaneFrusta>;

    fn name(&self) -> String {
        super::lane_frusta_name(self.width)
    }

    fn scratch(&self) -> Self::Scratch {
        ShadowScratch::default()
    }

    #[inline]
    fn soft_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        shadow_frusta::soft_lanes::<I, C>(tree, self.width, scratch, job, visible, counters)
    }

    fn soft_point<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        _: &cones::Cone,
        counters: &mut C,
    ) -> u16 {
        four_packets::<I, C>(tree, rays, counters)
    }
}
