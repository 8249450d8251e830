//! Clipping a triangle to a box (Sutherland-Hodgman), the basis of perfect splits (thesis
//! 3.2.1: "candidate split planes were taken as the edges of each polygon's clipped bounding
//! box"; Wald & Havran 2006, section 4.3 "split clipping").
//!
//! The clip runs in `f64` on the `f32` inputs, and the clipped box is rounded outward to
//! `f32`. Coordinates that are exact stay exact: input vertex coordinates, the plane
//! coordinate of a clipped vertex (set, not computed), and coordinates along which an edge
//! does not move (`a + t * 0 = a`), and outward rounding leaves an `f32` value unchanged. So
//! a triangle lying in a plane stays planar and a vertex on a split plane stays on it, while
//! computed coordinates are widened to the enclosing `f32`s (the `f64` error, about `2^-50`
//! relative, is far below an `f32` step).

use glam::Vec3;

/// The most vertices a triangle clipped by seven planes (a box, then a split plane) can have.
const MAX_VERTS: usize = 10;

/// A convex polygon: a triangle clipped to a box, in `f64`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Polygon {
    /// Number of vertices.
    len: usize,
    /// Vertices.
    v: [[f64; 3]; MAX_VERTS],
}

impl Default for Polygon {
    fn default() -> Self {
        Polygon::EMPTY
    }
}

impl Polygon {
    const EMPTY: Polygon = Polygon { len: 0, v: [[0.0; 3]; MAX_VERTS] };

    /// The vertices.
    #[inline]
    pub fn verts(&self) -> &[[f64; 3]] {
        &self.v[..self.len]
    }

    /// Writes to `dst` the part of `self` with `x_k >= c` (`UPPER = false`) or `x_k <= c`
    /// (`UPPER = true`). Points on the plane are kept.
    #[inline]
    fn clip_into<const UPPER: bool>(&self, dst: &mut Polygon, k: usize, c: f64) {
        let inside = |x: f64| if UPPER { x <= c } else { x >= c };
        let n = self.len;
        let mut w = 0;
        let mut a = self.v[n - 1];
        let mut ain = inside(a[k]);
        for i in 0..n {
            let b = self.v[i];
            let bin = inside(b[k]);
            if ain != bin && w < MAX_VERTS {
                let t = (c - a[k]) / (b[k] - a[k]);
                let mut p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])];
                p[k] = c;
                dst.v[w] = p;
                w += 1;
            }
            if bin && w < MAX_VERTS {
                dst.v[w] = b;
                w += 1;
            }
            a = b;
            ain = bin;
        }
        dst.len = w;
    }

    /// The `f32` box of the polygon, which lies in the box `[lo, hi]`: rounded outward, then
    /// clamped to the box.
    #[cfg(test)]
    fn bounds(&self, lo: [f32; 3], hi: [f32; 3]) -> Bounds {
        let mut mn = self.v[0];
        let mut mx = self.v[0];
        for v in &self.v[1..self.len] {
            extend(&mut mn, &mut mx, v);
        }
        to_bounds(&mn, &mx, lo, hi)
    }

    /// The `f32` boxes of the parts of the polygon (inside the box `[lo, hi]`) below and above
    /// the plane `x_k = p`, computed in one pass without building the two polygons: the
    /// vertices on each side (those on the plane on both) and the points where edges cross.
    #[inline]
    fn split_bounds(&self, lo: [f32; 3], hi: [f32; 3], k: usize, p: f32) -> (Option<Bounds>, Option<Bounds>) {
        let c = f64::from(p);
        let (mut lmin, mut lmax) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let (mut rmin, mut rmax) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut a = self.v[self.len - 1];
        for &b in &self.v[..self.len] {
            if b[k] <= c {
                extend(&mut lmin, &mut lmax, &b);
            }
            if b[k] >= c {
                extend(&mut rmin, &mut rmax, &b);
            }
            if (a[k] < c && b[k] > c) || (a[k] > c && b[k] < c) {
                let t = (c - a[k]) / (b[k] - a[k]);
                let mut q = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])];
                q[k] = c;
                extend(&mut lmin, &mut lmax, &q);
                extend(&mut rmin, &mut rmax, &q);
            }
            a = b;
        }
        let (mut lhi, mut rlo) = (hi, lo);
        lhi[k] = p;
        rlo[k] = p;
        let left = (lmin[0] <= lmax[0]).then(|| to_bounds(&lmin, &lmax, lo, lhi));
        let right = (rmin[0] <= rmax[0]).then(|| to_bounds(&rmin, &rmax, rlo, hi));
        (left, right)
    }
}

/// Grows the box `[mn, mx]` to contain `v`.
#[inline(always)]
fn extend(mn: &mut [f64; 3], mx: &mut [f64; 3], v: &[f64; 3]) {
    for k in 0..3 {
        mn[k] = mn[k].min(v[k]);
        mx[k] = mx[k].max(v[k]);
    }
}

/// The `f64` box `[mn, mx]` rounded outward to `f32` and clamped to the box `[lo, hi]`.
#[inline]
fn to_bounds(mn: &[f64; 3], mx: &[f64; 3], lo: [f32; 3], hi: [f32; 3]) -> Bounds {
    let mut bmin = [0.0f32; 3];
    let mut bmax = [0.0f32; 3];
    for k in 0..3 {
        bmin[k] = round_down(mn[k]).clamp(lo[k], hi[k]);
        bmax[k] = round_up(mx[k]).clamp(lo[k], hi[k]).max(bmin[k]);
    }
    (bmin, bmax)
}

/// A clipped triangle's box: `(min, max)` corners.
pub(crate) type Bounds = ([f32; 3], [f32; 3]);

/// One clip step on the ping-pong buffers: clips `bufs[*cur]` into the other buffer and
/// makes that current; false when nothing is left.
#[inline]
fn step<const UPPER: bool>(bufs: &mut [Polygon; 2], cur: &mut usize, k: usize, c: f64) -> bool {
    let [a, b] = bufs;
    let (src, dst) = if *cur == 0 { (&*a, b) } else { (&*b, a) };
    src.clip_into::<UPPER>(dst, k, c);
    *cur ^= 1;
    dst.len > 0
}

/// Clips triangle `tri` to the closed box `[lo, hi]` in the ping-pong buffers; returns the
/// index of the buffer holding the polygon, or `None` when they do not meet. Only the planes
/// the triangle's own box crosses are clipped against.
#[inline]
fn clip_to_box(tri: &[Vec3; 3], lo: [f64; 3], hi: [f64; 3], bufs: &mut [Polygon; 2]) -> Option<usize> {
    let t = tri.map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)]);
    bufs[0].len = 3;
    bufs[0].v[..3].copy_from_slice(&t);
    let mut cur = 0;
    for k in 0..3 {
        // The current polygon's extent: planes it no longer crosses are skipped.
        let poly = &bufs[cur];
        let (mut tmin, mut tmax) = (poly.v[0][k], poly.v[0][k]);
        for v in &poly.v[1..poly.len] {
            tmin = tmin.min(v[k]);
            tmax = tmax.max(v[k]);
        }
        if tmax < lo[k] || tmin > hi[k] {
            return None;
        }
        if tmin < lo[k] && !step::<false>(bufs, &mut cur, k, lo[k]) {
            return None;
        }
        if tmax > hi[k] && !step::<true>(bufs, &mut cur, k, hi[k]) {
            return None;
        }
    }
    Some(cur)
}

/// Clips triangle `tri` to the closed box `[lo, hi]`. `None` when they do not meet.
pub(crate) fn clip_triangle(tri: &[Vec3; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<Polygon> {
    let mut bufs = [Polygon::EMPTY; 2];
    clip_to_box(tri, lo, hi, &mut bufs).map(|c| bufs[c])
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
/// Exact polygon coordinates are kept exactly; computed ones are rounded outward, so the
/// result contains the clipped polygon (whose `f64` error, about `2^-50` relative, is far
/// below an `f32` step). It is clamped to the box.
#[cfg(test)]
pub(crate) fn clipped_bounds(tri: &[Vec3; 3], lo: [f32; 3], hi: [f32; 3]) -> Option<Bounds> {
    let mut bufs = [Polygon::EMPTY; 2];
    let c = clip_to_box(tri, lo.map(f64::from), hi.map(f64::from), &mut bufs)?;
    Some(bufs[c].bounds(lo, hi))
}

/// The clipped boxes of `tri` in the two children of the box `[lo, hi]` split on axis `k` at
/// `p`: the triangle is clipped to the node box once and the polygon cut by the plane, which
/// gives both children (`T ∩ child = (T ∩ node) ∩ half-space`). `bufs` are scratch polygons
/// (their contents do not matter), kept by the caller so they are not cleared for every call.
pub(crate) fn clipped_split_bounds(
    tri: &[Vec3; 3],
    lo: [f32; 3],
    hi: [f32; 3],
    k: usize,
    p: f32,
    bufs: &mut [Polygon; 2],
) -> (Option<Bounds>, Option<Bounds>) {
    match clip_to_box(tri, lo.map(f64::from), hi.map(f64::from), bufs) {
        Some(c) => bufs[c].split_bounds(lo, hi, k, p),
        None => (None, None),
    }
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
    fn split_bounds_match_clipping_each_child() {
        let t = [v(0.1, 0.2, 0.3), v(1.9, 0.4, 0.5), v(0.3, 1.7, 1.9)];
        let (lo, hi) = ([0.0, 0.0, 0.0], [1.5, 1.5, 1.5]);
        for k in 0..3 {
            for p in [0.25f32, 0.5, 1.0] {
                let (mut lhi, mut rlo) = (hi, lo);
                lhi[k] = p;
                rlo[k] = p;
                let (l, r) = clipped_split_bounds(&t, lo, hi, k, p, &mut Default::default());
                for (a, b) in [(l, clipped_bounds(&t, lo, lhi)), (r, clipped_bounds(&t, rlo, hi))] {
                    assert_eq!(a.is_some(), b.is_some());
                    let (Some(a), Some(b)) = (a, b) else { continue };
                    for i in 0..3 {
                        assert!((a.0[i] - b.0[i]).abs() < 1e-6 && (a.1[i] - b.1[i]).abs() < 1e-6, "{a:?} {b:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn rounding_helpers() {
        assert!(next_down(0.0) < 0.0 && next_up(0.0) > 0.0);
        assert!(next_down(1.0) < 1.0 && next_up(-1.0) > -1.0);
        let x = 0.1f64;
        assert!(f64::from(round_down(x)) <= x && f64::from(round_up(x)) >= x);
    }
}
