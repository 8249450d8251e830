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

use std::marker::PhantomData;

use cones::Cone;
use cones::shadows::SAMPLES;
use kdtree::{Hit, Intersector, KdTree, Ray, WaldTest, WatertightTest};
use packets::LaneWidth;
use packets::PacketTreeTest;
use scenes::{Camera, Tile};

use crate::error::Error;
use crate::method::{Method, ShadowJob, SoftJob, SoftStats, TileCounters, Tracer};
use crate::registry::{Binding, KernelNames, Options, Structures};

/// Our kd-tree with its triangle test `I` bound (`I` the tree's own, [`bind`] picks it): the
/// single-ray [`Tracer`] of the kernels, which calls [`KdTree::intersect_with_counted`] and
/// so matches on no intersector per ray.
#[derive(Debug)]
pub struct TreeWith<'t, I> {
    tree: &'t KdTree,
    test: PhantomData<fn() -> I>,
}

impl<'t, I: PacketTreeTest> TreeWith<'t, I> {
    /// `tree` traced with the test `I`, which must be the tree's own (`tree.intersector()`).
    #[inline]
    pub fn new(tree: &'t KdTree) -> Self {
        debug_assert_eq!(tree.intersector(), I::INTERSECTOR, "a kernel bound with another tree's test");
        TreeWith { tree, test: PhantomData }
    }
}

impl<I: PacketTreeTest> Tracer for TreeWith<'_, I> {
    #[inline]
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        self.tree.intersect_with_counted::<I, C>(ray, counters)
    }

    #[inline]
    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> bool {
        self.tree.occluded_with_counted::<I, C>(ray, counters)
    }
}

/// The lane frusta's width for `options`: `--lanes`, narrowed to what the SIMD level runs
/// ([`Options::simd`], [`LaneWidth::capped`]).
fn lane_width(options: &Options) -> LaneWidth {
    options.lanes.capped(options.simd)
}

/// The lane frusta kernels' identity: `kd-lane-frusta` at eight lanes (AVX2),
/// `kd-lane-frusta-x16`, `-x4` and `-x1` otherwise.
fn lane_frusta_name(width: LaneWidth) -> String {
    match width {
        LaneWidth::Eight => "kd-lane-frusta".into(),
        width => format!("kd-lane-frusta-x{}", width.lanes()),
    }
}

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
    /// What the tile sizes it takes are a multiple of: 4, or 8 for a tile split into 16
    /// regions of whole 2x2 packets ([`primary::MftX16`]).
    const TILE_MULTIPLE: u32 = 4;

    /// Its identity: `kd-single`, `kd-mft-16`, ...
    fn name(&self) -> String;
    /// Fresh scratch.
    fn scratch(&self) -> Self::Scratch;
    /// [`Method::primary_tile`] on `tree`, whose triangle test is `I` (bound once, [`bind`]).
    fn primary_tile<I: PacketTreeTest, C: TileCounters>(
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
    /// [`Method::shadow_tile`] on `tree`, whose triangle test is `I`.
    fn shadow_tile<I: PacketTreeTest, C: TileCounters>(
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
    /// [`Method::soft_tile`] on `tree`, whose triangle test is `I`.
    fn soft_tile<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats;
    /// [`Method::soft_point`] on `tree`: the 16 rays of one point, bit `i` for ray `i`.
    fn soft_point<I: PacketTreeTest, C: TileCounters>(
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
    /// [`Method::stream`] on `tree`, whose triangle test is `I`.
    fn stream<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    );
    /// [`Method::stream_occluded`] on `tree`, whose triangle test is `I`.
    fn stream_occluded<I: PacketTreeTest, C: TileCounters>(
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
/// loops are those of the kernels themselves. `I` is the tree's triangle test, chosen once
/// when the method is bound ([`bind`]) and handed to every kernel call as a type, so no
/// kernel matches on the intersector per tile or per packet.
#[derive(Debug)]
pub struct Composed<'t, I, P, H, S, R> {
    /// The tree every kernel traces.
    pub tree: &'t KdTree,
    /// The tree's triangle test.
    test: PhantomData<fn() -> I>,
    /// The primary-ray kernel.
    pub primary: P,
    /// The hard-shadow kernel.
    pub shadow: H,
    /// The soft-shadow kernel.
    pub soft: S,
    /// The stream kernel.
    pub stream: R,
}

impl<'t, I: PacketTreeTest, P: Primary, H: HardShadow, S: SoftShadow, R: Stream> Composed<'t, I, P, H, S, R> {
    /// The four kernels of `options` on `tree`, whose triangle test must be `I`: an error
    /// otherwise (a tree holds only its own test's records).
    pub fn new(tree: &'t KdTree, options: &Options) -> Result<Self, Error> {
        if tree.intersector() != I::INTERSECTOR {
            return Err(Error::Usage(format!(
                "a method bound with the {} test on a tree built for the {} test",
                I::INTERSECTOR.name(),
                tree.intersector().name()
            )));
        }
        Ok(Composed {
            tree,
            test: PhantomData,
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

impl<I: PacketTreeTest, P: Primary, H: HardShadow, S: SoftShadow, R: Stream> Method for Composed<'_, I, P, H, S, R> {
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
        self.primary.primary_tile::<I, C>(self.tree, &mut scratch.0, camera, tile, out, counters);
    }

    #[inline]
    fn shadow_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64) {
        self.shadow.shadow_tile::<I, C>(self.tree, &mut scratch.1, job, out, counters)
    }

    #[inline]
    fn soft_tile<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        job: &SoftJob<'_>,
        visible: &mut [f32],
        counters: &mut C,
    ) -> SoftStats {
        self.soft.soft_tile::<I, C>(self.tree, &mut scratch.2, job, visible, counters)
    }

    #[inline]
    fn soft_point<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        counters: &mut C,
    ) -> u16 {
        self.soft.soft_point::<I, C>(self.tree, &mut scratch.2, rays, cone, counters)
    }

    #[inline]
    fn stream<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        self.stream.stream::<I, C>(self.tree, &mut scratch.3, rays, out, counters);
    }

    #[inline]
    fn stream_occluded<C: TileCounters>(
        &self,
        scratch: &mut Self::Scratch,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        self.stream.stream_occluded::<I, C>(self.tree, &mut scratch.3, rays, out, counters);
    }
}

/// Binds the composition of `P`, `H`, `S` and `R` to our kd-tree of `structures` with
/// `options`: what a registry line of ours binds (`crate::registry::Bind`), its kernels named
/// from the bound kernels. The tree's triangle test is matched here, once, and is a type
/// parameter of the composition ([`Composed`]) from then on.
pub fn bind<'s, P, H, S, R>(structures: &'s Structures<'_>, options: &Options) -> Result<Binding<'s>, Error>
where
    P: Primary + 'static,
    H: HardShadow + 'static,
    S: SoftShadow + 'static,
    R: Stream + 'static,
{
    bind_tree::<P, H, S, R>(structures.kdtree(), options)
}

/// [`bind`] on `tree` itself, the binding borrowing only the tree: for a caller that keeps a
/// composition beside the tree (`experiments::shadows` traces its frames' primary rays so).
pub fn bind_tree<'t, P, H, S, R>(tree: &'t KdTree, options: &Options) -> Result<Binding<'t>, Error>
where
    P: Primary + 'static,
    H: HardShadow + 'static,
    S: SoftShadow + 'static,
    R: Stream + 'static,
{
    match tree.intersector() {
        Intersector::Wald => bind_with::<WaldTest, P, H, S, R>(tree, options),
        Intersector::Watertight => bind_with::<WatertightTest, P, H, S, R>(tree, options),
    }
}

/// [`bind`] with the tree's triangle test `I`.
fn bind_with<'s, I, P, H, S, R>(tree: &'s KdTree, options: &Options) -> Result<Binding<'s>, Error>
where
    I: PacketTreeTest,
    P: Primary + 'static,
    H: HardShadow + 'static,
    S: SoftShadow + 'static,
    R: Stream + 'static,
{
    let composed = Composed::<I, P, H, S, R>::new(tree, options)?;
    let names = composed.names();
    Ok(Binding::method(composed).named(names))
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use kdtree::BuildConfig;

    use super::*;

    fn tree(intersector: Intersector) -> KdTree {
        let tris = [[Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)]];
        KdTree::build_soup(&tris, &BuildConfig { intersector, ..Default::default() }).expect("one triangle builds")
    }

    type Singles = Composed<'static, WaldTest, primary::Single, shadow::Single, soft::Single, stream::Single>;
    type WatertightSingles =
        Composed<'static, WatertightTest, primary::Single, shadow::Single, soft::Single, stream::Single>;

    /// A composition is made only with its tree's own triangle test (what [`bind`] picks):
    /// the other test is refused, never traced over the other test's empty records.
    #[test]
    fn a_composition_takes_only_its_trees_test() {
        let (wald, watertight) = (Box::leak(Box::new(tree(Intersector::Wald))), tree(Intersector::Watertight));
        let watertight: &'static KdTree = Box::leak(Box::new(watertight));
        let options = Options::default();
        assert!(Singles::new(wald, &options).is_ok());
        assert!(WatertightSingles::new(watertight, &options).is_ok());
        assert!(matches!(Singles::new(watertight, &options), Err(Error::Usage(_))));
        assert!(matches!(WatertightSingles::new(wald, &options), Err(Error::Usage(_))));
    }

    /// The single-ray tracer of a bound tree answers as the tree's own entry points, for both
    /// tests.
    #[test]
    fn a_bound_tree_traces_as_the_tree() {
        let ray = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let miss = Ray::new(Vec3::new(2.0, 2.0, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let tree = tree(intersector);
            let (hit, blocked) = match intersector {
                Intersector::Wald => {
                    let bound = TreeWith::<WaldTest>::new(&tree);
                    (bound.intersect(&ray), bound.occluded(&miss))
                }
                Intersector::Watertight => {
                    let bound = TreeWith::<WatertightTest>::new(&tree);
                    (bound.intersect(&ray), bound.occluded(&miss))
                }
            };
            assert!(hit.is_some());
            assert_eq!(hit, tree.intersect(&ray), "{intersector:?}");
            assert!(!blocked && !tree.occluded(&miss), "{intersector:?}");
        }
    }
}
