//! The per-tile entry point of every packet method (thesis 4.1.2-4.1.5): [`TileMethod`]
//! names the method, [`TileTracer::trace`] traces a loaded tile with it. It is the one place
//! that turns a method into a traversal; the traversals live in [`crate::omni`],
//! [`crate::samesign`] and [`crate::frustum`].

use kdtree::{Counters, KdTree};

use crate::bound;
use crate::frustum::{self, Bounds};
use crate::tile::TileTracer;
use crate::{omni, samesign};

/// How a tile's rays are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TileMethod {
    /// Each 2x2 packet on its own, omni-directional (4.1.2).
    Packet,
    /// Each 2x2 packet on its own, standard same-sign traversal (2.3.1), split by signs.
    SameSign,
    /// The whole tile as one frustum interval (2.3.2, 4.1.3) with packet/leaf culling.
    Frustum,
    /// The tile's four quadrants as four frusta in SSE lanes (4.1.5).
    Mft,
}

impl TileMethod {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            TileMethod::Packet => "packet",
            TileMethod::SameSign => "samesign",
            TileMethod::Frustum => "frustum",
            TileMethod::Mft => "mft",
        }
    }
}

impl TileTracer {
    /// Traces the loaded tile's closest hits with `method` (any hits for the frustum methods
    /// in any-hit mode): each 2x2 packet on its own (4.1.2, 2.3.1), the tile as one frustum
    /// (2.3.2) or as its four quadrant frusta (4.1.5).
    pub fn trace<C: Counters>(&mut self, tree: &KdTree, method: TileMethod, counters: &mut C) {
        match method {
            TileMethod::Packet => {
                self.reset(tree, false);
                for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
                    *hit = omni::intersect(tree, packet, counters);
                }
            }
            TileMethod::SameSign => {
                self.reset(tree, false);
                for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
                    *hit = samesign::intersect(tree, &packet.rays, counters);
                }
            }
            TileMethod::Frustum => {
                self.reset(tree, true);
                let f = bound::pyramid(tree, &self.packets, &mut self.done);
                frustum::intersect(tree, self, &Bounds::one(&f), counters);
            }
            TileMethod::Mft => {
                let bounds = self.prepare(tree);
                frustum::intersect(tree, self, &Bounds::four(&bounds), counters);
            }
        }
    }
}
