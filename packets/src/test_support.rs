//! What the shadow-kernel tests share: a seeded generator, both intersectors' trees, random
//! triangle soups and a grid of axis-aligned quads whose planes are split planes.

use glam::Vec3;
use kdtree::triangle::Intersector;
use kdtree::{BuildConfig, KdTree, Ray};

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

/// A scene of the packet-width tests: its name, both intersectors' trees, its box and its
/// split planes `(axis, position)`.
pub(crate) struct HardScene {
    pub(crate) name: &'static str,
    pub(crate) trees: Vec<KdTree>,
    lo: Vec3,
    hi: Vec3,
    planes: Vec<(usize, f32)>,
    triangles: usize,
}

/// The scenes the wide packets are checked on: a random soup; the grid (split planes on the
/// quads' planes); the soup at tiny (1e-30, where the watertight test's edge functions
/// underflow to exact zeros) and huge (1e18) coordinates; and the soup 1e5 from the origin.
pub(crate) fn hard_scenes() -> Vec<HardScene> {
    let mut rng = Rng(0x05ee_d0f1_a9e5);
    let (positions, triangles) = soup(&mut rng, 300, Vec3::splat(-1.0), Vec3::ONE);
    let moved = |f: &dyn Fn(Vec3) -> Vec3| positions.iter().map(|&p| f(p)).collect::<Vec<_>>();
    let (grid_positions, grid_triangles) = grid();
    [
        ("soup", positions.clone(), triangles.clone()),
        ("grid", grid_positions, grid_triangles),
        ("tiny", moved(&|p| p * 1e-30), triangles.clone()),
        ("huge", moved(&|p| p * 1e18), triangles.clone()),
        ("far", moved(&|p| p + Vec3::new(1e5, -1e5, 1e5)), triangles.clone()),
    ]
    .into_iter()
    .map(|(name, positions, triangles)| {
        let trees = trees(&positions, &triangles);
        let b = trees[0].bounds();
        let planes = trees[0].nodes().iter().filter(|n| !n.is_leaf()).map(|n| (n.axis(), n.split())).collect();
        HardScene { name, lo: b.min, hi: b.max, planes, triangles: triangles.len(), trees }
    })
    .collect()
}

impl HardScene {
    /// A packet of up to `width` rays, `kind` naming the hard case: directions (half of them
    /// at a triangle's centre, so that many hit; so in `1`, `2` and `4`) in every octant
    /// (`0`), directions with zero components of both signs (`1`), an origin on a split
    /// plane with half the rays in the plane (`2`), rays from far outside the box aimed
    /// into it, z their dominant axis (`3`), fewer rays than lanes (`4`), rays aimed at
    /// vertices and edge points (`5`). With `shared_origin` every ray starts at one point at
    /// `t_min = 0` (an omni-directional packet); otherwise each ray has its own origin and
    /// some start behind it (`t_min < 0`).
    pub(crate) fn rays(&self, rng: &mut Rng, width: usize, kind: usize, shared_origin: bool) -> Vec<Ray> {
        let size = self.hi - self.lo;
        let (lo, hi) = (self.lo - 0.2 * size, self.hi + 0.2 * size);
        let scale = size.max_element();
        let signed = |rng: &mut Rng| 2.0 * rng.next() - 1.0;
        let dir = |rng: &mut Rng| Vec3::new(signed(rng), signed(rng), signed(rng));
        let mut origin = rng.vec(lo, hi);
        let plane = self.planes[(rng.next() * self.planes.len() as f32) as usize % self.planes.len()];
        if kind == 2 {
            origin[plane.0] = plane.1;
        } else if kind == 3 {
            // Far below the box on z: every ray's dominant axis is z.
            origin = self.lo - size * Vec3::new(0.2, 0.3, 3.0);
        }
        let count = if kind == 4 { 1 + (rng.next() * (width - 1) as f32) as usize } else { width };
        (0..count)
            .map(|lane| {
                let o = if shared_origin || lane == 0 {
                    origin
                } else if kind == 2 {
                    // Other points of the same plane.
                    let mut o = rng.vec(lo, hi);
                    o[plane.0] = plane.1;
                    o
                } else {
                    origin + 0.1 * scale * dir(rng)
                };
                let tri = self.trees[0].triangle((rng.next() * self.triangles as f32) as u32 % self.triangles as u32);
                let mut d = match kind {
                    3 => rng.vec(self.lo, self.hi) - o,
                    5 => {
                        let s = rng.next();
                        [tri[0], tri[1], tri[0].lerp(tri[1], s), tri[1].lerp(tri[2], s)][lane % 4] - o
                    }
                    // Half the rays at a triangle's centre, so that many hit.
                    _ if lane % 2 == 0 => (tri[0] + tri[1] + tri[2]) / 3.0 - o,
                    _ => dir(rng) * scale,
                };
                if kind == 1 {
                    // One or two components zero, of either sign.
                    let zero = if lane % 2 == 0 { 0.0 } else { -0.0 };
                    d[lane % 3] = zero;
                    if lane % 4 == 3 {
                        d[(lane + 1) % 3] = -zero;
                    }
                }
                if kind == 2 && lane % 2 == 1 {
                    d[plane.0] = 0.0;
                }
                if d == Vec3::ZERO {
                    d = Vec3::X;
                }
                let t_min = if shared_origin || lane % 3 != 1 { 0.0 } else { -0.5 };
                let t_max = if lane % 4 == 2 { 0.25 + rng.next() } else { f32::INFINITY };
                Ray::new(o, d, t_min, t_max)
            })
            .collect()
    }
}

/// A hit as bits (`t`, `u`, `v`, triangle), so that answers compare bit for bit.
pub(crate) fn hit_bits(hit: Option<kdtree::Hit>) -> Option<[u32; 4]> {
    hit.map(|h| [h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim])
}

/// Checks a packet's closest hits and any hits against single rays: lane `l < rays.len()`
/// must be `tree.intersect(&rays[l])` bit for bit and blocked as `tree.occluded`; the lanes
/// past the rays get nothing. Returns the number of rays that hit something.
pub(crate) fn check_against_single_rays<V: crate::simd::SimdF32>(
    tree: &KdTree,
    rays: &[Ray],
    closest: &crate::PacketHit<V>,
    any: &crate::PacketHit<V>,
    what: &str,
) -> usize {
    use crate::simd::SimdMask;
    let mut hits = 0;
    for lane in 0..V::LANES {
        let (want, blocked) = match rays.get(lane) {
            Some(ray) => (tree.intersect(ray), tree.occluded(ray)),
            None => (None, false),
        };
        assert_eq!(hit_bits(closest.get(lane)), hit_bits(want), "{what}: lane {lane} {:?}", rays.get(lane));
        assert_eq!(any.found.bitmask() >> lane & 1 != 0, blocked, "{what} any hit: lane {lane} {:?}", rays.get(lane));
        hits += usize::from(blocked);
    }
    hits
}

/// Every lane of a packet's hits as bits (`t`, `u`, `v`, triangle, found), lanes without a
/// hit included.
pub(crate) fn packet_hit_bits<V: crate::simd::SimdF32>(hit: &crate::PacketHit<V>) -> Vec<[u32; 5]> {
    use crate::simd::SimdMask;
    (0..V::LANES)
        .map(|l| {
            [hit.t[l].to_bits(), hit.u[l].to_bits(), hit.v[l].to_bits(), hit.prim[l], hit.found.bitmask() >> l & 1]
        })
        .collect()
}

/// Every field of a packet as bits: the per-axis vectors lane by lane, then the intervals
/// and the valid lanes.
pub(crate) fn ray_packet_bits<V: crate::simd::SimdF32>(p: &crate::RayPacket<V>) -> Vec<u32> {
    use crate::simd::SimdMask;
    let lanes = |v: &V| (0..V::LANES).map(|l| v[l].to_bits()).collect::<Vec<_>>();
    let mut bits: Vec<u32> = p.o.iter().chain(&p.d).chain(&p.inv).chain([&p.t_min, &p.t_max]).flat_map(lanes).collect();
    bits.push(p.valid.bitmask());
    bits
}

/// Values where SSE and IEEE rules part (signed zeros, infinities, NaNs of both signs and
/// other payloads, denormals, the extremes), then random bit patterns.
pub(crate) fn specials() -> Vec<f32> {
    let mut v = vec![
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        3.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        -f32::NAN,
        f32::from_bits(0x7f80_0001),
        f32::from_bits(0xffc0_1234),
        f32::MIN_POSITIVE,
        -f32::MIN_POSITIVE,
        1e-45,
        -1e-45,
        f32::from_bits(0x0040_0000),
        f32::MAX,
        f32::MIN,
        1e-30,
        -1e30,
        -7e22,
        1e38,
        1e-38,
    ];
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..48 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        v.push(f32::from_bits((seed >> 32) as u32));
    }
    v
}
