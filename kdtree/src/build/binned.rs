//! The binned top of a [`super::BuildStrategy::Binned`] build: min-max binning (Shevtsov,
//! Soupikov and Kapustin 2007, section 3; Mitsuba's `gkdtree` bins nodes above 65,536
//! triangles with 128 bins) for the nodes with at least `min_tris` triangles, then the exact
//! event sweep ([`super::build_par`]) below them, its events made for each subtree only.
//!
//! - A binned node keeps its triangles as [`Item`]s: the triangle and its box clipped to the
//!   node (at the root, the triangle's own box), in ascending triangle order.
//! - Min-max binning: per axis, `bins` equal bins over the node's extent; each item's box
//!   minimum is counted in the bin it falls in, its maximum in another count. The SAH cost
//!   (thesis 2.2.1, with the empty bonus) is evaluated on the `bins - 1` inner bin
//!   boundaries: left of boundary `i` are the items whose minimum is in a bin below `i`,
//!   right of it those whose maximum is not. The counts are those of the boxes at the bins'
//!   resolution, the plane is the boundary itself; the split then classifies every item
//!   against the plane exactly, as the sweep does, and clips the straddling ones to both
//!   children (perfect splits, thesis 3.2.1), so the children's boxes are as tight as in the
//!   exact build and only the plane's position is rounded to a bin.
//! - When no boundary is cheaper than a leaf, the node is handed to the exact sweep, which
//!   decides between its own best plane and a leaf.
//! - Parallel from the root: the binning runs over fixed chunks of items with rayon (the
//!   counts of the chunks summed: integers, so the sum does not depend on the order), the
//!   split over fixed chunks too, concatenated in chunk order, and the two children with
//!   `rayon::join`. The chunks do not depend on the number of threads, so neither does the
//!   tree.
//! - Memory: the items (28 bytes each), the chunks of a split and the children's items are
//!   taken from the build's [`super::Meter`]; the hand-off's event lists and their sort as in
//!   the exact build's root.

use glam::Vec3;
use rayon::prelude::*;

use super::clip::Polygon;
use super::events::{Lists, push_box_events, radix_sort_events};
use super::sah::{Costs, Split, extent64};
use super::small::{Item, partition};
use super::split::child_boxes;
use super::{At, BuildError, Ctx, Sub, build_par};
use crate::Aabb;

/// Bytes of one [`Item`] (as metered).
pub(crate) const ITEM_BYTES: u64 = std::mem::size_of::<Item>() as u64;

/// Items per chunk of the parallel binning and split. Fixed, so the tree does not depend on
/// the number of threads.
const CHUNK: usize = 8192;

/// The binned build's parameters.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Binning {
    /// Bins per axis.
    pub bins: usize,
    /// Nodes with at least this many triangles are binned.
    pub min_tris: usize,
}

/// The root items: each triangle of `prims` (ascending) with its own box.
pub(crate) fn root_items(tris: &[[Vec3; 3]], prims: &[u32]) -> Vec<Item> {
    prims
        .par_iter()
        .with_min_len(CHUNK)
        .map(|&p| {
            let [a, b, c] = tris[p as usize];
            let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
            Item { prim: p, lo: lo.to_array(), hi: hi.to_array() }
        })
        .collect()
}

/// Builds the subtree of a node whose triangles are `items` (their bytes taken from the
/// meter, given back here when they are freed): binned while it has at least `min_tris`
/// triangles, by the exact sweep below.
pub(crate) fn build_binned(ctx: &Ctx, items: Vec<Item>, b: Aabb, at: At, binning: &Binning) -> Result<Sub, BuildError> {
    let n = items.len();
    let item_bytes = ITEM_BYTES * items.capacity() as u64;
    // Only a boundary cheaper than the leaf splits here: a costlier one (a bad refine) is
    // left to the exact sweep of the hand-off, which finds its own plane.
    let split = if n >= binning.min_tris && at.depth < ctx.depth_limit {
        let limit = ctx.costs.leaf(n);
        binned_split(&items, &b, &ctx.costs, binning.bins).filter(|s| s.cost < limit)
    } else {
        None
    };
    let Some(s) = split else {
        let lists = hand_off(ctx, &items);
        drop(items);
        ctx.meter.give(item_bytes);
        return build_par(ctx, lists?, n, b, at);
    };
    let next = At { depth: at.depth + 1, bad: at.bad };
    // Each chunk's two outputs hold at most its items each.
    let chunk_bytes = 2 * ITEM_BYTES * n as u64;
    if let Err(e) = ctx.meter.take(chunk_bytes, "a binned node's split chunks") {
        ctx.meter.give(item_bytes);
        return Err(e);
    }
    let split_chunk = |c: &[Item]| {
        let mut polys = [Polygon::default(); 2];
        let (mut l, mut r) = (Vec::with_capacity(c.len()), Vec::with_capacity(c.len()));
        partition(ctx.tris, c, &b, &s, &mut polys, &mut l, &mut r);
        (l, r)
    };
    if n <= CHUNK {
        // One chunk: its outputs are the children's items (the bytes already taken).
        let (left, right) = split_chunk(&items);
        drop(items);
        ctx.meter.give(item_bytes);
        let (bl, br) = child_boxes(&b, &s);
        let (l, r) =
            rayon::join(|| build_binned(ctx, left, bl, next, binning), || build_binned(ctx, right, br, next, binning));
        return Ok(Sub::Inner { axis: s.axis, pos: s.pos, kids: Box::new((l?, r?)) });
    }
    let parts: Vec<(Vec<Item>, Vec<Item>)> = items.par_chunks(CHUNK).map(split_chunk).collect();
    drop(items);
    ctx.meter.give(item_bytes);
    let (nl, nr) = parts.iter().fold((0, 0), |(a, b), (l, r)| (a + l.len(), b + r.len()));
    let child_bytes = ITEM_BYTES * (nl + nr) as u64;
    if let Err(e) = ctx.meter.take(child_bytes, "a binned node's children's items") {
        ctx.meter.give(chunk_bytes);
        return Err(e);
    }
    let (mut left, mut right) = (Vec::with_capacity(nl), Vec::with_capacity(nr));
    for (l, r) in parts {
        left.extend_from_slice(&l);
        right.extend_from_slice(&r);
    }
    ctx.meter.give(chunk_bytes);
    let (bl, br) = child_boxes(&b, &s);
    let (l, r) =
        rayon::join(|| build_binned(ctx, left, bl, next, binning), || build_binned(ctx, right, br, next, binning));
    Ok(Sub::Inner { axis: s.axis, pos: s.pos, kids: Box::new((l?, r?)) })
}

/// The sorted event lists of a node's items (ascending triangles, so the radix sort
/// applies), their bytes taken from the meter.
fn hand_off(ctx: &Ctx, items: &[Item]) -> Result<Lists, BuildError> {
    let n = items.len();
    let list_bytes = 3 * 2 * 8 * n as u64;
    ctx.meter.take(list_bytes, "a binned node's event lists")?;
    let mut lists: [Vec<u64>; 3] = Default::default();
    for l in &mut lists {
        l.reserve_exact(2 * n);
    }
    for it in items {
        push_box_events(&mut lists, it.prim, it.lo, it.hi);
    }
    let sort_bytes: u64 = lists.iter().map(|l| 8 * l.len() as u64).sum();
    if let Err(e) = ctx.meter.take(sort_bytes, "a binned node's event sort") {
        ctx.meter.give(list_bytes);
        return Err(e);
    }
    let sort = |l: &mut Vec<u64>| radix_sort_events(l, &mut Vec::new());
    let [l0, l1, l2] = &mut lists;
    if n >= super::PAR_MIN_TRIS {
        rayon::join(|| sort(l0), || rayon::join(|| sort(l1), || sort(l2)));
    } else {
        sort(l0);
        sort(l1);
        sort(l2);
    }
    ctx.meter.give(sort_bytes);
    // The radix sort swaps buffers: the capacities are now the second buffers'.
    let lists = Lists::from_vecs(lists);
    ctx.meter.give(list_bytes);
    ctx.meter.take(lists.heap_bytes(), "a binned node's event lists")?;
    Ok(lists)
}

/// Per axis, per bin: the items whose box minimum (`[.., 0]`) and maximum (`[.., 1]`) fall in
/// the bin.
type Counts = Vec<[u32; 2]>;

/// The bin of `x` among `bins` bins from `lo` of width `1 / inv`, clamped. In `f32`: a
/// box edge within rounding of a boundary may be counted in the bin on its other side,
/// which only moves the cost estimate (the split classifies exactly).
#[inline(always)]
fn bin_of(x: f32, lo: f32, inv: f32, bins: usize) -> usize {
    let f = (x - lo) * inv;
    // `as` saturates: negative values (and NaN) give 0, huge ones `u32::MAX`.
    (f as u32 as usize).min(bins - 1)
}

/// The cheapest bin boundary of the node `items` in `b` (min-max binning, see the module
/// docs), or `None` when no boundary lies strictly inside the box.
pub(crate) fn binned_split(items: &[Item], b: &Aabb, costs: &Costs, bins: usize) -> Option<Split> {
    let e = extent64(b);
    let sa = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0]);
    if !(sa > 0.0 && sa.is_finite()) {
        return None;
    }
    let lo = [0, 1, 2].map(|k| f64::from(b.min[k]));
    let lo32 = b.min.to_array();
    // Infinite for extents of a few f32 steps near zero: then `bin_of` clamps (0 * inf is
    // NaN, which counts as bin 0), and only the estimate is coarser.
    let inv32 = [0, 1, 2].map(|k| if e[k] > 0.0 { (bins as f64 / e[k]) as f32 } else { 0.0 });
    let count = |c: &[Item]| -> [Counts; 3] {
        let mut h: [Counts; 3] = std::array::from_fn(|_| vec![[0u32; 2]; bins]);
        for it in c {
            for k in 0..3 {
                h[k][bin_of(it.lo[k], lo32[k], inv32[k], bins)][0] += 1;
                h[k][bin_of(it.hi[k], lo32[k], inv32[k], bins)][1] += 1;
            }
        }
        h
    };
    let merge = |mut a: [Counts; 3], b: [Counts; 3]| {
        for (ha, hb) in a.iter_mut().zip(&b) {
            for (x, y) in ha.iter_mut().zip(hb) {
                x[0] += y[0];
                x[1] += y[1];
            }
        }
        a
    };
    let h = if items.len() > CHUNK {
        items.par_chunks(CHUNK).map(count).reduce_with(merge).unwrap_or_else(|| count(&[]))
    } else {
        count(items)
    };
    let nf = items.len() as f64;
    let scale = costs.c_isect * 2.0 * (1.0 / sa);
    let mut pick: Option<Split> = None;
    for (k, hk) in h.iter().enumerate() {
        if e[k] <= 0.0 {
            continue;
        }
        let (o1, o2) = ((k + 1) % 3, (k + 2) % 3);
        let (cross, sum) = (e[o1] * e[o2], e[o1] + e[o2]);
        let (mut nl, mut nr) = (0.0f64, nf);
        for (i, c) in hk.iter().enumerate().take(bins - 1) {
            nl += f64::from(c[0]);
            nr -= f64::from(c[1]);
            // The boundary above bin `i`, as an f32 strictly inside the box.
            let x = (lo[k] + (i + 1) as f64 * (e[k] / bins as f64)) as f32;
            if !(x > b.min[k] && x < b.max[k]) {
                continue;
            }
            let d = f64::from(x) - lo[k];
            let (a_l, a_r) = (cross + d * sum, cross + (e[k] - d) * sum);
            let f = if costs.empty_factor != 1.0 && (nl == 0.0 || nr == 0.0) { costs.empty_factor } else { 1.0 };
            let cost = (costs.c_trav + scale * (costs.groups(nl) * a_l + costs.groups(nr) * a_r)) * f;
            if pick.is_none_or(|p| cost < p.cost) {
                pick = Some(Split { axis: k, pos: x, planar_left: true, cost });
            }
        }
    }
    pick
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    const COSTS: Costs = Costs { c_trav: 1.0, c_isect: 5.0, empty_factor: 1.0, width: 1.0 };

    fn item(prim: u32, lo: [f32; 3], hi: [f32; 3]) -> Item {
        Item { prim, lo, hi }
    }

    #[test]
    fn splits_between_two_clusters_on_a_boundary() {
        let mut items = Vec::new();
        for i in 0..50 {
            let x = i as f32 * 0.01;
            items.push(item(i, [x, 0.0, 0.0], [x + 0.5, 1.0, 1.0]));
            items.push(item(100 + i, [9.0 + x, 0.0, 0.0], [9.5 + x, 1.0, 1.0]));
        }
        let b = Aabb::new(Vec3::ZERO, Vec3::new(10.0, 1.0, 1.0));
        let s = binned_split(&items, &b, &COSTS, 16).unwrap();
        assert_eq!(s.axis, 0);
        // The gap is (1.0, 9.0): a boundary of 16 bins of 0.625 inside it.
        assert!(s.pos > 0.99 && s.pos < 9.0, "{s:?}");
        assert_eq!((s.pos / 0.625).fract(), 0.0, "{s:?}");
        assert!(s.cost < 100.0 * 5.0);
    }

    #[test]
    fn flat_boxes_and_tiny_extents_give_no_split() {
        let items = [item(0, [0.0; 3], [1.0, 1.0, 0.0])];
        assert!(binned_split(&items, &Aabb::new(Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0)), &COSTS, 8).is_none());
        assert!(binned_split(&items, &Aabb::EMPTY, &COSTS, 8).is_none());
        // An extent of one f32 step has no boundary strictly inside.
        let b = Aabb::new(Vec3::ONE, Vec3::new(1.0, f32::from_bits(1.0f32.to_bits() + 1), 1.0));
        assert!(binned_split(&items, &b, &COSTS, 8).is_none());
    }

    /// The counts of a boundary are those of the boxes against it, when no box edge is
    /// inside a bin's rounding distance from it: checked against counting directly.
    #[test]
    fn binned_costs_match_direct_counts() {
        let mut rng = XorShift(0x2545_f491_4f6c_dd1d);
        let mut r = move |m: u64| rng.below(m);
        for case in 0..200 {
            let bins = 8 << r(3);
            let b = Aabb::new(Vec3::ZERO, Vec3::splat(8.0));
            // Box edges at odd multiples of a half bin: never on a boundary.
            let half = 8.0 / (2 * bins) as f32;
            let n = 1 + r(3 * CHUNK as u64) as usize;
            let items: Vec<Item> = (0..n)
                .map(|i| {
                    let (mut lo, mut hi) = ([0.0; 3], [0.0; 3]);
                    for k in 0..3 {
                        let (x, y) = (r(bins) as f32, r(bins) as f32);
                        (lo[k], hi[k]) = ((2.0 * x.min(y) + 1.0) * half, (2.0 * x.max(y) + 1.0) * half);
                    }
                    item(i as u32, lo, hi)
                })
                .collect();
            let width = [1.0, 4.0, 8.0][(case / 2) % 3];
            let costs = Costs { c_trav: 1.0, c_isect: 1.5, empty_factor: if case % 2 == 0 { 1.0 } else { 0.8 }, width };
            let got = binned_split(&items, &b, &costs, bins as usize).unwrap();
            let k = got.axis;
            let (nl, nr) = items.iter().fold((0.0, 0.0), |(l, r), it| {
                (l + f64::from(u8::from(it.lo[k] < got.pos)), r + f64::from(u8::from(it.hi[k] > got.pos)))
            });
            let (a_l, a_r) = (64.0 + 16.0 * f64::from(got.pos), 64.0 + 16.0 * (8.0 - f64::from(got.pos)));
            let f = if nl == 0.0 || nr == 0.0 { costs.empty_factor } else { 1.0 };
            let (gl, gr) = (f64::ceil(nl / width), f64::ceil(nr / width));
            let want = (1.0 + 1.5 * 2.0 / 384.0 * (gl * a_l + gr * a_r)) * f;
            assert!((got.cost - want).abs() <= 1e-9 * want, "case {case}: {got:?} want {want}");
        }
    }
}
