//! Cone proxy traversal (thesis 4.1.6-4.1.9): primary rays at 1024x1024 with one cone and
//! with MFT cones per tile size (4 to 32) beside the single pyramid frustum of the same tile
//! and single rays, on the atrium and Sponza; and 16-sample soft shadows to a spherical light
//! of radius 1 and 2 (Sponza units, scaled to the scene) at 256x256, cone vs pyramid vs
//! single rays (Table 4.6).

use bench::render::Method;
use bench::soft::{primary_hits, scaled_radius, soft_shadow_pass};
use cones::ShadowMethod;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kdtree::NoCounters;
use scenes::SphereLight;

mod common;

fn primary(c: &mut Criterion) {
    let mut configs: Vec<(Method, u32)> = Vec::new();
    for t in [4, 8, 16, 32] {
        configs.extend([(Method::Frustum, t), (Method::Cone, t), (Method::MftCone, t)]);
    }
    common::bench_primary_methods(c, "cones", &configs);
}

fn soft_shadows(c: &mut Criterion) {
    for (name, scene, tree, camera) in bench::harness::packet_workloads(256) {
        let hits = primary_hits(&scene, &tree, &camera);
        let diag = (tree.bounds().max - tree.bounds().min).length();
        for r in [1.0, 2.0] {
            let light = SphereLight {
                center: scene.point_light.position,
                radius: scaled_radius(r, diag),
                intensity: glam::Vec3::ONE,
            };
            let mut g = c.benchmark_group(format!("cones-soft16/{name}/r{r}"));
            g.sample_size(10)
                .warm_up_time(std::time::Duration::from_secs(1))
                .measurement_time(std::time::Duration::from_secs(3));
            let rays = soft_shadow_pass::<NoCounters>(&scene, &tree, &camera, &hits, &light, ShadowMethod::Single).rays;
            g.throughput(Throughput::Elements(rays));
            for m in ShadowMethod::ALL {
                g.bench_function(m.name(), |b| {
                    b.iter(|| soft_shadow_pass::<NoCounters>(&scene, &tree, &camera, &hits, &light, m).blocked)
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
