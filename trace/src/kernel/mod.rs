//! Typed kernels, one trait per pass, and [`Composed`], a method made of four of them.
//!
//! The model is pbrt-v4's split of an aggregate's queries (`Intersect`, `IntersectP`) and
//! Embree's kernels bound once per scene: a method of ours is not one type matching on
//! enums per tile, but four kernels chosen once, when the registry binds the method:
//! - [`Primary`]: a tile of primary rays (single rays, 2x2 packets, one frustum, MFT, one
//!   cone, MFT cones; thesis 2.2.1, 4.1.2-4.1.9), in [`primary`];
//! - [`HardShadow`]: a tile's hard shadow rays ([`ShadowJob`]), in [`shadow`];
//! - [`SoftShadow`]: a tile's 16-sample soft shadows ([`SoftJob`]) and one point's 16 rays,
//!   in [`soft`];
//! - [`Stream`]: an arbitrary run of rays, closest and any hit, in [`stream`].
//!
//! Each kernel is a type with its own per-thread scratch, the options it reads as its fields
//! (the tile of a frustum, culling, the lane width) and a [`Primary::name`] (and so on) that
//! is its identity: `rttest compare` times each distinct kernel once by it. Every kernel
//! traces our kd-tree, which the composition holds and hands to each call; every kernel is
//! made from the registry's [`Options`] ([`FromOptions`]), reading only its own fields.
//!
//! A registry line composes four kernels into a method ([`bind`]); a new method from
//! existing kernels is one line of `crate::ours`, a new kernel its own type here plus the
//! lines that compose it.

pub mod primary;
pub mod shadow;
pub mod soft;
pub mod stream;

use cones::Cone;
use cones::shadows::SAMPLES;
use kdtree::{Hit, KdTree, Ray};
use scenes::{Camera, Tile};

use crate::error::Error;
use crate::method::{Method, ShadowJob, SoftJob, SoftStats, TileCounters};
use crate::registry::{Binding, KernelNames, Options, Structures};

/// A kernel made from the options of a method's selection, reading only its own fields
/// (tile, culling, lane width). An option it cannot take is an error.
pub trait FromOptions: Sized {
    /// The kernel for `options`.
    fn from_options(options: &Options) -> Result<Self, Error>;
}

/// A kernel that reads no option: made by its `Default` (the [`FromOptions`] of every such
/// kernel).
pub trait NoOptions: Default {}

impl<K: NoOptions> FromOptions for K {
    fn from_options(_: &Options) -> Result<Self, Error> {
        Ok(K::default())
    }
}

/// The primary-ray kernel of a method: a tile of camera rays.
pub trait Primary: FromOptions + Sync {
    /// Per-thread scratch (a tile's packets), made once per rayon task.
    type Scratch: Send;
    /// Whether the tile is part of the kernel (a frustum or cone per tile): the method then
    /// has one name per tile size, `mft-8`, `mft-16`, ...
    const TILED: bool;
    /// Whether it traces 2x2 packets (N and I are then counted per packet, single rays per
    /// 4 rays), and whose cost images are attributed per tile.
    const PACKETS: bool;

    /// Its identity: `kd-single`, `kd-mft-16`, ...
    fn name(&self) -> String;
    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;
    /// [`Method::primary_tile`] on `tree`.
    fn primary_tile<C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    );
}

/// The hard-shadow kernel of a method: a tile's shadow rays to the point light.
pub trait HardShadow: FromOptions + Sync {
    /// Per-thread scratch.
    type Scratch: Send;
    /// Its identity: `kd-single`, `kd-packets`, `kd-frusta-16`, `kd-lane-frusta`.
    fn name(&self) -> String;
    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;
    /// [`Method::shadow_tile`] on `tree`.
    fn shadow_tile<C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64);
}

/// The soft-shadow kernel of a method: a tile's 16-sample soft shadows, and one point's 16
/// rays.
pub trait SoftShadow: FromOptions + Sync {
    /// Per-thread scratch.
    type Scratch: Send;
    /// Its identity: `kd-single`, `kd-stratum-packets`, `kd-pyramid`, `kd-cone`,
    /// `kd-multi-frusta-16`, `kd-lane-frusta`.
    fn name(&self) -> String;
    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;
    /// [`Method::soft_tile`] on `tree`.
    fn soft_tile<C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats;
    /// [`Method::soft_point`] on `tree`: the 16 rays of one point, bit `i` for ray `i`.
    fn soft_point<C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        counters: &mut C,
    ) -> u16;
}

/// The stream kernel of a method: arbitrary runs of rays (ray files, the incoherent
/// workload).
pub trait Stream: FromOptions + Sync {
    /// Per-thread scratch.
    type Scratch: Send;
    /// Its identity: `kd-single`, `kd-omni-packets`, `kd-mft-runs`, ...
    fn name(&self) -> String;
    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;
    /// [`Method::stream`] on `tree`.
    fn stream<C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    );
    /// [`Method::stream_occluded`] on `tree`.
    fn stream_occluded<C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    );
}

/// A method of ours: four kernels on our kd-tree, each pass delegated to its kernel. The
/// delegation is static (one monomorphic type per registry line), so the frame driver's
/// loops are those of the kernels themselves.
#[derive(Debug)]
pub struct Composed<'t, P, H, S, R> {
    /// The tree every kernel traces.
    pub tree: &'t KdTree,
    /// The primary-ray kernel.
    pub primary: P,
    /// The hard-shadow kernel.
    pub shadow: H,
    /// The soft-shadow kernel.
    pub soft: S,
    /// The stream kernel.
    pub stream: R,
}

impl<'t, P: Primary, H: HardShadow, S: SoftShadow, R: Stream> Composed<'t, P, H, S, R> {
    /// The four kernels of `options` on `tree`.
    pub fn new(tree: &'t KdTree, options: &Options) -> Result<Self, Error> {
        Ok(Composed {
            tree,
            primary: P::from_options(options)?,
            shadow: H::from_options(options)?,
            soft: S::from_options(options)?,
            stream: R::from_options(options)?,
        })
    }

    /// The kernels' identities.
    pub fn names(&self) -> KernelNames {
        KernelNames {
            primary: self.primary.name(),
            shadow: self.shadow.name(),
            soft: self.soft.name(),
            stream: self.stream.name(),
        }
    }
}

impl<P: Primary, H: HardShadow, S: SoftShadow, R: Stream> Method for Composed<'_, P, H, S, R> {
    type Scratch = (P::Scratch, H::Scratch, S::Scratch, R::Scratch);

    fn scratch(&self) -> Self::Scratch {
        (self.primary.scratch(), self.shadow.scratch(), self.soft.scratch(), self.stream.scratch())
    }

    #[inline]
    fn primary_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        self.primary.primary_tile(self.tree, &mut scratch.0, camera, tile, out, counters);
    }

    #[inline]
    fn shadow_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64) {
        self.shadow.shadow_tile(self.tree, &mut scratch.1, job, out, counters)
    }

    #[inline]
    fn soft_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        self.soft.soft_tile(self.tree, &mut scratch.2, job, visible, counters)
    }

    #[inline]
    fn soft_point<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        counters: &mut C,
    ) -> u16 {
        self.soft.soft_point(self.tree, &mut scratch.2, rays, cone, counters)
    }

    #[inline]
    fn stream<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        self.stream.stream(self.tree, &mut scratch.3, rays, out, counters);
    }

    #[inline]
    fn stream_occluded<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        self.stream.stream_occluded(self.tree, &mut scratch.3, rays, out, counters);
    }
}

/// Binds the composition of `P`, `H`, `S` and `R` to our kd-tree of `structures` with
/// `options`: what a registry line of ours binds (`crate::registry::Bind`), its kernels named
/// from the bound kernels.
pub fn bind<'s, P, H, S, R>(structures: &'s Structures<'_>, options: &Options) -> Result<Binding<'s>, Error>
where
    P: Primary + 'static,
    H: HardShadow + 'static,
    S: SoftShadow + 'static,
    R: Stream + 'static,
{
    let composed = Composed::<P, H, S, R>::new(structures.kdtree(), options)?;
    let names = composed.names();
    Ok(Binding::method(composed).named(names))
}
