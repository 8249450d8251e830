//! The per-tile entry points of the packet kernels (thesis 4.1.2-4.1.5): each traces a loaded
//! tile one way. They are the one place that turns a kernel into a traversal; the traversals
//! live in [`crate::omni`], [`crate::samesign`] and [`crate::frustum`]. Which one a method
//! runs is chosen once, by the type of its kernel (crate `trace`, `kernel::primary`).

use kdtree::{Counters, KdTree};

use crate::bound;
use crate::frustum::{self, Bounds};
use crate::tile::TileTracer;
use crate::{omni, samesign};

impl TileTracer {
    /// Traces the loaded tile's closest hits as 2x2 packets, each on its own,
    /// omni-directional (4.1.2).
    pub fn trace_packets<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        self.reset(tree, false);
        for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
            *hit = omni::intersect(tree, packet, counters);
        }
    }

    /// Traces the loaded tile's closest hits as 2x2 packets, each on its own, with the
    /// standard same-sign traversal split by signs (2.3.1).
    pub fn trace_samesign<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        self.reset(tree, false);
        for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
            *hit = samesign::intersect(tree, &packet.rays, counters);
        }
    }

    /// Traces the loaded tile as one frustum interval (2.3.2, 4.1.3) with packet/leaf
    /// culling: its closest hits, or any hits in any-hit mode.
    pub fn trace_frustum<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        self.reset(tree, true);
        let f = bound::pyramid(tree, &self.packets, &mut self.done);
        frustum::intersect(tree, self, &Bounds::one(&f), counters);
    }

    /// Traces the loaded tile as its four quadrant frusta in SSE lanes (4.1.5): its closest
    /// hits, or any hits in any-hit mode.
    pub fn trace_mft<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        let bounds = self.prepare(tree);
        frustum::intersect(tree, self, &Bounds::four(&bounds), counters);
    }
}
