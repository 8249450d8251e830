//! Clipping a triangle to a box (Sutherland-Hodgman), the basis of perfect splits (thesis
//! 3.2.1: "candidate split planes were taken as the edges of each polygon's clipped bounding
//! box"; Wald & Havran 2006, section 4.3 "split clipping").
//!
//! The clip runs in `f64` on the `f32` inputs, and the clipped box is rounded outward to
//! `f32`. It is *conservative*: the box always contains the exact box of the triangle's part
//! inside the clip box, so the builder never leaves a triangle out of a leaf it enters.
//!
//! - **Exact coordinates stay exact**: input vertex coordinates, the plane coordinate of a
//!   clipped vertex (set, not computed), and coordinates along which an edge does not move
//!   (`a + t * 0 = a`); outward rounding leaves an `f32` value unchanged. So a triangle lying
//!   in a plane stays planar and a vertex on a split plane stays on it. Each vertex carries a
//!   mask of its exact coordinates.
//! - **Computed coordinates carry a bounded error.** A new vertex, computed as
//!   `(a_j (b_k - c) + b_j (c - a_k)) / (b_k - a_k)` for the crossing of edge `a -> b` with
//!   the plane `x_k = c`, is off the exact crossing of the computed edge by at most about
//!   `5 u M` per coordinate (`u = 2^-53`, `M` the largest magnitude among the triangle's
//!   coordinates, which bounds every clipped coordinate). Each step adds [`RHO_REL`]` * M`
//!   (`128 u M`, a wide margin) to the error bound of every axis along which it computed a
//!   coordinate that is not provably exact. The error does not depend on the edge's slope,
//!   and it is not relative to the box: a triangle with 1e29 coordinates clipped to a 1e9
//!   box has errors far larger than the box. (A fuzz finding: the former `a + t (b - a)` with
//!   `t = 1 - 2e-20` rounded to 1 moved a clipped vertex by 1.4e9, the clipped box missed
//!   most of the triangle's part in the box, and the tree left the triangle out of a leaf.)
//! - **No part of the triangle is cut off by an error.** A plane on an axis whose coordinates
//!   have error `E` is moved outward by `E` before clipping, so a vertex that is inside in
//!   exact arithmetic is never dropped, and the inexact extremes of the final box are moved
//!   outward by the error of their axis. By induction over the clip steps, every point of
//!   the exact clipped triangle lies within the error bound of the computed polygon, so the
//!   widened box contains its exact box. The result is clamped to the clip box and cut to the
//!   triangle's own (exact) box, which brings a widened extreme back to the vertex coordinate
//!   it passed. For ordinary scenes the bound is about `1e-14 M`, far below an `f32` step of
//!   most coordinates, so the boxes are nearly as tight as without it: 0.2% to 1% more
//!   references on the built-in scenes, where planes moved by an error put vertices within it
//!   of a split on both sides.
//!   The bookkeeping costs about 15% of the build's instructions (callgrind, atrium).
//!
//! [`clip_triangle`] is the same clip without moving the planes, for
//! [`crate::KdTree::validate`]: its polygon lies within the error bound of the exact one, so
//! a point inside the box by more than the bound is inside in exact arithmetic.

use glam::Vec3;

/// The most vertices a triangle clipped by seven planes (a box, then a split plane) can have.
const MAX_VERTS: usize = 10;

/// The error bound one clip step adds to a computed coordinate, relative to the largest
/// coordinate magnitude `M` of the triangle: `2^-46 = 128 u`, over twenty times the `5 u M`
/// that the step's seven roundings (the two weights, the two products, their sum, the
/// denominator, the quotient) can add, so that the bound also covers the roundings of the
/// widening itself.
const RHO_REL: f64 = 1.0 / (1u64 << 46) as f64;

/// All three coordinates of a vertex exact.
const ALL_EXACT: u8 = 0b111;

/// `i mod 3` for `i < 5`: the two axes other than `k` are `MOD3[k + 1]`, `MOD3[k + 2]`.
const MOD3: [usize; 5] = [0, 1, 2, 0, 1];

/// A convex polygon: a triangle clipped to a box, in `f64`, with error bounds.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Polygon {
    /// Number of vertices.
    len: usize,
    /// Vertices.
    v: [[f64; 3]; MAX_VERTS],
    /// Per vertex, bit `j` set when coordinate `j` is exact.
    exact: [u8; MAX_VERTS],
    /// Per axis, a bound on the absolute error of the vertices' inexact coordinates.
    err: [f64; 3],
    /// The error one clip step adds: [`RHO_REL`] times the triangle's largest magnitude.
    rho: f64,
    /// The triangle's own box (exact), which contains every clipped part of it: a widened
    /// extreme that passes it is cut back to the triangle's vertex coordinate.
    tri_lo: [f32; 3],
    /// Upper corner of the triangle's box.
    tri_hi: [f32; 3],
}

impl Default for Polygon {
    fn default() -> Self {
        Polygon::EMPTY
    }
}

/// The `f64` box of some polygon vertices, each inexact coordinate widened by its error.
struct BoxAcc {
    mn: [f64; 3],
    mx: [f64; 3],
}

impl BoxAcc {
    const EMPTY: BoxAcc = BoxAcc { mn: [f64::INFINITY; 3], mx: [f64::NEG_INFINITY; 3] };

    /// Grows the box to `v` widened by `widen` (per axis: the error, or 0 where exact; see
    /// [`widen_table`]).
    #[inline(always)]
    fn add(&mut self, v: &[f64; 3], widen: &[f64; 3]) {
        for k in 0..3 {
            self.mn[k] = self.mn[k].min(v[k] - widen[k]);
            self.mx[k] = self.mx[k].max(v[k] + widen[k]);
        }
    }

    fn is_empty(&self) -> bool {
        self.mn[0] > self.mx[0]
    }
}

/// Per exact mask (bit `k` set: coordinate `k` exact), the widening of each coordinate: `err`
/// where inexact, 0 where exact.
#[inline(always)]
fn widen_table(err: &[f64; 3]) -> [[f64; 3]; 8] {
    std::array::from_fn(|m| std::array::from_fn(|k| if m >> k & 1 == 1 { 0.0 } else { err[k] }))
}

/// `c` moved outward (down for a lower plane, up for an upper one) by the error `e`, rounded
/// outward; `c` itself when `e` is zero.
#[inline(always)]
fn widen(c: f64, e: f64, upper: bool) -> f64 {
    if e == 0.0 {
        c
    } else if upper {
        (c + e).next_up()
    } else {
        (c - e).next_down()
    }
}

impl Polygon {
    const EMPTY: Polygon = Polygon {
        len: 0,
        v: [[0.0; 3]; MAX_VERTS],
        exact: [0; MAX_VERTS],
        err: [0.0; 3],
        rho: 0.0,
        tri_lo: [0.0; 3],
        tri_hi: [0.0; 3],
    };

    /// Makes this polygon the whole triangle `tri`: exact, no error yet. Only the fields read
    /// later are written (the vertex arrays beyond the three are left as they are).
    #[inline]
    fn set_triangle(&mut self, tri: &[Vec3; 3]) {
        self.len = 3;
        let mut m = 0.0f32;
        for (i, v) in tri.iter().enumerate() {
            self.v[i] = [f64::from(v.x), f64::from(v.y), f64::from(v.z)];
            self.exact[i] = ALL_EXACT;
            m = m.max(v.abs().max_element());
        }
        self.err = [0.0; 3];
        self.rho = f64::from(m) * RHO_REL;
        self.tri_lo = tri[0].min(tri[1]).min(tri[2]).to_array();
        self.tri_hi = tri[0].max(tri[1]).max(tri[2]).to_array();
    }

    /// The vertices.
    #[inline]
    pub fn verts(&self) -> &[[f64; 3]] {
        &self.v[..self.len]
    }

    /// Per axis, the bound on the absolute error of the vertices' coordinates (zero where
    /// every coordinate is exact).
    #[inline]
    pub fn err(&self) -> [f64; 3] {
        self.err
    }

    /// The error one more computation on these vertices may add ([`RHO_REL`] times the
    /// triangle's largest magnitude); a bound for the rounding of a centroid, for example.
    #[inline]
    pub fn rho(&self) -> f64 {
        self.rho
    }

    /// The crossing of the edge `a -> b` (exact masks `ea`, `eb`) with the plane `x_k = c`,
    /// which the edge crosses; returns the point, its exact mask, and the axes along which it
    /// was computed with a possible rounding (bit mask), whose error bounds grow by `rho`.
    ///
    /// A computed coordinate that comes out as an `f32` value is checked for exactness (when
    /// its inputs are exact): otherwise widening it would move it off that `f32` value, often
    /// a plane where other triangles' vertices lie, and cost tightness for nothing.
    #[inline(always)]
    fn crossing(a: &[f64; 3], ea: u8, b: &[f64; 3], eb: u8, k: usize, c: f64) -> ([f64; 3], u8, u8) {
        // p_j = (a_j (b_k - c) + b_j (c - a_k)) / (b_k - a_k): one rounding of the exact
        // quotient when the terms are exact (so a crossing at an `f32` value comes out
        // exactly), and an error of a few ulps of max(|a_j|, |b_j|) whatever the slope.
        let (wa, wb, d) = (b[k] - c, c - a[k], b[k] - a[k]);
        let mut p = *a;
        p[k] = c;
        let mut exact = 1 << k;
        let mut moved = 0;
        let both = ea & eb;
        for j in [MOD3[k + 1], MOD3[k + 2]] {
            let bit = 1 << j;
            if a[j] == b[j] {
                // No new error, exact if both ends are.
                exact |= both & bit;
                continue;
            }
            p[j] = (a[j] * wa + b[j] * wb) / d;
            if both & (bit | 1 << k) == bit | 1 << k
                && f64::from(p[j] as f32) == p[j]
                && exact_crossing(a[j], b[j], a[k], b[k], c, p[j])
            {
                exact |= bit;
            } else {
                moved |= bit;
            }
        }
        (p, exact, moved)
    }

    /// Writes to `dst` the part of `self` with `x_k >= c` (`UPPER = false`) or `x_k <= c`
    /// (`UPPER = true`). Points on the plane are kept.
    #[inline]
    fn clip_into<const UPPER: bool>(&self, dst: &mut Polygon, k: usize, c: f64) {
        let inside = |x: f64| if UPPER { x <= c } else { x >= c };
        let n = self.len;
        let mut w = 0;
        let mut moved = 0u8;
        let mut ia = n - 1;
        let mut ain = inside(self.v[ia][k]);
        for i in 0..n {
            let b = self.v[i];
            let bin = inside(b[k]);
            if ain != bin && w < MAX_VERTS {
                let (p, e, m) = Self::crossing(&self.v[ia], self.exact[ia], &b, self.exact[i], k, c);
                dst.v[w] = p;
                dst.exact[w] = e;
                moved |= m;
                w += 1;
            }
            if bin && w < MAX_VERTS {
                dst.v[w] = b;
                dst.exact[w] = self.exact[i];
                w += 1;
            }
            ia = i;
            ain = bin;
        }
        dst.len = w;
        dst.rho = self.rho;
        dst.tri_lo = self.tri_lo;
        dst.tri_hi = self.tri_hi;
        for j in 0..3 {
            dst.err[j] = self.err[j] + if moved & (1 << j) != 0 { self.rho } else { 0.0 };
        }
    }

    /// The `f32` box of the polygon, which lies in the box `[lo, hi]`: inexact coordinates
    /// widened by their error, rounded outward, then clamped to the box.
    #[cfg(test)]
    fn bounds(&self, lo: [f32; 3], hi: [f32; 3]) -> Bounds {
        let mut acc = BoxAcc::EMPTY;
        let widen = widen_table(&self.err);
        for i in 0..self.len {
            acc.add(&self.v[i], &widen[self.exact[i] as usize]);
        }
        self.rounded_bounds(&acc, lo, hi)
    }

    /// The `f32` boxes of the parts of the polygon (inside the box `[lo, hi]`) below and above
    /// the plane `x_k = p`, computed in one pass without building the two polygons: the
    /// vertices on each side (those on the plane on both) and the points where edges cross.
    /// Where the polygon's `k` coordinates have an error, each side's plane is moved outward
    /// by it (the left one up, the right one down), as in [`clip_into`](Self::clip_into).
    #[inline]
    fn split_bounds(&self, lo: [f32; 3], hi: [f32; 3], k: usize, p: f32) -> (Option<Bounds>, Option<Bounds>) {
        let c = f64::from(p);
        let (cl, cr) = (widen(c, self.err[k], true), widen(c, self.err[k], false));
        // The crossings are new computed coordinates: one more step of error on them.
        let mut err_new = self.err;
        for e in &mut err_new {
            *e += self.rho;
        }
        let (old, new) = (widen_table(&self.err), widen_table(&err_new));
        let (mut left, mut right) = (BoxAcc::EMPTY, BoxAcc::EMPTY);
        let mut ia = self.len - 1;
        for ib in 0..self.len {
            let (a, b) = (&self.v[ia], &self.v[ib]);
            let eb = self.exact[ib];
            if b[k] <= cl {
                left.add(b, &old[eb as usize]);
            }
            if b[k] >= cr {
                right.add(b, &old[eb as usize]);
            }
            let crosses = |x: f64| (a[k] < x && b[k] > x) || (a[k] > x && b[k] < x);
            if crosses(cl) {
                let (q, e, _) = Self::crossing(a, self.exact[ia], b, eb, k, cl);
                left.add(&q, &new[e as usize]);
                if cr == cl {
                    right.add(&q, &new[e as usize]);
                }
            }
            if cr != cl && crosses(cr) {
                let (q, e, _) = Self::crossing(a, self.exact[ia], b, eb, k, cr);
                right.add(&q, &new[e as usize]);
            }
            ia = ib;
        }
        let (mut lhi, mut rlo) = (hi, lo);
        lhi[k] = p;
        rlo[k] = p;
        let l = (!left.is_empty()).then(|| self.rounded_bounds(&left, lo, lhi));
        let r = (!right.is_empty()).then(|| self.rounded_bounds(&right, rlo, hi));
        (l, r)
    }

    /// The `f64` box `acc` rounded outward to `f32`, cut to the triangle's own box and
    /// clamped to the box `[lo, hi]`.
    #[inline]
    fn rounded_bounds(&self, acc: &BoxAcc, lo: [f32; 3], hi: [f32; 3]) -> Bounds {
        let mut bmin = [0.0f32; 3];
        let mut bmax = [0.0f32; 3];
        for k in 0..3 {
            bmin[k] = round_down(acc.mn[k]).max(self.tri_lo[k]).clamp(lo[k], hi[k]);
            bmax[k] = round_up(acc.mx[k]).min(self.tri_hi[k]).clamp(lo[k], hi[k]).max(bmin[k]);
        }
        (bmin, bmax)
    }
}

/// True if the crossing coordinate `p = (aj (bk - c) + bj (c - ak)) / (bk - ak)`, as computed
/// in `f64` by [`Polygon::crossing`], is exact: every operation was. Knuth's TwoSum and
/// Dekker's product give each operation's rounding error exactly (no overflow or underflow
/// is possible for `f32`-range inputs in `f64`); all must be zero, and `p (bk - ak)` must be
/// the numerator exactly.
#[inline(never)]
fn exact_crossing(aj: f64, bj: f64, ak: f64, bk: f64, c: f64, p: f64) -> bool {
    let (wa, wb, d) = (bk - c, c - ak, bk - ak);
    let (x, y) = (aj * wa, bj * wb);
    let num = x + y;
    sum_err(bk, -c, wa) == 0.0
        && sum_err(c, -ak, wb) == 0.0
        && sum_err(bk, -ak, d) == 0.0
        && prod_err(aj, wa, x) == 0.0
        && prod_err(bj, wb, y) == 0.0
        && sum_err(x, y, num) == 0.0
        && p * d == num
        && prod_err(p, d, num) == 0.0
}

/// The rounding error of the `f64` sum `s = a + b` (Knuth's TwoSum): `a + b - s` exactly.
#[inline(always)]
fn sum_err(a: f64, b: f64, s: f64) -> f64 {
    let bb = s - a;
    (a - (s - bb)) + (b - bb)
}

/// The rounding error of the `f64` product `p = a * b` (Dekker's product with Veltkamp's
/// split): `a * b - p` exactly.
#[inline(always)]
fn prod_err(a: f64, b: f64, p: f64) -> f64 {
    let split = |x: f64| {
        let c = 134_217_729.0 * x;
        let hi = c - (c - x);
        (hi, x - hi)
    };
    let ((ah, al), (bh, bl)) = (split(a), split(b));
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
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
/// the triangle's own box crosses are clipped against. With `widen`, each plane is first
/// moved outward by the error bound of its axis (the builder's conservative clip).
#[inline]
fn clip_to_box(
    tri: &[Vec3; 3],
    lo: [f64; 3],
    hi: [f64; 3],
    bufs: &mut [Polygon; 2],
    widen_planes: bool,
) -> Option<usize> {
    bufs[0].set_triangle(tri);
    let mut cur = 0;
    for k in 0..3 {
        // The current polygon's extent: planes it no longer crosses are skipped.
        // Plain comparisons, not `f64::min` / `max` (which also handle NaN, never met here:
        // coordinates are finite): the extremes only feed the comparisons below.
        let poly = &bufs[cur];
        let (mut tmin, mut tmax) = (poly.v[0][k], poly.v[0][k]);
        for v in &poly.v[1..poly.len] {
            if v[k] < tmin {
                tmin = v[k];
            }
            if v[k] > tmax {
                tmax = v[k];
            }
        }
        let e = if widen_planes { poly.err[k] } else { 0.0 };
        let (lo_k, hi_k) = (widen(lo[k], e, false), widen(hi[k], e, true));
        if tmax < lo_k || tmin > hi_k {
            return None;
        }
        if tmin < lo_k && !step::<false>(bufs, &mut cur, k, lo_k) {
            return None;
        }
        if tmax > hi_k && !step::<true>(bufs, &mut cur, k, hi_k) {
            return None;
        }
    }
    Some(cur)
}

/// Clips triangle `tri` to the closed box `[lo, hi]` without moving the planes (see the
/// module docs): the polygon lies within [`Polygon::err`] of the exact one. `None` when they
/// do not meet.
pub(crate) fn clip_triangle(tri: &[Vec3; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<Polygon> {
    let mut bufs = [Polygon::EMPTY; 2];
    clip_to_box(tri, lo, hi, &mut bufs, false).map(|c| bufs[c])
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
    let c = clip_to_box(tri, lo.map(f64::from), hi.map(f64::from), &mut bufs, true)?;
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
    match clip_to_box(tri, lo.map(f64::from), hi.map(f64::from), bufs, true) {
        Some(c) => bufs[c].split_bounds(lo, hi, k, p),
        None => (None, None),
    }
}

/// The boxes of the parts of triangle `tri` inside `bounds` on either side of the plane
/// `x_axis = pos`: `[below, above]`, `None` for a side the part does not reach. Conservative,
/// as the kd-tree's perfect splits (module docs): each box contains the exact box of its part.
/// This is the reference split of spatial-split BVHs (Stich, Friedrich & Dietrich 2009,
/// section 4.2), used by the multi-BVH's build.
pub fn split_reference(tri: &[Vec3; 3], bounds: &crate::Aabb, axis: usize, pos: f32) -> [Option<crate::Aabb>; 2] {
    let mut bufs = [Polygon::EMPTY; 2];
    let (lo, hi) = (bounds.min.to_array(), bounds.max.to_array());
    let (l, r) = clipped_split_bounds(tri, lo, hi, axis, pos, &mut bufs);
    let to_box = |b: Option<Bounds>| b.map(|(lo, hi)| crate::Aabb::new(Vec3::from(lo), Vec3::from(hi)));
    [to_box(l), to_box(r)]
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

    /// A fuzz finding: a triangle with 1e29 coordinates clipped to a 1e9 box. Crossing points
    /// interpolated from the far vertex were off by 1.4e9 (`t = 1 - 2e-20` rounds to 1), so
    /// the clipped box missed most of the triangle's part in the box, and the builder left
    /// the triangle out of a leaf it enters. Points of that part, computed accurately from
    /// the near vertex, must lie in the clipped box.
    #[test]
    fn huge_triangle_in_a_small_box_is_contained() {
        let (a, b, c) = (
            v(865320900.0, 2012718800.0, 865309600.0),
            v(2.809e-41, 865304600.0, 865309600.0),
            v(865309600.0, -1.4812316e29, -6.404351e28),
        );
        // The node the builder split at y = 0, and its right child.
        let (lo, hi) = ([-1.4787274e-30f32, -1.1360284e9, 0.0], [865320900.0f32, 2012718800.0, 865309600.0]);
        let (left, right) = clipped_split_bounds(&[a, b, c], lo, hi, 1, 0.0, &mut Default::default());
        let (mut lhi, mut rlo) = (hi, lo);
        (lhi[1], rlo[1]) = (0.0, 0.0);
        let (a64, b64, c64) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
        for (clipped, lo, hi) in [(left, lo, lhi), (right, rlo, hi), (clipped_bounds(&[a, b, c], lo, hi), lo, hi)] {
            let (blo, bhi) = clipped.expect("the triangle meets the box");
            let mut inside = 0;
            for i in 0..=200 {
                for j in 0..=200 {
                    // p = a + s (c - a) + r (b - a), accurate near `a` for tiny `s`.
                    let (s, r) = (f64::from(i) * 1.5e-22, f64::from(j) / 200.0);
                    let p = a64 + s * (c64 - a64) + r * (b64 - a64);
                    let margin = 1e3;
                    if (0..3).all(|k| p[k] > f64::from(lo[k]) + margin && p[k] < f64::from(hi[k]) - margin) {
                        inside += 1;
                        for k in 0..3 {
                            assert!(
                                f64::from(blo[k]) <= p[k] && p[k] <= f64::from(bhi[k]),
                                "{p} outside {blo:?} {bhi:?}"
                            );
                        }
                    }
                }
            }
            assert!(inside > 100, "the test samples the box ({inside} points)");
        }
    }

    #[test]
    fn exact_coordinates_stay_exact_after_inexact_clips() {
        // A triangle in the plane z = 0.5 crossing two box faces diagonally: the clipped box
        // keeps z exactly, and the faces it crosses exactly.
        let t = [v(-1.0, -0.3, 0.5), v(2.0, 0.4, 0.5), v(0.3, 2.5, 0.5)];
        let (lo, hi) = clipped_bounds(&t, [0.0; 3], [1.0; 3]).unwrap();
        assert_eq!((lo[2], hi[2]), (0.5, 0.5));
        assert_eq!((lo[0], hi[0], hi[1]), (0.0, 1.0, 1.0));
    }

    #[test]
    fn exactly_computed_crossings_are_not_widened() {
        // Crossings at (1, 1, 0.5) and (0, 1, 0.5): computed, but exact.
        let t = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 1.0)];
        let (lo, hi) = clipped_bounds(&t, [0.0; 3], [1.0; 3]).unwrap();
        assert_eq!((lo, hi), ([0.0; 3], [1.0, 1.0, 0.5]));
        // A crossing at 1/3 is inexact: widened outward past the f32 nearest to it.
        let t = [v(0.0, 0.0, 0.0), v(3.0, 0.0, 0.0), v(0.0, 3.0, 1.0)];
        let (_, hi) = clipped_bounds(&t, [0.0; 3], [1.0; 3]).unwrap();
        assert!(f64::from(hi[2]) > 1.0 / 3.0 && hi[2] < 0.3334, "{hi:?}");
    }

    #[test]
    fn error_free_transforms() {
        assert_eq!(sum_err(1.0, 2.0, 3.0), 0.0);
        assert_eq!(sum_err(1e16, 1.0, 1e16 + 1.0), 1.0);
        assert_eq!(prod_err(0.5, 3.0, 1.5), 0.0);
        let (a, b) = (0.1f64, 0.3f64);
        assert_ne!(prod_err(a, b, a * b), 0.0);
        let e = prod_err(1.0 + f64::EPSILON, 1.0 + f64::EPSILON, (1.0 + f64::EPSILON) * (1.0 + f64::EPSILON));
        assert_eq!(e, f64::EPSILON * f64::EPSILON);
        assert!(exact_crossing(0.0, 2.0, 2.0, 0.0, 1.0, 1.0));
        assert!(!exact_crossing(0.0, 1.0, 0.0, 3.0, 1.0, 1.0 / 3.0));
        // 1/3 of the way from 0 to 3 is 1, exactly, though 1/3 is not.
        assert!(exact_crossing(0.0, 3.0, 0.0, 3.0, 1.0, 1.0));
    }

    #[test]
    fn rounding_helpers() {
        assert!(next_down(0.0) < 0.0 && next_up(0.0) > 0.0);
        assert!(next_down(1.0) < 1.0 && next_up(-1.0) > -1.0);
        let x = 0.1f64;
        assert!(f64::from(round_down(x)) <= x && f64::from(round_up(x)) >= x);
    }
}
