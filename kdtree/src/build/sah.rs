//! The SAH plane search: one linear sweep over each axis's sorted events (Wald & Havran 2006,
//! section 4.2, algorithm 4), with the planar-triangle side rule (section 3.3: triangles lying
//! in the plane go to the side that gives the lower cost).

use super::events::{END, PLANAR, START, ev_key, ev_type, key_pos};
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
pub(crate) fn surface_area64(b: &Aabb) -> f64 {
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
/// axis order, then position order, so the result is deterministic.
pub(crate) fn find_split(lists: [&[u64]; 3], n: usize, b: &Aabb, costs: &Costs) -> Option<Split> {
    let e = extent64(b);
    let sa = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0]);
    if !(sa > 0.0 && sa.is_finite()) {
        return None;
    }
    let inv_sa = 1.0 / sa;
    let mut best: Option<Split> = None;
    let mut best_cost = f64::INFINITY;
    for (k, ev) in lists.iter().enumerate() {
        if e[k] <= 0.0 {
            continue;
        }
        let (o1, o2) = ((k + 1) % 3, (k + 2) % 3);
        let cross = e[o1] * e[o2];
        let sum = e[o1] + e[o2];
        let (lo, hi) = (b.min[k], b.max[k]);
        let lo64 = f64::from(lo);
        let hi64 = f64::from(hi);
        // Scale once: cost = c_trav + c_isect * (nl * sa_l + nr * sa_r) / sa.
        let scale = costs.c_isect * 2.0 * inv_sa;
        let (mut nl, mut nr) = (0usize, n);
        let mut i = 0;
        let len = ev.len();
        while i < len {
            let key = ev_key(ev[i]);
            let (mut pe, mut pp, mut ps) = (0usize, 0usize, 0usize);
            while i < len && ev_key(ev[i]) == key {
                let t = ev_type(ev[i]);
                pe += usize::from(t == END);
                pp += usize::from(t == PLANAR);
                ps += usize::from(t == START);
                i += 1;
            }
            nr -= pe + pp;
            let p = key_pos(key);
            if p > lo && p < hi {
                let p64 = f64::from(p);
                let sa_l = cross + (p64 - lo64) * sum;
                let sa_r = cross + (hi64 - p64) * sum;
                let cost_of = |l: usize, r: usize| {
                    let c = costs.c_trav + scale * (l as f64 * sa_l + r as f64 * sa_r);
                    if l == 0 || r == 0 { c * costs.empty_factor } else { c }
                };
                let c_left = cost_of(nl + pp, nr);
                let c_right = if pp > 0 { cost_of(nl, nr + pp) } else { f64::INFINITY };
                let (c, planar_left) = if c_left <= c_right { (c_left, true) } else { (c_right, false) };
                if c < best_cost {
                    best_cost = c;
                    best = Some(Split { axis: k, pos: p, planar_left, cost: c });
                }
            }
            nl += ps + pp;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::super::events::{Lists, push_box_events};
    use super::*;
    use glam::Vec3;

    const COSTS: Costs = Costs { c_trav: 1.0, c_isect: 5.0, empty_factor: 1.0 };

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
        let s = find_split(l.axes(), 2, &b, &COSTS).unwrap();
        assert_eq!(s.axis, 0);
        assert!(s.pos == 1.0 || s.pos == 9.0, "{s:?}");
        assert!(s.cost < 10.0);
    }

    #[test]
    fn flat_and_empty_boxes_give_no_split() {
        let boxes = [([0.0, 0.0, 0.0], [1.0, 1.0, 0.0])];
        let l = lists_of(&boxes);
        // A box flat in two axes has no area.
        let b = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0));
        assert!(find_split(l.axes(), 1, &b, &COSTS).is_none());
        assert!(find_split(l.axes(), 1, &Aabb::EMPTY, &COSTS).is_none());
    }

    #[test]
    fn huge_and_tiny_boxes_are_finite() {
        for s in [1e-30f32, 1e30, 3e38] {
            let boxes = [([0.0, 0.0, 0.0], [0.1 * s, 0.1 * s, 0.1 * s]), ([0.9 * s, 0.0, 0.0], [s, s, s])];
            let l = lists_of(&boxes);
            let b = Aabb::new(Vec3::splat(-s), Vec3::splat(s));
            let sp = find_split(l.axes(), 2, &b, &COSTS).unwrap();
            assert!(sp.cost.is_finite() && sp.cost > 0.0, "{s}: {sp:?}");
        }
    }
}
