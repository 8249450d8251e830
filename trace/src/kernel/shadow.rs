//! Hard-shadow kernels: the shadow rays of a tile's primary hits to the point light.
//!
//! - [`Single`]: each ray alone (`kd-single`);
//! - [`Packets`]: the tile's rays in Morton order, each run of four as a same-sign 2x2
//!   packet (thesis 2.3.1; `kd-packets`, the hard shadows of every packet, frustum and cone
//!   method);
//! - [`Frusta`]: the tile's rays as one of Benthin & Wald's (2009) shadow frusta
//!   (`packets::shadow_frustum`; `kd-frusta-N`, the tile its frustum);
//! - [`Lanes`]: each run of 16 rays in Morton order (a 4x4 block, the light its apex) as one
//!   of Benthin & Wald's multi-frusta, several in SIMD lanes (`packets::lane_frusta`;
//!   `kd-lane-frusta`).
//!
//! The grouped kernels are also the [`Grouping`]s of `crate::shadow_frusta`, which gathers
//! a tile's rays in Morton order for them, and of the soft-shadow kernels that trace a tile's
//! rays to each light stratum together (`super::soft`).

use glam::Vec3;
use kdtree::{KdTree, Ray};
use packets::PacketTreeTest;
use packets::lane_frusta::FRUSTUM_RAYS;
use packets::{LaneFrusta, LaneWidth, ShadowFrustum, Width, samesign};

use super::{FromOptions, HardShadow, NoOptions, TreeWith};
use crate::error::Error;
use crate::method::{Method, ShadowJob, SingleRays, TileCounters};
use crate::registry::Options;
use crate::shadow_frusta::{self, Grouping, ShadowScratch};

/// Each shadow ray alone ([`KdTree::occluded`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Single;

impl NoOptions for Single {}

impl HardShadow for Single {
    type Scratch = ();

    fn name(&self) -> String {
        "kd-single".into()
    }

    fn scratch(&self) {}

    #[inline]
    fn shadow_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64) {
        SingleRays(TreeWith::<I>::new(tree)).shadow_tile(&mut (), job, out, counters)
    }
}

/// Same-sign packets of neighbouring pixels' rays, `width` at a time in Morton order (thesis
/// 2.3.1): 2x2 pixels at 4 lanes (`kd-packets`), 4x2 at 8 (`kd-packets-w8`, AVX2), 4x4 at 16
/// (`kd-packets-w16`, AVX-512).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Packets {
    /// Rays per packet, from the method's SIMD level ([`Options::simd`]).
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

impl Grouping for Packets {
    type Scratch = ();

    #[inline]
    fn occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        starts: &[Vec3],
        ends: &[Vec3],
        blocked: &mut Vec<bool>,
        counters: &mut C,
    ) {
        packets::at_width!(self.width, V => {
            samesign::occluded_segments_with::<I, V, C>(tree, starts, ends, blocked, counters)
        });
    }
}

/// Benthin & Wald's shadow frustum of a tile's rays: one per tile (and light stratum, for
/// soft shadows), split where wide (`packets::ShadowFrustum`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frusta {
    /// The tile, which is the frustum: part of the kernel's name (`kd-frusta-16`).
    pub tile: u32,
}

impl FromOptions for Frusta {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(Frusta { tile: options.tile })
    }
}

impl Grouping for Frusta {
    type Scratch = ShadowFrustum;

    #[inline]
    fn occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        frustum: &mut ShadowFrustum,
        starts: &[Vec3],
        ends: &[Vec3],
        blocked: &mut Vec<bool>,
        counters: &mut C,
    ) {
        frustum.clear();
        for (&start, &end) in starts.iter().zip(ends) {
            frustum.push(Ray::segment(start, end));
        }
        frustum.trace_with::<I, C>(tree, counters);
        blocked.extend_from_slice(frustum.blocked());
    }
}

/// Benthin & Wald's multi-frusta in SIMD lanes: each run of 16 rays (a 4x4 block of the tile
/// in Morton order, sharing the light as their end) one frustum, `width` of them at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lanes {
    /// How many frusta go down the tree together (`--lanes`; by default the widest this CPU
    /// runs natively, [`LaneWidth::widest`]).
    pub width: LaneWidth,
}

impl FromOptions for Lanes {
    fn from_options(options: &Options) -> Result<Self, Error> {
        Ok(Lanes { width: super::lane_width(options) })
    }
}

impl Grouping for Lanes {
    type Scratch = LaneFrusta;

    #[inline]
    fn occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        lanes: &mut LaneFrusta,
        starts: &[Vec3],
        ends: &[Vec3],
        blocked: &mut Vec<bool>,
        counters: &mut C,
    ) {
        // Each run of 16 (a 4x4 block in Morton order) as one frustum.
        lanes.clear();
        for (starts, ends) in starts.chunks(FRUSTUM_RAYS).zip(ends.chunks(FRUSTUM_RAYS)) {
            lanes.push(starts, ends);
        }
        lanes.trace_with::<I, C>(tree, self.width, counters);
        for (&mask, run) in lanes.blocked().iter().zip(starts.chunks(FRUSTUM_RAYS)) {
            blocked.extend((0..run.len()).map(|k| mask >> k & 1 != 0));
        }
    }
}

/// The grouped kernels: a tile's rays gathered in Morton order by `shadow_frusta::hard` and
/// traced by the grouping.
macro_rules! grouped {
    ($kernel:ty, |$k:ident| $name:expr) => {
        impl HardShadow for $kernel {
            type Scratch = ShadowScratch<<$kernel as Grouping>::Scratch>;

            fn name(&self) -> String {
                let $k = self;
                $name
            }

            fn scratch(&self) -> Self::Scratch {
                ShadowScratch::default()
            }

            #[inline]
            fn shadow_tile<I: PacketTreeTest, C: TileCounters>(
                &self,
                tree: &KdTree,
                scratch: &mut Self::Scratch,
                job: &ShadowJob<'_>,
                out: &mut [bool],
                counters: &mut C,
            ) -> (u64, u64) {
                shadow_frusta::hard::<I, _, C>(tree, self, scratch, job, out, counters)
            }
        }
    };
}

grouped!(Packets, |k| format!("kd-packets{}", k.width.suffix()));
grouped!(Frusta, |k| format!("kd-frusta-{}", k.tile));
grouped!(Lanes, |k| super::lane_frusta_name(k.width));
