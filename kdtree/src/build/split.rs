//! Splitting a node's event lists at the chosen plane (Wald & Havran 2006, section 4.3):
//! classify each triangle left-only / right-only / both from the events of the split axis,
//! copy the one-sided triangles' events to their side (still sorted), clip the straddling ones
//! to each child box, sort their few new events and merge them in. Nothing is re-sorted.

use glam::Vec3;

use super::BuildError;
use super::clip::{Polygon, clipped_split_bounds};
use super::events::{END, Lists, START, ev_key, ev_prim, ev_type, pos_key, push_box_events};
use super::sah::Split;
use crate::Aabb;

/// Classification of a triangle: both sides (straddles the plane).
pub(crate) const BOTH: u8 = 0;
/// Classification of a triangle: left (below the plane) only.
pub(crate) const LEFT: u8 = 1;
/// Classification of a triangle: right (above the plane) only.
pub(crate) const RIGHT: u8 = 2;

/// Ends the new-event lists so the merge needs no bounds test: above every event (its key
/// would be a NaN position).
const SENTINEL: u64 = u64::MAX;

/// Reusable buffers of the split step.
#[derive(Default)]
pub(crate) struct SplitScratch {
    /// Triangles that straddle the plane, in the order of the split axis's events.
    both: Vec<u32>,
    /// New events of the clipped straddling triangles, left and right.
    new: [[Vec<u64>; 3]; 2],
    /// The clipper's polygon buffers.
    pub polys: [Polygon; 2],
}

/// The children boxes of `b` split by `s`.
#[inline]
pub(crate) fn child_boxes(b: &Aabb, s: &Split) -> (Aabb, Aabb) {
    let (mut l, mut r) = (*b, *b);
    l.max[s.axis] = s.pos;
    r.min[s.axis] = s.pos;
    (l, r)
}

/// Splits the node whose sorted events are `lists` at `s` into `left` and `right` (cleared
/// first), returning the triangle counts of the children. `class` is indexed by triangle and
/// only the entries of this node's triangles are written and read. With `par` the axes are
/// copied in parallel (for big nodes); the result is the same.
///
/// `reserve` is told, before the children's buffers grow, how many bytes they need at most
/// (the parent's events plus the straddlers' new ones, per child and axis): the memory meter
/// of a big node (see [`super::Meter`]); an error from it stops the split.
#[allow(clippy::too_many_arguments)]
pub(crate) fn split_lists(
    tris: &[[Vec3; 3]],
    lists: &Lists,
    b: &Aabb,
    s: &Split,
    class: &mut [u8],
    scratch: &mut SplitScratch,
    left: &mut Lists,
    right: &mut Lists,
    par: bool,
    reserve: &mut dyn FnMut(u64) -> Result<(), BuildError>,
) -> Result<(usize, usize), BuildError> {
    let k = s.axis;
    let pkey = pos_key(s.pos);
    let planar_side = if s.planar_left { LEFT } else { RIGHT };
    scratch.both.clear();
    // Classify from the split axis. A triangle's first event is its start (or its only,
    // planar, event); its end follows later in the sorted list, and only then is a triangle
    // that started left of the plane known to straddle it.
    let (mut nl, mut nr) = (0usize, 0usize);
    for &e in lists.axis(k) {
        let prim = ev_prim(e);
        let key = ev_key(e);
        match ev_type(e) {
            START => {
                let right = key >= pkey;
                nr += usize::from(right);
                class[prim as usize] = if right { RIGHT } else { BOTH };
            }
            END => {
                if key <= pkey {
                    class[prim as usize] = LEFT;
                    nl += 1;
                } else if class[prim as usize] == BOTH {
                    scratch.both.push(prim);
                }
            }
            _ => {
                let c = match key.cmp(&pkey) {
                    std::cmp::Ordering::Less => LEFT,
                    std::cmp::Ordering::Greater => RIGHT,
                    std::cmp::Ordering::Equal => planar_side,
                };
                nl += usize::from(c == LEFT);
                nr += usize::from(c == RIGHT);
                class[prim as usize] = c;
            }
        }
    }
    // Clip the straddling triangles to both children first; their new events (few) are
    // sorted and then merged into the copy below.
    let [new_l, new_r] = &mut scratch.new;
    for v in new_l.iter_mut().chain(new_r.iter_mut()) {
        v.clear();
    }
    if !scratch.both.is_empty() {
        let (lo, hi) = (b.min.to_array(), b.max.to_array());
        for v in new_l.iter_mut().chain(new_r.iter_mut()) {
            v.reserve(2 * scratch.both.len() + 1);
        }
        for &prim in &scratch.both {
            let tri = &tris[prim as usize];
            let (l, r) = clipped_split_bounds(tri, lo, hi, k, s.pos, &mut scratch.polys);
            if let Some((lo, hi)) = l {
                push_box_events(new_l, prim, lo, hi);
                nl += 1;
            }
            if let Some((lo, hi)) = r {
                push_box_events(new_r, prim, lo, hi);
                nr += 1;
            }
        }
        for a in 0..3 {
            for v in [&mut new_l[a], &mut new_r[a]] {
                v.sort_unstable();
                v.push(SENTINEL);
            }
        }
    }
    // The children's buffers grow to at most the parent's events plus the new ones.
    let need: usize = (0..3).map(|a| 2 * lists.axis(a).len() + new_l[a].len() + new_r[a].len()).sum();
    reserve(8 * need as u64)?;
    // Copy the one-sided triangles' events (the three axes in parallel for big nodes).
    let class = &*class;
    let [lb, rb] = [left.bufs_mut(), right.bufs_mut()];
    let [l0, l1, l2] = lb;
    let [r0, r1, r2] = rb;
    let copy =
        |a: usize, l: &mut Vec<u64>, r: &mut Vec<u64>| copy_axis(lists.axis(a), class, &new_l[a], &new_r[a], l, r);
    let lens = if par {
        let (x, (y, z)) = rayon::join(|| copy(0, l0, r0), || rayon::join(|| copy(1, l1, r1), || copy(2, l2, r2)));
        [x, y, z]
    } else {
        [copy(0, l0, r0), copy(1, l1, r1), copy(2, l2, r2)]
    };
    for (a, (il, ir)) in lens.into_iter().enumerate() {
        left.set_len(a, il);
        right.set_len(a, ir);
    }
    Ok((nl, nr))
}

/// Copies the events `src` of one axis of a node to its children's buffers `l` and `r` (grown
/// as needed), dropping those of straddling triangles (class [`BOTH`]) and merging in the
/// sorted new events `xl` and `xr` of the clipped straddling triangles (both empty, or both
/// ended by [`SENTINEL`]). Returns the lengths.
#[inline]
fn copy_axis(src: &[u64], class: &[u8], xl: &[u64], xr: &[u64], l: &mut Vec<u64>, r: &mut Vec<u64>) -> (usize, usize) {
    grow(l, src.len() + xl.len());
    grow(r, src.len() + xr.len());
    let (mut il, mut ir) = (0usize, 0usize);
    debug_assert!(xl.is_empty() == xr.is_empty() && xl.last().is_none_or(|&x| x == SENTINEL));
    // Branch-free: every event is written to both outputs and each output's cursor advances
    // only for its own side.
    if xl.is_empty() && xr.is_empty() {
        for &e in src {
            let c = class[ev_prim(e) as usize];
            l[il] = e;
            r[ir] = e;
            il += usize::from(c == LEFT);
            ir += usize::from(c == RIGHT);
        }
        return (il, ir);
    }
    let (mut jl, mut jr) = (0usize, 0usize);
    for &e in src {
        // The sentinel stops these loops.
        while xl[jl] < e {
            l[il] = xl[jl];
            il += 1;
            jl += 1;
        }
        while xr[jr] < e {
            r[ir] = xr[jr];
            ir += 1;
            jr += 1;
        }
        let c = class[ev_prim(e) as usize];
        l[il] = e;
        r[ir] = e;
        il += usize::from(c == LEFT);
        ir += usize::from(c == RIGHT);
    }
    let (xl, xr) = (&xl[..xl.len() - 1], &xr[..xr.len() - 1]);
    l[il..il + xl.len() - jl].copy_from_slice(&xl[jl..]);
    il += xl.len() - jl;
    r[ir..ir + xr.len() - jr].copy_from_slice(&xr[jr..]);
    ir += xr.len() - jr;
    (il, ir)
}

/// Grows `v` to at least `n` entries (new ones zero, old ones kept: stale contents are fine).
#[inline]
fn grow(v: &mut Vec<u64>, n: usize) {
    if v.len() < n {
        v.resize(n, 0);
    }
}
