//! Surface records: what starting a ray on a triangle needs, precomputed once per scene.
//!
//! Every shadow ray starts at a primary hit: the hit point from its barycentrics
//! ([`crate::ray::surface_point`]), the triangle's geometric normal turned toward the viewer
//! (which side is lit) and the origin moved off the surface by [`crate::ray::offset_origin`].
//! Computed from the mesh, that is an index load, three scattered vertex loads, an `f32` and
//! an `f64` normalisation per ray: about as much time as a 2x2 packet's traversal of the
//! shadow ray itself on Sponza. A [`Surface`] holds all of it in one 64-byte cache line,
//! computed once per scene by [`Surfaces::new`], and gives the same results bit for bit
//! (tested against the mesh-based functions).

use glam::Vec3;

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
