//! Clipping a triangle to a box (Sutherland-Hodgman), the basis of perfect splits (thesis
//! 3.2.1: "candidate split planes were taken as the edges of each polygon's clipped bounding
//! box"; Wald & Havran 2006, section 4.3 "split clipping").
//!
//! The clip runs in `f64` on the `f32` inputs. Each polygon vertex remembers which of its
//! coordinates are exact (an input vertex coordinate, or the coordinate of a clip plane), so
//! that the clipped box can be rounded to `f32` exactly where it is exact (a triangle lying
//! in a plane stays planar, a vertex on a split plane stays on it) and outward, with a margin,
//! where it was computed.

use glam::Vec3;

/// The most vertices a triangle clipped by six planes can have (3 + 6).
const MAX_VERTS: usize = 9;

/// A convex polygon: a triangle clipped to a box, in `f64`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Polygon {
    /// Number of vertices.
    pub len: usize,
    /// Vertices.
    pub v: [[f64; 3]; MAX_VERTS],
    /// Bit `k` set: coordinate `k` of the vertex is exact.
    exact: [u8; MAX_VERTS],
}

impl Polygon {
    /// The triangle as a polygon (all coordinates exact).
    #[inline]
    fn triangle(tri: &[Vec3; 3]) -> Polygon {
        let mut p = Polygon { len: 3, v: [[0.0; 3]; MAX_VERTS], exact: [7; MAX_VERTS] };
        for (i, t) in tri.iter().enumerate() {
            p.v[i] = [f64::from(t.x), f64::from(t.y), f64::from(t.z)];
        }
        p
    }

    /// The vertices.
    #[inline]
    pub fn verts(&self) -> &[[f64; 3]] {
        &self.v[..self.len]
    }

    /// Keeps the part with `sign * (x_k - c) >= 0` (`sign` is +1 for a lower plane, -1 for an
    /// upper one). Returns false when nothing is left.
    #[inline]
    fn clip_plane(&mut self, k: usize, c: f64, upper: bool) -> bool {
        let inside = |x: f64| if upper { x <= c } else { x >= c };
        let mut out = Polygon { len: 0, v: [[0.0; 3]; MAX_VERTS], exact: [0; MAX_VERTS] };
        for i in 0..self.len {
            let a = self.v[i];
            let ea = self.exact[i];
            let j = if i + 1 == self.len { 0 } else { i + 1 };
            let b = self.v[j];
            let eb = self.exact[j];
            let (ain, bin) = (inside(a[k]), inside(b[k]));
            if ain && out.len < MAX_VERTS {
                out.v[out.len] = a;
                out.exact[out.len] = ea;
                out.len += 1;
            }
            if ain != bin && out.len < MAX_VERTS {
                let t = (c - a[k]) / (b[k] - a[k]);
                let mut p = [0.0; 3];
                let mut ex = 1u8 << k;
                for m in 0..3 {
                    if m == k {
                        p[m] = c;
                    } else if a[m] == b[m] {
                        p[m] = a[m];
                        ex |= ea & eb & (1 << m);
                    } else {
                        p[m] = a[m] + t * (b[m] - a[m]);
                    }
                }
                out.v[out.len] = p;
                out.exact[out.len] = ex;
                out.len += 1;
            }
        }
        *self = out;
        self.len > 0
    }
}

/// Clips triangle `tri` to the closed box `[lo, hi]`. `None` when they do not meet. Only the
/// planes the triangle's own box crosses are clipped against.
#[inline]
pub(crate) fn clip_triangle(tri: &[Vec3; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<Polygon> {
    let mut p = Polygon::triangle(tri);
    for k in 0..3 {
        let (mut tmin, mut tmax) = (p.v[0][k], p.v[0][k]);
        for v in &p.v[1..3] {
            tmin = tmin.min(v[k]);
            tmax = tmax.max(v[k]);
        }
        if tmax < lo[k] || tmin > hi[k] {
            return None;
        }
        if tmin < lo[k] && !p.clip_plane(k, lo[k], false) {
            return None;
        }
        if tmax > hi[k] && !p.clip_plane(k, hi[k], true) {
            return None;
        }
    }
    Some(p)
}

/// The next `f32` below `x` (finite, non-NaN input).
#[inline]
fn next_down(x: f32) -> f32 {
    if x == 0.0 {
        return -f32::from_bits(1);
    }
    let b = x.to_bits();
    f32::from_bits(if x > 0.0 { b - 1 } else { b + 1 })
}

/// The next `f32` above `x`.
#[inline]
fn next_up(x: f32) -> f32 {
    -next_down(-x)
}

/// The largest `f32` that is `<= x` (saturating at `f32::MIN`).
#[inline]
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x && f > f32::MIN { next_down(f) } else { f }
}

/// The smallest `f32` that is `>= x` (saturating at `f32::MAX`).
#[inline]
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x && f < f32::MAX { next_up(f) } else { f }
}

/// The box of `tri` clipped to the box `[lo, hi]`, as `f32`, or `None` when they do not meet.
///
/// Exact polygon coordinates are kept exactly; computed ones are widened by a relative margin
/// of the triangle's coordinate magnitude (far above the `f64` rounding error) and rounded
/// outward, so the result contains the exact clipped triangle. It is clamped to the box.
pub(crate) fn clipped_bounds(tri: &[Vec3; 3], lo: [f32; 3], hi: [f32; 3]) -> Option<([f32; 3], [f32; 3])> {
    let lo64 = lo.map(f64::from);
    let hi64 = hi.map(f64::from);
    let poly = clip_triangle(tri, lo64, hi64)?;
    let mut margin = [0.0f64; 3];
    for (k, m) in margin.iter_mut().enumerate() {
        let mag = tri.iter().fold(lo64[k].abs().max(hi64[k].abs()), |acc, v| acc.max(f64::from(v[k]).abs()));
        *m = mag * (1.0 / (1u64 << 36) as f64);
    }
    let mut bmin = [f32::INFINITY; 3];
    let mut bmax = [f32::NEG_INFINITY; 3];
    for i in 0..poly.len {
        for k in 0..3 {
            let x = poly.v[i][k];
            let (a, b) = if poly.exact[i] & (1 << k) != 0 {
                (x as f32, x as f32)
            } else {
                (round_down(x - margin[k]), round_up(x + margin[k]))
            };
            bmin[k] = bmin[k].min(a);
            bmax[k] = bmax[k].max(b);
        }
    }
    for k in 0..3 {
        bmin[k] = bmin[k].clamp(lo[k], hi[k]);
        bmax[k] = bmax[k].clamp(lo[k], hi[k]);
        if bmax[k] < bmin[k] {
            bmax[k] = bmin[k];
        }
    }
    Some((bmin, bmax))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f32, y: f32, z: f32) -> Vec3 {
        Vec3::new(x, y, z)
    }

    #[test]
    fn inside_triangle_is_its_own_box() {
        let t = [v(0.1, 0.2, 0.3), v(0.9, 0.2, 0.3), v(0.1, 0.8, 0.7)];
        let (lo, hi) = clipped_bounds(&t, [0.0; 3], [1.0; 3]).unwrap();
        assert_eq!(lo, [0.1, 0.2, 0.3]);
        assert_eq!(hi, [0.9, 0.8, 0.7]);
    }

    #[test]
    fn clipping_tightens_and_contains() {
        // A diagonal triangle clipped to the lower-left quarter.
        let t = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)];
        let (lo, hi) = clipped_bounds(&t, [1.0, 1.0, -1.0], [2.0, 2.0, 1.0]).unwrap();
        // Only the corner point (1, 1) is inside; computed coordinates are widened a little.
        for k in 0..2 {
            assert!(lo[k] == 1.0 && hi[k] >= 1.0 && hi[k] < 1.0001, "{lo:?} {hi:?}");
        }
        assert_eq!((lo[2], hi[2]), (0.0, 0.0));
        let (lo, hi) = clipped_bounds(&t, [0.5, 0.5, -1.0], [2.0, 2.0, 1.0]).unwrap();
        assert!(lo[0] <= 0.5 && hi[0] >= 1.5 && hi[0] < 1.5001, "{lo:?} {hi:?}");
        assert_eq!((lo[2], hi[2]), (0.0, 0.0)); // planar stays planar
        assert!(clipped_bounds(&t, [1.5, 1.5, -1.0], [2.0, 2.0, 1.0]).is_none());
    }

    #[test]
    fn rounding_helpers() {
        assert!(next_down(0.0) < 0.0 && next_up(0.0) > 0.0);
        assert!(next_down(1.0) < 1.0 && next_up(-1.0) > -1.0);
        let x = 0.1f64;
        assert!(f64::from(round_down(x)) <= x && f64::from(round_up(x)) >= x);
    }
}
