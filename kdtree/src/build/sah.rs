//! The SAH plane search: one linear sweep over each axis's sorted events (Wald & Havran 2006,
//! section 4.2, algorithm 4), with the planar-triangle side rule (section 3.3: triangles lying
//! in the plane go to the side that gives the lower cost).

use super::events::{END, PLANAR, START, ev_key, ev_type, key_pos, pos_key};
use crate::Aabb;

/// The SAH terms in `f64` (thesis 2.2.1; MacDonald & Booth 1990).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Costs {
    /// Cost of a traversal step.
    pub c_trav: f64,
    /// Cost of a triangle test.
    pub c_isect: f64,
    /// `1 - empty_bonus`: the factor on the cost of a split with an empty side.
    pub empty_factor: f64,
    /// The leaf's SIMD group width `W` ([`super::BuildConfig::leaf_width`]; 1: per triangle).
    pub width: f64,
}

impl Costs {
    /// The terms of `config`.
    pub fn of(config: &super::BuildConfig) -> Costs {
        Costs {
            c_trav: f64::from(config.c_trav),
            c_isect: f64::from(config.c_isect),
            empty_factor: 1.0 - f64::from(config.empty_bonus),
            width: f64::from(config.leaf_width),
        }
    }

    /// The SIMD groups of `n` triangles, `ceil(n / W)`: the tests one ray makes in a leaf of
    /// `n` (`n` itself, exactly, for `W = 1`). `n` is a whole number.
    ///
    /// `n` itself for `W = 1`, without the division. Otherwise the quotient is at least 0
    /// and below `2^53`, so truncating it to an integer is exact and one more when it had a
    /// fraction is its ceiling, without the library call that `f64::ceil` is on x86-64
    /// without SSE 4.1.
    #[inline(always)]
    pub fn groups(&self, n: f64) -> f64 {
        if self.width == 1.0 {
            return n;
        }
        let q = n / self.width;
        let t = q as i64 as f64;
        if t < q { t + 1.0 } else { t }
    }

    /// The cost of a leaf of `n` triangles, `C_isect * ceil(n / W)`.
    #[inline]
    pub fn leaf(&self, n: usize) -> f64 {
        self.c_isect * self.groups(n as f64)
    }
}

/// The chosen plane of a node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Split {
    /// Axis 0, 1 or 2.
    pub axis: usize,
    /// Plane position, strictly inside the node box.
    pub pos: f32,
    /// Triangles lying in the plane go left (true) or right (false).
    pub planar_left: bool,
    /// SAH cost of the split.
    pub cost: f64,
}

/// The surface area of a box in `f64` (no overflow or underflow for finite `f32` corners).
#[inline]
pub fn surface_area64(b: &Aabb) -> f64 {
    if b.is_empty() {
        return 0.0;
    }
    let e = extent64(b);
    2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
}

/// `max - min` in `f64`.
#[inline]
pub(crate) fn extent64(b: &Aabb) -> [f64; 3] {
    [0, 1, 2].map(|k| f64::from(b.max[k]) - f64::from(b.min[k]))
}

/// The cheapest split of a node with `n` triangles whose events are `lists` (each sorted),
/// or `None` when no plane lies strictly inside the box. Ties keep the first candidate in
/// axis order, then position order, so the result is deterministic. With `par` the three
/// axes are swept in parallel (for big nodes); the result is the same.
///
/// Each side's triangles are priced by their SIMD groups, `ceil(n_l / W)` and
/// `ceil(n_r / W)` ([`Costs::groups`]), as the leaf is.
///
/// Only splits cheaper than `limit` are sought: when the cheapest costs at least `limit`,
/// the result is `None` or a split that costs at least `limit`. Every candidate of axis `k`
/// costs at least `c_trav + scale * (n / W) * A_k` (each triangle is on at least one side,
/// `ceil(x / W) >= x / W`, and each side's area is at least the box's face across `k`,
/// `A_k`), so axes whose bound, with a
/// relative margin far above rounding errors, exceeds `limit` or (sequentially, lowest bound
/// first) the best cost found are not swept: they could only give costlier planes.
pub(crate) fn find_split(
    lists: [&[u64]; 3],
    n: usize,
    b: &Aabb,
    costs: &Costs,
    par: bool,
    limit: f64,
) -> Option<Split> {
    let e = extent64(b);
    let sa = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0]);
    if !(sa > 0.0 && sa.is_finite()) {
        return None;
    }
    let node = Node { e, b, nf: n as f64, scale: costs.c_isect * 2.0 * (1.0 / sa), costs };
    // Without an empty bonus the factor is 1 and its tests are dropped (same costs).
    // With one triangle per group the planar triangles' terms are added as before the
    // groups were (the same costs, bit for bit).
    let sweep = |k: usize| match (costs.empty_factor == 1.0, costs.width == 1.0) {
        (true, true) => sweep_axis::<false, false>(lists[k], k, &node),
        (false, true) => sweep_axis::<true, false>(lists[k], k, &node),
        (true, false) => sweep_axis::<false, true>(lists[k], k, &node),
        (false, false) => sweep_axis::<true, true>(lists[k], k, &node),
    };
    let min_factor = costs.empty_factor.min(1.0);
    let nw = node.nf / costs.width;
    let lb = [0, 1, 2].map(|k| (costs.c_trav + node.scale * (nw * (e[(k + 1) % 3] * e[(k + 2) % 3]))) * min_factor);
    let beats = |k: usize, best: f64| lb[k] * (1.0 - 1e-9) <= best;
    let best = if par {
        let sweep = |k: usize| if beats(k, limit) { sweep(k) } else { None };
        let (x, (y, z)) = rayon::join(|| sweep(0), || rayon::join(|| sweep(1), || sweep(2)));
        [x, y, z]
    } else {
        let mut order = [0, 1, 2];
        order.sort_by(|&i, &j| lb[i].total_cmp(&lb[j]));
        let mut best = [None; 3];
        let mut bound = limit;
        for k in order {
            if beats(k, bound) {
                best[k] = sweep(k);
                if let Some((c, _, _)) = best[k] {
                    bound = bound.min(c);
                }
            }
        }
        best
    };
    // Axis order with strict `<`: the first of equal costs wins, as in one sequential sweep.
    let mut pick: Option<Split> = None;
    for (axis, c) in best.into_iter().enumerate() {
        if let Some((cost, key, planar_left)) = c
            && pick.is_none_or(|p| cost < p.cost)
        {
            pick = Some(Split { axis, pos: key_pos(key), planar_left, cost });
        }
    }
    pick
}

/// What the sweep of each axis needs to know about the node.
struct Node<'a> {
    /// Box extents.
    e: [f64; 3],
    /// Box.
    b: &'a Aabb,
    /// Triangle count.
    nf: f64,
    /// `c_isect * 2 / SA(V)`: cost = `c_trav + scale * (n_l * A_l + n_r * A_r)` with `A` half
    /// a child's surface area.
    scale: f64,
    /// The cost terms.
    costs: &'a Costs,
}

/// The sweep of axis `k` (events `ev`, sorted): the cheapest plane strictly inside the box as
/// `(cost, position key, planar triangles left)`, the first of equal costs. `BONUS`: whether
/// the empty-side factor is other than 1; `GROUPS`: whether the leaf width is other than 1.
#[inline]
fn sweep_axis<const BONUS: bool, const GROUPS: bool>(ev: &[u64], k: usize, node: &Node) -> Option<(f64, u32, bool)> {
    let (e, b) = (&node.e, node.b);
    if e[k] <= 0.0 {
        return None;
    }
    let (scale, c_trav, factor) = (node.scale, node.costs.c_trav, node.costs.empty_factor);
    let (mut best_cost, mut best_key, mut best_left) = (f64::INFINITY, 0u32, true);
    let (o1, o2) = ((k + 1) % 3, (k + 2) % 3);
    let cross = e[o1] * e[o2];
    let sum = e[o1] + e[o2];
    let (lo, hi) = (b.min[k], b.max[k]);
    let (lo_key, hi_key) = (pos_key(lo), pos_key(hi));
    let lo64 = f64::from(lo);
    let ext = e[k];
    // Clipped boxes lie in the node box, so every event is in `[lo, hi]`, and those on the
    // box's faces (often about 40% of them: the clipped triangles of the node's sides) are
    // no candidates. The ones on the lower face only count: a start or planar event there
    // puts its triangle left of every candidate, an end or planar event takes it off the
    // right. Those on the upper face come after every candidate and are never read.
    let mut first = 0;
    let (mut nl_lo, mut nr_lo) = (0u32, 0u32);
    while first < ev.len() && ev_key(ev[first]) <= lo_key {
        let t = ev_type(ev[first]);
        nl_lo += u32::from(t != END);
        nr_lo += u32::from(t != START);
        first += 1;
    }
    let mut last = ev.len();
    while last > first && ev_key(ev[last - 1]) >= hi_key {
        last -= 1;
    }
    // Counts as f64: they only feed the cost, and exact up to 2^53.
    let (mut nl, mut nr) = (f64::from(nl_lo), node.nf - f64::from(nr_lo));
    let mut it = ev[first..last].iter().copied();
    let mut next = it.next();
    while let Some(e) = next {
        let key = ev_key(e);
        // The group of events at this position: ends, then planars, then starts.
        let t = ev_type(e);
        let (mut pe, mut pp, mut ps) = (u32::from(t == END), u32::from(t == PLANAR), u32::from(t == START));
        loop {
            next = it.next();
            match next {
                Some(e2) if ev_key(e2) == key => {
                    let t2 = ev_type(e2);
                    pe += u32::from(t2 == END);
                    pp += u32::from(t2 == PLANAR);
                    ps += u32::from(t2 == START);
                }
                _ => break,
            }
        }
        let ppf = f64::from(pp);
        nr -= f64::from(pe) + ppf;
        let d = f64::from(key_pos(key)) - lo64;
        let (a_l, a_r) = (cross + d * sum, cross + (ext - d) * sum);
        let (base_l, base_r) = if GROUPS {
            let g = |x: f64| node.costs.groups(x);
            (g(nl + ppf) * a_l + g(nr) * a_r, g(nl) * a_l + g(nr + ppf) * a_r)
        } else {
            let base = nl * a_l + nr * a_r;
            (base + ppf * a_l, base + ppf * a_r)
        };
        let f_l = if BONUS && (nl + ppf == 0.0 || nr == 0.0) { factor } else { 1.0 };
        let mut c = (c_trav + scale * base_l) * f_l;
        let mut left = true;
        if pp > 0 {
            let f_r = if BONUS && (nl == 0.0 || nr + ppf == 0.0) { factor } else { 1.0 };
            let c_right = (c_trav + scale * base_r) * f_r;
            if c_right < c {
                c = c_right;
                left = false;
            }
        }
        if c < best_cost {
            (best_cost, best_key, best_left) = (c, key, left);
        }
        nl += f64::from(ps) + ppf;
    }
    (best_cost < f64::INFINITY).then_some((best_cost, best_key, best_left))
}

#[cfg(test)]
mod tests {
    use super::super::events::{Lists, push_box_events};
    use super::*;
    use glam::Vec3;

    const COSTS: Costs = Costs { c_trav: 1.0, c_isect: 5.0, empty_factor: 1.0, width: 1.0 };

    fn lists_of(boxes: &[([f32; 3], [f32; 3])]) -> Lists {
        let mut l: [Vec<u64>; 3] = Default::default();
        for (i, &(lo, hi)) in boxes.iter().enumerate() {
            push_box_events(&mut l, i as u32, lo, hi);
        }
        for v in &mut l {
            v.sort_unstable();
        }
        Lists::from_vecs(l)
    }

    #[test]
    fn splits_between_two_clusters() {
        let boxes = [([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]), ([9.0, 0.0, 0.0], [10.0, 1.0, 1.0])];
        let l = lists_of(&boxes);
        let b = Aabb::new(Vec3::ZERO, Vec3::new(10.0, 1.0, 1.0));
        let s = find_split(l.axes(), 2, &b, &COSTS, false, f64::INFINITY).unwrap();
        assert_eq!(s.axis, 0);
        assert!(s.pos == 1.0 || s.pos == 9.0, "{s:?}");
        assert!(s.cost < 10.0);
    }

    /// Each side is priced by its groups of `W`: on the box [0, 10] x [0, 1]^2 with 5
    /// triangles' boxes at [0, 1] and one at [9, 10], the best plane costs
    /// `C_trav + C_isect * (ceil(n_l / W) SA_l + ceil(n_r / W) SA_r) / SA` at x = 1 for
    /// `W` = 1, 4, 8, and the sweep with the lower bound `n / W` (in parallel, limited to
    /// the leaf) finds it when it beats the leaf.
    #[test]
    fn the_split_cost_counts_groups_of_the_leaf_width() {
        let mut boxes = vec![([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]); 5];
        boxes.push(([9.0, 0.0, 0.0], [10.0, 1.0, 1.0]));
        let l = lists_of(&boxes);
        let b = Aabb::new(Vec3::ZERO, Vec3::new(10.0, 1.0, 1.0));
        let sa = |x: f64| 2.0 * (x + 1.0 + x);
        for width in [1.0, 4.0, 8.0] {
            let costs = Costs { width, ..COSTS };
            let s = find_split(l.axes(), 6, &b, &costs, false, f64::INFINITY).unwrap();
            let g = |n: f64| (n / width).ceil();
            // The cheapest plane of axis 0 is one of the two faces of the gap, x = 1 or 9.
            let at = |x: f64| 1.0 + 5.0 * (g(5.0) * sa(x) + g(1.0) * sa(10.0 - x)) / sa(10.0);
            let want = at(1.0).min(at(9.0));
            assert_eq!(s.axis, 0, "{width}: {s:?}");
            assert!((s.cost - want).abs() <= 1e-12 * want, "{width}: {s:?}, want {want}");
            let par = find_split(l.axes(), 6, &b, &costs, true, costs.leaf(6)).filter(|p| p.cost < costs.leaf(6));
            assert_eq!(par, (s.cost < costs.leaf(6)).then_some(s), "{width}");
        }
        // W = 4: the split (1 + 5 * (2 * 6 + 38) / 42 = 6.95) beats the leaf (2 groups, 10);
        // W = 8: the leaf is one group (5), under the split (1 + 5 * (6 + 38) / 42 = 6.24).
        let w4 = Costs { width: 4.0, ..COSTS };
        assert!(find_split(l.axes(), 6, &b, &w4, false, f64::INFINITY).unwrap().cost < w4.leaf(6));
        let w8 = Costs { width: 8.0, ..COSTS };
        assert!(find_split(l.axes(), 6, &b, &w8, false, f64::INFINITY).unwrap().cost > w8.leaf(6));
    }

    /// The groups are the ceiling of `n / W`, as `f64::ceil` gives it, for every count up to
    /// far past a node's and every leaf width.
    #[test]
    fn groups_are_the_ceiling() {
        for width in 1..=16u32 {
            let costs = Costs { width: f64::from(width), ..COSTS };
            for n in (0..5000u64).chain([1 << 40, (1 << 52) + 1, (1 << 53) - 1]) {
                let n = n as f64;
                assert_eq!(costs.groups(n).to_bits(), (n / f64::from(width)).ceil().to_bits(), "{n} / {width}");
            }
        }
    }

    #[test]
    fn flat_and_empty_boxes_give_no_split() {
        let boxes = [([0.0, 0.0, 0.0], [1.0, 1.0, 0.0])];
        let l = lists_of(&boxes);
        // A box flat in two axes has no area.
        let b = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0));
        assert!(find_split(l.axes(), 1, &b, &COSTS, false, f64::INFINITY).is_none());
        assert!(find_split(l.axes(), 1, &Aabb::EMPTY, &COSTS, false, f64::INFINITY).is_none());
    }

    #[test]
    fn huge_and_tiny_boxes_are_finite() {
        for s in [1e-30f32, 1e30, 3e38] {
            let boxes = [([0.0, 0.0, 0.0], [0.1 * s, 0.1 * s, 0.1 * s]), ([0.9 * s, 0.0, 0.0], [s, s, s])];
            let l = lists_of(&boxes);
            let b = Aabb::new(Vec3::splat(-s), Vec3::splat(s));
            let sp = find_split(l.axes(), 2, &b, &COSTS, false, f64::INFINITY).unwrap();
            assert!(sp.cost.is_finite() && sp.cost > 0.0, "{s}: {sp:?}");
        }
    }
}
