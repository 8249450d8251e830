//! Counters for the thesis's packet statistics (Tables 4.1-4.3), compiled away when off.
//!
//! The thesis counts per 2x2 packet: **N**, traversal steps (a frustum's steps divided by its
//! number of 2x2 packets), and **I**, ray-triangle tests, where one 4-ray x 1-triangle test
//! counts once. Table 4.2 adds the share of packets culled at leaves (4.1.4). The kernels
//! take a `C: PacketCounters`; with [`kdtree::NoCounters`] every call is empty and inlined.

use kdtree::{Counters, NoCounters};

/// What the packet and frustum kernels count.
pub trait PacketCounters {
    /// False for [`NoCounters`]: lets a kernel skip work done only for the counts.
    const ENABLED: bool = true;
    /// One traversal step (a node fetched by a packet, a frustum or the four MFT frusta).
    fn node(&mut self);
    /// One leaf visited.
    fn leaf(&mut self);
    /// `n` packet-triangle tests (each tests up to four rays against one triangle).
    fn tests(&mut self, n: u64);
    /// At one leaf: `considered` unfinished 2x2 packets, of which packet/leaf culling skipped
    /// `culled` before any triangle test.
    fn leaf_packets(&mut self, considered: u64, culled: u64);
}

impl PacketCounters for NoCounters {
    const ENABLED: bool = false;
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn tests(&mut self, _n: u64) {}
    #[inline(always)]
    fn leaf_packets(&mut self, _considered: u64, _culled: u64) {}
}

/// The counts, summed over packets or tiles. It also counts single rays (as
/// [`kdtree::Counters`]: a ray-triangle test is one test), so one type serves every method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PacketCounts {
    /// Traversal steps.
    pub nodes: u64,
    /// Leaves visited.
    pub leaves: u64,
    /// Packet-triangle tests.
    pub tests: u64,
    /// Packets considered at leaves.
    pub leaf_packets: u64,
    /// Of those, packets culled before any triangle test.
    pub culled: u64,
}

impl PacketCounters for PacketCounts {
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

impl Counters for PacketCounts {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn leaf(&mut self) {
        self.leaves += 1;
    }
    #[inline(always)]
    fn isects(&mut self, n: u64) {
        self.tests += n;
    }
}

impl std::ops::AddAssign for PacketCounts {
    fn add_assign(&mut self, o: PacketCounts) {
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.tests += o.tests;
        self.leaf_packets += o.leaf_packets;
        self.culled += o.culled;
    }
}

impl PacketCounts {
    /// N: traversal steps per 2x2 packet, over `packets` packets.
    pub fn steps_per_packet(&self, packets: u64) -> f64 {
        self.nodes as f64 / packets.max(1) as f64
    }

    /// I: packet-triangle tests per 2x2 packet, over `packets` packets.
    pub fn tests_per_packet(&self, packets: u64) -> f64 {
        self.tests as f64 / packets.max(1) as f64
    }

    /// Percentage of the packets considered at leaves that were culled (`None` when no
    /// packet was considered: single rays, 2x2 packets).
    pub fn culled_percent(&self) -> Option<f64> {
        (self.leaf_packets > 0).then(|| 100.0 * self.culled as f64 / self.leaf_packets as f64)
    }
}
