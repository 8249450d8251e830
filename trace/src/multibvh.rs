//! Our multi-branching BVHs (crate `mbvh`, Wald, Benthin & Boulos 2008) as single-ray
//! [`Tracer`]s: the registry's methods `mbvh-4` (4-wide nodes) and `mbvh-8` (8-wide nodes)
//! trace them one ray at a time ([`crate::SingleRays`]), the SIMD lanes spent on a node's
//! children and a leaf's four triangles.
//!
//! Each tree is a structure of the registry (`mbvh`, `mbvh8`, built from the scene like
//! Embree's, so `rttest compare` times its build). Their leaves hold both intersectors'
//! records; a method answers with the triangle test of the frame's kd-tree
//! ([`kdtree::KdTree::intersector`]), so that its answers are comparable with `mono`'s under
//! the conformance rules. `mbvh-8` tests its nodes in AVX2 where the CPU has it, asked once
//! when the method is bound ([`mbvh::Avx2::detect`]), and with the scalar 8-wide test
//! elsewhere.
//!
//! `mbvh-8-p16` traces the 8-wide tree's ray streams (the incoherent AO and diffuse rays) and
//! each point's 16 soft-shadow rays by packets of 16 rays, one AVX-512 register per ray
//! coordinate, lanes finished by single rays below a threshold ([`mbvh::packet`]: the hybrid
//! traversal that Embree's `embree-16` incoherent rows run); primary and hard-shadow tiles go
//! ray by ray through the same tree as `mbvh-8`. Without AVX-512 (or below it by
//! `Options::simd`) the packets run as two AVX2 halves, and without AVX2 in the portable
//! lanes, the same answers bit for bit.

use cones::Cone;
use cones::shadows::SAMPLES;
use kdtree::isa::SimdLevel;
use kdtree::{Hit, KdTree, Ray};
use mbvh::{
    Avx2, Avx512, BoxTest, DefaultTest, LeafBlock, Mbvh, Mbvh8, Mbvh16, MultiBvh, Node8, PacketLanes, PacketTraversal,
    Portable16, Traversal,
};
use scenes::{Camera, Scene, Tile};

use crate::error::Error;
use crate::method::{Method, ShadowJob, SingleRays, TileCounters, Tracer};
use crate::registry::{Binding, KernelNames};

/// The registry's name of the 4-wide BVH structure.
pub const MBVH: &str = "mbvh";

/// The registry's name of the 8-wide BVH structure.
pub const MBVH8: &str = "mbvh8";

/// The registry's name of the 16-wide BVH structure.
pub const MBVH16: &str = "mbvh16";

impl<B: LeafBlock, K: BoxTest> Tracer for Traversal<'_, B, K> {
    #[inline]
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit> {
        Traversal::intersect_counted(self, ray, counters)
    }

    #[inline]
    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, counters: &mut C) -> bool {
        Traversal::occluded_counted(self, ray, counters)
    }
}

/// Builds the 4-wide BVH of `scene` (the registry's structure [`MBVH`]).
pub fn build(scene: &Scene) -> Result<Mbvh, Error> {
    Mbvh::build(&scene.mesh.positions, &scene.mesh.triangles).map_err(|e| Error::Usage(format!("mbvh build: {e}")))
}

/// Builds the 8-wide BVH of `scene` (the registry's structure [`MBVH8`]).
pub fn build8(scene: &Scene) -> Result<Mbvh8, Error> {
    Mbvh8::build(&scene.mesh.positions, &scene.mesh.triangles).map_err(|e| Error::Usage(format!("mbvh8 build: {e}")))
}

/// Builds the 16-wide BVH of `scene` (the registry's structure [`MBVH16`]; the paper's
/// width, Wald, Benthin & Boulos 2008).
pub fn build16(scene: &Scene) -> Result<Mbvh16, Error> {
    Mbvh16::build(&scene.mesh.positions, &scene.mesh.triangles).map_err(|e| Error::Usage(format!("mbvh16 build: {e}")))
}

/// A traversal's frame passes, one ray at a time.
fn driven<'s, B: LeafBlock + 's, K: BoxTest + 's>(tr: Traversal<'s, B, K>) -> Result<Binding<'s>, Error> {
    Ok(Binding::method(SingleRays(tr)))
}

/// `mbvh-4`: single rays through the 4-wide BVH `bvh` with the triangle test of `tree`.
pub fn bind<'s>(bvh: &'s Mbvh, tree: &KdTree) -> Result<Binding<'s>, Error> {
    match tree.intersector() {
        kdtree::Intersector::Wald => driven(bvh.wald()),
        kdtree::Intersector::Watertight => driven(bvh.watertight()),
    }
}

/// `mbvh-8`: single rays through the 8-wide BVH `bvh` with the triangle test of `tree`, the
/// node test in AVX2 if this CPU has it and `simd` allows it (checked here, once), else
/// scalar (the kernel then named `mbvh-8-scalar-nodes`).
pub fn bind8<'s>(bvh: &'s Mbvh8, tree: &KdTree, simd: SimdLevel) -> Result<Binding<'s>, Error> {
    let avx2 = Avx2::detect().filter(|_| simd >= SimdLevel::Avx2);
    bind_wide(bvh, tree, avx2, "mbvh-8-scalar-nodes")
}

/// `mbvh-16`: single rays through the 16-wide BVH `bvh` with the triangle test of `tree`,
/// one ray against 16 children per AVX-512 step (Wald, Benthin & Boulos 2008, as published)
/// if this CPU has it and `simd` allows it, else the scalar node test (the kernel then named
/// `mbvh-16-scalar-nodes`).
pub fn bind16<'s>(bvh: &'s Mbvh16, tree: &KdTree, simd: SimdLevel) -> Result<Binding<'s>, Error> {
    let avx512 = Avx512::detect().filter(|_| simd >= SimdLevel::Avx512);
    bind_wide(bvh, tree, avx512, "mbvh-16-scalar-nodes")
}

/// A wide BVH bound with its SIMD node test `token` where there is one, else with its
/// default (scalar) test and its kernels named `scalar_name`.
fn bind_wide<'s, N: DefaultTest, T: BoxTest<Node = N> + 's>(
    bvh: &'s MultiBvh<N>,
    tree: &KdTree,
    token: Option<T>,
    scalar_name: &str,
) -> Result<Binding<'s>, Error> {
    match (tree.intersector(), token) {
        (kdtree::Intersector::Wald, Some(t)) => driven(bvh.wald().with_test(t)),
        (kdtree::Intersector::Watertight, Some(t)) => driven(bvh.watertight().with_test(t)),
        (kdtree::Intersector::Wald, None) => Ok(driven(bvh.wald())?.named(KernelNames::whole(scalar_name))),
        (kdtree::Intersector::Watertight, None) => Ok(driven(bvh.watertight())?.named(KernelNames::whole(scalar_name))),
    }
}

/// `mbvh-8-p16`: the 8-wide BVH `bvh` with the triangle test of `tree`, ray streams and
/// soft-shadow points by packets of 16 rays ([`PacketTraversal`]), in AVX-512 if this CPU has
/// it and `simd` allows it, else as two 8-lane AVX2 halves if it has AVX2 (the kernel then
/// named `mbvh-8-p16-avx2`), else in the portable lanes (`mbvh-8-p16-portable`); single
/// rays (primary and hard-shadow tiles, and lanes below the hybrid threshold) through
/// `mbvh-8`'s node test (AVX2 or scalar, as [`bind8`] picks).
pub fn bind8_p16<'s>(bvh: &'s Mbvh8, tree: &KdTree, simd: SimdLevel) -> Result<Binding<'s>, Error> {
    let avx512 = Avx512::detect().filter(|_| simd >= SimdLevel::Avx512);
    let avx2 = Avx2::detect().filter(|_| simd >= SimdLevel::Avx2);
    let portable = KernelNames::whole("mbvh-8-p16-portable");
    let in_avx2 = KernelNames::whole("mbvh-8-p16-avx2");
    match (tree.intersector(), avx512, avx2) {
        (kdtree::Intersector::Wald, Some(t), Some(a)) => {
            Ok(Binding::method(Packets(bvh.wald().with_test(a).packets(t))))
        }
        (kdtree::Intersector::Watertight, Some(t), Some(a)) => {
            Ok(Binding::method(Packets(bvh.watertight().with_test(a).packets(t))))
        }
        (kdtree::Intersector::Wald, _, Some(a)) => {
            Ok(Binding::method(Packets(bvh.wald().with_test(a).packets(a))).named(in_avx2))
        }
        (kdtree::Intersector::Watertight, _, Some(a)) => {
            Ok(Binding::method(Packets(bvh.watertight().with_test(a).packets(a))).named(in_avx2))
        }
        (kdtree::Intersector::Wald, _, None) => {
            Ok(Binding::method(Packets(bvh.wald().packets(Portable16))).named(portable))
        }
        (kdtree::Intersector::Watertight, _, None) => {
            Ok(Binding::method(Packets(bvh.watertight().packets(Portable16))).named(portable))
        }
    }
}

/// The 8-wide tree as a [`Method`] traced by 16-ray packets: streams and soft-shadow points
/// by packets, primary and hard-shadow tiles ray by ray.
#[derive(Debug)]
struct Packets<'s, B, K: BoxTest<Node = Node8>, L>(PacketTraversal<'s, B, K, L>);

impl<B: LeafBlock, K: BoxTest<Node = Node8>, L: PacketLanes> Method for Packets<'_, B, K, L> {
    type Scratch = ();

    fn scratch(&self) {}

    fn primary_tile<C: TileCounters>(
        &self,
        scratch: &mut (),
        camera: &Camera,
        tile: &Tile,
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        SingleRays(self.0.single()).primary_tile(scratch, camera, tile, out, counters);
    }

    fn shadow_tile<C: TileCounters>(
        &self,
        scratch: &mut (),
        job: &ShadowJob<'_>,
        out: &mut [bool],
        counters: &mut C,
    ) -> (u64, u64) {
        SingleRays(self.0.single()).shadow_tile(scratch, job, out, counters)
    }

    fn soft_point<C: TileCounters>(&self, _: &mut (), rays: &[Ray; SAMPLES], _: &Cone, counters: &mut C) -> u16 {
        let mut blocked = [false; SAMPLES];
        self.0.occluded_stream(rays, &mut blocked, counters);
        blocked.iter().enumerate().fold(0, |m, (i, &b)| m | u16::from(b) << i)
    }

    fn stream<C: TileCounters>(&self, _: &mut (), rays: &[Ray], out: &mut [Option<Hit>], counters: &mut C) {
        self.0.intersect_stream(rays, out, counters);
    }

    fn stream_occluded<C: TileCounters>(&self, _: &mut (), rays: &[Ray], out: &mut [bool], counters: &mut C) {
        self.0.occluded_stream(rays, out, counters);
    }
}
