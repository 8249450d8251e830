//! Property tests of the build over seeded random soups: every tree validates (structure,
//! split positions, depth, completeness), whatever the sizes, scales and degenerate
//! configurations; and the tree is bit-identical across thread counts.

mod common;

use common::Rng;
use glam::Vec3;
use kdtree::{BuildConfig, BuildStrategy, KdTree};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

/// A soup of `n` triangles in the unit cube times `scale`, mixing: small random triangles,
/// axis-aligned triangles on a few common planes (x = 0.5, y = 0.25, z = 0.75 and the cube
/// faces), exact duplicates, faces of grid cells that touch each other, and, `big` times in
/// a thousand, large random triangles and long slivers crossing the whole cube.
fn soup(seed: u64, n: usize, scale: f32, big: u32) -> Vec<[Vec3; 3]> {
    let mut r = Rng::new(seed);
    let planes = [0.0, 0.25, 0.5, 0.75, 1.0];
    let mut tris: Vec<[Vec3; 3]> = Vec::with_capacity(n);
    while tris.len() < n {
        let kind = match r.below(1000) {
            x if x < big / 2 => 1,
            x if x < big => 5,
            x => [0, 0, 2, 3, 4][(x % 5) as usize],
        };
        let t = match kind {
            0 => {
                let c = r.vec3();
                let s = 0.001 + 0.05 * r.f32();
                [c, c + (r.vec3() - 0.5) * s, c + (r.vec3() - 0.5) * s]
            }
            1 => [r.vec3(), r.vec3(), r.vec3()],
            2 => {
                // Lies in an axis plane shared with many others.
                let axis = r.below(3) as usize;
                let p = planes[r.below(5) as usize];
                let mut t = [r.vec3(), r.vec3(), r.vec3()];
                let s = 0.02 + 0.3 * r.f32();
                let c = t[0];
                for v in &mut t[1..] {
                    *v = c + (*v - 0.5) * s;
                }
                for v in &mut t {
                    v[axis] = p;
                }
                t
            }
            3 if !tris.is_empty() => tris[r.below(tris.len() as u32) as usize],
            4 => {
                // A face of a grid cell: boxes touching their neighbours.
                let g = 4.0;
                let (i, j, k) = (r.below(4) as f32 / g, r.below(4) as f32 / g, r.below(4) as f32 / g);
                let (a, b, c) = (Vec3::new(i, j, k), Vec3::new(1.0 / g, 0.0, 0.0), Vec3::new(0.0, 1.0 / g, 0.0));
                if r.below(2) == 0 { [a, a + b, a + c] } else { [a + b + c, a + c, a + b] }
            }
            _ => {
                // Long thin slivers crossing the whole cube.
                let a = r.vec3();
                let d = r.vec3() - 0.5;
                [a - d * 2.0, a + d * 2.0, a + d * 2.0 + r.vec3() * 0.01]
            }
        };
        tris.push(t);
    }
    tris.iter().map(|t| t.map(|p| p * scale)).collect()
}

fn check(tris: &[[Vec3; 3]], config: &BuildConfig) -> KdTree {
    let tree = KdTree::build_soup(tris, config).expect("build");
    if let Err(e) = tree.validate() {
        panic!("invalid tree ({} triangles, {config:?}): {e}", tris.len());
    }
    let s = tree.stats();
    assert!(s.sah_cost.is_finite(), "{s:?}");
    assert!(s.depth <= config.depth_limit(s.triangles_in_tree.max(1)) as usize, "{s:?}");
    tree
}

/// The exact build, and binned builds with binned nodes at these soups' sizes (a few bins,
/// down to a few triangles; Mitsuba's 128 bins) and the default.
const STRATEGIES: [BuildStrategy; 4] = [
    BuildStrategy::Exact,
    BuildStrategy::Binned { bins: 4, min_tris: 4 },
    BuildStrategy::Binned { bins: 128, min_tris: 64 },
    BuildStrategy::BINNED,
];

fn config() -> Config {
    Config { cases: 48, rng_seed: RngSeed::Fixed(0x6b64_7472), failure_persistence: None, ..Config::default() }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn random_soups_validate(
        seed in any::<u64>(),
        n in 1usize..600,
        scale in prop::sample::select(vec![1.0f32, 1e30, 1e-12, 3e5, 1e37]),
        c_isect in prop::sample::select(vec![1.0f32, 5.0, 80.0]),
        empty_bonus in prop::sample::select(vec![0.0f32, 0.5, 0.9]),
        strategy in prop::sample::select(STRATEGIES.to_vec()),
        leaf_width in prop::sample::select(vec![1u32, 4, 8]),
        max_bad_refines in prop::sample::select(vec![0u32, 0, 3]),
        collapse in any::<bool>(),
    ) {
        let tris = soup(seed, n, scale, 100);
        let config =
            BuildConfig { c_isect, empty_bonus, strategy, leaf_width, max_bad_refines, collapse, ..BuildConfig::default() };
        check(&tris, &config);
    }
}

#[test]
fn larger_soups_validate() {
    for strategy in [BuildStrategy::Exact, BuildStrategy::BINNED] {
        let config = BuildConfig { strategy, ..BuildConfig::default() };
        for (seed, n) in [(1u64, 5_000usize), (2, 20_000)] {
            check(&soup(seed, n, 1.0, 5), &config);
        }
        // Offset far from the origin: small extents relative to the coordinates.
        let tris: Vec<_> = soup(3, 3000, 1.0, 20).iter().map(|t| t.map(|p| p + Vec3::splat(1e4))).collect();
        check(&tris, &config);
    }
}

/// The binned build's SAH cost stays near the exact build's on a soup (the measured figures
/// on the real scenes are in `docs/results/build-and-large-scenes.md`).
#[test]
fn binned_trees_cost_about_the_exact_ones() {
    let tris = soup(7, 20_000, 1.0, 5);
    let cost = |strategy| check(&tris, &BuildConfig { strategy, ..BuildConfig::default() }).stats().sah_cost;
    let (exact, binned) = (cost(BuildStrategy::Exact), cost(BuildStrategy::BINNED));
    assert!(binned != exact, "the binned build changes the tree: {binned} vs {exact}");
    assert!((binned / exact - 1.0).abs() < 0.05, "binned {binned} vs exact {exact}");
}

#[test]
fn identical_across_thread_counts() {
    for strategy in [BuildStrategy::Exact, BuildStrategy::BINNED, BuildStrategy::Binned { bins: 32, min_tris: 200 }] {
        identical_across_thread_counts_with(strategy);
    }
}

fn identical_across_thread_counts_with(strategy: BuildStrategy) {
    let tris = soup(42, 40_000, 1.0, 3);
    let config = BuildConfig { strategy, ..BuildConfig::default() };
    let build = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| KdTree::build_soup(&tris, &config).unwrap())
    };
    let reference = build(1);
    reference.validate().unwrap();
    let bytes = reference.layout_bytes();
    for threads in [2, 4, 3] {
        assert!(build(threads).layout_bytes() == bytes, "{strategy:?}: tree differs with {threads} threads");
    }
    // And with the global pool, twice.
    assert!(KdTree::build_soup(&tris, &config).unwrap().layout_bytes() == bytes);
    assert!(KdTree::build_soup(&tris, &config).unwrap().layout_bytes() == bytes);
}
