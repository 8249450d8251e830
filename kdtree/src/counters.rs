//! Traversal statistics that compile to nothing when off: the thesis's N (traversal steps),
//! I (intersection tests) and the share of packets culled at leaves (Tables 4.1-4.3, 4.1.4).
//!
//! Every traversal method, single rays here and packets, frusta and cones in the crates
//! above, takes a `C: Counters` parameter. With [`NoCounters`] (a zero-sized type whose
//! methods are empty and inlined, and whose [`Counters::ENABLED`] is false) the counting code
//! disappears from the kernel; with [`Counts`] it counts nodes traversed, leaves visited,
//! intersection tests and, for the frustum methods, the packets considered and culled at
//! leaves. Counts of tiles or threads are summed with `+=`.

use std::ops::AddAssign;

/// What a traversal counts (thesis Tables 4.1-4.3): N, I and packet/leaf culling (4.1.4).
///
/// The counts are summed over rays, packets, tiles and threads with `Default` and `+=`.
pub trait Counters: Default + AddAssign {
    /// False for [`NoCounters`]: lets a kernel skip work done only for the counts.
    const ENABLED: bool = true;
    /// One traversal step: a node (inner or leaf) fetched by a ray, a packet, a frustum or
    /// the four MFT frusta.
    fn node(&mut self);
    /// One leaf visited (its triangles are about to be tested).
    fn leaf(&mut self);
    /// `n` intersection tests: ray-triangle tests for single rays, packet-triangle tests for
    /// packets (one test of up to four rays against one triangle counts once).
    fn tests(&mut self, n: u64);
    /// At one leaf of a frustum traversal: `considered` unfinished 2x2 packets, of which
    /// packet/leaf culling (4.1.4) skipped `culled` before any triangle test. Methods without
    /// culling never call it.
    #[inline(always)]
    fn leaf_packets(&mut self, considered: u64, culled: u64) {
        let _ = (considered, culled);
    }
    /// A leaf's visit (its triangle tests) starts: the kd descent
    /// ([`crate::descent::descend`]) calls it before every leaf visit and
    /// [`Counters::leaf_visit_end`] after. [`crate::clock::LeafClock`] times the visits, to
    /// split a pass's time into traversal and intersection (thesis Table 3.1); every other
    /// counter does nothing. (Two calls, not a closure around the visit: a closure is a
    /// function of its own, compiled without the kernel's `#[target_feature]`s.)
    #[inline(always)]
    fn leaf_visit_start(&mut self) {}
    /// The leaf's visit that [`Counters::leaf_visit_start`] announced has ended.
    #[inline(always)]
    fn leaf_visit_end(&mut self) {}
    /// Ray generation starts: a tile's packets, or one primary ray, are about to be made
    /// (the frame driver's primary kernels call it, and [`Counters::generation_end`] after).
    /// [`crate::clock::LeafClock`] times it, Table 3.1's "ray generation"; the others do
    /// nothing.
    #[inline(always)]
    fn generation_start(&mut self) {}
    /// The ray generation [`Counters::generation_start`] announced has ended.
    #[inline(always)]
    fn generation_end(&mut self) {}
}

/// Counting switched off: every method is empty and compiles away.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCounters;

impl Counters for NoCounters {
    const ENABLED: bool = false;
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn tests(&mut self, _n: u64) {}
}

impl AddAssign for NoCounters {
    #[inline(always)]
    fn add_assign(&mut self, _other: NoCounters) {}
}

/// The counts of one traversal, summed over rays, packets or tiles: what the thesis reports
/// as N and I per ray or per 2x2 packet (Tables 4.1-4.3) and the share of packets culled at
/// leaves (Table 4.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Traversal steps (nodes fetched, inner and leaf).
    pub nodes: u64,
    /// Leaves visited.
    pub leaves: u64,
    /// Intersection tests (ray-triangle, or packet-triangle for packets).
    pub tests: u64,
    /// Packets considered at leaves (frustum methods).
    pub leaf_packets: u64,
    /// Of those, packets culled before any triangle test.
    pub culled: u64,
}

impl Counters for Counts {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    #[inline(always)]
    fn tests(&mut self, n: u64) {
        self.tests += n;
    }
    #[inline(always)]
    fn leaf_packets(&mut self, considered: u64, culled: u64) {
        self.leaf_packets += considered;
        self.culled += culled;
    }
}

impl AddAssign for Counts {
    fn add_assign(&mut self, o: Counts) {
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.tests += o.tests;
        self.leaf_packets += o.leaf_packets;
        self.culled += o.culled;
    }
}

impl Counts {
    /// N: traversal steps per 2x2 packet (or per ray), over `packets` packets (thesis
    /// Tables 4.1-4.3).
    pub fn steps_per_packet(&self, packets: u64) -> f64 {
        self.nodes as f64 / packets.max(1) as f64
    }

    /// I: intersection tests per 2x2 packet (or per ray), over `packets` packets (thesis
    /// Tables 4.1-4.3).
    pub fn tests_per_packet(&self, packets: u64) -> f64 {
        self.tests as f64 / packets.max(1) as f64
    }

    /// Percentage of the packets considered at leaves that were culled (thesis 4.1.4, Table
    /// 4.2); `None` when no packet was considered (single rays, 2x2 packets).
    pub fn culled_percent(&self) -> Option<f64> {
        (self.leaf_packets > 0).then(|| 100.0 * self.culled as f64 / self.leaf_packets as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counting through the trait, summing with `+=`, and the per-packet ratios.
    #[test]
    fn counts_add_up() {
        fn count<C: Counters>(c: &mut C) {
            c.node();
            c.node();
            c.leaf();
            c.tests(3);
            c.leaf_packets(4, 1);
        }
        let mut a = Counts::default();
        count(&mut a);
        let mut sum = Counts::default();
        sum += a;
        sum += a;
        assert_eq!(sum, Counts { nodes: 4, leaves: 2, tests: 6, leaf_packets: 8, culled: 2 });
        assert_eq!(sum.steps_per_packet(2), 2.0);
        assert_eq!(sum.tests_per_packet(0), 6.0, "no packets count as one");
        assert_eq!(sum.culled_percent(), Some(25.0));
        assert_eq!(Counts::default().culled_percent(), None);
        let mut none = NoCounters;
        count(&mut none);
        none += NoCounters;
        const { assert!(!NoCounters::ENABLED && Counts::ENABLED) };
    }
}
