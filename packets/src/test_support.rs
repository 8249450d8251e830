//! What the shadow-kernel tests share: a seeded generator, both intersectors' trees, random
//! triangle soups and a grid of axis-aligned quads whose planes are split planes.

use glam::Vec3;
use kdtree::triangle::Intersector;
use kdtree::{BuildConfig, KdTree};

/// A deterministic generator (xorshift).
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// A float in `[0, 1)`.
    pub(crate) fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A point of the box `lo..hi`.
    pub(crate) fn vec(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(self.next(), self.next(), self.next())
    }
}

/// The tree of the mesh for each intersector.
pub(crate) fn trees(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<KdTree> {
    [Intersector::Wald, Intersector::Watertight]
        .into_iter()
        .map(|intersector| {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            KdTree::build(positions, triangles, &config).unwrap()
        })
        .collect()
}

/// `n` random triangles of the box `lo..hi`, each within 5% of the box's size.
pub(crate) fn soup(rng: &mut Rng, n: usize, lo: Vec3, hi: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for i in 0..n as u32 {
        let c = rng.vec(lo, hi);
        let s = (hi - lo).max_element() * 0.05;
        for _ in 0..3 {
            positions.push(c + rng.vec(Vec3::splat(-s), Vec3::splat(s)));
        }
        triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    (positions, triangles)
}

/// A 6x6 grid of axis-aligned quads at heights 0, 1 and 2, so that split planes lie on the
/// quads' planes.
pub(crate) fn grid() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            let (x, z) = (i as f32, j as f32);
            let y = ((i + j) % 3) as f32;
            let base = positions.len() as u32;
            positions.extend([
                Vec3::new(x, y, z),
                Vec3::new(x + 0.8, y, z),
                Vec3::new(x + 0.8, y, z + 0.8),
                Vec3::new(x, y, z + 0.8),
            ]);
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        }
    }
    (positions, triangles)
}
