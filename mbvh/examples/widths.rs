//! The 4-, 8- and 16-wide BVHs of one scene side by side: nodes, leaves, depth, mean
//! branching, bytes (nodes and one intersector's leaf blocks) per triangle, and build
//! milliseconds (median of interleaved rounds: 4-wide, 8-wide, 16-wide, 4-wide, ...).
//!
//! ```sh
//! cargo run --release -p mbvh --example widths -- ../shared/scenes/sponza-dabrovic.obj.gz 5
//! ```

use std::time::Instant;

use mbvh::{MultiBvh, MultiNode, Node, Node4, Node8};

/// Builds, validates and returns the stats and the build's milliseconds.
fn build<N: MultiNode>(scene: &scenes::Scene) -> (mbvh::MbvhStats, f64) {
    let start = Instant::now();
    let bvh = MultiBvh::<N>::build(&scene.mesh.positions, &scene.mesh.triangles).expect("the scene builds");
    let ms = start.elapsed().as_secs_f64() * 1e3;
    bvh.validate(&scene.mesh.positions, &scene.mesh.triangles).expect("the tree validates");
    (bvh.stats(), ms)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(spec) = args.next() else {
        eprintln!("usage: widths SCENE [ROUNDS]");
        std::process::exit(2);
    };
    let rounds: usize = match args.next().map(|r| r.parse()) {
        None => 5,
        Some(Ok(r)) if r > 0 => r,
        Some(_) => {
            eprintln!("ROUNDS: a whole number > 0");
            std::process::exit(2);
        }
    };
    let scene = match scenes::load_scene(&spec) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{spec}: {e}");
            std::process::exit(1);
        }
    };
    let (mut ms4, mut ms8, mut ms16) = (Vec::new(), Vec::new(), Vec::new());
    let (mut s4, mut s8, mut s16) = (None, None, None);
    for _ in 0..rounds {
        let (s, ms) = build::<Node4>(&scene);
        s4 = Some(s);
        ms4.push(ms);
        let (s, ms) = build::<Node8>(&scene);
        s8 = Some(s);
        ms8.push(ms);
        let (s, ms) = build::<Node<16>>(&scene);
        s16 = Some(s);
        ms16.push(ms);
    }
    let triangles = scene.mesh.triangles.len();
    println!("{}: {triangles} triangles, {rounds} interleaved builds each, medians", scene.name);
    println!();
    println!("| width | nodes | node bytes | leaves | depth | branching | bytes/triangle | build ms |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (width, s, ms, node) in
        [(4, s4, ms4, size_of::<Node4>()), (8, s8, ms8, size_of::<Node8>()), (16, s16, ms16, size_of::<Node<16>>())]
    {
        let s = s.expect("rounds > 0");
        println!(
            "| {width} | {} | {node} | {} | {} | {:.2} | {:.1} | {:.1} |",
            s.nodes,
            s.leaves,
            s.depth,
            s.branching,
            s.bytes as f64 / triangles as f64,
            median(ms)
        );
    }
}
