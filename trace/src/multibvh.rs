//! Our 4-wide BVH (crate `mbvh`, Wald, Benthin & Boulos 2008) as single-ray [`Tracer`]s: the
//! registry's method `mbvh-4` traces it one ray at a time ([`crate::SingleRays`]), the SIMD
//! lanes spent on a node's four children and a leaf's four triangles.
//!
//! The tree is a structure of the registry (`mbvh`, built from the scene like Embree's, so
//! `rttest compare` times its build). Its leaves hold both intersectors' records; a method
//! answers with the triangle test of the frame's kd-tree ([`kdtree::KdTree::intersector`]),
//! so that its answers are comparable with `mono`'s under the conformance rules.

use kdtree::{Hit, Ray};
use mbvh::{LeafBlock, Mbvh, Traversal};
use scenes::Scene;

use crate::Error;
use crate::frame::{Driven, FrameTracer};
use crate::method::{SingleRays, TileCounters, Tracer};
use crate::registry::Structures;

/// The registry's name of the 4-wide BVH structure.
pub const MBVH: &str = "mbvh";

impl<B: LeafBlock> Tracer for Traversal<'_, B> {
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

/// `mbvh-4`: single rays through the 4-wide BVH with the kd-tree's triangle test.
pub fn bind<'s>(s: &'s Structures<'_>) -> Result<Box<dyn FrameTracer + 's>, Error> {
    let bvh = s.get::<Mbvh>(MBVH)?;
    Ok(match s.kdtree().intersector() {
        kdtree::Intersector::Wald => Box::new(Driven(SingleRays(bvh.wald()))),
        kdtree::Intersector::Watertight => Box::new(Driven(SingleRays(bvh.watertight()))),
    })
}
