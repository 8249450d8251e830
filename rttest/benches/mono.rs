//! Single-ray ("mono") traversal throughput: primary closest-hit rays/s and shadow any-hit
//! rays/s at 1024x1024, on the atrium and, when the shared scenes are present, on Sponza from
//! its benchmark view (eye (-10, 3, 0), target (0, 4, 0), fovy 70).
//!
//! Scenes, trees and rays are made outside the timed loop ([`trace::setup::Workload`]); the
//! loop times only the queries, on all cores.

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use kdtree::BuildConfig;
use scenes::Camera;
use trace::setup::{self as harness, Workload};

const SIZE: u32 = 1024;

fn bench_workload(c: &mut Criterion, name: &str, work: &Workload) {
    let mut group = c.benchmark_group(format!("mono/{name}"));
    group.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(4));
    group.throughput(Throughput::Elements(work.primary.len() as u64));
    group.bench_function("primary", |b| b.iter(|| harness::trace_closest(&work.tree, &work.primary)));
    group.throughput(Throughput::Elements(work.shadow.len() as u64));
    group.bench_function("shadow", |b| b.iter(|| harness::trace_any(&work.tree, &work.shadow)));
    group.finish();
}

fn mono(c: &mut Criterion) {
    let atrium = Workload::new("atrium", None, SIZE, SIZE).expect("atrium");
    bench_workload(c, "atrium", &atrium);
    drop(atrium);
    match harness::sponza_path() {
        Some(path) => {
            // The Embree comparison view, spelled out rather than trusted to the view name.
            let (scene, tree, _) =
                harness::load_and_build(&path.to_string_lossy(), &BuildConfig::default()).expect("sponza");
            let camera = Camera::look_at(Vec3::new(-10.0, 3.0, 0.0), Vec3::new(0.0, 4.0, 0.0), 70.0, SIZE, SIZE)
                .expect("sponza camera");
            let sponza = Workload::with_camera(scene, tree, camera);
            bench_workload(c, "sponza", &sponza);
        }
        None => eprintln!("mono/sponza: skipped, no shared scenes folder"),
    }
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, mono);
}
criterion_main!(group::benches);
