//! Shared by the packet, frustum and MFT benches.

/// The criterion group `group/scene` timing one primary pass of each `(method, tile)` of
/// `configs` (ray generation, traversal and intersection of every pixel; no shading, no
/// shadows), on all cores, with single rays through the same renderer as the reference.
pub fn bench_primary_methods(c: &mut criterion::Criterion, group: &str, configs: &[(bench::render::Method, u32)]) {
    use criterion::Throughput;
    for (name, scene, tree, camera) in bench::harness::packet_workloads(1024) {
        let mut g = c.benchmark_group(format!("{group}/{name}"));
        g.sample_size(10)
            .warm_up_time(std::time::Duration::from_secs(1))
            .measurement_time(std::time::Duration::from_secs(3));
        g.throughput(Throughput::Elements(u64::from(camera.width) * u64::from(camera.height)));
        let mono = [(bench::render::Method::Mono, bench::render::TILE_SIZE)];
        for &(method, tile) in mono.iter().chain(configs) {
            let renderer = bench::render::Renderer::new(&scene, &tree, camera, method, bench::render::Shadows::None)
                .with_tile(tile)
                .expect("bench tile sizes are valid");
            let mut buffers = renderer.buffers();
            g.bench_function(format!("{}-{tile}", method.name()), |b| b.iter(|| renderer.trace(&mut buffers).hits));
        }
        g.finish();
    }
}
