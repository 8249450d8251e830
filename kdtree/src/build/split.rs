//! Splitting a node's event lists at the chosen plane (Wald & Havran 2006, section 4.3):
//! classify each triangle left-only / right-only / both from the events of the split axis,
//! copy the one-sided triangles' events to their side (still sorted), clip the straddling ones
//! to each child box, sort their few new events and merge them in. Nothing is re-sorted.

use glam::Vec3;

use super::clip::clipped_bounds;
use super::events::{END, Lists, PLANAR, START, ev_key, ev_prim, ev_type, merge_into, pos_key, push_box_events};
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
    new: [Lists; 2],
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
    // Classify from the split axis. A triangle's first event is its start (or its only,
    // planar, event); its end follows later in the sorted list.
    for &e in &lists.ev[k] {
        let prim = ev_prim(e) as usize;
        let key = ev_key(e);
        match ev_type(e) {
            START => class[prim] = if key >= pkey { RIGHT } else { BOTH },
            END => {
                if key <= pkey {
                    class[prim] = LEFT;
                }
            }
            _ => {
                class[prim] = match key.cmp(&pkey) {
                    std::cmp::Ordering::Less => LEFT,
                    std::cmp::Ordering::Greater => RIGHT,
                    std::cmp::Ordering::Equal => planar_side,
                }
            }
        }
    }
    left.clear();
    right.clear();
    scratch.both.clear();
    let (mut nl, mut nr) = (0usize, 0usize);
    for a in 0..3 {
        let (l, r) = (&mut left.ev[a], &mut right.ev[a]);
        for &e in &lists.ev[a] {
            match class[ev_prim(e) as usize] {
                LEFT => l.push(e),
                RIGHT => r.push(e),
                _ => {}
            }
        }
    }
    for &e in &lists.ev[k] {
        let t = ev_type(e);
        if t == START || t == PLANAR {
            match class[ev_prim(e) as usize] {
                LEFT => nl += 1,
                RIGHT => nr += 1,
                _ => scratch.both.push(ev_prim(e)),
            }
        }
    }
    if scratch.both.is_empty() {
        return (nl, nr);
    }
    let (bl, br) = child_boxes(b, s);
    let (bl_lo, bl_hi) = (bl.min.to_array(), bl.max.to_array());
    let (br_lo, br_hi) = (br.min.to_array(), br.max.to_array());
    let [new_l, new_r] = &mut scratch.new;
    new_l.clear();
    new_r.clear();
    for &prim in &scratch.both {
        let tri = &tris[prim as usize];
        if let Some((lo, hi)) = clipped_bounds(tri, bl_lo, bl_hi) {
            push_box_events(&mut new_l.ev, prim, lo, hi);
            nl += 1;
        }
        if let Some((lo, hi)) = clipped_bounds(tri, br_lo, br_hi) {
            push_box_events(&mut new_r.ev, prim, lo, hi);
            nr += 1;
        }
    }
    for a in 0..3 {
        new_l.ev[a].sort_unstable();
        new_r.ev[a].sort_unstable();
        merge_into(&mut left.ev[a], &new_l.ev[a]);
        merge_into(&mut right.ev[a], &new_r.ev[a]);
    }
    (nl, nr)
}
