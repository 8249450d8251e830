//! Compact split-candidate events (Wald & Havran 2006, section 4.2).
//!
//! An event is one `u64`: the high 32 bits are the plane position mapped to an unsigned key
//! that sorts like the float, the low 32 bits hold the event type (2 bits) above the triangle
//! index (30 bits). Sorting the `u64`s therefore sorts by position, then by type in the order
//! the sweep needs (end < planar < start at the same position), then by triangle: a total
//! order, so the sorted lists, and the tree built from them, never depend on the sort
//! algorithm or on scheduling.

/// A triangle's extent ends at the event position (`max` of its clipped box).
pub(crate) const END: u32 = 0;
/// The triangle's clipped box is flat at the event position (it lies in the plane).
pub(crate) const PLANAR: u32 = 1;
/// A triangle's extent starts at the event position (`min` of its clipped box).
pub(crate) const START: u32 = 2;

/// Bits of an event that hold the triangle index.
pub(crate) const PRIM_BITS: u32 = 30;
/// Mask of the triangle index in the low word of an event.
pub(crate) const PRIM_MASK: u32 = (1 << PRIM_BITS) - 1;

/// The unsigned key of a finite position: sorts like the float, `-0.0` mapped to `+0.0` so
/// that both zeros are one plane.
#[inline(always)]
pub(crate) fn pos_key(pos: f32) -> u32 {
    let bits = (pos + 0.0).to_bits();
    if bits & 0x8000_0000 != 0 { !bits } else { bits | 0x8000_0000 }
}

/// The position of a key made by [`pos_key`].
#[inline(always)]
pub(crate) fn key_pos(key: u32) -> f32 {
    let bits = if key & 0x8000_0000 != 0 { key & 0x7fff_ffff } else { !key };
    f32::from_bits(bits)
}

/// The event of type `ty` for triangle `prim` (`< 2^30`) at `pos`.
#[inline(always)]
pub(crate) fn event(pos: f32, ty: u32, prim: u32) -> u64 {
    (u64::from(pos_key(pos)) << 32) | u64::from((ty << PRIM_BITS) | prim)
}

/// The position key of an event.
#[inline(always)]
pub(crate) fn ev_key(e: u64) -> u32 {
    (e >> 32) as u32
}

/// The type of an event ([`END`], [`PLANAR`] or [`START`]).
#[inline(always)]
pub(crate) fn ev_type(e: u64) -> u32 {
    ((e >> PRIM_BITS) & 3) as u32
}

/// The triangle of an event.
#[inline(always)]
pub(crate) fn ev_prim(e: u64) -> u32 {
    (e as u32) & PRIM_MASK
}

/// Per-axis sorted event lists of one node. The buffers only grow; the logical lengths are
/// kept apart so that reusing them never re-initialises memory.
#[derive(Default, Debug)]
pub(crate) struct Lists {
    buf: [Vec<u64>; 3],
    len: [usize; 3],
}

impl Lists {
    /// Lists holding the given (sorted) vectors.
    pub fn from_vecs(v: [Vec<u64>; 3]) -> Lists {
        let len = [v[0].len(), v[1].len(), v[2].len()];
        Lists { buf: v, len }
    }

    /// Bytes of the three buffers (their capacity), for the memory meter.
    pub fn heap_bytes(&self) -> u64 {
        self.buf.iter().map(|b| 8 * b.capacity() as u64).sum()
    }

    /// The events of axis `a`.
    #[inline]
    pub fn axis(&self, a: usize) -> &[u64] {
        &self.buf[a][..self.len[a]]
    }

    /// The events of the three axes.
    #[inline]
    pub fn axes(&self) -> [&[u64]; 3] {
        [self.axis(0), self.axis(1), self.axis(2)]
    }

    /// A buffer of at least `n` entries for axis `a` to write into; its contents are stale.
    #[cfg(test)]
    pub fn writable(&mut self, a: usize, n: usize) -> &mut [u64] {
        if self.buf[a].len() < n {
            self.buf[a].resize(n, 0);
        }
        &mut self.buf[a]
    }

    /// The buffers of the three axes to write into (contents stale, lengths set with
    /// [`Lists::set_len`]).
    #[inline]
    pub fn bufs_mut(&mut self) -> &mut [Vec<u64>; 3] {
        &mut self.buf
    }

    /// Sets the length of axis `a` (at most the buffer's).
    #[inline]
    pub fn set_len(&mut self, a: usize, n: usize) {
        debug_assert!(n <= self.buf[a].len());
        self.len[a] = n;
    }

    /// Merges the sorted `extra` into axis `a` in place (from the back, no buffer).
    #[cfg(test)]
    pub fn merge(&mut self, a: usize, extra: &[u64]) {
        if extra.is_empty() {
            return;
        }
        let old = self.len[a];
        let total = old + extra.len();
        let dst = self.writable(a, total);
        let (mut i, mut j, mut w) = (old, extra.len(), total);
        // Branch-free: 0 sorts below every event, so an exhausted `dst` never wins.
        while j > 0 {
            let a = if i > 0 { dst[i - 1] } else { 0 };
            let b = extra[j - 1];
            let take_a = a > b;
            w -= 1;
            dst[w] = if take_a { a } else { b };
            i -= usize::from(take_a);
            j -= usize::from(!take_a);
        }
        self.len[a] = total;
    }
}

/// Appends the events of triangle `prim` whose clipped box is `[lo, hi]` to the lists.
#[inline]
pub(crate) fn push_box_events(lists: &mut [Vec<u64>; 3], prim: u32, lo: [f32; 3], hi: [f32; 3]) {
    for (k, l) in lists.iter_mut().enumerate() {
        if lo[k] == hi[k] {
            l.push(event(lo[k], PLANAR, prim));
        } else {
            l.push(event(lo[k], START, prim));
            l.push(event(hi[k], END, prim));
        }
    }
}

/// Sorts `v`, events of ascending triangles per type (as made by [`push_box_events`] over
/// ascending triangles), into the full `u64` order. An LSD radix sort (stable) on the bits
/// above the triangle index, position key and type, leaves equal keys in triangle order, which
/// is the rest of the `u64` order. `tmp` is scratch.
///
/// The 34 bits are sorted in three digits of 11, 11 and 12 bits for long lists (the root's)
/// and in four of 8, 8, 8 and 10 bits for short ones (a binned build's subtrees, from a few
/// hundred events), where clearing and scanning the larger histograms would cost more than
/// the extra pass. Either way the result is the sorted list.
pub(crate) fn radix_sort_events(v: &mut Vec<u64>, tmp: &mut Vec<u64>) {
    const LONG: [(u32, u32); 3] = [(PRIM_BITS, 11), (PRIM_BITS + 11, 11), (PRIM_BITS + 22, 12)];
    const SHORT: [(u32, u32); 4] = [(PRIM_BITS, 8), (PRIM_BITS + 8, 8), (PRIM_BITS + 16, 8), (PRIM_BITS + 24, 10)];
    if v.len() >= 1 << 16 {
        radix_sort_digits::<3, { 1 << 12 }>(v, tmp, &LONG);
    } else {
        radix_sort_digits::<4, { 1 << 10 }>(v, tmp, &SHORT);
    }
}

/// [`radix_sort_events`] with `D` digits `(shift, bits)` (least significant first, covering
/// the 34 bits above the triangle index), `H` at least the largest `1 << bits`.
fn radix_sort_digits<const D: usize, const H: usize>(v: &mut Vec<u64>, tmp: &mut Vec<u64>, digits: &[(u32, u32); D]) {
    let mut hist = [[0usize; H]; D];
    for &e in v.iter() {
        for (h, &(shift, bits)) in hist.iter_mut().zip(digits) {
            h[((e >> shift) & ((1 << bits) - 1)) as usize] += 1;
        }
    }
    tmp.clear();
    tmp.resize(v.len(), 0);
    for (h, &(shift, bits)) in hist.iter_mut().zip(digits) {
        let h = &mut h[..1 << bits];
        // A digit shared by all events leaves the order as it is.
        if h.contains(&v.len()) {
            continue;
        }
        let mut sum = 0;
        for c in h.iter_mut() {
            (*c, sum) = (sum, sum + *c);
        }
        for &e in v.iter() {
            let d = ((e >> shift) & ((1 << bits) - 1)) as usize;
            tmp[h[d]] = e;
            h[d] += 1;
        }
        std::mem::swap(v, tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    #[test]
    fn keys_sort_like_floats() {
        let xs = [-1e30f32, -2.5, -1e-30, -0.0, 0.0, 1e-38, 1e-30, 0.5, 3.0, 1e30, f32::MAX, f32::MIN];
        for &a in &xs {
            assert_eq!(key_pos(pos_key(a)), a + 0.0);
            for &b in &xs {
                assert_eq!(a.partial_cmp(&b), pos_key(a).partial_cmp(&pos_key(b)), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn events_order_by_position_then_type() {
        let e = event(1.0, END, 7);
        let p = event(1.0, PLANAR, 3);
        let s = event(1.0, START, 1);
        assert!(e < p && p < s);
        assert!(s < event(1.5, END, 0));
        assert_eq!((ev_type(p), ev_prim(p), key_pos(ev_key(p))), (PLANAR, 3, 1.0));
        assert_eq!(ev_prim(event(0.0, START, PRIM_MASK)), PRIM_MASK);
    }

    #[test]
    fn radix_sort_matches_sort() {
        let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
        let mut lists: [Vec<u64>; 3] = Default::default();
        for prim in 0..40_000u32 {
            // Few distinct positions, both signs, so that keys tie often.
            let mut r = || ((rng.next_u64() >> 40) % 64) as f32 * 0.25 - 8.0;
            let (a, b, c) = (r(), r(), r());
            let (lo, hi) = ([a.min(b), b, c.min(a)], [a.max(b), b, c.max(a)]);
            push_box_events(&mut lists, prim, lo, hi);
        }
        let mut tmp = Vec::new();
        for l in &mut lists {
            let mut want = l.clone();
            want.sort_unstable();
            radix_sort_events(l, &mut tmp);
            assert_eq!(*l, want);
        }
    }

    /// Both digit layouts (short and long lists) on positions spread over every exponent.
    #[test]
    fn radix_sort_matches_sort_on_wide_positions() {
        let mut rng = XorShift(0x2545_f491_4f6c_dd1d);
        for n in [1usize, 300, 3000, 40_000] {
            let mut l: [Vec<u64>; 3] = Default::default();
            for prim in 0..n as u32 {
                let mut r = || {
                    let x = f32::from_bits((rng.next_u64() >> 32) as u32);
                    if x.is_finite() { x } else { 1.5 }
                };
                let (a, b) = (r(), r());
                push_box_events(&mut l, prim, [a.min(b), a, b], [a.max(b), a, b.max(a)]);
            }
            let mut tmp = Vec::new();
            for v in &mut l {
                let mut want = v.clone();
                want.sort_unstable();
                radix_sort_events(v, &mut tmp);
                assert_eq!(*v, want, "{n} triangles");
            }
        }
    }

    #[test]
    fn merge_keeps_order() {
        let mut a = Lists::from_vecs([vec![1, 4, 9, 12], vec![], vec![7]]);
        a.merge(0, &[0, 5, 13]);
        a.merge(1, &[2, 3]);
        a.merge(2, &[]);
        assert_eq!(a.axes(), [&[0, 1, 4, 5, 9, 12, 13][..], &[2, 3], &[7]]);
        a.set_len(0, 2);
        a.merge(0, &[3]);
        assert_eq!(a.axis(0), &[0, 1, 3]);
    }
}
