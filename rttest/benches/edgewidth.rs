//! Criterion bench `edgewidth` (thesis chapter 5, Table 5.1): one whole frame of atrium (and
//! Sponza when present) at 256x256 for hard shadows, single-ray and packet edge widths,
//! silhouette widths (`edgewidth::silhouette`), convolved edge widths
//! (`edgewidth::convolution`), 4 samples, and the interleaved 16 samples with their filter. Scene,
//! tree and camera are made outside the timed loop; each iteration renders one whole frame
//! (primary rays, visibility, shading), as Table 5.1 counts it.

use criterion::{Criterion, criterion_group, criterion_main};
use edgewidth::AreaLight;
use experiments::shadows::{ShadowMethod, ShadowSetup};
use kdtree::{BuildConfig, KdTree};

fn frames(c: &mut Criterion) {
    let mut specs = vec!["atrium".to_string()];
    if let Some(p) = trace::setup::sponza_path() {
        specs.push(p.display().to_string());
    }
    for spec in specs {
        let scene = scenes::load_scene(&spec).expect("scene loads");
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).expect("tree");
        let camera = scene.default_view().camera(256, 256).expect("camera");
        let setup = ShadowSetup::new(&scene, &tree, camera, AreaLight::Rect(scene.area_light)).expect("setup");
        let mut group = c.benchmark_group(format!("edgewidth/{}", scene.name));
        group.sample_size(10);
        for method in [
            ShadowMethod::Hard,
            ShadowMethod::EdgeWidth,
            ShadowMethod::EdgeWidthPacket,
            ShadowMethod::Silhouette,
            ShadowMethod::Convolution,
            ShadowMethod::Sampled(4),
            ShadowMethod::Interleaved,
        ] {
            group.bench_function(method.name(), |b| b.iter(|| setup.frame(method).shadow_rays));
        }
        group.finish();
    }
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, frames);
}
criterion_main!(group::benches);
