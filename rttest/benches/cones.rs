//! Cone proxy traversal (thesis 4.1.6-4.1.9): primary rays at 1024x1024 with one cone and
//! with MFT cones per tile size (4 to 32) beside the single pyramid frustum of the same tile
//! and single rays, on the atrium and Sponza; and 16-sample soft shadows to a spherical light
//! of radius 1 and 2 (Sponza units, scaled to the scene) at 256x256, cone vs pyramid vs
//! single rays (Table 4.6).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use trace::{Options, Structures, TileLayout};

mod common;

fn primary(c: &mut Criterion) {
    let names: Vec<String> =
        [4, 8, 16, 32].into_iter().flat_map(|t| ["frustum", "cone", "mft-cone"].map(|m| format!("{m}-{t}"))).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    common::bench_primary_methods(c, "cones", &names);
}

fn soft_shadows(c: &mut Criterion) {
    let registry = baselines::registry();
    for (name, scene, tree, camera) in trace::setup::packet_workloads(256) {
        let structures = Structures::new(&tree);
        let layout = TileLayout::new(camera.width, camera.height, trace::registry::TILE_SIZE);
        let surfaces = trace::shade::surfaces(&scene.mesh);
        let view = trace::frame::View { layout: &layout, scene: &scene, surfaces: &surfaces, camera: &camera };
        let bind = |m: &str| registry.bind(&registry.select(m, Options::default()).expect("registered"), &structures);
        let mono = bind("mono").expect("mono binds");
        let mut hits = vec![None; layout.pixel_count()];
        mono.tracer.primary(&layout, &camera, &mut hits, None);
        let mut visible = vec![0.0; layout.pixel_count()];
        for r in [1.0, 2.0] {
            let light = trace::soft::scene_light(&scene, &tree, r);
            let mut g = c.benchmark_group(format!("cones-soft16/{name}/r{r}"));
            g.sample_size(10)
                .warm_up_time(std::time::Duration::from_secs(1))
                .measurement_time(std::time::Duration::from_secs(3));
            let rays = mono.tracer.soft(&view, &hits, &light, &mut visible, None).rays;
            g.throughput(Throughput::Elements(rays));
            // One method per soft-shadow kernel: single rays, the pyramid, the cone.
            for (kernel, method) in [("single", "mono"), ("pyramid", "packet"), ("cone", "cone")] {
                let bound = bind(method).expect("registered methods bind");
                g.bench_function(kernel, |b| {
                    b.iter(|| bound.tracer.soft(&view, &hits, &light, &mut visible, None).blocked)
                });
            }
            g.finish();
        }
    }
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, primary, soft_shadows);
}
criterion_main!(group::benches);
