//! Shared test support: triangle soups, ray generators, a spatial-median builder (a second
//! tree shape, independent of the SAH builder) and the oracle comparison.
#![allow(dead_code)]

use glam::Vec3;
use kdtree::{Aabb, BruteForce, BuildConfig, KdNode, KdTree, Ray};
use proptest::prelude::*;

/// The number of property-test cases: `PROPTEST_CASES` if set, else `default`.
pub fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

/// Compares tree and oracle on one ray (see [`BruteForce::check`]), and the SIMD leaves
/// against their scalar twin (bit for bit, any hit too).
pub fn check_ray(tree: &KdTree, oracle: &BruteForce, ray: &Ray) -> Result<(), String> {
    let (hit, twin) = (tree.intersect(ray), tree.intersect_scalar_leaves(ray));
    let bits = |h: Option<kdtree::Hit>| h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim));
    if bits(hit) != bits(twin) {
        return Err(format!("{ray:?}: SIMD leaves {hit:?}, scalar leaves {twin:?}"));
    }
    let occluded = tree.occluded(ray);
    if occluded != tree.occluded_scalar_leaves(ray) {
        return Err(format!("{ray:?}: SIMD leaves occluded {occluded}, scalar leaves not"));
    }
    oracle.check(ray, hit, occluded)
}

/// Checks every ray, reporting the first disagreement and the number of them.
pub fn check_rays(tree: &KdTree, rays: &[Ray]) -> Result<(), String> {
    let oracle = BruteForce::for_tree(tree);
    let mut first = None;
    let mut bad = 0usize;
    for ray in rays {
        if let Err(e) = check_ray(tree, &oracle, ray) {
            bad += 1;
            first.get_or_insert(e);
        }
    }
    match first {
        None => Ok(()),
        Some(e) => Err(format!("{bad} of {} rays disagree; first: {e}", rays.len())),
    }
}

/// A spatial-median kd-tree over triangle bounding boxes: splits each node box in the middle
/// of its longest axis, sends a triangle to every child whose closed box its bounding box
/// overlaps, stops at `leaf_size` triangles or depth 20.
pub fn median_tree(tris: &[[Vec3; 3]], leaf_size: usize, config: &BuildConfig) -> KdTree {
    let bounds = Aabb::from_points(&tris.iter().flatten().copied().collect::<Vec<_>>());
    let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(t)).collect();
    let mut nodes = vec![KdNode::leaf(0, 0)];
    let mut refs = Vec::new();
    let all: Vec<u32> = (0..tris.len() as u32).collect();
    let mut todo = vec![(0usize, bounds, all, 0u32)];
    while let Some((index, bx, prims, depth)) = todo.pop() {
        let axis = bx.extent().max_position();
        let split = 0.5 * (bx.min[axis] + bx.max[axis]);
        if prims.len() <= leaf_size || depth >= 20 || split <= bx.min[axis] || split >= bx.max[axis] {
            nodes[index] = KdNode::leaf(refs.len() as u32, prims.len() as u32);
            refs.extend_from_slice(&prims);
            continue;
        }
        let (mut lo, mut hi) = (bx, bx);
        lo.max[axis] = split;
        hi.min[axis] = split;
        let left = nodes.len();
        nodes.push(KdNode::leaf(0, 0));
        nodes.push(KdNode::leaf(0, 0));
        nodes[index] = KdNode::inner(axis as u32, split, left as u32);
        let l: Vec<u32> = prims.iter().copied().filter(|&p| boxes[p as usize].overlaps(&lo)).collect();
        let r: Vec<u32> = prims.iter().copied().filter(|&p| boxes[p as usize].overlaps(&hi)).collect();
        todo.push((left, lo, l, depth + 1));
        todo.push((left + 1, hi, r, depth + 1));
    }
    KdTree::from_parts(tris.to_vec(), nodes, refs, bounds, config).expect("median tree")
}

/// A vertex coordinate: either snapped to a coarse grid (so that triangles share vertices,
/// edges and axis planes, and split planes fall on them) or free.
fn coord(scale: f32) -> impl Strategy<Value = f32> {
    prop_oneof![(-4i32..=4).prop_map(move |k| k as f32 * 0.25 * scale), (-1.0f32..1.0).prop_map(move |x| x * scale),]
}

/// A vertex from [`coord`].
pub fn vertex(scale: f32) -> impl Strategy<Value = Vec3> {
    (coord(scale), coord(scale), coord(scale)).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// A triangle: three free or snapped vertices, or a small triangle around a point, or one
/// lying in an axis plane.
pub fn triangle(scale: f32) -> impl Strategy<Value = [Vec3; 3]> {
    prop_oneof![
        [vertex(scale), vertex(scale), vertex(scale)],
        (vertex(scale), vertex(0.05 * scale), vertex(0.05 * scale), vertex(0.05 * scale)).prop_map(|(c, a, b, d)| [
            c + a,
            c + b,
            c + d
        ]),
        (0usize..3, coord(scale), [vertex(scale), vertex(scale), vertex(scale)]).prop_map(|(axis, v, mut t)| {
            for p in &mut t {
                p[axis] = v;
            }
            t
        }),
    ]
}

/// A direction with some components zero (+0.0 or -0.0) or all free.
pub fn direction() -> impl Strategy<Value = Vec3> {
    let comp = prop_oneof![3 => -1.0f32..1.0, 1 => Just(0.0f32), 1 => Just(-0.0f32)];
    (comp.clone(), comp.clone(), comp).prop_filter_map("zero direction", |(x, y, z)| {
        let d = Vec3::new(x, y, z);
        (d.length_squared() > 1e-12).then_some(d)
    })
}

/// Rays for a soup: free rays, rays from snapped origins (lying in and starting on split
/// planes), rays aimed at vertices and edge midpoints, rays starting on a triangle.
pub fn rays_for(tris: &[[Vec3; 3]], scale: f32, seeds: &[(Vec3, Vec3, usize, u8)]) -> Vec<Ray> {
    let mut rays = Vec::new();
    for &(o, d, pick, kind) in seeds {
        let t = tris[pick % tris.len()];
        let (origin, dir, t_min) = match kind % 5 {
            0 => (o * 2.0, d, 0.0),
            1 => (o, d, 0.0),
            2 => (o * 2.0, t[pick % 3] - o * 2.0, 0.0),
            3 => (o * 2.0, 0.5 * (t[pick % 3] + t[(pick + 1) % 3]) - o * 2.0, 0.0),
            _ => ((t[0] + t[1] + t[2]) / 3.0, d, 0.0),
        };
        if dir.length_squared() > 0.0 && dir.is_finite() {
            rays.push(Ray::new(origin, dir, t_min, f32::INFINITY));
            rays.push(Ray::new(origin, dir, t_min, 0.5 * scale));
        }
    }
    rays
}

/// A deterministic xorshift generator for fixed seeded soups (the same triangles every run,
/// unlike proptest's).
pub struct Rng(pub u64);

impl Rng {
    /// A generator from any seed (scrambled, never zero).
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// A number in `[0, 1)`.
    pub fn f32(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A point in the unit cube.
    pub fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.f32(), self.f32(), self.f32())
    }

    /// A whole number below `n`.
    pub fn below(&mut self, n: u32) -> u32 {
        ((self.f32() * n as f32) as u32).min(n - 1)
    }

    /// `n` triangles, each made by `make` from this generator.
    pub fn triangles(&mut self, n: usize, mut make: impl FnMut(&mut Rng) -> [Vec3; 3]) -> Vec<[Vec3; 3]> {
        (0..n).map(|_| make(self)).collect()
    }
}
