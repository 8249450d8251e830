//! Splitting a node's event lists at the chosen plane (Wald & Havran 2006, section 4.3):
//! classify each triangle left-only / right-only / both from the events of the split axis,
//! copy the one-sided triangles' events to their side (still sorted), clip the straddling ones
//! to each child box, sort their few new events and merge them in. Nothing is re-sorted.

use glam::Vec3;

use super::clip::clipped_split_bounds;
use super::events::{END, Lists, START, ev_key, ev_prim, ev_type, pos_key, push_box_events};
use super::sah::Split;
use crate::Aabb;

/// Classification of a triangle: both sides (straddles the plane).
pub(crate) const BOTH: u8 = 0;
/// Classification of a triangle: left (below the plane) only.
pub(crate) const LEFT: u8 = 1;
/// Classification of a triangle: right (above the plane) only.
pub(crate) const RIGHT: u8 = 2;

/// Reusable buffers of the split step.
#[derive(Default)]
pub(crate) struct SplitScratch {
    /// Triangles that straddle the plane, in the order of the split axis's events.
    both: Vec<u32>,
    /// New events of the clipped straddling triangles, left and right.
    new: [[Vec<u64>; 3]; 2],
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
/// only the entries of this node's triangles are written and read.
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
) -> (usize, usize) {
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
        for &prim in &scratch.both {
            let tri = &tris[prim as usize];
            let (l, r) = clipped_split_bounds(tri, lo, hi, k, s.pos);
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
            new_l[a].sort_unstable();
            new_r[a].sort_unstable();
        }
    }
    // Copy the one-sided triangles' events, branch-free: every event is written to both
    // outputs and each output's cursor advances only for its own side. The new events are
    // merged in on the way (a straddling triangle's old events are dropped: class BOTH).
    for a in 0..3 {
        let src = lists.axis(a);
        let (xl, xr) = (&new_l[a][..], &new_r[a][..]);
        let l = left.writable(a, src.len() + xl.len());
        let r = right.writable(a, src.len() + xr.len());
        let (mut il, mut ir) = (0usize, 0usize);
        if xl.is_empty() && xr.is_empty() {
            for &e in src {
                let c = class[ev_prim(e) as usize];
                l[il] = e;
                r[ir] = e;
                il += usize::from(c == LEFT);
                ir += usize::from(c == RIGHT);
            }
        } else {
            let (mut jl, mut jr) = (0usize, 0usize);
            for &e in src {
                while jl < xl.len() && xl[jl] < e {
                    l[il] = xl[jl];
                    il += 1;
                    jl += 1;
                }
                while jr < xr.len() && xr[jr] < e {
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
            l[il..il + xl.len() - jl].copy_from_slice(&xl[jl..]);
            il += xl.len() - jl;
            r[ir..ir + xr.len() - jr].copy_from_slice(&xr[jr..]);
            ir += xr.len() - jr;
        }
        left.set_len(a, il);
        right.set_len(a, ir);
    }
    (nl, nr)
}
