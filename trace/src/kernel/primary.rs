//! Primary-ray kernels: a tile of camera rays through our kd-tree.
//!
//! - [`Single`]: each pixel's ray alone (thesis 2.2.1), the scalar twin;
//! - the tile kernels, which load the tile into a `packets::TileTracer` as 2x2 packets and
//!   trace it whole ([`TileKernel`]): [`Packet`] (omni-directional packets, 4.1.2),
//!   [`SameSign`] (same-sign packets split by signs, 2.3.1), [`Frustum`] (the tile as one
//!   frustum with packet/leaf culling, 2.3.2, 4.1.3-4.1.4), [`Mft`] (its four quadrant
//!   frusta, 4.1.5), [`Cone`] (one cone as the proxy of its rays, 4.1.6-4.1.8) and
//!   [`MftCone`] (four quadrant cones, 4.1.9).
//!
//! A tile kernel's tile is the render tile, so the frustum (or cone) of `frustum`, `mft`,
//! `cone` and `mft-cone` is the frame driver's tile: it is a field of the kernel, and part of
//! its name (`kd-mft-16`).

use cones::traverse;
use glam::Vec4;
use kdtree::{Counters, Hit, KdTree, TreeTest};
use packets::simd::{PortableF32, SimdF32};
use packets::triangle4::PacketTest;
use packets::{PacketTreeTest, TileTracer, Width, at_width};
use scenes::{Camera, Tile};

use super::{FromOptions, NoOptions, Primary, TreeWith};
use crate::error::Error;
use crate::method::{Method, SingleRays, TileCounters};
use crate::registry::Options;

/// Single rays ([`KdTree::intersect`]), the scalar twin of every kernel (thesis 2.2.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Single;

impl NoOptions for Single {}

impl Primary for Single {
    type Scratch = ();
    const TILED: bool = false;
    const PACKETS: bool = false;

    fn name(&self) -> String {
        "kd-single".into()
    }

    fn scratch(&self) {}

    #[inline]
    fn primary_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        _: &mut (),
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        SingleRays(TreeWith::<I>::new(tree)).primary_tile(&mut (), camera, tile, out, counters);
    }
}

/// How a tile loaded in a [`TileTracer`] (a primary tile, or packets sharing one origin) is
/// traced: the traversal of one tile kernel, at any packet width. Also what a stream's runs
/// of rays sharing an origin are traced with (`super::stream::Runs`, 2x2 packets).
pub trait TileKernel: Primary {
    /// The kernel's part of its names: `mft` in `kd-mft-16` and `kd-mft-runs`.
    const NAME: &'static str;

    /// The frusta its tiles are split into ([`TileTracer::set_regions`]): the four quadrants,
    /// or 16 regions for [`MftX16`].
    const REGIONS: usize = 4;

    /// Traces the tile loaded in `tracer`: the closest hits (any hits in the tracer's any-hit
    /// mode, for the frustum and cone kernels), exactly those of single rays.
    fn trace_loaded<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
        tree: &KdTree,
        tracer: &mut TileTracer<V>,
        counters: &mut C,
    );
}

/// The options a tile kernel reads: its tile (a multiple of 4 in `4..=64`, checked),
/// packet/leaf culling (thesis 4.1.4) and its packets' width: the one the method asks for
/// ([`Options::packet_width`]: by default the widest of its SIMD level) if the tile holds
/// its packets whole in each quadrant, else 2x2 packets (a tile of 4 or 12 pixels; wider
/// packets need a multiple of 8).
fn tile_options(options: &Options, regions: usize) -> Result<(u32, bool, Width), Error> {
    let tile = options.tile;
    TileTracer::<Vec4>::check_regions(tile, regions).map_err(|e| Error::Usage(format!("tile: {e}")))?;
    // The tracer's own size rule for each width (its portable twin has the same packets).
    let width = match options.packet_width()? {
        Width::Eight if TileTracer::<PortableF32<8>>::check_regions(tile, regions).is_ok() => Width::Eight,
        w @ (Width::Sixteen | Width::SixteenInPairs)
            if TileTracer::<PortableF32<16>>::check_regions(tile, regions).is_ok() =>
        {
            w
        }
        _ => Width::Four,
    };
    Ok((tile, options.culling, width))
}

/// The per-thread tile tracers of a tile kernel: one slot per lane type it may run at
/// ([`at_width!`]); only the bound width's tracer is ever made.
#[derive(Debug, Default)]
pub struct TileScratch {
    four: Option<TileTracer<Vec4>>,
    eight: Option<TileTracer<PortableF32<8>>>,
    sixteen: Option<TileTracer<PortableF32<16>>>,
    #[cfg(target_arch = "x86_64")]
    avx2: Option<TileTracer<packets::F32x8>>,
    #[cfg(target_arch = "x86_64")]
    avx512: Option<TileTracer<packets::F32x16>>,
    #[cfg(target_arch = "x86_64")]
    avx2_pairs: Option<TileTracer<packets::F32x8x2>>,
}

/// The slot of [`TileScratch`] for packets of lane type `V`.
pub trait TracerSlot<V: SimdF32> {
    /// The tracer slot of `V`.
    fn slot(&mut self) -> &mut Option<TileTracer<V>>;
}

macro_rules! tracer_slot {
    ($($(#[$cfg:meta])* $field:ident: $lanes:ty;)*) => {$(
        $(#[$cfg])*
        impl TracerSlot<$lanes> for TileScratch {
            #[inline(always)]
            fn slot(&mut self) -> &mut Option<TileTracer<$lanes>> {
                &mut self.$field
            }
        }
    )*};
}

tracer_slot! {
    four: Vec4;
    eight: PortableF32<8>;
    sixteen: PortableF32<16>;
    #[cfg(target_arch = "x86_64")]
    avx2: packets::F32x8;
    #[cfg(target_arch = "x86_64")]
    avx512: packets::F32x16;
    #[cfg(target_arch = "x86_64")]
    avx2_pairs: packets::F32x8x2;
}

/// [`Primary::primary_tile`] of the tile kernel `K` with tiles of `size` and `culling`, in
/// packets of lane type `V` (inlined into [`at_width!`]'s `target_feature` function).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn primary_tile<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, K: TileKernel, C: TileCounters>(
    size: u32,
    culling: bool,
    tree: &KdTree,
    slot: &mut Option<TileTracer<V>>,
    camera: &Camera,
    tile: &Tile,
    out: &mut [Option<Hit>],
    counters: &mut C,
) {
    let tracer = slot.get_or_insert_with(|| {
        // The size was checked for this width and these regions by `from_options`.
        let mut tracer = TileTracer::with_size(size).expect("tile size checked");
        tracer.set_regions(K::REGIONS).expect("tile size checked");
        tracer.set_culling(culling);
        tracer
    });
    // The frame driver's tiles fit the tracer (same size, inside the image).
    counters.generation_start();
    // The output's lines are asked for while the packets are made, to be in cache for
    // `write_hits`.
    tracer.load_primary_prefetching(camera, tile, out).expect("tile fits the tracer");
    counters.generation_end();
    K::trace_loaded::<I, V, C>(tree, tracer, counters);
    tracer.write_hits(out);
}

/// Defines a tile kernel: its type with the tile and culling fields, and its traversal.
macro_rules! tile_kernel {
    ($(#[$doc:meta])* $kernel:ident, $name:literal, tiled: $tiled:literal,
     |$tree:ident, $tracer:ident, $counters:ident| $trace:expr) => {
        tile_kernel!($(#[$doc])* $kernel, $name, tiled: $tiled, regions: 4,
            |$tree, $tracer, $counters| $trace);
    };
    ($(#[$doc:meta])* $kernel:ident, $name:literal, tiled: $tiled:literal, regions: $regions:literal,
     |$tree:ident, $tracer:ident, $counters:ident| $trace:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub struct $kernel {
            /// The tile side: the tracer's size (and, for the frustum and cone kernels, the
            /// frustum).
            pub tile: u32,
            /// Packet/leaf culling (thesis 4.1.4); only the frustum and cone kernels cull.
            pub culling: bool,
            /// Rays per packet: 2x2 pixels at 4 (the thesis's), 4x2 at 8, 4x4 at 16.
            pub width: Width,
        }

        impl FromOptions for $kernel {
            fn from_options(options: &Options) -> Result<Self, Error> {
                let (tile, culling, width) = tile_options(options, $regions)?;
                Ok($kernel { tile, culling, width })
            }
        }

        impl TileKernel for $kernel {
            const NAME: &'static str = $name;
            const REGIONS: usize = $regions;

            #[inline(always)]
            fn trace_loaded<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
                $tree: &KdTree,
                $tracer: &mut TileTracer<V>,
                $counters: &mut C,
            ) {
                $trace
            }
        }

        impl Primary for $kernel {
            type Scratch = TileScratch;
            const TILED: bool = $tiled;
            const TILE_MULTIPLE: u32 = if $regions == 16 { 8 } else { 4 };
            const PACKETS: bool = true;

            fn name(&self) -> String {
                let width = self.width.suffix();
                if Self::TILED { format!("kd-{}-{}{width}", $name, self.tile) } else { format!("kd-{}{width}", $name) }
            }

            fn scratch(&self) -> TileScratch {
                TileScratch::default()
            }

            #[inline]
            fn primary_tile<I: PacketTreeTest, C: TileCounters>(
                &self,
                tree: &KdTree,
                scratch: &mut TileScratch,
                camera: &Camera,
                tile: &Tile,
                out: &mut [Option<Hit>],
                counters: &mut C,
            ) {
                let (size, culling) = (self.tile, self.culling);
                at_width!(self.width, V => {
                    let slot = TracerSlot::<V>::slot(scratch);
                    primary_tile::<I, V, Self, C>(size, culling, tree, slot, camera, tile, out, counters)
                })
            }
        }
    };
}

tile_kernel!(
    /// Each 2x2 packet of the tile on its own, omni-directional (thesis 4.1.2).
    Packet, "omni-packets", tiled: false,
    |tree, tracer, counters| tracer.trace_packets_with::<I, C>(tree, counters)
);

tile_kernel!(
    /// Each 2x2 packet of the tile on its own, standard same-sign traversal split where
    /// signs differ (thesis 2.3.1).
    SameSign, "samesign-packets", tiled: false,
    |tree, tracer, counters| tracer.trace_samesign_with::<I, C>(tree, counters)
);

tile_kernel!(
    /// The tile as one frustum interval with packet/leaf culling (thesis 2.3.2, 4.1.3-4.1.4).
    Frustum, "frustum", tiled: true,
    |tree, tracer, counters| tracer.trace_frustum_with::<I, C>(tree, counters)
);

tile_kernel!(
    /// Multiple Frustum Traversal: the tile's four quadrants as four frusta in the lanes of a
    /// `Vec4` (thesis 4.1.5).
    Mft, "mft", tiled: true,
    |tree, tracer, counters| tracer.trace_mft_with::<I, C>(tree, counters)
);

tile_kernel!(
    /// Multiple Frustum Traversal with 16 frusta: the tile split into 4 x 4 regions, each
    /// region's frustum one lane of a 16-lane vector (`F32x16` inside the AVX-512 kernel, the
    /// portable twin elsewhere), each culling and testing its own packets at leaves
    /// ([`TileTracer::trace_mft_regions_with`]). The measured alternative to [`Mft`]'s four
    /// frusta of wider packets (issue 28's question: four frusta of W-ray packets, or W
    /// frusta?). Tiles: a multiple of 8 (of 16 for 8- and 16-lane packets, else 2x2 packets).
    MftX16, "mft-x16", tiled: true, regions: 16,
    |tree, tracer, counters| {
        if V::LANES == 16 {
            tracer.trace_mft_regions_with::<I, V, C>(tree, counters)
        } else {
            tracer.trace_mft_regions_with::<I, PortableF32<16>, C>(tree, counters)
        }
    }
);

tile_kernel!(
    /// One cone per tile as the proxy of its rays (thesis 4.1.6-4.1.8).
    Cone, "cone", tiled: true,
    |tree, tracer, counters| traverse::trace_cone_wide_with::<I, V, C>(tree, tracer, counters)
);

tile_kernel!(
    /// Four quadrant cones per tile in the lanes of a `Vec4` (thesis 4.1.9).
    MftCone, "mft-cone", tiled: true,
    |tree, tracer, counters| traverse::trace_mft_cone_wide_with::<I, V, C>(tree, tracer, counters)
);
