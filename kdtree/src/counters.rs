//! Traversal statistics that compile to nothing when off.
//!
//! Every traversal method takes a `C: Counters` parameter. With [`NoCounters`] (a zero-sized
//! type whose methods are empty and inlined) the counting code disappears from the kernel;
//! with [`TraversalCounts`] it counts nodes traversed, leaves visited and intersection tests.

/// The three events a traversal counts.
pub trait Counters {
    /// One node (inner or leaf) fetched by a traversal step.
    fn node(&mut self);
    /// One leaf visited (its triangles are about to be tested).
    fn leaf(&mut self);
    /// `n` ray-triangle intersection tests.
    fn isects(&mut self, n: u64);
}

/// Counting switched off: every method is empty and compiles away.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCounters;

impl Counters for NoCounters {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn isects(&mut self, _n: u64) {}
}

/// Counts of nodes traversed, leaves visited and intersection tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    /// Traversal steps (nodes fetched, inner and leaf).
    pub nodes: u64,
    /// Leaves visited.
    pub leaves: u64,
    /// Ray-triangle intersection tests.
    pub isects: u64,
}

impl Counters for TraversalCounts {
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
        self.isects += n;
    }
}

impl std::ops::AddAssign for TraversalCounts {
    fn add_assign(&mut self, o: TraversalCounts) {
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.isects += o.isects;
    }
}
