//! When two different answers are both right: the geometry of ties.
//!
//! Two tracers (or two kernels of one) may name different triangles for one ray and both be
//! right where the ray meets both at one distance: at an edge or vertex the triangles share,
//! or on coincident (coplanar, overlapping) faces. `experiments::compare` classifies its
//! mismatches with these tests and the conformance harness (the test-support crate
//! `conformance`) accepts such ties.

use glam::Vec3;

/// Whether `p` lies within `tol` of the shared corners `shared` of two triangles: of the
/// vertex, or of the edge between the first two.
pub fn near_shared(shared: &[Vec3], p: Vec3, tol: f32) -> bool {
    match shared {
        [] => false,
        [v] => (p - *v).length() <= tol,
        [v, w, ..] => {
            let e = *w - *v;
            let s = ((p - *v).dot(e) / e.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
            (p - (*v + s * e)).length() <= tol
        }
    }
}

/// Whether two triangles lie in one plane: normals parallel within 1e-4 rad, the second's
/// corners within 1e-4 of the triangles' size from the first's plane (in `f64`).
pub fn coplanar(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    let [a, b] = [a, b].map(|t| t.map(|v| v.as_dvec3()));
    let (na, nb) = ((a[1] - a[0]).cross(a[2] - a[0]), (b[1] - b[0]).cross(b[2] - b[0]));
    let (Some(na), Some(nb)) = (na.try_normalize(), nb.try_normalize()) else { return false };
    let size = a.iter().chain(&b).fold(0.0f64, |m, v| m.max((*v - a[0]).length()));
    na.cross(nb).length() <= 1e-4 && b.iter().all(|v| na.dot(*v - a[0]).abs() <= 1e-4 * size)
}
