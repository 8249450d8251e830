//! Shared by the packet, frustum, MFT, cone and shadow benches.

/// The criterion group `group/scene` timing one primary pass of each registered method of
/// `names` (`packet`, `frustum-8`, ...: ray generation, traversal and intersection of every
/// pixel; no shading, no shadows), on all cores, with single rays (`mono`) through the same
/// renderer as the reference.
#[allow(dead_code)] // Each bench compiles this module; not every bench calls this.
pub fn bench_primary_methods(c: &mut criterion::Criterion, group: &str, names: &[&str]) {
    use criterion::Throughput;
    use trace::{Options, Renderer, Shadows, Structures};
    let registry = baselines::registry();
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

/// The criterion groups `group-hard/scene` and `group-soft16/scene` timing one hard-shadow
/// pass and one 16-sample soft-shadow pass (light radius 1 in Sponza units) of each
/// registered method of `methods` with its soft-shadow grouping (a per-point one is timed on
/// soft shadows only, as `NAME per-point`), from the same primary hits (made once by single
/// rays), on all cores, with single rays (`mono`) as the reference.
#[allow(dead_code)] // Each bench compiles this module; not every bench calls this.
pub fn bench_shadow_methods(c: &mut criterion::Criterion, group: &str, methods: &[(&str, trace::SoftGrouping)]) {
    use criterion::Throughput;
    use trace::frame::View;
    use trace::{Options, Structures, TileLayout, soft};
    let registry = baselines::registry();
    for (name, scene, tree, camera) in trace::setup::packet_workloads(1024) {
        let structures = Structures::new(&tree);
        let layout = TileLayout::new(camera.width, camera.height, trace::registry::TILE_SIZE);
        let mono =
            registry.bind(&registry.select("mono", Options::default()).expect("mono"), &structures).expect("mono");
        let mut hits = vec![None; layout.pixel_count()];
        mono.tracer.primary(&layout, &camera, &mut hits, None);
        let light = soft::scene_light(&scene, &tree, 1.0);
        let surfaces = trace::shade::surfaces(&scene.mesh);
        let view = View { layout: &layout, scene: &scene, surfaces: &surfaces, camera: &camera };
        let mut occluded = vec![false; layout.pixel_count()];
        let mut visible = vec![0.0f32; layout.pixel_count()];
        let (rays, _) = mono.tracer.shadow(&view, &hits, &mut occluded, None);
        let soft_rays = mono.tracer.soft(&view, &hits, &light, &mut visible, None).rays;
        for (kind, elements) in [("hard", rays), ("soft16", soft_rays)] {
            let mut g = c.benchmark_group(format!("{group}-{kind}/{name}"));
            g.sample_size(10)
                .warm_up_time(std::time::Duration::from_secs(1))
                .measurement_time(std::time::Duration::from_secs(3));
            g.throughput(Throughput::Elements(elements));
            // The rays alone, made as every method makes them and not traced: the part of
            // each pass below that no kernel can save.
            g.bench_function("rays-only", |b| b.iter(|| make_rays(&view, &hits, &light, kind == "hard")));
            for &(method, soft) in std::iter::once(&("mono", trace::SoftGrouping::Strata)).chain(methods) {
                // Per-point soft shadows are soft-shadow kernels only.
                if kind == "hard" && soft == trace::SoftGrouping::PerPoint {
                    continue;
                }
                let options = Options { soft, ..Options::default() };
                let selected = registry.select(method, options).expect("bench methods are registered");
                let bound = registry.bind(&selected, &structures).expect("bench tile sizes are valid");
                let layout = TileLayout::new(camera.width, camera.height, bound.options.tile);
                // The hits in this method's tile order.
                let mut method_hits = vec![None; layout.pixel_count()];
                mono.tracer.primary(&layout, &camera, &mut method_hits, None);
                let view = View { layout: &layout, ..view };
                let id = match soft {
                    trace::SoftGrouping::PerPoint => format!("{} per-point", bound.name),
                    trace::SoftGrouping::Strata => bound.name.clone(),
                };
                g.bench_function(&id, |b| match kind {
                    "hard" => b.iter(|| bound.tracer.shadow(&view, &method_hits, &mut occluded, None)),
                    _ => b.iter(|| bound.tracer.soft(&view, &method_hits, &light, &mut visible, None)),
                });
            }
            g.finish();
        }
    }
}

/// The shadow rays of every lit hit of `hits` (tile order of `view.layout`), made in
/// parallel over tiles as the frame driver does (`ShadowJob::segments`, a row's directions in
/// SIMD lanes, for hard shadows, `SoftJob::point` for soft ones) and not traced: how many
/// there are.
#[allow(dead_code)] // Each bench compiles this module; not every bench calls this.
pub fn make_rays(
    view: &trace::frame::View<'_>,
    hits: &[Option<kdtree::Hit>],
    light: &scenes::SphereLight,
    hard: bool,
) -> u64 {
    use rayon::prelude::*;
    use trace::{ShadowJob, SoftJob};
    let chunks = view.layout.chunks(hits);
    view.layout
        .tiles()
        .par_iter()
        .zip(chunks)
        .map(|(tile, hits)| {
            let job = ShadowJob { scene: view.scene, surfaces: view.surfaces, camera: view.camera, tile, hits };
            if hard {
                let mut segments = Vec::new();
                job.segments(&mut segments);
                let rays = segments.iter().flatten().map(|&(start, end)| kdtree::Ray::segment(start, end));
                rays.map(std::hint::black_box).count() as u64
            } else {
                let soft = SoftJob { hits: job, light };
                (0..hits.len()).filter_map(|i| soft.point(i)).map(std::hint::black_box).count() as u64 * 16
            }
        })
        .sum()
}
