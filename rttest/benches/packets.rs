//! 2x2 packet throughput (thesis 4.1.2): omni-directional packets and the standard same-sign
//! packets beside single rays, on primary rays at 1024x1024 (the atrium and Sponza) and on
//! secondary rays: the reflections of the atrium's floor tiles, a packet per 2x2 pixels
//! from the mirrored eye, whose rays mix direction signs.
//!
//! Primary rows trace one frame's primary pass (ray generation, traversal, intersection)
//! through the renderer, so the single-ray row is measured the same way. Reflection rows
//! time only the traversal of packets built beforehand.

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kdtree::{BuildConfig, KdTree, NoCounters, Ray};
use packets::{mirror, omni, samesign};

mod common;

fn packets(c: &mut Criterion) {
    common::bench_primary_methods(c, "packets", &["packet", "samesign"]);
    reflections(c);
}

/// Omni-directional against same-sign traversal on mirror reflections.
fn reflections(c: &mut Criterion) {
    let scene = scenes::load_scene("atrium").expect("atrium");
    let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).expect("tree");
    let floor = scene.mesh.materials.iter().position(|m| m.name.starts_with("floor tile")).expect("floor material");
    let is_mirror = |prim: u32| scene.mesh.material_ids[prim as usize] as usize == floor;
    let camera = scene.default_view().camera(1024, 1024).expect("camera");
    let mut packets = Vec::new();
    for y in (0..1024).step_by(2) {
        for x in (0..1024).step_by(2) {
            let dirs = [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)].map(|(px, py)| camera.pixel_ray(px, py).1);
            let hits = dirs.map(|d| tree.intersect(&Ray::new(camera.eye, d, 0.0, f32::INFINITY)));
            packets.extend(mirror::reflections(&tree, camera.eye, &dirs, &hits, is_mirror));
        }
    }
    let rays: Vec<Ray> = packets
        .iter()
        .flat_map(|p| (0..4).filter(|&l| p.rays.valid.bitmask() >> l & 1 != 0).map(|l| p.rays.ray(l)))
        .collect();
    let mixed = packets.iter().filter(|p| samesign::sign_groups(&p.rays).count() > 1).count();
    eprintln!("reflections: {} packets, {} rays, {} packets with mixed signs", packets.len(), rays.len(), mixed);
    let mut g = c.benchmark_group("packets/atrium-reflections");
    g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("mono", |b| b.iter(|| rays.iter().filter(|r| tree.intersect(r).is_some()).count()));
    g.bench_function("packet-omni", |b| {
        b.iter(|| packets.iter().map(|p| omni::intersect(&tree, p, &mut NoCounters).found.bitmask()).sum::<u32>())
    });
    g.bench_function("packet-samesign", |b| {
        b.iter(|| {
            packets.iter().map(|p| samesign::intersect(&tree, &p.rays, &mut NoCounters).found.bitmask()).sum::<u32>()
        })
    });
    g.finish();
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, packets);
}
criterion_main!(group::benches);
