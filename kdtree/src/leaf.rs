//! SIMD leaves: each leaf's triangles stored inline, in leaf order, as precomputed records in
//! groups of four laid out structure-of-arrays, and tested four at a time against one ray.
//!
//! Single-ray traversal ([`crate::traverse`]) reads only these groups at a leaf: it never
//! touches the reference array nor the per-triangle records, so a leaf costs one contiguous
//! read of `ceil(n / 4)` groups instead of `n` dependent loads. The layout (see
//! [`crate::tree`]): every non-empty leaf's references start at a multiple of 4 in the tree's
//! reference array (the gaps hold [`GAP`]), and group `g` holds references `4g .. 4g + 4`.
//!
//! Each lane computes exactly what the scalar test of [`crate::triangle`] computes, with the
//! same operations in the same order (Rust never fuses a multiply and an add on its own, and
//! SSE's `mulps`, `addps`, `subps` and `divps` round each lane as `mulss` and friends do), so
//! a group's answer is bit for bit the scalar loop's, ties included: the closest lane wins,
//! and of equal distances the later one, as the scalar loop's `t <= t_hit` takes the later of
//! two equal hits. Padding lanes hold NaN records, which never hit.
//!
//! Four lanes, not eight: this CPU (Zen 1) runs 256-bit AVX2 as two 128-bit halves, and the
//! trees' leaves hold 2-5 triangles on average (`rttest sah-sweep`), so an 8-wide group would
//! mostly test padding. glam's `Vec4` is SSE2 on x86-64 (part of the baseline, no run-time
//! detection needed) and scalar elsewhere, which is this module's scalar twin; the
//! per-triangle tests of [`crate::triangle`] stay the reference that the tests below and the
//! oracle compare against.

use glam::{BVec4A, Vec3, Vec4};

use crate::Ray;
use crate::triangle::{ShearedRay, TriangleTest, WaldTriangle, WatertightTriangle};

/// The value of the reference array's gaps (padding before a leaf's first reference).
pub const GAP: u32 = u32::MAX;

/// Triangles per group.
pub const LANES: usize = 4;

/// A group of four triangles' records, tested against one ray at a time.
pub trait LeafGroup: Copy + Send + Sync + std::fmt::Debug {
    /// The per-triangle record the group is made of.
    type Record: TriangleTest;
    /// What the test precomputes once per ray.
    type RayData: Copy;
    /// The group of `records` (at most [`LANES`]; missing lanes are padding that never hits).
    fn new(records: &[Self::Record]) -> Self;
    /// The per-ray precomputation.
    fn prepare(ray: &Ray) -> Self::RayData;
    /// The lanes that hit in `[ray.t_min, t_max]`, with their `t`, `u` and `v`.
    fn intersect(&self, ray: &Ray, data: &Self::RayData, t_max: f32) -> GroupHits;
    /// Every field's bits, lane by lane (to compare groups exactly, NaN padding included).
    fn bits(&self) -> Vec<u32>;
    /// The record of lane `lane` (NaN for a padding lane), for scalar twins and checks.
    fn lane(&self, lane: usize) -> Self::Record;
}

/// The bits of the lanes of `fields`, in order.
fn lane_bits(fields: &[Vec4]) -> Vec<u32> {
    fields.iter().flat_map(|f| f.to_array().map(f32::to_bits)).collect()
}

/// The hits of one group: the lanes that hit and each lane's `t`, `u`, `v` (meaningless in
/// lanes that missed).
#[derive(Clone, Copy, Debug)]
pub struct GroupHits {
    /// Lanes that hit.
    pub mask: BVec4A,
    /// Hit distances.
    pub t: Vec4,
    /// Barycentric weights of the second vertices.
    pub u: Vec4,
    /// Barycentric weights of the third vertices.
    pub v: Vec4,
}

impl GroupHits {
    /// The lane the scalar loop would keep: the smallest `t`, the last lane among equal ones;
    /// `None` if no lane hit.
    #[inline(always)]
    pub fn closest(&self) -> Option<usize> {
        let bits = self.mask.bitmask();
        if bits == 0 {
            return None;
        }
        let t = Vec4::select(self.mask, self.t, Vec4::INFINITY);
        let min = t.min_element();
        let at_min = self.mask & t.cmpeq(Vec4::splat(min));
        Some(31 - at_min.bitmask().leading_zeros() as usize)
    }
}

/// Wald records of four triangles (thesis 4.2), structure-of-arrays: lane `i` of each field
/// is triangle `i`'s [`WaldTriangle`] field. The projection axis `k` differs per lane, so
/// the ray's `o[k]`, `o[u]`, `o[v]` (and `d`) are picked per lane by two selects each.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Wald4 {
    /// The projection axis `k` of each lane as a float (0, 1 or 2).
    pub k: Vec4,
    /// `n_u / n_k`.
    pub n_u: Vec4,
    /// `n_v / n_k`.
    pub n_v: Vec4,
    /// Vertex `a`'s `k` coordinate.
    pub a_k: Vec4,
    /// Vertex `a`'s `u` coordinate.
    pub a_u: Vec4,
    /// Vertex `a`'s `v` coordinate.
    pub a_v: Vec4,
    /// Second barycentric, `u` coefficient.
    pub b_nu: Vec4,
    /// Second barycentric, `v` coefficient.
    pub b_nv: Vec4,
    /// Third barycentric, `u` coefficient.
    pub c_nu: Vec4,
    /// Third barycentric, `v` coefficient.
    pub c_nv: Vec4,
}

const _: () = assert!(std::mem::size_of::<Wald4>() == 160);

/// A ray's origin and direction, each component splatted over four lanes.
#[derive(Clone, Copy, Debug)]
pub struct SplatRay {
    /// `o.x`, `o.y`, `o.z` in all lanes.
    pub o: [Vec4; 3],
    /// `d.x`, `d.y`, `d.z` in all lanes.
    pub d: [Vec4; 3],
    /// `t_min` in all lanes.
    pub t_min: Vec4,
}

impl SplatRay {
    /// The splats of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> SplatRay {
        let (o, d) = (ray.origin, ray.dir);
        SplatRay {
            o: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            d: [Vec4::splat(d.x), Vec4::splat(d.y), Vec4::splat(d.z)],
            t_min: Vec4::splat(ray.t_min),
        }
    }
}

impl LeafGroup for Wald4 {
    type Record = WaldTriangle;
    type RayData = SplatRay;

    fn new(records: &[WaldTriangle]) -> Wald4 {
        let lane = |i: usize| records.get(i).copied();
        let field = |f: fn(&WaldTriangle) -> f32| {
            Vec4::from_array(std::array::from_fn(|i| lane(i).map_or(f32::NAN, |r| f(&r))))
        };
        Wald4 {
            k: field(|r| r.axes().0 as f32),
            n_u: field(|r| r.n_u),
            n_v: field(|r| r.n_v),
            a_k: field(|r| r.a_k),
            a_u: field(|r| r.a_u),
            a_v: field(|r| r.a_v),
            b_nu: field(|r| r.b_nu),
            b_nv: field(|r| r.b_nv),
            c_nu: field(|r| r.c_nu),
            c_nv: field(|r| r.c_nv),
        }
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> SplatRay {
        SplatRay::new(ray)
    }

    #[inline(always)]
    fn intersect(&self, _ray: &Ray, r: &SplatRay, t_max: f32) -> GroupHits {
        // Lane masks of k = 0 and k = 1 (else 2); u = k + 1 and v = k + 2 (mod 3).
        let k0 = self.k.cmpeq(Vec4::ZERO);
        let k1 = self.k.cmpeq(Vec4::ONE);
        let pick = |c: &[Vec4; 3], a: usize, b: usize, e: usize| Vec4::select(k0, c[a], Vec4::select(k1, c[b], c[e]));
        let (ok, ou, ov) = (pick(&r.o, 0, 1, 2), pick(&r.o, 1, 2, 0), pick(&r.o, 2, 0, 1));
        let (dk, du, dv) = (pick(&r.d, 0, 1, 2), pick(&r.d, 1, 2, 0), pick(&r.d, 2, 0, 1));
        // As the scalar test (`WaldTriangle::intersect`), operation for operation.
        let denom = dk + self.n_u * du + self.n_v * dv;
        let (ak, au, av) = (self.a_k - ok, self.a_u - ou, self.a_v - ov);
        let t = (ak + self.n_u * au + self.n_v * av) / denom;
        let in_range = t.cmpge(r.t_min) & t.cmple(Vec4::splat(t_max)) & t.cmplt(Vec4::INFINITY);
        let hu = t * du - au;
        let hv = t * dv - av;
        let beta = self.b_nu * hu + self.b_nv * hv;
        let gamma = self.c_nu * hu + self.c_nv * hv;
        let inside = beta.cmpge(Vec4::ZERO) & gamma.cmpge(Vec4::ZERO) & (beta + gamma).cmple(Vec4::ONE);
        GroupHits { mask: in_range & inside, t, u: beta, v: gamma }
    }

    fn lane(&self, i: usize) -> WaldTriangle {
        let f = |v: Vec4| v.to_array()[i];
        WaldTriangle {
            // A padding lane's NaN `k` becomes axis 0; its NaN fields never hit.
            kuv: crate::triangle::pack_axes(f(self.k) as usize % 3),
            n_u: f(self.n_u),
            n_v: f(self.n_v),
            a_k: f(self.a_k),
            a_u: f(self.a_u),
            a_v: f(self.a_v),
            b_nu: f(self.b_nu),
            b_nv: f(self.b_nv),
            c_nu: f(self.c_nu),
            c_nv: f(self.c_nv),
        }
    }

    fn bits(&self) -> Vec<u32> {
        lane_bits(&[
            self.k, self.n_u, self.n_v, self.a_k, self.a_u, self.a_v, self.b_nu, self.b_nv, self.c_nu, self.c_nv,
        ])
    }
}

/// Watertight records of four triangles (Woop, Benthin & Wald 2013), structure-of-arrays:
/// the three vertices' coordinates, lane `i` triangle `i`.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Watertight4 {
    /// `[a.x, a.y, a.z]`, `[b.x, ...]`, `[c.x, ...]`, each over the four lanes.
    pub v: [[Vec4; 3]; 3],
}

const _: () = assert!(std::mem::size_of::<Watertight4>() == 144);

/// The watertight test's per-ray data for a group: the shear and the origin's splats.
#[derive(Clone, Copy, Debug)]
pub struct ShearedSplat {
    /// The scalar shear (axes `kx`, `ky`, `kz` below 4, and `sx`, `sy`, `sz`).
    pub shear: ShearedRay,
    /// `o.x`, `o.y`, `o.z` in all lanes.
    pub o: [Vec4; 3],
    /// `t_min` in all lanes.
    pub t_min: Vec4,
}

impl LeafGroup for Watertight4 {
    type Record = WatertightTriangle;
    type RayData = ShearedSplat;

    fn new(records: &[WatertightTriangle]) -> Watertight4 {
        let coord = |vertex: usize, axis: usize| {
            Vec4::from_array(std::array::from_fn(|i| records.get(i).map_or(f32::NAN, |r| r.v[vertex][axis])))
        };
        Watertight4 { v: std::array::from_fn(|vertex| std::array::from_fn(|axis| coord(vertex, axis))) }
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> ShearedSplat {
        let s = WatertightTriangle::prepare(ray);
        let o = ray.origin;
        ShearedSplat {
            shear: ShearedRay { kx: s.kx & 3, ky: s.ky & 3, kz: s.kz & 3, ..s },
            o: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            t_min: Vec4::splat(ray.t_min),
        }
    }

    #[inline(always)]
    fn intersect(&self, ray: &Ray, r: &ShearedSplat, t_max: f32) -> GroupHits {
        let s = &r.shear;
        let (kx, ky, kz) = (s.kx.min(2), s.ky.min(2), s.kz.min(2));
        let (sx, sy, sz) = (Vec4::splat(s.sx), Vec4::splat(s.sy), Vec4::splat(s.sz));
        // Vertices relative to the origin (as the scalar `self.v[i] - ray.origin`), then
        // sheared so that the ray runs along +z.
        let rel = |p: &[Vec4; 3]| [p[0] - r.o[0], p[1] - r.o[1], p[2] - r.o[2]];
        let (a, b, c) = (rel(&self.v[0]), rel(&self.v[1]), rel(&self.v[2]));
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = Vec4::ZERO;
        let negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
        let positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
        let det = u + v + w;
        let t_scaled = u * (sz * a[kz]) + v * (sz * b[kz]) + w * (sz * c[kz]);
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        let in_range = t.cmpge(r.t_min) & t.cmple(Vec4::splat(t_max)) & t.cmplt(Vec4::INFINITY);
        let mask = !(negative & positive) & det.cmpne(zero) & det.cmpeq(det) & in_range;
        let mut hits = GroupHits { mask, t, u: v * inv_det, v: w * inv_det };
        // An exact zero edge function may be a rounding artefact: those lanes take the scalar
        // test, whose double-precision fallback decides them (rare: rays through edges).
        let exact_zero = (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask();
        if exact_zero != 0 {
            hits = self.redo_lanes(exact_zero, ray, s, t_max, hits);
        }
        hits
    }

    fn lane(&self, i: usize) -> WatertightTriangle {
        WatertightTriangle { v: self.v.map(|c| Vec3::new(c[0][i], c[1][i], c[2][i])) }
    }

    fn bits(&self) -> Vec<u32> {
        lane_bits(&self.v.concat())
    }
}

impl Watertight4 {
    /// `hits` with the lanes of `lanes` (a bit mask) replaced by the scalar test's answers.
    #[cold]
    #[inline(never)]
    fn redo_lanes(&self, lanes: u32, ray: &Ray, s: &ShearedRay, t_max: f32, hits: GroupHits) -> GroupHits {
        let (mut mask, mut t, mut u, mut v) =
            (hits.mask.bitmask(), hits.t.to_array(), hits.u.to_array(), hits.v.to_array());
        for i in (0..LANES).filter(|i| lanes >> i & 1 != 0) {
            match self.lane(i).intersect(ray, s, t_max) {
                Some((ti, ui, vi)) => {
                    (t[i], u[i], v[i]) = (ti, ui, vi);
                    mask |= 1 << i;
                }
                None => mask &= !(1 << i),
            }
        }
        let mask = BVec4A::new(mask & 1 != 0, mask & 2 != 0, mask & 4 != 0, mask & 8 != 0);
        GroupHits { mask, t: Vec4::from_array(t), u: Vec4::from_array(u), v: Vec4::from_array(v) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangle::TriangleTest;

    /// A deterministic generator (xorshift), so the tests need no dependency.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
        fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * scale
        }
    }

    /// The scalar loop's answer over `records`: closest, the later of equal hits.
    fn scalar<T: TriangleTest>(records: &[T], ray: &Ray) -> Option<(usize, f32, f32, f32)> {
        let data = T::prepare(ray);
        let mut best = None;
        let mut t_max = ray.t_max;
        for (i, r) in records.iter().enumerate() {
            if let Some((t, u, v)) = r.intersect(ray, &data, t_max) {
                best = Some((i, t, u, v));
                t_max = t;
            }
        }
        best
    }

    fn grouped<G: LeafGroup>(records: &[G::Record], ray: &Ray) -> Option<(usize, f32, f32, f32)> {
        let data = G::prepare(ray);
        let mut best = None;
        let mut t_max = ray.t_max;
        for (g, chunk) in records.chunks(LANES).enumerate() {
            let hits = G::new(chunk).intersect(ray, &data, t_max);
            if let Some(lane) = hits.closest() {
                let t = hits.t.to_array()[lane];
                best = Some((g * LANES + lane, t, hits.u.to_array()[lane], hits.v.to_array()[lane]));
                t_max = t;
            }
        }
        best
    }

    /// Bit-identical answers, on soups built to make ties and edge hits: triangles sharing
    /// edges and duplicated, rays aimed at vertices and edge midpoints, zero direction
    /// components, degenerate triangles and origins 1e5 out.
    fn agree<G: LeafGroup>(make: fn(&[Vec3; 3]) -> G::Record) {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut differences = 0;
        let mut hits = 0;
        for case in 0..3000 {
            let offset = if case % 3 == 0 { Vec3::splat(1e5) } else { Vec3::ZERO };
            let n = 1 + case % 11;
            let mut tris: Vec<[Vec3; 3]> = Vec::new();
            for i in 0..n {
                let t = match i % 4 {
                    // Shares an edge with the previous triangle.
                    1 if i > 0 => {
                        let p = tris[i - 1];
                        [p[0], p[2], p[2] + rng.vec(1.0)]
                    }
                    // A duplicate: an exact tie.
                    2 if i > 0 => tris[i - 1],
                    // Degenerate (collinear).
                    3 if case % 5 == 0 => {
                        let a = rng.vec(1.0);
                        [a, a + Vec3::X, a + 2.0 * Vec3::X]
                    }
                    _ => [rng.vec(2.0), rng.vec(2.0), rng.vec(2.0)],
                };
                tris.push(t.map(|p| p + offset));
            }
            let records: Vec<G::Record> = tris.iter().map(make).collect();
            let target = match case % 3 {
                0 => tris[case % n][case % 3],
                1 => 0.5 * (tris[case % n][0] + tris[case % n][1]),
                _ => offset + rng.vec(2.0),
            };
            let mut dir = rng.vec(2.0);
            if case % 4 == 0 {
                dir.x = 0.0;
            }
            let dir = if dir == Vec3::ZERO { Vec3::Z } else { dir };
            let ray = Ray::new(target - 3.0 * dir, dir, if case % 7 == 0 { 2.9 } else { 0.0 }, f32::INFINITY);
            let (want, got) = (scalar(&records, &ray), grouped::<G>(&records, &ray));
            hits += usize::from(want.is_some());
            let bits =
                |h: Option<(usize, f32, f32, f32)>| h.map(|(i, t, u, v)| (i, t.to_bits(), u.to_bits(), v.to_bits()));
            if bits(want) != bits(got) {
                differences += 1;
                eprintln!("case {case}: scalar {want:?}, group {got:?}");
            }
        }
        assert_eq!(differences, 0);
        assert!(hits > 1000, "the soups must be hit often: {hits} hits");
    }

    #[test]
    fn wald_groups_are_bit_identical_to_the_scalar_test() {
        agree::<Wald4>(WaldTriangle::new);
    }

    #[test]
    fn watertight_groups_are_bit_identical_to_the_scalar_test() {
        agree::<Watertight4>(WatertightTriangle::new);
    }

    #[test]
    fn padding_lanes_never_hit() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let ray = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        let w = Wald4::new(&[WaldTriangle::new(&tri)]);
        assert_eq!(w.intersect(&ray, &Wald4::prepare(&ray), f32::INFINITY).mask.bitmask(), 1);
        let wt = Watertight4::new(&[WatertightTriangle::new(&tri)]);
        assert_eq!(wt.intersect(&ray, &Watertight4::prepare(&ray), f32::INFINITY).mask.bitmask(), 1);
        let empty = Wald4::new(&[]);
        assert_eq!(empty.intersect(&ray, &Wald4::prepare(&ray), f32::INFINITY).mask.bitmask(), 0);
    }

    #[test]
    fn the_closest_lane_is_the_last_of_equal_distances() {
        let hits = GroupHits {
            mask: BVec4A::new(true, true, false, true),
            t: Vec4::new(2.0, 1.0, 0.5, 1.0),
            u: Vec4::ZERO,
            v: Vec4::ZERO,
        };
        assert_eq!(hits.closest(), Some(3));
        let none = GroupHits { mask: BVec4A::FALSE, ..hits };
        assert_eq!(none.closest(), None);
    }
}
