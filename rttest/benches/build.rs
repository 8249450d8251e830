//! Build-time benches: every built-in scene, Sponza when the shared scenes are present, and
//! the atrium refined to 1, 2, 4 and 8 times its triangles (how the build scales with N),
//! with the default build; and the atrium and Sponza with each build strategy (exact and
//! binned, `build-strategy`).
//!
//! Scenes are loaded outside the timed loop; only `KdTree::build` is timed. Few samples and
//! short measurement times keep the whole suite at a few minutes on two cores.

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use kdtree::{BuildConfig, BuildStrategy, KdTree};
use scenes::Mesh;
use trace::setup as harness;

fn bench_mesh(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    id: BenchmarkId,
    mesh: &Mesh,
    config: &BuildConfig,
) {
    group.throughput(Throughput::Elements(mesh.triangle_count() as u64));
    group.bench_with_input(id, mesh, |b, mesh| {
        b.iter(|| KdTree::build(&mesh.positions, &mesh.triangles, config).expect("build"))
    });
}

fn builtin_scenes(c: &mut Criterion) {
    let mut group = c.benchmark_group("build");
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2));
    for name in scenes::builtin::NAMES.iter().filter(|n| !scenes::builtin::MATERIAL_VARIANTS.contains(n)) {
        let scene = scenes::load_scene(name).expect("built-in scene");
        bench_mesh(&mut group, BenchmarkId::from_parameter(name), &scene.mesh, &BuildConfig::default());
    }
    match harness::sponza_path() {
        Some(path) => {
            let scene = scenes::load_scene(&path.to_string_lossy()).expect("sponza");
            group.measurement_time(Duration::from_secs(10));
            bench_mesh(&mut group, BenchmarkId::from_parameter("sponza"), &scene.mesh, &BuildConfig::default());
        }
        None => eprintln!("build/sponza: skipped, no shared scenes folder"),
    }
    group.finish();
}

fn scaling(c: &mut Criterion) {
    let mut group = c.benchmark_group("build-scaling");
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    let atrium = scenes::load_scene("atrium").expect("atrium");
    for doublings in 0..=3 {
        let mesh = harness::refined(&atrium.mesh, doublings);
        let id = BenchmarkId::new("atrium", format!("{}N-{}", 1 << doublings, mesh.triangle_count()));
        bench_mesh(&mut group, id, &mesh, &BuildConfig::default());
    }
    group.finish();
}

/// The exact and the binned build (`BuildStrategy`) on the atrium and, when present, Sponza.
fn strategies(c: &mut Criterion) {
    let mut group = c.benchmark_group("build-strategy");
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    let mut meshes = vec![("atrium", scenes::load_scene("atrium").expect("atrium").mesh)];
    match harness::sponza_path() {
        Some(path) => meshes.push(("sponza", scenes::load_scene(&path.to_string_lossy()).expect("sponza").mesh)),
        None => eprintln!("build-strategy/sponza: skipped, no shared scenes folder"),
    }
    for (name, mesh) in &meshes {
        for strategy in [BuildStrategy::Exact, BuildStrategy::BINNED] {
            let config = BuildConfig { strategy, ..BuildConfig::default() };
            bench_mesh(&mut group, BenchmarkId::new(*name, strategy.name()), mesh, &config);
        }
    }
    group.finish();
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, builtin_scenes, scaling, strategies);
}
criterion_main!(group::benches);
