//! Surface records: what starting a ray on a triangle needs, precomputed once per scene.
//!
//! Every shadow ray starts at a primary hit: the hit point from its barycentrics
//! ([`crate::ray::surface_point`]), the triangle's geometric normal turned toward the viewer
//! (which side is lit) and the origin moved off the surface by [`crate::ray::offset_origin`].
//! Computed from the mesh, that is an index load, three scattered vertex loads, an `f32` and
//! an `f64` normalisation per ray: about as much time as a 2x2 packet's traversal of the
//! shadow ray itself on Sponza. A [`Surface`] holds all of it in one 64-byte cache line,
//! computed once per scene by [`Surfaces::new`], and gives the same results bit for bit
//! (tested against the mesh-based functions). [`SurfaceLanes`] holds four records in SIMD
//! lanes, for setting up four rays with one instruction per operation.

use glam::{Mat4, Vec3, Vec4};

use crate::Hit;

/// One triangle's record: vertex `a`, the edges `b - a` and `c - a`, the unit geometric
/// normal `(b - a) x (c - a)` normalised in `f32`, the same normal normalised in `f64` (the
/// offset direction of [`crate::ray::offset_origin`]) and the offset distance, 32 ulps of
/// the triangle's largest coordinate magnitude.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Surface {
    /// Vertex `a`.
    pub a: Vec3,
    /// `b - a`.
    pub e1: Vec3,
    /// `c - a`.
    pub e2: Vec3,
    /// The unit normal `e1 x e2` in `f32` (zero for a degenerate triangle), as
    /// `scenes::Mesh::geometric_normal`.
    pub normal: Vec3,
    /// The unit normal computed in `f64` from the vertices, rounded to `f32`: the direction
    /// [`crate::ray::offset_origin`] moves a point along.
    pub offset_normal: Vec3,
    /// How far [`crate::ray::offset_origin`] moves a point.
    pub offset: f32,
}

const _: () = assert!(std::mem::size_of::<Surface>() == 64);

impl Surface {
    /// The record of the triangle with vertices `tri`.
    pub fn new(tri: &[Vec3; 3]) -> Surface {
        let [a, b, c] = *tri;
        let [a64, b64, c64] = tri.map(|v| v.as_dvec3());
        let m = a.abs().max(b.abs()).max(c.abs()).max_element().max(1e-30);
        Surface {
            a,
            e1: b - a,
            e2: c - a,
            normal: (b - a).cross(c - a).normalize_or_zero(),
            offset_normal: (b64 - a64).cross(c64 - a64).normalize_or_zero().as_vec3(),
            offset: m * (32.0 * f32::EPSILON),
        }
    }

    /// The hit point from its barycentrics: [`crate::ray::surface_point`].
    #[inline(always)]
    pub fn point(&self, hit: &Hit) -> Vec3 {
        self.a + hit.u * self.e1 + hit.v * self.e2
    }

    /// The geometric normal on the side the ray direction `dir` came from (the viewer's).
    #[inline(always)]
    pub fn facing_normal(&self, dir: Vec3) -> Vec3 {
        if self.normal.dot(dir) > 0.0 { -self.normal } else { self.normal }
    }

    /// The surface point `p` moved off the surface toward `toward`:
    /// [`crate::ray::offset_origin`] with `p` its `surface_point`.
    #[inline(always)]
    pub fn offset_origin(&self, p: Vec3, toward: Vec3) -> Vec3 {
        let n = if self.offset_normal.dot(toward) < 0.0 { -self.offset_normal } else { self.offset_normal };
        p + n * self.offset
    }
}

/// Three coordinates of four points or vectors, one per SIMD lane: `[x, y, z]`.
pub type Lanes3 = [Vec4; 3];

/// The lane-by-lane dot product `a . b`, summed from `x` as [`Vec3::dot`] sums it (so each
/// lane is that dot product bit for bit).
#[inline(always)]
pub fn dot4(a: &Lanes3, b: &Lanes3) -> Vec4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `-v` where `mask` is set, `v` elsewhere.
#[inline(always)]
fn negate_where(mask: glam::BVec4A, v: &Lanes3) -> Lanes3 {
    v.map(|c| Vec4::select(mask, -c, c))
}

/// Four [`Surface`] records in SIMD lanes (a structure of arrays): lane `l` is record `l`.
/// Its methods are [`Surface`]'s, four lanes at once, each lane the scalar method's result
/// bit for bit (the same operations in the same order, each rounded alike; tested).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceLanes {
    /// Vertex `a` of each record.
    pub a: Lanes3,
    /// The edges `b - a`.
    pub e1: Lanes3,
    /// The edges `c - a`.
    pub e2: Lanes3,
    /// The `f32` unit normals.
    pub normal: Lanes3,
    /// The `f64`-normalised offset normals.
    pub offset_normal: Lanes3,
    /// The offset distances.
    pub offset: Vec4,
}

impl SurfaceLanes {
    /// The four records in lanes: each record's 64 bytes read as four vectors, then four
    /// 4x4 transposes (shuffles on SIMD targets) put each field's coordinate in one vector.
    #[inline(always)]
    pub fn gather(records: [&Surface; 4]) -> SurfaceLanes {
        let rows = records.map(|s| {
            [
                Vec4::new(s.a.x, s.a.y, s.a.z, s.e1.x),
                Vec4::new(s.e1.y, s.e1.z, s.e2.x, s.e2.y),
                Vec4::new(s.e2.z, s.normal.x, s.normal.y, s.normal.z),
                Vec4::new(s.offset_normal.x, s.offset_normal.y, s.offset_normal.z, s.offset),
            ]
        });
        let field = |k: usize| {
            let m = Mat4::from_cols(rows[0][k], rows[1][k], rows[2][k], rows[3][k]).transpose();
            [m.x_axis, m.y_axis, m.z_axis, m.w_axis]
        };
        let [ax, ay, az, e1x] = field(0);
        let [e1y, e1z, e2x, e2y] = field(1);
        let [e2z, nx, ny, nz] = field(2);
        let [ox, oy, oz, offset] = field(3);
        SurfaceLanes {
            a: [ax, ay, az],
            e1: [e1x, e1y, e1z],
            e2: [e2x, e2y, e2z],
            normal: [nx, ny, nz],
            offset_normal: [ox, oy, oz],
            offset,
        }
    }

    /// [`Surface::point`] in each lane, at the barycentrics `(u, v)`.
    #[inline(always)]
    pub fn point(&self, u: Vec4, v: Vec4) -> Lanes3 {
        std::array::from_fn(|i| self.a[i] + u * self.e1[i] + v * self.e2[i])
    }

    /// [`Surface::facing_normal`] in each lane, against `dir`.
    #[inline(always)]
    pub fn facing_normal(&self, dir: &Lanes3) -> Lanes3 {
        negate_where(dot4(&self.normal, dir).cmpgt(Vec4::ZERO), &self.normal)
    }

    /// [`Surface::offset_origin`] in each lane: `p` moved off the surface towards `toward`.
    #[inline(always)]
    pub fn offset_origin(&self, p: &Lanes3, toward: &Lanes3) -> Lanes3 {
        let n = negate_where(dot4(&self.offset_normal, toward).cmplt(Vec4::ZERO), &self.offset_normal);
        std::array::from_fn(|i| p[i] + n[i] * self.offset)
    }
}

/// The [`Surface`] of every triangle of a mesh, indexed like its triangles (and like the
/// `prim` of a [`Hit`]).
#[derive(Clone, Debug, Default)]
pub struct Surfaces {
    records: Vec<Surface>,
}

impl Surfaces {
    /// The records of the triangles `triangles` (indices into `positions`). A mesh that
    /// passed its checks (`scenes::Mesh::check`) has every index in range; an index past the
    /// positions gives a NaN vertex, so the rays started on that triangle are non-finite and
    /// rejected as any NaN input is, never a panic.
    pub fn new(positions: &[Vec3], triangles: &[[u32; 3]]) -> Surfaces {
        let vertex = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::NAN);
        let records = triangles.iter().map(|&[a, b, c]| Surface::new(&[vertex(a), vertex(b), vertex(c)])).collect();
        Surfaces { records }
    }

    /// The record of triangle `prim`.
    #[inline(always)]
    pub fn get(&self, prim: u32) -> &Surface {
        &self.records[prim as usize]
    }

    /// The number of records.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Bytes held.
    pub fn heap_bytes(&self) -> usize {
        self.records.capacity() * std::mem::size_of::<Surface>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::{offset_origin, surface_point};
    use crate::test_rng::XorShift;

    fn triangles() -> Vec<[Vec3; 3]> {
        let mut rng = XorShift(0x2545_f491_4f6c_dd1d);
        let mut next = move || rng.unit() - 0.5;
        let mut out = Vec::new();
        for scale in [1e-30f32, 1e-3, 1.0, 1e5, 1e30] {
            for shift in [0.0f32, 1e5, -3e6] {
                for _ in 0..40 {
                    let mut v = || Vec3::new(next(), next(), next()) * scale + Vec3::splat(shift);
                    out.push([v(), v(), v()]);
                }
            }
        }
        // Degenerate: a point, a line, and a sliver.
        out.push([Vec3::ONE; 3]);
        out.push([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
        out.push([Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1e-30, 0.0)]);
        out
    }

    #[test]
    fn records_answer_as_the_mesh_functions_bit_for_bit() {
        let hits = [(0.25f32, 0.5f32), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.3, 0.7), (0.1, 0.05)];
        let towards = [Vec3::X, -Vec3::Y, Vec3::new(0.3, -2.0, 0.5), Vec3::ZERO, Vec3::NAN];
        for tri in triangles() {
            let s = Surface::new(&tri);
            let [a, b, c] = tri;
            assert_eq!(s.normal.to_array(), (b - a).cross(c - a).normalize_or_zero().to_array());
            for (u, v) in hits {
                let hit = Hit { t: 1.0, u, v, prim: 0 };
                let p = s.point(&hit);
                assert_eq!(p.to_array(), surface_point(&tri, &hit).to_array());
                for toward in towards {
                    let want = offset_origin(&tri, &hit, toward);
                    let got = s.offset_origin(p, toward);
                    assert!(
                        want.to_array().iter().zip(got.to_array()).all(|(w, g)| w.to_bits() == g.to_bits()),
                        "{tri:?} {hit:?} {toward}: {want} != {got}"
                    );
                }
                for dir in towards {
                    let n = s.normal;
                    let want = if n.dot(dir) > 0.0 { -n } else { n };
                    assert_eq!(s.facing_normal(dir).to_array(), want.to_array());
                }
            }
        }
    }

    /// Four lanes of records answer as the scalar records, bit for bit: every run of four
    /// triangles (huge, tiny, far from the origin and degenerate ones), at every hit and
    /// direction of the scalar test, zero and NaN ones included.
    #[test]
    fn lanes_answer_as_the_records_bit_for_bit() {
        let records: Vec<Surface> = triangles().iter().map(Surface::new).collect();
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        let lane = |c: &Lanes3, l: usize| Vec3::new(c[0].to_array()[l], c[1].to_array()[l], c[2].to_array()[l]);
        let towards = [Vec3::X, -Vec3::Y, Vec3::new(0.3, -2.0, 0.5), Vec3::ZERO, Vec3::NAN];
        let hits = [(0.25f32, 0.5f32), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.3, 0.7), (0.1, 0.05)];
        for (k, group) in records.windows(4).enumerate() {
            let lanes = SurfaceLanes::gather([&group[0], &group[1], &group[2], &group[3]]);
            // Each lane its own hit and direction, rotated so that lanes differ.
            let (u, v) = (
                Vec4::from_array(std::array::from_fn(|l| hits[(k + l) % 6].0)),
                Vec4::from_array(std::array::from_fn(|l| hits[(k + l) % 6].1)),
            );
            let toward: Vec<Vec3> = (0..4).map(|l| towards[(k + 2 * l) % towards.len()]).collect();
            let toward4: Lanes3 = std::array::from_fn(|i| Vec4::from_array(std::array::from_fn(|l| toward[l][i])));
            let p = lanes.point(u, v);
            let facing = lanes.facing_normal(&toward4);
            let start = lanes.offset_origin(&p, &toward4);
            for (l, s) in group.iter().enumerate() {
                let hit = Hit { t: 1.0, u: u.to_array()[l], v: v.to_array()[l], prim: 0 };
                let want = s.point(&hit);
                assert_eq!(bits(lane(&p, l)), bits(want), "{s:?} lane {l}");
                assert_eq!(bits(lane(&facing, l)), bits(s.facing_normal(toward[l])), "{s:?} lane {l}");
                assert_eq!(bits(lane(&start, l)), bits(s.offset_origin(want, toward[l])), "{s:?} lane {l}");
            }
        }
    }

    #[test]
    fn non_finite_vertices_give_non_finite_points_not_panics() {
        let s = Surface::new(&[Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Z]);
        let p = s.point(&Hit { t: 1.0, u: 0.5, v: 0.25, prim: 0 });
        assert!(!p.is_finite());
        assert!(!s.offset_origin(p, Vec3::Y).is_finite());
    }

    #[test]
    fn table_follows_the_triangles_and_poisons_bad_indices() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let table = Surfaces::new(&positions, &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!(table.len(), 2);
        assert_eq!(table.get(1), &Surface::new(&[Vec3::ZERO, Vec3::Y, Vec3::Z]));
        assert!(table.heap_bytes() >= 128);
        let bad = Surfaces::new(&positions, &[[0, 1, 9]]);
        assert!(!bad.get(0).point(&Hit { t: 1.0, u: 0.2, v: 0.2, prim: 0 }).is_finite());
    }
}
