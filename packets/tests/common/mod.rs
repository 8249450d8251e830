//! Test support shared by the packet tests and, through `#[path]`, the cone tests
//! (`cones/tests/tiles.rs`) and the conformance harness's random soups
//! (`conformance/tests/ours.rs`): the oracle's rule for "the same hit", trees of built-in
//! scenes, a seeded generator and random soup vertices.
#![allow(dead_code)]

use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Hit, Intersector, KdTree, Ray};
use proptest::prelude::*;

/// `got` stands for the single ray's hit `want` by the oracle's one rule
/// ([`BruteForce::equivalent_hits`]: the same hit, a tie at the same distance, or a rounding
/// artefact on a triangle the ray cannot reach).
pub fn same_hit(tree: &KdTree, ray: &Ray, got: Option<Hit>, want: Option<Hit>) -> bool {
    got == want || BruteForce::for_tree(tree).equivalent_hits(ray, got, want)
}

/// The tree of `scene` with `intersector`.
pub fn build(scene: &scenes::Scene, intersector: Intersector) -> KdTree {
    let config = BuildConfig { intersector, ..Default::default() };
    KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).unwrap()
}

/// The arena's tree with `intersector`, and the eye of its default view: a common origin for
/// packets of rays in every direction.
pub fn arena_and_eye(intersector: Intersector) -> (KdTree, Vec3) {
    let scene = scenes::load_scene("arena").unwrap();
    (build(&scene, intersector), scene.default_view().eye)
}

/// A seeded xorshift generator of numbers in `[-1, 1]`.
pub fn signed_rng(seed: u32) -> impl FnMut() -> f32 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32 * 2.0 - 1.0
    }
}

/// A corner: on a grid of quarters (shared vertices, axis planes) or anywhere in [-1, 1].
pub fn vertex() -> impl Strategy<Value = Vec3> {
    let c = || prop_oneof![(-4i32..=4).prop_map(|k| k as f32 * 0.25), -1.0f32..1.0];
    (c(), c(), c()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}
