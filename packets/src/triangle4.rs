//! The packet x 1-triangle tests: both intersectors of `kdtree`, one packet's rays per
//! instruction (four with the default `Vec4` lanes; the width is the lane type's,
//! [`crate::simd`]).
//!
//! Each lane computes exactly what the single-ray test computes, with the same operations in
//! the same order (Rust never fuses a multiply and an add on its own), so a packet lane and
//! a single ray agree bit for bit on `t`, `u` and `v`, and on ties: like the single-ray
//! test, a lane takes a hit at `t <= ` its closest so far, so the later of two equal hits
//! wins in both.
//!
//! - Wald's test (thesis 4.2) projects along the triangle's own axis `k`, the same for all
//!   rays of the packet: a straight SIMD translation.
//! - The watertight test shears along each *ray's* dominant axis. When the packet's valid
//!   lanes share their shear axes (almost always for coherent rays) the SIMD path runs;
//!   otherwise, and for lanes whose edge functions hit an exact zero (the double-precision
//!   fallback), the lane runs the scalar test.
//!
//! The methods keep their 4-wide names (`prepare4`, `intersect4`: the thesis's 2x2 packet)
//! at every width.

use glam::Vec4;
use kdtree::TreeTest;
use kdtree::triangle::{ShearedRay, TriangleTest, WaldTriangle, WatertightTriangle};

use crate::packet::{PacketHit, RayPacket};
use crate::simd::{PortableF32, SimdF32, SimdMask};

/// A ray-triangle test that also takes a packet of rays at once: `V::LANES` rays, four
/// (`Vec4`) unless another lane type is named.
pub trait PacketTest<V: SimdF32 = Vec4>: TriangleTest {
    /// What the test precomputes once per packet.
    type PacketData: Copy;
    /// The per-packet precomputation.
    fn prepare4(rays: &RayPacket<V>) -> Self::PacketData;
    /// The precomputation of packet `i` of a tile, looked up in the per-trace table
    /// `sheared` that [`TileTracer::trace`](crate::TileTracer::trace) fills for watertight
    /// trees (not remade at every leaf the packet meets).
    fn tile_data(sheared: &[ShearedPacket<V>], i: usize) -> Self::PacketData;
    /// Tests the lanes of `active`; each lane that hits at `t` in `[t_min, hit.t]` records the
    /// hit as triangle `prim`. Returns the lanes that hit.
    fn intersect4(
        &self,
        rays: &RayPacket<V>,
        data: &Self::PacketData,
        active: V::Mask,
        hit: &mut PacketHit<V>,
        prim: u32,
    ) -> V::Mask;
}

/// A tree's triangle test ([`TreeTest`]) whose records also test packets of every lane type
/// a kernel runs at ([`crate::Width`]: `Vec4`, the AVX2 and AVX-512 types and their portable
/// twins): what a kernel of this crate (or one composed of them) is generic over. Both of
/// `kdtree`'s tests are ([`kdtree::WaldTest`], [`kdtree::WatertightTest`]).
pub trait PacketTreeTest: TreeTest<Record: AnyWidth> {}

impl<I: TreeTest<Record: AnyWidth>> PacketTreeTest for I {}

/// A triangle record that tests packets of every lane type [`crate::at_width!`] runs.
#[cfg(target_arch = "x86_64")]
pub trait AnyWidth:
    PacketTest
    + PacketTest<PortableF32<8>>
    + PacketTest<PortableF32<16>>
    + PacketTest<crate::simd_x86::F32x8>
    + PacketTest<crate::simd_x86::F32x16>
    + PacketTest<crate::simd_x86::F32x8x2>
{
}

/// A triangle record that tests packets of every lane type [`crate::at_width!`] runs.
#[cfg(not(target_arch = "x86_64"))]
pub trait AnyWidth: PacketTest + PacketTest<PortableF32<8>> + PacketTest<PortableF32<16>> {}

#[cfg(target_arch = "x86_64")]
impl<
    R: PacketTest
        + PacketTest<PortableF32<8>>
        + PacketTest<PortableF32<16>>
        + PacketTest<crate::simd_x86::F32x8>
        + PacketTest<crate::simd_x86::F32x16>
        + PacketTest<crate::simd_x86::F32x8x2>,
> AnyWidth for R
{
}

#[cfg(not(target_arch = "x86_64"))]
impl<R: PacketTest + PacketTest<PortableF32<8>> + PacketTest<PortableF32<16>>> AnyWidth for R {}

impl<V: SimdF32> PacketTest<V> for WaldTriangle {
    type PacketData = ();

    #[inline(always)]
    fn prepare4(_rays: &RayPacket<V>) {}

    #[inline(always)]
    fn tile_data(_sheared: &[ShearedPacket<V>], _i: usize) {}

    #[inline(always)]
    fn intersect4(&self, r: &RayPacket<V>, _: &(), active: V::Mask, hit: &mut PacketHit<V>, prim: u32) -> V::Mask {
        let (k, u, v) = self.axes();
        let (ok, ou, ov) = (r.o[k], r.o[u], r.o[v]);
        let (dk, du, dv) = (r.d[k], r.d[u], r.d[v]);
        let (n_u, n_v) = (V::splat(self.n_u), V::splat(self.n_v));
        let denom = dk + n_u * du + n_v * dv;
        // As the scalar test: vertex `a` relative to the origin first.
        let (ak, au, av) = (V::splat(self.a_k) - ok, V::splat(self.a_u) - ou, V::splat(self.a_v) - ov);
        let t = (ak + n_u * au + n_v * av) / denom;
        // NaN fails every comparison, as in the scalar test.
        let mut mask = active & t.cmpge(r.t_min) & t.cmple(hit.t) & t.cmplt(V::INFINITY);
        if !mask.any() {
            return mask;
        }
        let hu = t * du - au;
        let hv = t * dv - av;
        let beta = V::splat(self.b_nu) * hu + V::splat(self.b_nv) * hv;
        let gamma = V::splat(self.c_nu) * hu + V::splat(self.c_nv) * hv;
        mask &= beta.cmpge(V::ZERO) & gamma.cmpge(V::ZERO) & (beta + gamma).cmple(V::ONE);
        if mask.any() {
            hit.record(mask, t, beta, gamma, prim);
        }
        mask
    }
}

/// The watertight test's per-packet shear: the lanes' shared axes (when `uniform`) and the
/// per-lane shear factors, plus each lane's scalar shear for the fallback.
#[derive(Clone, Copy, Debug)]
pub struct ShearedPacket<V: SimdF32 = Vec4> {
    /// True when every valid lane has the same `(kx, ky, kz)`.
    pub uniform: bool,
    /// Shared axes `(kx, ky, kz)` (meaningful when `uniform`).
    pub axes: (usize, usize, usize),
    /// `d[kx] / d[kz]` per lane.
    pub sx: V,
    /// `d[ky] / d[kz]` per lane.
    pub sy: V,
    /// `1 / d[kz]` per lane.
    pub sz: V,
    /// Each lane's scalar shear.
    pub lanes: V::Array<ShearedRay>,
}

impl<V: SimdF32> PacketTest<V> for WatertightTriangle {
    type PacketData = ShearedPacket<V>;

    #[inline(always)]
    fn prepare4(rays: &RayPacket<V>) -> ShearedPacket<V> {
        let lanes = V::array_from_fn(|lane| WatertightTriangle::prepare(&rays.ray(lane)));
        let valid = rays.valid.bitmask();
        let first = (valid.trailing_zeros() as usize).min(V::LANES - 1);
        let key = |s: &ShearedRay| (s.kx, s.ky, s.kz);
        let uniform = (0..V::LANES).all(|lane| valid >> lane & 1 == 0 || key(&lanes[lane]) == key(&lanes[first]));
        ShearedPacket {
            uniform,
            axes: key(&lanes[first]),
            sx: V::from_fn(|lane| lanes[lane].sx),
            sy: V::from_fn(|lane| lanes[lane].sy),
            sz: V::from_fn(|lane| lanes[lane].sz),
            lanes,
        }
    }

    #[inline(always)]
    fn tile_data(sheared: &[ShearedPacket<V>], i: usize) -> ShearedPacket<V> {
        sheared[i]
    }

    #[inline(always)]
    fn intersect4(
        &self,
        r: &RayPacket<V>,
        s: &ShearedPacket<V>,
        active: V::Mask,
        hit: &mut PacketHit<V>,
        prim: u32,
    ) -> V::Mask {
        if !s.uniform {
            return watertight_by_lane(self, r, s, active, hit, prim);
        }
        let (kx, ky, kz) = (s.axes.0 & 3, s.axes.1 & 3, s.axes.2 & 3);
        // Vertices relative to the origin, each coordinate as (vertex - origin) per lane.
        let rel = |vertex: usize, axis: usize| V::splat(self.v[vertex][axis]) - r.o[axis];
        let (a_z, b_z, c_z) = (rel(0, kz), rel(1, kz), rel(2, kz));
        let (ax, ay) = (rel(0, kx) - s.sx * a_z, rel(0, ky) - s.sy * a_z);
        let (bx, by) = (rel(1, kx) - s.sx * b_z, rel(1, ky) - s.sy * b_z);
        let (cx, cy) = (rel(2, kx) - s.sx * c_z, rel(2, ky) - s.sy * c_z);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = V::ZERO;
        // Lanes with an exact zero take the scalar test and its double-precision fallback.
        let exact_zero = active & (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero));
        let negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
        let positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
        let det = u + v + w;
        let mut mask = active & !exact_zero & !(negative & positive) & det.cmpne(zero) & det.cmpeq(det);
        if mask.any() {
            let t_scaled = u * (s.sz * a_z) + v * (s.sz * b_z) + w * (s.sz * c_z);
            let inv_det = V::ONE / det;
            let t = t_scaled * inv_det;
            mask &= t.cmpge(r.t_min) & t.cmple(hit.t) & t.cmplt(V::INFINITY);
            if mask.any() {
                hit.record(mask, t, v * inv_det, w * inv_det, prim);
            }
        }
        if exact_zero.any() {
            mask |= watertight_by_lane(self, r, s, exact_zero, hit, prim);
        }
        mask
    }
}

/// The scalar watertight test, lane by lane, for the lanes of `active`.
#[cold]
fn watertight_by_lane<V: SimdF32>(
    tri: &WatertightTriangle,
    r: &RayPacket<V>,
    s: &ShearedPacket<V>,
    active: V::Mask,
    hit: &mut PacketHit<V>,
    prim: u32,
) -> V::Mask {
    let bits = active.bitmask();
    let mut hits = V::array_from_fn(|_| false);
    for lane in 0..V::LANES {
        if bits >> lane & 1 == 0 {
            continue;
        }
        let ray = r.ray(lane);
        if let Some((t, u, v)) = tri.intersect(&ray, &s.lanes[lane], hit.t[lane]) {
            let mut mask = V::array_from_fn(|_| false);
            mask[lane] = true;
            let mask = V::Mask::from_fn(|l| mask[l]);
            hit.record(mask, V::splat(t), V::splat(u), V::splat(v), prim);
            hits[lane] = true;
        }
    }
    V::Mask::from_fn(|lane| hits[lane])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::PortableF32;
    use glam::Vec3;
    use kdtree::Ray;
    use proptest::prelude::*;

    fn check_lanes<T: PacketTest>(tri: &T, rays: &[Ray; 4]) {
        check_width::<Vec4, T>(tri, rays);
    }

    /// `rays` as one packet of `V`'s width (lanes past them invalid): each lane's answer is
    /// the single-ray test's, bit for bit.
    fn check_width<V: SimdF32, T: PacketTest<V>>(tri: &T, rays: &[Ray]) {
        let p = RayPacket::<V>::from_rays(rays);
        let data = T::prepare4(&p);
        let mut hit = PacketHit::new(&p);
        let mask = tri.intersect4(&p, &data, p.valid, &mut hit, 9);
        for (lane, ray) in rays.iter().enumerate() {
            let single = tri.intersect(ray, &T::prepare(ray), ray.t_max);
            let got = hit.get(lane).map(|h| (h.t, h.u, h.v));
            assert_eq!(got, single, "lane {lane}: {ray:?}");
            assert_eq!(mask.bitmask() >> lane & 1 != 0, single.is_some());
            // Bit for bit, not only ==.
            if let (Some(a), Some(b)) = (got, single) {
                assert_eq!(
                    (a.0.to_bits(), a.1.to_bits(), a.2.to_bits()),
                    (b.0.to_bits(), b.1.to_bits(), b.2.to_bits())
                );
            }
        }
        assert_eq!(mask.bitmask() >> rays.len(), 0, "invalid lanes never hit");
    }

    fn vec3() -> impl Strategy<Value = Vec3> {
        (-4.0f32..4.0, -4.0f32..4.0, -4.0f32..4.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    proptest! {
        /// Random triangles and four random rays (mixed origins and direction signs): every
        /// lane equals the single-ray test, for both intersectors.
        #[test]
        fn lanes_equal_single_rays(a in vec3(), b in vec3(), c in vec3(),
                                   rays in prop::array::uniform4((vec3(), vec3(), 0.0f32..1.0, 1.0f32..20.0))) {
            let tri = [a, b, c];
            let rays = rays.map(|(o, d, t0, t1)| Ray::new(o, if d == Vec3::ZERO { Vec3::X } else { d }, t0, t1));
            check_lanes(&WaldTriangle::new(&tri), &rays);
            check_lanes(&WatertightTriangle::new(&tri), &rays);
        }

        /// 8 and 16 random rays in one packet of the portable lane type (mixed shear axes,
        /// so the watertight test's scalar lanes; and one shared direction, so its SIMD
        /// path), and fewer rays than lanes: every lane equals the single-ray test.
        #[test]
        fn wide_lanes_equal_single_rays(a in vec3(), b in vec3(), c in vec3(), n in 1usize..=16,
                                        rays in prop::array::uniform16((vec3(), vec3(), 0.0f32..1.0, 1.0f32..20.0))) {
            let tri = [a, b, c];
            let rays = rays.map(|(o, d, t0, t1)| Ray::new(o, if d == Vec3::ZERO { Vec3::X } else { d }, t0, t1));
            let d = (a + b + c) / 3.0 - rays[0].origin;
            let shared = rays.map(|r| Ray::new(r.origin, if d == Vec3::ZERO { Vec3::X } else { d }, r.t_min, r.t_max));
            for rays in [&rays, &shared] {
                check_width::<PortableF32<8>, _>(&WaldTriangle::new(&tri), &rays[..8]);
                check_width::<PortableF32<8>, _>(&WatertightTriangle::new(&tri), &rays[..8]);
                check_width::<PortableF32<16>, _>(&WaldTriangle::new(&tri), &rays[..n]);
                check_width::<PortableF32<16>, _>(&WatertightTriangle::new(&tri), &rays[..n]);
            }
        }

        /// Rays aimed exactly at vertices and edge points from one origin: the watertight
        /// test's exact-zero fallback runs in the lanes that need it.
        #[test]
        fn lanes_equal_single_rays_at_edges_and_vertices(o in vec3(), s in 0.0f32..1.0) {
            let tri = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)];
            let targets = [tri[0], tri[1], tri[0].lerp(tri[1], s), tri[1].lerp(tri[2], s)];
            let rays = targets.map(|p| Ray::new(o, if p == o { Vec3::Z } else { p - o }, 0.0, f32::INFINITY));
            check_lanes(&WaldTriangle::new(&tri), &rays);
            check_lanes(&WatertightTriangle::new(&tri), &rays);
            let targets = [tri[0], tri[1], tri[2], tri[0].lerp(tri[1], s), tri[1].lerp(tri[2], s), tri[2].lerp(tri[0], s)];
            let rays = targets.map(|p| Ray::new(o, if p == o { Vec3::Z } else { p - o }, 0.0, f32::INFINITY));
            check_width::<PortableF32<8>, _>(&WaldTriangle::new(&tri), &rays);
            check_width::<PortableF32<8>, _>(&WatertightTriangle::new(&tri), &rays);
        }
    }

    #[test]
    fn mixed_shear_axes_take_the_lane_path_and_agree() {
        let tri = [Vec3::new(-1.0, -1.0, 2.0), Vec3::new(3.0, -1.0, 2.0), Vec3::new(-1.0, 3.0, 2.0)];
        let o = Vec3::new(0.2, 0.1, 0.0);
        let rays = [Vec3::Z, Vec3::new(1.5, 0.2, 1.0), Vec3::new(0.1, 1.4, 1.0), Vec3::new(0.0, 0.0, -1.0)]
            .map(|d| Ray::new(o, d, 0.0, f32::INFINITY));
        let p = RayPacket::new(&rays);
        assert!(!WatertightTriangle::prepare4(&p).uniform);
        check_lanes(&WatertightTriangle::new(&tri), &rays);
    }

    #[test]
    fn degenerate_triangles_and_invalid_lanes_never_hit() {
        let flat = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        let rays = [Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY); 4];
        check_lanes(&WaldTriangle::new(&flat), &rays);
        check_lanes(&WatertightTriangle::new(&flat), &rays);
        let tri = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(3.0, -1.0, 1.0), Vec3::new(-1.0, 3.0, 1.0)];
        let p = RayPacket::new(&rays[..1]);
        let mut hit = PacketHit::new(&p);
        let mask = WaldTriangle::new(&tri).intersect4(&p, &(), p.valid, &mut hit, 0);
        assert_eq!(mask.bitmask(), 0b0001);
    }
}
