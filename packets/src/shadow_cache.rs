//! The shadow cache (Haines & Greenberg 1986's "light buffer" idea in its simplest form,
//! as Pearce's shadow cache, Graphics Gems II, 1991): the triangles that blocked the last
//! shadow packets, tested against the next packet before it walks the tree.
//!
//! A tile's shadow rays run side by side to the same light, so the triangle that blocked one
//! 4x4 block's rays (a column, an arch, a railing) very often blocks the next block's too. A
//! packet first tests its rays against the few cached triangles, with the same packet test
//! its leaves use ([`PacketTest::intersect4`], over each ray's whole interval); the lanes
//! blocked there are done, and only the others walk the tree (all of them, when the cache
//! blocked none). A fully blocked packet takes a handful of triangle tests instead of its
//! descent: on Sponza's hard shadows a 16-ray packet takes about 40 traversal steps.
//!
//! The answer stays the single ray's: a shadow query asks whether *any* triangle blocks the
//! ray inside its interval, and a cached triangle that the leaf test finds blocking inside
//! it is such a triangle, found by the very test the single ray's leaves run. Which triangle
//! is found first changes; whether one is found does not (the conformance harness checks
//! every kernel that uses the cache against the single rays).

use kdtree::TreeTest;

use crate::packet::{PacketHit, RayPacket};
use crate::simd::{SimdF32, SimdMask};
use crate::triangle4::PacketTest;

/// How many blockers the cache remembers: the most recent distinct ones.
pub const CACHE_SIZE: usize = 4;

/// The triangles that blocked the most recent packets' rays, most recent first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadowCache {
    prims: [u32; CACHE_SIZE],
    len: usize,
}

impl ShadowCache {
    /// An empty cache.
    pub fn new() -> ShadowCache {
        ShadowCache::default()
    }

    /// The cached triangles, most recent first.
    pub fn prims(&self) -> &[u32] {
        &self.prims[..self.len]
    }

    /// Tests the valid lanes of `rays` that `hit` has not found yet against the cached
    /// triangles (records of `I`, the tree's test, with the packet's `data`), recording each
    /// hit in `hit` as a leaf would; returns the lanes found here.
    #[inline(always)]
    pub fn test<I: TreeTest<Record: PacketTest<V>>, V: SimdF32>(
        &self,
        records: &[I::Record],
        rays: &RayPacket<V>,
        data: &<I::Record as PacketTest<V>>::PacketData,
        hit: &mut PacketHit<V>,
    ) -> V::Mask {
        let mut found = V::Mask::splat(false);
        for &prim in self.prims() {
            let Some(record) = records.get(prim as usize) else { continue };
            let active = rays.valid & !hit.found;
            if !active.any() {
                break;
            }
            found |= record.intersect4(rays, data, active, hit, prim);
        }
        found
    }

    /// Remembers the triangles that blocked the lanes of `hit` (the `prim`s of its `found`
    /// lanes), most recent first, dropping the oldest beyond [`CACHE_SIZE`].
    #[inline(always)]
    pub fn remember<V: SimdF32>(&mut self, hit: &PacketHit<V>) {
        let mut bits = hit.found.bitmask();
        while bits != 0 {
            let lane = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            self.push(hit.prim[lane]);
        }
    }

    /// Puts `prim` first (moving it there if cached already).
    #[inline(always)]
    fn push(&mut self, prim: u32) {
        if self.len > 0 && self.prims[0] == prim {
            return;
        }
        let at = self.prims[..self.len].iter().position(|&p| p == prim).unwrap_or_else(|| {
            self.len = (self.len + 1).min(CACHE_SIZE);
            self.len - 1
        });
        self.prims.copy_within(0..at, 1);
        self.prims[0] = prim;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_most_recent_distinct_blockers_are_kept_first() {
        let mut cache = ShadowCache::new();
        for prim in [7, 7, 3, 9, 7, 1, 5] {
            cache.push(prim);
        }
        assert_eq!(cache.prims(), &[5, 1, 7, 9]);
        cache.push(9);
        assert_eq!(cache.prims(), &[9, 5, 1, 7]);
    }
}
