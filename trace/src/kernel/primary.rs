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
use kdtree::{Counters, Hit, KdTree};
use packets::PacketTreeTest;
use packets::TileTracer;
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
/// traced: the traversal of one tile kernel. Also what a stream's runs of rays sharing an
/// origin are traced with (`super::stream::Runs`).
pub trait TileKernel: Primary {
    /// The kernel's part of its names: `mft` in `kd-mft-16` and `kd-mft-runs`.
    const NAME: &'static str;

    /// Traces the tile loaded in `tracer`: the closest hits (any hits in the tracer's any-hit
    /// mode, for the frustum and cone kernels), exactly those of single rays.
    fn trace_loaded<I: PacketTreeTest, C: Counters>(tree: &KdTree, tracer: &mut TileTracer, counters: &mut C);
}

/// The options a tile kernel reads: its tile (a multiple of 4 in `4..=64`, checked) and
/// packet/leaf culling (thesis 4.1.4).
fn tile_options(options: &Options) -> Result<(u32, bool), Error> {
    TileTracer::check_size(options.tile).map_err(|e| Error::Usage(format!("tile: {e}")))?;
    Ok((options.tile, options.culling))
}

/// [`Primary::primary_tile`] of the tile kernel `K` with tiles of `size` and `culling`.
#[inline]
#[allow(clippy::too_many_arguments)]
fn primary_tile<I: PacketTreeTest, K: TileKernel, C: TileCounters>(
    size: u32,
    culling: bool,
    tree: &KdTree,
    scratch: &mut Option<TileTracer>,
    camera: &Camera,
    tile: &Tile,
    out: &mut [Option<Hit>],
    counters: &mut C,
) {
    let tracer = scratch.get_or_insert_with(|| {
        // The size was checked by `from_options`.
        let mut tracer = TileTracer::new(size).expect("tile size checked");
        tracer.set_culling(culling);
        tracer
    });
    // The frame driver's tiles fit the tracer (same size, inside the image).
    tracer.load_primary(camera, tile).expect("tile fits the tracer");
    K::trace_loaded::<I, C>(tree, tracer, counters);
    tracer.write_hits(out);
}

/// Defines a tile kernel: its type with the tile and culling fields, and its traversal.
macro_rules! tile_kernel {
    ($(#[$doc:meta])* $kernel:ident, $name:literal, tiled: $tiled:literal,
     |$tree:ident, $tracer:ident, $counters:ident| $trace:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub struct $kernel {
            /// The tile side: the tracer's size (and, for the frustum and cone kernels, the
            /// frustum).
            pub tile: u32,
            /// Packet/leaf culling (thesis 4.1.4); only the frustum and cone kernels cull.
            pub culling: bool,
        }

        impl FromOptions for $kernel {
            fn from_options(options: &Options) -> Result<Self, Error> {
                let (tile, culling) = tile_options(options)?;
                Ok($kernel { tile, culling })
            }
        }

        impl TileKernel for $kernel {
            const NAME: &'static str = $name;

            #[inline]
            fn trace_loaded<I: PacketTreeTest, C: Counters>($tree: &KdTree, $tracer: &mut TileTracer, $counters: &mut C) {
                $trace
            }
        }

        impl Primary for $kernel {
            type Scratch = Option<TileTracer>;
            const TILED: bool = $tiled;
            const PACKETS: bool = true;

            fn name(&self) -> String {
                if Self::TILED { format!("kd-{}-{}", $name, self.tile) } else { format!("kd-{}", $name) }
            }

            fn scratch(&self) -> Option<TileTracer> {
                None
            }

            #[inline]
            fn primary_tile<I: PacketTreeTest, C: TileCounters>(
                &self,
                tree: &KdTree,
                scratch: &mut Option<TileTracer>,
                camera: &Camera,
                tile: &Tile,
                out: &mut [Option<Hit>],
                counters: &mut C,
            ) {
                primary_tile::<I, Self, C>(self.tile, self.culling, tree, scratch, camera, tile, out, counters);
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
    /// Multiple Frustum Traversal: the tile's four quadrants as four frusta in SSE lanes
    /// (thesis 4.1.5).
    Mft, "mft", tiled: true,
    |tree, tracer, counters| tracer.trace_mft_with::<I, C>(tree, counters)
);

tile_kernel!(
    /// One cone per tile as the proxy of its rays (thesis 4.1.6-4.1.8).
    Cone, "cone", tiled: true,
    |tree, tracer, counters| traverse::trace_cone_with::<I, C>(tree, tracer, counters)
);

tile_kernel!(
    /// Four quadrant cones per tile in the lanes of a `Vec4` (thesis 4.1.9).
    MftCone, "mft-cone", tiled: true,
    |tree, tracer, counters| traverse::trace_mft_cone_with::<I, C>(tree, tracer, counters)
);
