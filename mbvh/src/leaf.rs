//! Leaf blocks: up to four triangles of a leaf, stored SoA and tested against one ray at once
//! (Wald, Benthin & Boulos 2008, section 5.6: the leaf's triangles "pre-gathered during
//! building" in SoA form, then an N-wide test and a reduction to the closest hit).
//!
//! Both of `kdtree`'s intersectors have a block: [`WaldBlock`] (Wald's projected-barycentric
//! test, thesis 4.2) and [`WatertightBlock`] (Woop, Benthin & Wald 2013). Each lane computes
//! exactly the operations of the scalar test (`kdtree::triangle`), in the same order and
//! without fused multiply-adds, so a lane's `(t, u, v)` is the scalar test's bit for bit
//! (tested against the scalar records here and through the traversal in `tests/oracle.rs`).
//! The watertight test's exact-zero fallback (edge functions redone in `f64`) runs the
//! scalar test on the lanes that need it. Unused lanes hold NaN records, which never hit.

use glam::{BVec4A, Vec3, Vec4};
use kdtree::Ray;
use kdtree::triangle::{ShearedRay, TriangleTest, WaldTriangle, WatertightTriangle};

/// Lanes per block.
pub const LANES: usize = 4;

/// A 4-wide leaf test: the block of one intersector.
pub trait LeafBlock: Copy + Send + Sync + 'static {
    /// The scalar record it packs (`kdtree::triangle`).
    type Record: TriangleTest + Copy;
    /// What the test precomputes once per ray.
    type RayData: Copy;
    /// The per-ray precomputation.
    fn prepare(ray: &Ray) -> Self::RayData;
    /// The block of up to four records with their triangle ids (unused lanes never hit).
    fn pack(records: &[(Self::Record, u32)]) -> Self;
    /// The record of `lane` and its triangle id (`u32::MAX` for an unused lane).
    fn record(&self, lane: usize) -> (Self::Record, u32);
    /// The triangle id of `lane` (`u32::MAX` for an unused lane).
    fn record_prim(&self, lane: usize) -> u32;
    /// The closest hit in `[ray.t_min, t_max]` among the lanes, as `(lane, t, u, v)`; at
    /// equal `t` the lowest lane.
    fn closest(&self, ray: &Ray, data: &Self::RayData, t_max: f32) -> Option<(usize, f32, f32, f32)>;
    /// Whether any lane is hit in `[ray.t_min, t_max]`.
    fn any(&self, ray: &Ray, data: &Self::RayData, t_max: f32) -> bool;
    /// The scalar twin of [`LeafBlock::closest`]: the records one by one.
    fn closest_scalar(&self, ray: &Ray, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        let data = Self::Record::prepare(ray);
        let mut best: Option<(usize, f32, f32, f32)> = None;
        for lane in 0..LANES {
            let (rec, _) = self.record(lane);
            let limit = best.map_or(t_max, |b| b.1);
            if let Some((t, u, v)) = rec.intersect(ray, &data, limit)
                && best.is_none_or(|b| t < b.1)
            {
                best = Some((lane, t, u, v));
            }
        }
        best
    }
}

/// The closest valid lane of `t` (lowest lane at equal `t`).
#[inline(always)]
fn reduce(valid: BVec4A, t: Vec4) -> Option<usize> {
    if !valid.any() {
        return None;
    }
    let ts = Vec4::select(valid, t, Vec4::INFINITY);
    let m = ts.min_element();
    let at = ts.cmpeq(Vec4::splat(m)) & valid;
    Some(at.bitmask().trailing_zeros() as usize)
}

/// Four Wald records SoA (thesis 4.2, `kdtree::triangle::WaldTriangle`). The projection axis
/// `k` differs per lane; the ray's coordinates are picked per lane by two masks.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct WaldBlock {
    /// Lanes whose `k` is 0 (x).
    k0: BVec4A,
    /// Lanes whose `k` is 1 (y).
    k1: BVec4A,
    n_u: Vec4,
    n_v: Vec4,
    a_k: Vec4,
    a_u: Vec4,
    a_v: Vec4,
    b_nu: Vec4,
    b_nv: Vec4,
    c_nu: Vec4,
    c_nv: Vec4,
    /// Triangle ids (`u32::MAX`: unused lane).
    prim: [u32; LANES],
    /// Packed axes per lane, for [`LeafBlock::record`].
    kuv: [u32; LANES],
}

/// The ray splatted: origin and direction per axis.
#[derive(Clone, Copy, Debug)]
pub struct SplatRay {
    o: [Vec4; 3],
    d: [Vec4; 3],
}

impl SplatRay {
    fn new(ray: &Ray) -> SplatRay {
        let s = |v: Vec3| [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)];
        SplatRay { o: s(ray.origin), d: s(ray.dir) }
    }
}

/// The unused lane's Wald record: NaN, never hit.
fn nan_wald() -> WaldTriangle {
    WaldTriangle::new(&[Vec3::NAN; 3])
}

impl LeafBlock for WaldBlock {
    type Record = WaldTriangle;
    type RayData = SplatRay;

    #[inline(always)]
    fn prepare(ray: &Ray) -> SplatRay {
        SplatRay::new(ray)
    }

    fn pack(records: &[(WaldTriangle, u32)]) -> WaldBlock {
        assert!(records.len() <= LANES, "a block holds at most {LANES} triangles");
        let rec = |i: usize| records.get(i).map_or((nan_wald(), u32::MAX), |r| *r);
        let lanes: [(WaldTriangle, u32); LANES] = [rec(0), rec(1), rec(2), rec(3)];
        let f = |g: fn(&WaldTriangle) -> f32| Vec4::from_array(lanes.map(|(r, _)| g(&r)));
        let k = lanes.map(|(r, _)| r.axes().0);
        WaldBlock {
            k0: BVec4A::from_array(k.map(|k| k == 0)),
            k1: BVec4A::from_array(k.map(|k| k == 1)),
            n_u: f(|r| r.n_u),
            n_v: f(|r| r.n_v),
            a_k: f(|r| r.a_k),
            a_u: f(|r| r.a_u),
            a_v: f(|r| r.a_v),
            b_nu: f(|r| r.b_nu),
            b_nv: f(|r| r.b_nv),
            c_nu: f(|r| r.c_nu),
            c_nv: f(|r| r.c_nv),
            prim: lanes.map(|(_, p)| p),
            kuv: lanes.map(|(r, _)| r.kuv),
        }
    }

    #[inline(always)]
    fn record_prim(&self, lane: usize) -> u32 {
        self.prim[lane & 3]
    }

    fn record(&self, lane: usize) -> (WaldTriangle, u32) {
        let rec = WaldTriangle {
            kuv: self.kuv[lane],
            n_u: self.n_u[lane],
            n_v: self.n_v[lane],
            a_k: self.a_k[lane],
            a_u: self.a_u[lane],
            a_v: self.a_v[lane],
            b_nu: self.b_nu[lane],
            b_nv: self.b_nv[lane],
            c_nu: self.c_nu[lane],
            c_nv: self.c_nv[lane],
        };
        (rec, self.prim[lane])
    }

    #[inline(always)]
    fn closest(&self, ray: &Ray, r: &SplatRay, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        let (valid, t, beta, gamma) = self.test(ray, r, t_max);
        reduce(valid, t).map(|lane| (lane, t[lane], beta[lane], gamma[lane]))
    }

    #[inline(always)]
    fn any(&self, ray: &Ray, r: &SplatRay, t_max: f32) -> bool {
        self.test(ray, r, t_max).0.any()
    }
}

impl WaldBlock {
    /// The four lanes of `WaldTriangle::intersect`: valid lanes, `t`, `beta`, `gamma`.
    #[inline(always)]
    fn test(&self, ray: &Ray, r: &SplatRay, t_max: f32) -> (BVec4A, Vec4, Vec4, Vec4) {
        // Per lane the ray's coordinate on axis k, u = k + 1, v = k + 2 (mod 3).
        let pick = |a: &[Vec4; 3], i: usize| {
            Vec4::select(self.k0, a[i % 3], Vec4::select(self.k1, a[(i + 1) % 3], a[(i + 2) % 3]))
        };
        let (o_k, o_u, o_v) = (pick(&r.o, 0), pick(&r.o, 1), pick(&r.o, 2));
        let (d_k, d_u, d_v) = (pick(&r.d, 0), pick(&r.d, 1), pick(&r.d, 2));
        let denom = d_k + self.n_u * d_u + self.n_v * d_v;
        let (ak, au, av) = (self.a_k - o_k, self.a_u - o_u, self.a_v - o_v);
        let t = (ak + self.n_u * au + self.n_v * av) / denom;
        let in_range = t.cmpge(Vec4::splat(ray.t_min)) & t.cmple(Vec4::splat(t_max)) & t.cmplt(Vec4::INFINITY);
        let hu = t * d_u - au;
        let hv = t * d_v - av;
        let beta = self.b_nu * hu + self.b_nv * hv;
        let gamma = self.c_nu * hu + self.c_nv * hv;
        let inside = beta.cmpge(Vec4::ZERO) & gamma.cmpge(Vec4::ZERO) & (beta + gamma).cmple(Vec4::ONE);
        (in_range & inside, t, beta, gamma)
    }
}

/// Four watertight records SoA (Woop, Benthin & Wald 2013, `kdtree::triangle::
/// WatertightTriangle`): the vertices, per vertex and axis a `Vec4`. The shear is the ray's,
/// the same in every lane.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct WatertightBlock {
    /// `v[vertex][axis]`, lanes over the four triangles.
    v: [[Vec4; 3]; 3],
    /// Triangle ids (`u32::MAX`: unused lane).
    prim: [u32; LANES],
}

/// The watertight test's per-ray data: the origin splatted, the shear splatted and the scalar
/// shear (for lanes that fall back to the scalar test).
#[derive(Clone, Copy, Debug)]
pub struct ShearData {
    o: [Vec4; 3],
    s: ShearedRay,
    sx: Vec4,
    sy: Vec4,
    sz: Vec4,
}

impl LeafBlock for WatertightBlock {
    type Record = WatertightTriangle;
    type RayData = ShearData;

    #[inline(always)]
    fn prepare(ray: &Ray) -> ShearData {
        let s = WatertightTriangle::prepare(ray);
        let o = ray.origin;
        ShearData {
            o: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            s,
            sx: Vec4::splat(s.sx),
            sy: Vec4::splat(s.sy),
            sz: Vec4::splat(s.sz),
        }
    }

    fn pack(records: &[(WatertightTriangle, u32)]) -> WatertightBlock {
        assert!(records.len() <= LANES, "a block holds at most {LANES} triangles");
        let rec = |i: usize| records.get(i).map_or(([Vec3::NAN; 3], u32::MAX), |(r, p)| (r.v, *p));
        let lanes = [rec(0), rec(1), rec(2), rec(3)];
        let v = [0, 1, 2].map(|k| [0, 1, 2].map(|a| Vec4::from_array(lanes.map(|(v, _)| v[k][a]))));
        WatertightBlock { v, prim: lanes.map(|(_, p)| p) }
    }

    #[inline(always)]
    fn record_prim(&self, lane: usize) -> u32 {
        self.prim[lane & 3]
    }

    fn record(&self, lane: usize) -> (WatertightTriangle, u32) {
        let v = [0, 1, 2].map(|k| Vec3::new(self.v[k][0][lane], self.v[k][1][lane], self.v[k][2][lane]));
        (WatertightTriangle { v }, self.prim[lane])
    }

    #[inline(always)]
    fn closest(&self, ray: &Ray, r: &ShearData, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        let (valid, scalar, t, u, v) = self.test(ray, r, t_max);
        if scalar == 0 {
            return reduce(valid, t).map(|lane| (lane, t[lane], u[lane], v[lane]));
        }
        let (mut t, mut u, mut v, mut valid) = (t, u, v, valid.bitmask());
        for lane in 0..LANES {
            if scalar & (1 << lane) != 0
                && let Some((lt, lu, lv)) = self.record(lane).0.intersect(ray, &r.s, t_max)
            {
                (t[lane], u[lane], v[lane]) = (lt, lu, lv);
                valid |= 1 << lane;
            }
        }
        let mask = BVec4A::new(valid & 1 != 0, valid & 2 != 0, valid & 4 != 0, valid & 8 != 0);
        reduce(mask, t).map(|lane| (lane, t[lane], u[lane], v[lane]))
    }

    #[inline(always)]
    fn any(&self, ray: &Ray, r: &ShearData, t_max: f32) -> bool {
        let (valid, scalar, ..) = self.test(ray, r, t_max);
        valid.any()
            || (0..LANES)
                .any(|lane| scalar & (1 << lane) != 0 && self.record(lane).0.intersect(ray, &r.s, t_max).is_some())
    }
}

impl WatertightBlock {
    /// The four lanes of `WatertightTriangle::intersect` up to its exact-zero fallback:
    /// valid lanes, the bit mask of lanes with an edge function exactly zero (to redo with
    /// the scalar test), `t`, `u`, `v`.
    #[inline(always)]
    fn test(&self, ray: &Ray, r: &ShearData, t_max: f32) -> (BVec4A, u32, Vec4, Vec4, Vec4) {
        let rel = |k: usize| [self.v[k][0] - r.o[0], self.v[k][1] - r.o[1], self.v[k][2] - r.o[2], Vec4::ZERO];
        let (a, b, c) = (rel(0), rel(1), rel(2));
        let (kx, ky, kz) = (r.s.kx & 3, r.s.ky & 3, r.s.kz & 3);
        let (ax, ay) = (a[kx] - r.sx * a[kz], a[ky] - r.sy * a[kz]);
        let (bx, by) = (b[kx] - r.sx * b[kz], b[ky] - r.sy * b[kz]);
        let (cx, cy) = (c[kx] - r.sx * c[kz], c[ky] - r.sy * c[kz]);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO);
        let neg = u.cmplt(Vec4::ZERO) | v.cmplt(Vec4::ZERO) | w.cmplt(Vec4::ZERO);
        let pos = u.cmpgt(Vec4::ZERO) | v.cmpgt(Vec4::ZERO) | w.cmpgt(Vec4::ZERO);
        let det = u + v + w;
        let det_ok = det.cmpne(Vec4::ZERO) & det.cmpeq(det);
        let (az, bz, cz) = (r.sz * a[kz], r.sz * b[kz], r.sz * c[kz]);
        let t_scaled = u * az + v * bz + w * cz;
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        let in_range = t.cmpge(Vec4::splat(ray.t_min)) & t.cmple(Vec4::splat(t_max)) & t.cmplt(Vec4::INFINITY);
        let valid = !zero & !(neg & pos) & det_ok & in_range;
        (valid, zero.bitmask(), t, v * inv_det, w * inv_det)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn tri(c: &[f32; 9]) -> [Vec3; 3] {
        [Vec3::new(c[0], c[1], c[2]), Vec3::new(c[3], c[4], c[5]), Vec3::new(c[6], c[7], c[8])]
    }

    /// Every lane of the block against the scalar record: the same hit, bit for bit.
    fn lanes_equal_scalar<B: LeafBlock>(tris: &[[Vec3; 3]], ray: &Ray, new: fn(&[Vec3; 3]) -> B::Record) {
        let recs: Vec<(B::Record, u32)> = tris.iter().enumerate().map(|(i, t)| (new(t), i as u32)).collect();
        let block = B::pack(&recs);
        let data = B::prepare(ray);
        let got = block.closest(ray, &data, ray.t_max);
        let want = block.closest_scalar(ray, ray.t_max);
        let bits = |h: Option<(usize, f32, f32, f32)>| h.map(|(l, t, u, v)| (l, t.to_bits(), u.to_bits(), v.to_bits()));
        assert_eq!(bits(got), bits(want), "{ray:?}");
        assert_eq!(block.any(ray, &data, ray.t_max), want.is_some());
        // Each lane alone equals the scalar test.
        let sdata = B::Record::prepare(ray);
        for (lane, (rec, prim)) in recs.iter().enumerate() {
            assert_eq!(block.record(lane).1, *prim);
            let s = rec.intersect(ray, &sdata, ray.t_max);
            let alone = B::pack(&recs[lane..=lane]).closest(ray, &B::prepare(ray), ray.t_max);
            assert_eq!(
                alone.map(|h| (h.1.to_bits(), h.2.to_bits(), h.3.to_bits())),
                s.map(|(t, u, v)| (t.to_bits(), u.to_bits(), v.to_bits()))
            );
        }
    }

    fn coord() -> impl Strategy<Value = f32> {
        prop_oneof![(-4i32..5).prop_map(|i| i as f32 * 0.5), -2.0f32..2.0]
    }

    proptest! {
        #[test]
        fn blocks_equal_the_scalar_tests(
            tris in prop::collection::vec(prop::array::uniform9(coord()), 1..5),
            o in prop::array::uniform3(coord()), d in prop::array::uniform3(coord()),
        ) {
            let tris: Vec<[Vec3; 3]> = tris.iter().map(tri).collect();
            let d = Vec3::new(d[0], d[1], d[2]);
            prop_assume!(d != Vec3::ZERO);
            let ray = Ray::new(Vec3::new(o[0], o[1], o[2]) * 3.0, d, 0.0, f32::INFINITY);
            lanes_equal_scalar::<WaldBlock>(&tris, &ray, WaldTriangle::new);
            lanes_equal_scalar::<WatertightBlock>(&tris, &ray, WatertightTriangle::new);
        }
    }

    #[test]
    fn shared_edges_use_the_scalar_fallback_and_agree() {
        // Rays exactly through the shared diagonal: edge functions exactly zero.
        let t0 = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)];
        let t1 = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        for i in 0..=8 {
            let s = i as f32 / 8.0;
            let ray = Ray::new(Vec3::new(s, s, 2.0), -Vec3::Z, 0.0, f32::INFINITY);
            lanes_equal_scalar::<WatertightBlock>(&[t0, t1], &ray, WatertightTriangle::new);
            lanes_equal_scalar::<WaldBlock>(&[t0, t1], &ray, WaldTriangle::new);
            let block = WatertightBlock::pack(&[(WatertightTriangle::new(&t0), 0), (WatertightTriangle::new(&t1), 1)]);
            assert!(block.closest(&ray, &WatertightBlock::prepare(&ray), f32::INFINITY).is_some(), "leak at {s}");
        }
    }

    #[test]
    fn unused_lanes_and_degenerate_triangles_never_hit() {
        let flat = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        let ray = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, f32::NEG_INFINITY, f32::INFINITY);
        let w = WaldBlock::pack(&[(WaldTriangle::new(&flat), 7)]);
        assert!(w.closest(&ray, &WaldBlock::prepare(&ray), f32::INFINITY).is_none());
        let wt = WatertightBlock::pack(&[(WatertightTriangle::new(&flat), 7)]);
        assert!(!wt.any(&ray, &WatertightBlock::prepare(&ray), f32::INFINITY));
        assert_eq!(wt.record(1).1, u32::MAX);
    }
}
