//! The traversal stack of deferred voxels, shared by every kd-tree kernel that keeps one
//! entry per deferred back child (thesis Listing 2.1's stack).
//!
//! Its [`STACK_SIZE`] slots are left uninitialised: zeroing them took about 1.5% of a
//! single primary ray's time on Sponza (768 bytes; `perf`: `memset` under `intersect`), and
//! filling the 2x2 packets' 3 KiB of 48-byte entries took as long as the traversal of a
//! short shadow packet. A push past the last slot wraps around and overwrites the oldest
//! entry, as the other kernels' `sp % STACK_SIZE` does; the builder's depth limit
//! ([`crate::MAX_DEPTH`] < `STACK_SIZE`) keeps that from happening in a valid tree.

use std::mem::MaybeUninit;

use crate::STACK_SIZE;

/// A fixed-size stack of `T`, never allocating, never initialising what it does not hold.
pub struct Stack<T: Copy> {
    slots: [MaybeUninit<T>; STACK_SIZE],
    len: usize,
}

impl<T: Copy> Default for Stack<T> {
    fn default() -> Self {
        Stack::new()
    }
}

impl<T: Copy> Stack<T> {
    /// An empty stack.
    #[inline(always)]
    pub fn new() -> Stack<T> {
        Stack { slots: [const { MaybeUninit::uninit() }; STACK_SIZE], len: 0 }
    }

    /// Pushes `entry` (overwriting the oldest entry past [`STACK_SIZE`] of them).
    #[inline(always)]
    pub fn push(&mut self, entry: T) {
        self.slots[self.len % STACK_SIZE].write(entry);
        self.len += 1;
    }

    /// The last entry pushed and not popped, or `None`.
    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: `len` changes only by `push` (+1, after writing slot `len % STACK_SIZE`)
        // and `pop` (-1). The last time `len` went from `L` to `L + 1`
        // (here `L` is the new `len`), that push wrote slot `L % STACK_SIZE`; so the slot
        // read here is initialised.
        Some(unsafe { self.slots[self.len % STACK_SIZE].assume_init() })
    }

    /// The last entry pushed and not popped, left on the stack, or `None`.
    #[inline(always)]
    pub fn top(&self) -> Option<T> {
        let len = self.len.checked_sub(1)?;
        // SAFETY: as in `pop`: slot `(self.len - 1) % STACK_SIZE` was written by the push
        // that made `self.len` what it is.
        Some(unsafe { self.slots[len % STACK_SIZE].assume_init() })
    }

    /// The entries held, bottom first (after a wrap-around: every slot, oldest overwritten).
    #[inline(always)]
    pub fn entries(&self) -> &[T] {
        let n = self.len.min(STACK_SIZE);
        // SAFETY: each slot below `min(len, STACK_SIZE)` was written: slot `i` by the push
        // that took `len` from `i` to `i + 1` (or, after a wrap-around, by an earlier one),
        // and `pop` uninitialises nothing. `MaybeUninit<T>` has `T`'s layout.
        unsafe { std::slice::from_raw_parts(self.slots.as_ptr().cast::<T>(), n) }
    }

    /// Entries pushed and not popped (more than [`STACK_SIZE`] after a wrap-around).
    #[inline(always)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds no entry.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pops_in_reverse_order_and_wraps_past_its_size() {
        let mut s = Stack::new();
        assert_eq!(s.pop(), None);
        for i in 0..10u32 {
            s.push(i);
        }
        s.push(10);
        assert_eq!(s.len(), 11);
        assert_eq!((0..11).map(|_| s.pop().unwrap()).collect::<Vec<_>>(), (0..=10).rev().collect::<Vec<_>>());
        assert!(s.is_empty() && s.pop().is_none() && s.top().is_none() && s.entries().is_empty());
        s.push(7);
        s.push(8);
        assert_eq!((s.top(), s.entries()), (Some(8), &[7, 8][..]));
        s.pop();
        assert_eq!((s.top(), s.entries()), (Some(7), &[7][..]));
        s.pop();
        // Past the last slot the oldest entries are overwritten, never read uninitialised.
        for i in 0..(STACK_SIZE as u32 + 5) {
            s.push(i);
        }
        let popped: Vec<u32> = std::iter::from_fn(|| s.pop()).collect();
        assert_eq!(popped.len(), STACK_SIZE + 5);
        for i in 0..(STACK_SIZE as u32 + 5) {
            s.push(i);
        }
        assert_eq!(s.entries().len(), STACK_SIZE);
        while s.pop().is_some() {}
        assert_eq!(popped[..STACK_SIZE], (5..STACK_SIZE as u32 + 5).rev().collect::<Vec<_>>()[..]);
    }
}
