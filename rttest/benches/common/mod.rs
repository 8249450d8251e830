//! Shared by the packet, frustum, MFT and cone benches.

/// The criterion group `group/scene` timing one primary pass of each registered method of
/// `names` (`packet`, `frustum-8`, ...: ray generation, traversal and intersection of every
/// pixel; no shading, no shadows), on all cores, with single rays (`mono`) through the same
/// renderer as the reference.
pub fn bench_primary_methods(c: &mut criterion::Criterion, group: &str, names: &[&str]) {
    use criterion::Throughput;
    use trace::{Options, Registry, Renderer, Shadows, Structures};
    let registry = Registry::ours();
    for (name, scene, tree, camera) in trace::setup::packet_workloads(1024) {
        let structures = Structures::new(&tree);
        let mut g = c.benchmark_group(format!("{group}/{name}"));
        g.sample_size(10)
            .warm_up_time(std::time::Duration::from_secs(1))
            .measurement_time(std::time::Duration::from_secs(3));
        g.throughput(Throughput::Elements(u64::from(camera.width) * u64::from(camera.height)));
        for &method in std::iter::once(&"mono").chain(names) {
            let selected = registry.select(method, Options::default()).expect("bench methods are registered");
            let bound = registry.bind(&selected, &structures).expect("bench tile sizes are valid");
            let renderer = Renderer::new(&scene, &bound, camera, Shadows::None);
            let mut buffers = renderer.buffers();
            g.bench_function(&bound.name, |b| b.iter(|| renderer.trace(&mut buffers).hits));
        }
        g.finish();
    }
}
