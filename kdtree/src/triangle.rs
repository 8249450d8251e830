//! Ray-triangle intersection tests: Wald's projected-barycentric test (thesis 4.2) and the
//! watertight test of Woop, Benthin and Wald (JCGT 2013).
//!
//! Both take a ray and the current closest distance `t_max` and return the hit distance and
//! the barycentric weights `(u, v)` of the second and third vertices. A triangle of zero area
//! never reports a hit.

use glam::Vec3;

use crate::Ray;

/// True for a triangle of exactly zero area: its edge cross product, computed in f64 so that
/// tiny triangles (edges near 1e-30) do not underflow to zero, is zero. Such a triangle is
/// left out of the tree and never hit by either test (thesis 4.2: Wald's projection has no
/// dominant normal axis for it).
pub fn is_degenerate(t: &[Vec3; 3]) -> bool {
    let (a, b, c) = (t[0].as_dvec3(), t[1].as_dvec3(), t[2].as_dvec3());
    (b - a).cross(c - a) == glam::DVec3::ZERO
}

/// Which ray-triangle test a tree's traversal uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Intersector {
    /// Wald's projected-barycentric test, as in the thesis (4.2): 40-byte precomputed records,
    /// no vertices needed, fast, but rays through shared edges can slip between triangles.
    #[default]
    Wald,
    /// The watertight test of Woop, Benthin & Wald 2013: shears the triangle into ray space and
    /// evaluates edge functions with a double-precision fallback on exact zeros, so no ray
    /// passes between triangles that share an edge.
    Watertight,
}

impl Intersector {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Intersector::Wald => "wald",
            Intersector::Watertight => "watertight",
        }
    }
}

/// A ray-triangle test over precomputed per-triangle records, with an optional per-ray
/// precomputation. Traversal is generic over it, so the choice costs no dispatch per test.
pub trait TriangleTest: Sync {
    /// What the test precomputes once per ray.
    type RayData: Copy;
    /// The per-ray precomputation.
    fn prepare(ray: &Ray) -> Self::RayData;
    /// The hit `(t, u, v)` with `t` in `[ray.t_min, t_max]`, or `None`.
    fn intersect(&self, ray: &Ray, data: &Self::RayData, t_max: f32) -> Option<(f32, f32, f32)>;
}

/// Precomputed record of Wald's projected-barycentric test (thesis 4.2, `render_poly`).
///
/// The triangle's plane `n . p = n . a` is divided by the normal's largest component `n_k`,
/// so that along axis `k` the distance is `t = ((a_k - o_k) + n_u (a_u - o_u) + n_v (a_v -
/// o_v)) / (d_k + n_u d_u + n_v d_v)`; the hit point, projected onto the `(u, v)` plane
/// (`u = k+1`, `v = k+2` mod 3) and taken relative to vertex `a` (`t d_u - (a_u - o_u)`),
/// gives the barycentrics by two dot products with precomputed edge coefficients (the `n_k`
/// in their denominator is the projected triangle's doubled signed area).
///
/// The thesis (and Wald) store the plane offset `n_d = (n . a) / n_k` and compute
/// `n_d - o_k - n_u o_u - n_v o_v`: far from the origin that subtracts numbers near `|o|` and loses the
/// surface (at 1e5 units an f32 ulp is 0.008, and the error grows with `n_u`, `n_v`). Here
/// vertex `a` is stored and `a - o` is formed first, between nearby numbers, so the error is
/// relative to the distance to the triangle, not to the coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct WaldTriangle {
    /// The projection axes packed as `k | u << 8 | v << 16` (see [`WaldTriangle::axes`]).
    pub kuv: u32,
    /// `n_u / n_k`: the plane normal's `u` component over its largest, `k`.
    pub n_u: f32,
    /// `n_v / n_k`.
    pub n_v: f32,
    /// Vertex `a`: its `k` coordinate (with `a_u`, `a_v` the whole vertex).
    pub a_k: f32,
    /// Vertex `a` projected: its `u` coordinate.
    pub a_u: f32,
    /// Vertex `a` projected: its `v` coordinate.
    pub a_v: f32,
    /// Edge coefficient of the second barycentric (`u` weight of the hit point).
    pub b_nu: f32,
    /// Edge coefficient of the second barycentric (`v` weight of the hit point).
    pub b_nv: f32,
    /// Edge coefficient of the third barycentric (`u` weight of the hit point).
    pub c_nu: f32,
    /// Edge coefficient of the third barycentric (`v` weight of the hit point).
    pub c_nv: f32,
}

const _: () = assert!(std::mem::size_of::<WaldTriangle>() == 40);

impl WaldTriangle {
    /// The record of triangle `[a, b, c]`. A zero-area triangle, or one with a NaN or
    /// infinite vertex, gets NaN coefficients, which make every test fail.
    pub fn new(tri: &[Vec3; 3]) -> WaldTriangle {
        // Precomputed in f64 so that tiny (1e-30) and huge (1e30) triangles neither underflow
        // nor overflow before the ratios are formed.
        let [a, b, c] = tri.map(|p| p.as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let n = e1.cross(e2);
        let abs = n.abs();
        let k = if abs.x >= abs.y && abs.x >= abs.z {
            0
        } else if abs.y >= abs.z {
            1
        } else {
            2
        };
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let nk = n[k];
        if nk == 0.0 || !nk.is_finite() || !tri.iter().all(|p| p.is_finite()) {
            let nan = f32::NAN;
            return WaldTriangle {
                kuv: pack_axes(k),
                n_u: nan,
                n_v: nan,
                a_k: nan,
                a_u: nan,
                a_v: nan,
                b_nu: nan,
                b_nv: nan,
                c_nu: nan,
                c_nv: nan,
            };
        }
        let inv = 1.0 / nk;
        WaldTriangle {
            kuv: pack_axes(k),
            n_u: (n[u] * inv) as f32,
            n_v: (n[v] * inv) as f32,
            a_k: a[k] as f32,
            a_u: a[u] as f32,
            a_v: a[v] as f32,
            b_nu: (e2[v] * inv) as f32,
            b_nv: (-e2[u] * inv) as f32,
            c_nu: (-e1[v] * inv) as f32,
            c_nv: (e1[u] * inv) as f32,
        }
    }
}

impl WaldTriangle {
    /// The projection axes `(k, u, v)`: `k` the normal's largest component, `u = k + 1`,
    /// `v = k + 2` (mod 3). Each is below 4, so it indexes a 4-lane array without a check.
    #[inline(always)]
    pub fn axes(&self) -> (usize, usize, usize) {
        ((self.kuv & 3) as usize, (self.kuv >> 8 & 3) as usize, (self.kuv >> 16 & 3) as usize)
    }
}

/// `k | (k + 1) % 3 << 8 | (k + 2) % 3 << 16`.
pub(crate) fn pack_axes(k: usize) -> u32 {
    (k | ((k + 1) % 3) << 8 | ((k + 2) % 3) << 16) as u32
}

/// The ray as arrays of four lanes, so that an axis chosen at run time indexes them without
/// a bounds check or a branch (`axis & 3 < 4`).
#[derive(Clone, Copy, Debug)]
pub struct RayArrays {
    /// Origin, `[x, y, z, 0]`.
    pub o: [f32; 4],
    /// Direction, `[x, y, z, 0]`.
    pub d: [f32; 4],
}

impl RayArrays {
    /// The arrays of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> RayArrays {
        RayArrays { o: ray.origin.extend(0.0).to_array(), d: ray.dir.extend(0.0).to_array() }
    }
}

impl TriangleTest for WaldTriangle {
    type RayData = RayArrays;

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayArrays {
        RayArrays::new(ray)
    }

    #[inline(always)]
    fn intersect(&self, ray: &Ray, r: &RayArrays, t_max: f32) -> Option<(f32, f32, f32)> {
        let (k, u, v) = self.axes();
        let (o, d) = (&r.o, &r.d);
        let denom = d[k] + self.n_u * d[u] + self.n_v * d[v];
        // Vertex `a` relative to the origin: nearby numbers, subtracted first.
        let (ak, au, av) = (self.a_k - o[k], self.a_u - o[u], self.a_v - o[v]);
        let t = (ak + self.n_u * au + self.n_v * av) / denom;
        // Written so that NaN (a degenerate record, or 0/0 for a ray in the plane) fails.
        if !(t >= ray.t_min && t <= t_max && t < f32::INFINITY) {
            return None;
        }
        let hu = t * d[u] - au;
        let hv = t * d[v] - av;
        let beta = self.b_nu * hu + self.b_nv * hv;
        let gamma = self.c_nu * hu + self.c_nv * hv;
        if beta >= 0.0 && gamma >= 0.0 && beta + gamma <= 1.0 { Some((t, beta, gamma)) } else { None }
    }
}

const MOD3: [usize; 5] = [0, 1, 2, 0, 1];

/// Record of the watertight test: the three vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct WatertightTriangle {
    /// The vertices (NaN for a degenerate triangle).
    pub v: [Vec3; 3],
}

impl WatertightTriangle {
    /// The record of triangle `[a, b, c]`. A zero-area triangle gets NaN vertices, which make
    /// every test fail (in ray space a collinear triangle can otherwise round to a tiny
    /// non-zero area and report a hit that the tree, which leaves such triangles out, never
    /// could); so does a triangle with a NaN or infinite vertex.
    pub fn new(tri: &[Vec3; 3]) -> WatertightTriangle {
        if is_degenerate(tri) || !tri.iter().all(|p| p.is_finite()) {
            return WatertightTriangle { v: [Vec3::NAN; 3] };
        }
        WatertightTriangle { v: *tri }
    }
}

/// The per-ray shear of the watertight test: the axis `kz` of the largest direction
/// component becomes the ray's axis, `kx, ky` are swapped when `d[kz] < 0` to keep the
/// winding, and `(sx, sy, sz)` shear and scale the ray direction to `(0, 0, 1)`.
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay {
    /// The axis that becomes the sheared ray's x.
    pub kx: usize,
    /// The axis that becomes the sheared ray's y.
    pub ky: usize,
    /// The axis of the direction's largest component, the sheared ray's z.
    pub kz: usize,
    /// `d[kx] / d[kz]`.
    pub sx: f32,
    /// `d[ky] / d[kz]`.
    pub sy: f32,
    /// `1 / d[kz]`.
    pub sz: f32,
}

impl TriangleTest for WatertightTriangle {
    type RayData = ShearedRay;

    #[inline]
    fn prepare(ray: &Ray) -> ShearedRay {
        let a = ray.dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = MOD3[kz + 1];
        let mut ky = MOD3[kx + 1];
        if ray.dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = ray.dir[kz];
        ShearedRay { kx, ky, kz, sx: ray.dir[kx] / dz, sy: ray.dir[ky] / dz, sz: 1.0 / dz }
    }

    #[inline]
    fn intersect(&self, ray: &Ray, s: &ShearedRay, t_max: f32) -> Option<(f32, f32, f32)> {
        // Vertices relative to the origin, sheared so the ray runs along +z.
        let a = (self.v[0] - ray.origin).extend(0.0).to_array();
        let b = (self.v[1] - ray.origin).extend(0.0).to_array();
        let c = (self.v[2] - ray.origin).extend(0.0).to_array();
        let s = &ShearedRay { kx: s.kx & 3, ky: s.ky & 3, kz: s.kz & 3, ..*s };
        let (ax, ay) = (a[s.kx] - s.sx * a[s.kz], a[s.ky] - s.sy * a[s.kz]);
        let (bx, by) = (b[s.kx] - s.sx * b[s.kz], b[s.ky] - s.sy * b[s.kz]);
        let (cx, cy) = (c[s.kx] - s.sx * c[s.kz], c[s.ky] - s.sy * c[s.kz]);
        // Scaled barycentrics: the 2D edge functions at the ray's footprint (the origin).
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        // In f32 each edge function has the right sign or is zero (rounding is monotonic, and
        // a difference of floats is zero only when they are equal). An exact zero may be a
        // rounding artefact (products that underflowed, or rounded to equal): redo the edges
        // in double precision, where the products of f32 values are exact and the sign of
        // their difference is therefore exact, so that a ray through a shared edge lands on one
        // side of it consistently. The signs are taken in f64: converting first would flush a
        // tiny non-zero value (a ray passing 1e-40 beside an edge) back to zero, and report a
        // hit outside the triangle (a fuzz finding).
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let (ax, ay, bx, by, cx, cy) = (ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64);
            let (u64, v64, w64) = (cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax);
            if (u64 < 0.0 || v64 < 0.0 || w64 < 0.0) && (u64 > 0.0 || v64 > 0.0 || w64 > 0.0) {
                return None;
            }
            (u, v, w) = (u64 as f32, v64 as f32, w64 as f32);
        } else if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 || det.is_nan() {
            return None;
        }
        let (az, bz, cz) = (s.sz * a[s.kz], s.sz * b[s.kz], s.sz * c[s.kz]);
        let t_scaled = u * az + v * bz + w * cz;
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        if !(t >= ray.t_min && t <= t_max && t < f32::INFINITY) {
            return None;
        }
        Some((t, v * inv_det, w * inv_det))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn both(tri: [Vec3; 3], ray: &Ray) -> [Option<(f32, f32, f32)>; 2] {
        let w = WaldTriangle::new(&tri);
        let wt = WatertightTriangle::new(&tri);
        [
            w.intersect(ray, &WaldTriangle::prepare(ray), ray.t_max),
            wt.intersect(ray, &WatertightTriangle::prepare(ray), ray.t_max),
        ]
    }

    const TRI: [Vec3; 3] = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];

    #[test]
    fn both_tests_agree_on_a_plain_hit_from_either_side() {
        for dz in [-1.0f32, 1.0] {
            let ray = Ray::new(Vec3::new(0.25, 0.5, -dz * 2.0), Vec3::new(0.0, 0.0, dz), 0.0, f32::INFINITY);
            for hit in both(TRI, &ray) {
                let (t, u, v) = hit.expect("hit");
                assert_relative_eq!(t, 2.0, epsilon = 1e-6);
                assert_relative_eq!(u, 0.25, epsilon = 1e-6);
                assert_relative_eq!(v, 0.5, epsilon = 1e-6);
            }
        }
    }

    #[test]
    fn non_finite_triangles_and_rays_never_hit() {
        let rays: Vec<Ray> = [(0.25f32, 0.25f32), (0.0, 0.0), (0.5, 0.5), (0.1, 0.8), (2.0, 2.0), (-1.0, 0.5)]
            .iter()
            .flat_map(|&(x, y)| {
                [Vec3::Z, Vec3::new(0.3, -0.2, 1.0), Vec3::new(1.0, 1.0, 0.01)]
                    .map(|d| Ray::new(Vec3::new(x, y, 0.0) - 2.0 * d, d, 0.0, f32::INFINITY))
            })
            .collect();
        assert!(rays.iter().any(|r| both(TRI, r).iter().all(Option::is_some)), "the finite triangle is hit");
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for corner in 0..3 {
                for axis in 0..3 {
                    let mut tri = TRI;
                    tri[corner][axis] = bad;
                    for ray in &rays {
                        assert_eq!(both(tri, ray), [None, None], "{tri:?} {ray:?}");
                    }
                }
            }
        }
        for ray in [
            Ray::new(Vec3::new(0.25, f32::NAN, -1.0), Vec3::Z, 0.0, f32::INFINITY),
            Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::new(0.0, f32::NAN, 1.0), 0.0, f32::INFINITY),
            Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, f32::NAN, f32::INFINITY),
            Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, 0.0, f32::NAN),
            Ray::new(Vec3::new(0.25, 0.25, f32::NEG_INFINITY), Vec3::Z, 0.0, f32::INFINITY),
        ] {
            assert_eq!(both(TRI, &ray), [None, None], "{ray:?}");
        }
    }

    #[test]
    fn misses_outside_and_outside_the_interval() {
        let ray = Ray::new(Vec3::new(0.75, 0.75, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(both(TRI, &ray), [None, None]);
        let ray = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, 0.0, 0.5);
        assert_eq!(both(TRI, &ray), [None, None]);
        let ray = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, 1.5, 3.0);
        assert_eq!(both(TRI, &ray), [None, None]);
    }

    #[test]
    fn degenerate_triangles_never_hit() {
        let flat = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        let point = [Vec3::ONE; 3];
        let collinear =
            [Vec3::new(-0.75, -0.75, 0.4531973), Vec3::new(-0.75, -0.75, 0.3497554), Vec3::new(-0.75, -0.75, -1.0)];
        let ray = Ray::new(Vec3::new(-2.0, 1.3998178, 1.5), Vec3::new(1.25, -2.149818, -2.5), 0.0, f32::INFINITY);
        assert_eq!(both(collinear, &ray), [None, None]);
        for tri in [flat, point] {
            for d in [Vec3::Z, Vec3::Y, Vec3::X, Vec3::new(1.0, 1.0, 1.0)] {
                let ray = Ray::new(Vec3::new(0.5, 0.0, 0.0) - d, d, 0.0, f32::INFINITY);
                assert_eq!(both(tri, &ray), [None, None], "{tri:?} {d}");
            }
        }
    }

    #[test]
    fn ray_in_the_triangle_plane_does_not_hit() {
        let ray = Ray::new(Vec3::new(-1.0, 0.25, 0.0), Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(TRI, &ray), [None, None]);
    }

    #[test]
    fn watertight_rays_through_a_shared_edge_never_leak() {
        // Two triangles sharing the diagonal of the unit square; rays exactly on the diagonal.
        let t0 = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)];
        let t1 = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        for i in 1..100 {
            let s = i as f32 / 100.0;
            let d = Vec3::new(0.01, -0.013, -1.0);
            let ray = Ray::new(Vec3::new(s, s, 0.0) - 3.0 * d, d, 0.0, f32::INFINITY);
            let p = WatertightTriangle::prepare(&ray);
            let h0 = WatertightTriangle::new(&t0).intersect(&ray, &p, f32::INFINITY);
            let h1 = WatertightTriangle::new(&t1).intersect(&ray, &p, f32::INFINITY);
            assert!(h0.is_some() || h1.is_some(), "ray {i} leaked");
        }
    }
}
