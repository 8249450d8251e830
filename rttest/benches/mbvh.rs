//! The 4- and 8-wide BVHs (`mbvh-4`, `mbvh-8`, Wald, Benthin & Boulos 2008) against our
//! kd-tree (`mono`, `mft-16`) on the incoherent workload at 512x512: the ambient-occlusion
//! rays (4 per primary hit, any hit) and the diffuse bounces (1 per hit, closest hit) of
//! `trace::workload`, made once outside the timed loop from single-ray primary hits; the loop
//! times one stream pass of each method (traversal and intersection only), on all cores. The
//! atrium, and Sponza from its benchmark view when the shared scenes are present. Also the
//! 8-wide tree with its scalar node test (`mbvh-8-scalar-nodes`: `mbvh-8` on a CPU without
//! AVX2), to tell the AVX2 node test's share from the wider tree's.

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kdtree::Hit;
use mbvh::Mbvh8;
use trace::frame::Driven;
use trace::workload::{self, Incoherent};
use trace::{FrameTracer, Options, Structures, TileLayout};

const SIZE: u32 = 512;

fn incoherent(c: &mut Criterion) {
    let registry = baselines::registry();
    for (name, scene, tree, camera) in trace::setup::packet_workloads(SIZE) {
        let mut structures = Structures::new(&tree);
        registry.build_structures(&scene, &mut structures).expect("the scene's structures build");
        let layout = TileLayout::new(camera.width, camera.height, trace::registry::TILE_SIZE);
        let mut hits = vec![None; layout.pixel_count()];
        let (_, kdtree::NoCounters) =
            trace::frame::primary_pass(&trace::SingleRays(&tree), &layout, &camera, &mut hits);
        let diagonal = (tree.bounds().max - tree.bounds().min).length();
        let pixels = layout.tiles().iter().flat_map(|t| t.pixels());
        let rays = Incoherent::generate(&scene, &camera, pixels, &hits, diagonal, 4, workload::SEED);
        let mut g = c.benchmark_group(format!("incoherent/{name}"));
        g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
        for method in ["mono", "mft-16", "mbvh-4", "mbvh-8"] {
            let bound = registry
                .bind(&registry.select(method, Options::default()).expect("registered"), &structures)
                .expect("binds");
            let mut occluded = vec![false; rays.ao.len()];
            g.throughput(Throughput::Elements(rays.ao.len() as u64));
            g.bench_function(format!("ao/{method}"), |b| {
                b.iter(|| bound.tracer.stream_occluded(&rays.ao, &mut occluded))
            });
            let mut out: Vec<Option<Hit>> = vec![None; rays.diffuse.len()];
            g.throughput(Throughput::Elements(rays.diffuse.len() as u64));
            g.bench_function(format!("diffuse/{method}"), |b| b.iter(|| bound.tracer.stream(&rays.diffuse, &mut out)));
        }
        // The 8-wide tree with its scalar node test instead of AVX2 (what `mbvh-8` runs on a
        // CPU without AVX2): what the 256-bit node test itself is worth here.
        let bvh8 = structures.get::<Mbvh8>(trace::multibvh::MBVH8).expect("built above");
        let scalar_nodes: Box<dyn FrameTracer> = match tree.intersector() {
            kdtree::Intersector::Wald => Box::new(Driven(trace::SingleRays(bvh8.wald()))),
            kdtree::Intersector::Watertight => Box::new(Driven(trace::SingleRays(bvh8.watertight()))),
        };
        let mut occluded = vec![false; rays.ao.len()];
        g.throughput(Throughput::Elements(rays.ao.len() as u64));
        g.bench_function("ao/mbvh-8-scalar-nodes", |b| {
            b.iter(|| scalar_nodes.stream_occluded(&rays.ao, &mut occluded))
        });
        let mut out: Vec<Option<Hit>> = vec![None; rays.diffuse.len()];
        g.throughput(Throughput::Elements(rays.diffuse.len() as u64));
        g.bench_function("diffuse/mbvh-8-scalar-nodes", |b| b.iter(|| scalar_nodes.stream(&rays.diffuse, &mut out)));
        g.finish();
    }
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, incoherent);
}
criterion_main!(group::benches);
