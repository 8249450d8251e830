//! Exact segment-triangle incidence, for [`super::BruteForce::unreachable`].
//!
//! Every finite `f32` is `m 2^e` with an integer `|m| < 2^24` and `e >= -149`, so scaling all
//! coordinates by `2^149` turns them into integers (below `2^277` in magnitude) without
//! changing the ray parameter `t` of any point. On those integers the edge functions (triple
//! products), the plane crossing and its comparison with the ray's interval are computed
//! exactly with big integers: no rounding, no underflow, no overflow.

use std::cmp::Ordering;

use glam::Vec3;
use num_bigint::{BigInt, Sign};

/// A vector of scaled coordinates.
type V = [BigInt; 3];

/// The exponent of the scale, `2^149`: it makes every finite `f32` an integer.
const SCALE: usize = 149;

/// `x 2^149`, exactly (`x` finite).
fn scaled(x: f32) -> BigInt {
    let bits = x.to_bits();
    let (exp, frac) = ((bits >> 23) & 0xff, bits & 0x7f_ffff);
    // Subnormal: `frac 2^-149`; normal: `(2^23 + frac) 2^(exp - 150)`.
    let m = if exp == 0 { BigInt::from(frac) } else { BigInt::from(frac | 0x80_0000) << (exp - 1) };
    if bits >> 31 != 0 { -m } else { m }
}

fn vec(p: Vec3) -> V {
    [scaled(p.x), scaled(p.y), scaled(p.z)]
}

fn sub(a: &V, b: &V) -> V {
    [&a[0] - &b[0], &a[1] - &b[1], &a[2] - &b[2]]
}

fn cross(a: &V, b: &V) -> V {
    [&a[1] * &b[2] - &a[2] * &b[1], &a[2] * &b[0] - &a[0] * &b[2], &a[0] * &b[1] - &a[1] * &b[0]]
}

fn dot(a: &V, b: &V) -> BigInt {
    &a[0] * &b[0] + &a[1] * &b[1] + &a[2] * &b[2]
}

fn is_zero(a: &BigInt) -> bool {
    a.sign() == Sign::NoSign
}

fn is_zero_vec(a: &V) -> bool {
    a.iter().all(is_zero)
}

/// A ray parameter: an extended rational.
#[derive(Clone, Debug)]
enum Param {
    NegInf,
    /// `num / den` with `den > 0`.
    Finite(BigInt, BigInt),
    PosInf,
}

impl Param {
    /// The `f32` parameter `t` (not NaN), exactly.
    fn of(t: f32) -> Param {
        if t == f32::INFINITY {
            Param::PosInf
        } else if t == f32::NEG_INFINITY {
            Param::NegInf
        } else {
            Param::Finite(scaled(t), BigInt::from(1) << SCALE)
        }
    }

    /// `num / den`, `den` non-zero.
    fn ratio(num: BigInt, den: BigInt) -> Param {
        if den.sign() == Sign::Minus { Param::Finite(-num, -den) } else { Param::Finite(num, den) }
    }

    fn cmp(&self, other: &Param) -> Ordering {
        match (self, other) {
            (Param::NegInf, Param::NegInf) | (Param::PosInf, Param::PosInf) => Ordering::Equal,
            (Param::NegInf, _) | (_, Param::PosInf) => Ordering::Less,
            (_, Param::NegInf) | (Param::PosInf, _) => Ordering::Greater,
            (Param::Finite(a, b), Param::Finite(c, d)) => (a * d).cmp(&(c * b)),
        }
    }

    fn le(&self, other: &Param) -> bool {
        self.cmp(other) != Ordering::Greater
    }

    fn max(self, other: Param) -> Param {
        if self.le(&other) { other } else { self }
    }

    fn min(self, other: Param) -> Param {
        if self.le(&other) { self } else { other }
    }
}

/// Whether, in exact arithmetic, the segment `origin + t dir`, `t` real in `[t_min, t_max]`
/// (either end may be infinite), meets the closed triangle `tri` (edges and vertices
/// included). Every input is taken as the exact value of its `f32`.
///
/// - A proper triangle and a segment crossing its plane: the crossing parameter `t = ((v0 -
///   o) . n) / (d . n)`, `n = (v1 - v0) x (v2 - v0)`, lies in the interval, and the edge
///   functions `d . ((v_i - o) x (v_j - o))` have no two opposite signs.
/// - A segment parallel to the plane (`d . n = 0`, a zero `dir` included): off the plane it
///   misses; in the plane (coplanar) it meets the triangle if some point of it lies on the
///   inner side of all three edges, each edge clipping the interval (Cyrus-Beck, in the
///   projection along the normal's largest component, which keeps the triangle's area).
/// - A degenerate triangle (`n = 0`, collinear vertices): it is the segment between its two
///   extreme vertices (or a point), and the test is segment against segment.
///
/// An input with a NaN or infinite coordinate, or a NaN parameter, cannot be decided: the
/// answer is `true` (reachable), so that nothing is excused on it. An empty interval (`t_min >
/// t_max`, or no real `t` in it) meets nothing.
pub fn segment_meets_triangle(tri: &[Vec3; 3], origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> bool {
    if !(origin.is_finite() && dir.is_finite() && tri.iter().all(|p| p.is_finite())) || t_min.is_nan() || t_max.is_nan()
    {
        return true;
    }
    if t_min > t_max || t_min == f32::INFINITY || t_max == f32::NEG_INFINITY {
        return false;
    }
    let (o, d) = (vec(origin), vec(dir));
    let v = tri.map(vec);
    let (lo, hi) = (Param::of(t_min), Param::of(t_max));
    let n = cross(&sub(&v[1], &v[0]), &sub(&v[2], &v[0]));
    if is_zero_vec(&n) {
        return degenerate(&v, &o, &d, lo, hi);
    }
    let w = [sub(&v[0], &o), sub(&v[1], &o), sub(&v[2], &o)];
    let (num, dn) = (dot(&w[0], &n), dot(&d, &n));
    if !is_zero(&dn) {
        let t = Param::ratio(num, dn);
        if !(lo.le(&t) && t.le(&hi)) {
            return false;
        }
        let signs = [0, 1, 2].map(|i| dot(&d, &cross(&w[i], &w[(i + 1) % 3])).sign());
        return !(signs.contains(&Sign::Plus) && signs.contains(&Sign::Minus));
    }
    if !is_zero(&num) {
        return false;
    }
    coplanar(&v, &n, &o, &d, lo, hi)
}

/// A segment in the plane of the proper triangle `v` (normal `n`): clips `[lo, hi]` by the
/// three edges' half-planes, in the projection that drops the normal's largest component `k`
/// (the projected triangle's doubled signed area is `n_k`, not zero).
fn coplanar(v: &[V; 3], n: &V, o: &V, d: &V, mut lo: Param, mut hi: Param) -> bool {
    let k = (0..3).max_by(|&a, &b| n[a].magnitude().cmp(n[b].magnitude())).unwrap_or(0);
    let (a, b) = ((k + 1) % 3, (k + 2) % 3);
    // The k component of `p x q`: the projected cross product.
    let cross2 = |p: &V, q: &V| &p[a] * &q[b] - &p[b] * &q[a];
    let flip = n[k].sign() == Sign::Minus;
    for i in 0..3 {
        let (vi, vj) = (&v[i], &v[(i + 1) % 3]);
        let e = sub(vj, vi);
        // Inside edge i -> j at o + t d: `s (e x (o + t d - vi))_k >= 0`, `s` the sign of n_k.
        let (mut c0, mut c1) = (cross2(&e, &sub(o, vi)), cross2(&e, d));
        if flip {
            (c0, c1) = (-c0, -c1);
        }
        match c1.sign() {
            Sign::NoSign if c0.sign() == Sign::Minus => return false,
            Sign::NoSign => {}
            Sign::Plus => lo = lo.max(Param::ratio(-c0, c1)),
            Sign::Minus => hi = hi.min(Param::ratio(-c0, c1)),
        }
    }
    lo.le(&hi)
}

/// A degenerate triangle `v` (collinear vertices): the segment between its extreme vertices,
/// or a point, against the ray's segment.
fn degenerate(v: &[V; 3], o: &V, d: &V, lo: Param, hi: Param) -> bool {
    // Along an axis on which the vertices differ, the lowest and the highest are the ends.
    let (p, q) = match (0..3).find(|&a| v[0][a] != v[1][a] || v[0][a] != v[2][a]) {
        None => (&v[0], &v[0]),
        Some(a) => {
            let lowest = (0..3).min_by(|&i, &j| v[i][a].cmp(&v[j][a])).unwrap_or(0);
            let highest = (0..3).max_by(|&i, &j| v[i][a].cmp(&v[j][a])).unwrap_or(0);
            (&v[lowest], &v[highest])
        }
    };
    let e = sub(q, p);
    let w = sub(p, o);
    let dd = dot(d, d);
    if is_zero(&dd) {
        // The ray's segment is the point o (its interval holds a real t).
        let x = sub(o, p);
        let s = dot(&x, &e);
        return is_zero_vec(&cross(&x, &e)) && s.sign() != Sign::Minus && s <= dot(&e, &e);
    }
    let c = cross(d, &e);
    if is_zero_vec(&c) {
        // A point, or a segment parallel to the ray: on the ray's line, then the parameters
        // of its ends, `(p - o) . d / d . d` and `(q - o) . d / d . d`, against the interval.
        if !is_zero_vec(&cross(&w, d)) {
            return false;
        }
        let (tp, tq) = (Param::ratio(dot(&w, d), dd.clone()), Param::ratio(dot(&sub(q, o), d), dd));
        let (t0, t1) = if tp.le(&tq) { (tp, tq) } else { (tq, tp) };
        return lo.max(t0).le(&hi.min(t1));
    }
    // Skew lines miss; crossing lines meet at `o + t d = p + s e`, `t = ((w x e) . c) / c . c`,
    // `s = ((w x d) . c) / c . c`, `c = d x e`.
    if !is_zero(&dot(&w, &c)) {
        return false;
    }
    let cc = dot(&c, &c);
    let s = dot(&cross(&w, d), &c);
    if s.sign() == Sign::Minus || s > cc {
        return false;
    }
    let t = Param::ratio(dot(&cross(&w, &e), &c), cc);
    lo.le(&t) && t.le(&hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The triangle x, y >= 0, x + y <= 1 at z = 0.
    const UNIT: [Vec3; 3] = [Vec3::ZERO, Vec3::X, Vec3::Y];

    fn meets(tri: &[Vec3; 3], o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        segment_meets_triangle(tri, o, d, t_min, t_max)
    }

    fn down(x: f32, y: f32) -> bool {
        meets(&UNIT, Vec3::new(x, y, 1.0), -Vec3::Z, 0.0, f32::INFINITY)
    }

    #[test]
    fn scaling_is_exact() {
        assert_eq!(scaled(1.0), BigInt::from(1) << 149usize);
        assert_eq!(scaled(-0.75), -(BigInt::from(3) << 147usize));
        assert_eq!(scaled(f32::from_bits(1)), BigInt::from(1));
        assert_eq!(scaled(-0.0), BigInt::from(0));
        assert_eq!(scaled(f32::MAX), BigInt::from(0xff_ffff) << (104 + 149));
        assert_eq!(scaled(f32::MIN_POSITIVE), BigInt::from(1) << 23usize);
    }

    #[test]
    fn simple_hits_and_misses() {
        assert!(down(0.25, 0.25));
        assert!(!down(0.75, 0.75));
        assert!(!down(-0.25, 0.25));
        // Either winding, either direction.
        assert!(meets(&[Vec3::ZERO, Vec3::Y, Vec3::X], Vec3::new(0.2, 0.2, -1.0), Vec3::Z, 0.0, 2.0));
        assert!(meets(&UNIT, Vec3::new(0.2, 0.2, -1.0), Vec3::new(0.1, 0.0, 1.0), 0.0, 2.0));
        // Behind the origin: only with a negative interval.
        assert!(!meets(&UNIT, Vec3::new(0.2, 0.2, 1.0), Vec3::Z, 0.0, f32::INFINITY));
        assert!(meets(&UNIT, Vec3::new(0.2, 0.2, 1.0), Vec3::Z, f32::NEG_INFINITY, 0.0));
        assert!(meets(&UNIT, Vec3::new(0.2, 0.2, 1.0), Vec3::Z, -1.0, -1.0));
        // Empty intervals meet nothing; undecidable input is reachable.
        assert!(!meets(&UNIT, Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 2.0, 1.0));
        assert!(!meets(&UNIT, Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, f32::INFINITY, f32::INFINITY));
        assert!(meets(&UNIT, Vec3::new(9.0, 9.0, 1.0), -Vec3::Z, f32::NAN, 1.0));
    }

    #[test]
    fn edges_and_vertices_are_reachable() {
        assert!(down(0.5, 0.0) && down(0.0, 0.5) && down(0.5, 0.5));
        assert!(down(0.0, 0.0) && down(1.0, 0.0) && down(0.0, 1.0));
        // A slanted ray through the vertex (1, 0, 0) exactly.
        assert!(meets(&UNIT, Vec3::new(0.0, -1.0, 1.0), Vec3::new(1.0, 1.0, -1.0), 0.0, 1.0));
    }

    #[test]
    fn a_miss_by_one_ulp_is_a_miss() {
        assert!(!down(0.5f32.next_up(), 0.5));
        assert!(!down(0.0, (-0.0f32).next_down()));
        assert!(!down(1.0f32.next_up(), 0.0));
        // The smallest subnormal beside an edge of a 1e30 triangle.
        let big = UNIT.map(|p| p * 1e30);
        assert!(meets(&big, Vec3::new(0.0, 5e29, 1.0), -Vec3::Z, 0.0, 2.0));
        assert!(!meets(&big, Vec3::new(-f32::from_bits(1), 5e29, 1.0), -Vec3::Z, 0.0, 2.0));
    }

    #[test]
    fn interval_ends_exactly_at_the_crossing() {
        let o = Vec3::new(0.25, 0.25, 1.0);
        // Crossing at t = 1/3, not an f32: the nearest f32 on either side decides.
        let d = Vec3::new(0.0, 0.0, -3.0);
        let third = 1.0f32 / 3.0;
        let (below, above) =
            if f64::from(third) < 1.0 / 3.0 { (third, third.next_up()) } else { (third.next_down(), third) };
        assert!(meets(&UNIT, o, d, 0.0, above) && !meets(&UNIT, o, d, 0.0, below));
        assert!(meets(&UNIT, o, d, below, 1.0) && !meets(&UNIT, o, d, above, 1.0));
        // Crossing at t = 1 exactly: both closed ends count.
        assert!(meets(&UNIT, o, -Vec3::Z, 1.0, 1.0));
        assert!(meets(&UNIT, o, -Vec3::Z, 0.0, 1.0) && meets(&UNIT, o, -Vec3::Z, 1.0, 2.0));
        assert!(!meets(&UNIT, o, -Vec3::Z, 0.0, 1.0f32.next_down()));
        assert!(!meets(&UNIT, o, -Vec3::Z, 1.0f32.next_up(), 2.0));
    }

    #[test]
    fn parallel_and_coplanar_segments() {
        // Parallel above the plane.
        assert!(!meets(&UNIT, Vec3::new(-1.0, 0.25, 1.0), Vec3::X, f32::NEG_INFINITY, f32::INFINITY));
        // In the plane, crossing the triangle, entering at t = 1 through the edge x = 0.
        let o = Vec3::new(-1.0, 0.25, 0.0);
        assert!(meets(&UNIT, o, Vec3::X, 0.0, f32::INFINITY));
        assert!(meets(&UNIT, o, Vec3::X, 0.0, 1.0), "touching the edge");
        assert!(!meets(&UNIT, o, Vec3::X, 0.0, 1.0f32.next_down()));
        assert!(meets(&UNIT, o, Vec3::X, 1.75, 1.75), "the far edge, x + y = 1");
        assert!(!meets(&UNIT, o, Vec3::X, 1.75f32.next_up(), 9.0));
        // In the plane: beside the triangle; along its edge x + y = 1 and one ulp beside it;
        // through its vertex (0, 0) only.
        assert!(!meets(&UNIT, Vec3::new(-1.0, 1.5, 0.0), Vec3::X, f32::NEG_INFINITY, f32::INFINITY));
        assert!(meets(&UNIT, Vec3::new(-1.0, 2.0, 0.0), Vec3::new(1.0, -1.0, 0.0), 0.0, 9.0));
        assert!(!meets(&UNIT, Vec3::new(-1.0, 2.0f32.next_up(), 0.0), Vec3::new(1.0, -1.0, 0.0), 0.0, 9.0));
        assert!(meets(&UNIT, Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), 0.0, 9.0));
        assert!(!meets(&UNIT, Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), 0.0, 1.0f32.next_down()));
        // Along an edge, and the other winding.
        assert!(meets(&[Vec3::ZERO, Vec3::Y, Vec3::X], Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 0.0, 1.0));
        // A zero direction (a flushed denormal): the origin, in or out.
        assert!(meets(&UNIT, Vec3::new(0.25, 0.25, 0.0), Vec3::ZERO, 0.0, 1.0));
        assert!(!meets(&UNIT, Vec3::new(0.75, 0.75, 0.0), Vec3::ZERO, 0.0, 1.0));
        assert!(!meets(&UNIT, Vec3::new(0.25, 0.25, 1e-45), Vec3::ZERO, 0.0, 1.0));
        // A slanted plane (x + y + z = 1): coplanar through its middle.
        let slanted = [Vec3::X, Vec3::Y, Vec3::Z];
        let mid = Vec3::new(0.25, 0.25, 0.5);
        assert!(meets(&slanted, mid, Vec3::new(1.0, -1.0, 0.0), -0.125, 0.125));
        assert!(!meets(&slanted, mid, Vec3::new(1.0, -1.0, 0.0), 0.5, 1.0));
    }

    #[test]
    fn degenerate_triangles_are_segments_or_points() {
        let seg = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::X];
        assert!(meets(&seg, Vec3::new(1.5, -1.0, 0.0), Vec3::Y, 0.0, 1.0), "crossing it");
        assert!(!meets(&seg, Vec3::new(1.5, -1.0, 0.0), Vec3::Y, 0.0, 1.0f32.next_down()));
        assert!(!meets(&seg, Vec3::new(2.5, -1.0, 0.0), Vec3::Y, 0.0, 9.0), "beside its end");
        assert!(!meets(&seg, Vec3::new(1.5, -1.0, 1e-30), Vec3::Y, 0.0, 9.0), "skew");
        assert!(meets(&seg, Vec3::new(2.0, -1.0, 1.0), Vec3::new(0.0, 1.0, -1.0), 0.0, 9.0), "its end");
        assert!(meets(&seg, Vec3::new(3.0, 0.0, 0.0), -Vec3::X, 1.0, 1.0), "along it");
        assert!(!meets(&seg, Vec3::new(3.0, 0.0, 0.0), -Vec3::X, 0.0, 1.0f32.next_down()));
        assert!(meets(&seg, Vec3::new(1.0, 0.0, 0.0), Vec3::ZERO, 0.0, 0.0), "a point origin on it");
        let point = [Vec3::ONE; 3];
        assert!(meets(&point, Vec3::ZERO, Vec3::splat(0.5), 2.0, 2.0));
        assert!(!meets(&point, Vec3::ZERO, Vec3::splat(0.5), 0.0, 2.0f32.next_down()));
        assert!(!meets(&point, Vec3::ZERO, Vec3::new(0.5, 0.5, 0.5f32.next_up()), 0.0, 9.0));
    }

    #[test]
    fn huge_and_tiny_coordinates() {
        let huge = UNIT.map(|p| p * 1e30);
        assert!(meets(&huge, Vec3::new(2e29, 2e29, 1e30), -Vec3::Z, 0.0, f32::INFINITY));
        assert!(meets(&huge, Vec3::new(2e29, 2e29, 1e30), Vec3::new(0.0, 0.0, -1e30), 1.0, 1.0));
        assert!(!meets(&huge, Vec3::new(2e29, 2e29, 1e30), Vec3::new(0.0, 0.0, -1e30), 0.0, 1.0f32.next_down()));
        assert!(!meets(&huge, Vec3::new(6e29, 6e29, 1.0), -Vec3::Z, 0.0, f32::INFINITY));
        let tiny = UNIT.map(|p| p * 1e-40);
        assert!(meets(&tiny, Vec3::new(2e-41, 2e-41, 1.0), -Vec3::Z, 0.0, 1.0));
        assert!(!meets(&tiny, Vec3::new(2e-41, 2e-41, 1.0), -Vec3::Z, 0.0, 1.0f32.next_down()));
        assert!(!meets(&tiny, Vec3::new(6e-41, 6e-41, 1.0), -Vec3::Z, 0.0, 1.0));
        // A 1e-40 ray into a 1e30 triangle, and a 1e30 ray into a 1e-40 triangle.
        assert!(meets(&huge, Vec3::new(1e-40, 1e-40, 1e-40), Vec3::new(0.0, 0.0, -1e-40), 0.0, 1.0));
        assert!(!meets(&huge, Vec3::new(1e-40, 1e-40, 1e-40), Vec3::new(0.0, 0.0, -1e-40), 0.0, 0.99));
        assert!(meets(&tiny, Vec3::new(2e-41, 2e-41, 1e30), Vec3::new(0.0, 0.0, -1e30), 0.0, 1.0));
        assert!(meets(&tiny, Vec3::new(1e-40, 0.0, 1e30), Vec3::new(0.0, 0.0, -1e30), 0.0, 2.0), "its vertex");
        let drift = Vec3::new(f32::from_bits(1), 0.0, -1e30);
        assert!(!meets(&tiny, Vec3::new(1e-40, 0.0, 1e30), drift, 0.0, 2.0), "1.4e-45 past its vertex");
        assert!(!meets(&tiny, Vec3::new(-1e-45, 2e-41, 1e30), Vec3::new(0.0, 0.0, -1e30), 0.0, 2.0));
        // The extremes of f32.
        let max = [
            Vec3::new(-f32::MAX, -f32::MAX, f32::MAX),
            Vec3::new(f32::MAX, -f32::MAX, f32::MAX),
            Vec3::new(0.0, f32::MAX, f32::MAX),
        ];
        // It reaches z = f32::MAX at t = 2^149 f32::MAX, past every finite f32.
        let up = Vec3::new(0.0, 0.0, f32::from_bits(1));
        assert!(meets(&max, Vec3::ZERO, up, 0.0, f32::INFINITY));
        assert!(!meets(&max, Vec3::ZERO, up, 0.0, f32::MAX));
    }
}
