//! The per-tile entry points of the packet kernels (thesis 4.1.2-4.1.5): each traces a loaded
//! tile one way. They are the one place that turns a kernel into a traversal; the traversals
//! live in [`crate::omni`], [`crate::samesign`] and [`crate::frustum`]. Which one a method
//! runs is chosen once, by the type of its kernel (crate `trace`, `kernel::primary`), and so
//! is the tree's triangle test: the `_with::<I>` forms take it as a type ([`TreeTest`]); the
//! plain names match `tree.intersector()` once and call them.

use kdtree::{Counters, Intersector, KdTree, TreeTest, WaldTest, WatertightTest};

use crate::bound;
use crate::frustum::{self, Bounds};
use crate::tile::TileTracer;
use crate::triangle4::PacketTest;
use crate::{omni, samesign};

impl TileTracer {
    /// Traces the loaded tile's closest hits as 2x2 packets, each on its own,
    /// omni-directional (4.1.2).
    pub fn trace_packets<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_packets_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_packets_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`TileTracer::trace_packets`] with the tree's triangle test `I`, chosen once by the
    /// caller (see [`TreeTest`]).
    pub fn trace_packets_with<I: TreeTest<Record: PacketTest>, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        self.reset::<I>(false);
        for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
            *hit = omni::intersect_with::<I, _, C>(tree, packet, counters);
        }
    }

    /// Traces the loaded tile's closest hits as 2x2 packets, each on its own, with the
    /// standard same-sign traversal split by signs (2.3.1).
    pub fn trace_samesign<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_samesign_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_samesign_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`TileTracer::trace_samesign`] with the tree's triangle test `I` (see [`TreeTest`]).
    pub fn trace_samesign_with<I: TreeTest<Record: PacketTest>, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        self.reset::<I>(false);
        for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
            *hit = samesign::intersect_with::<I, _, C>(tree, &packet.rays, counters);
        }
    }

    /// Traces the loaded tile as one frustum interval (2.3.2, 4.1.3) with packet/leaf
    /// culling: its closest hits, or any hits in any-hit mode.
    pub fn trace_frustum<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_frustum_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_frustum_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`TileTracer::trace_frustum`] with the tree's triangle test `I` (see [`TreeTest`]).
    pub fn trace_frustum_with<I: TreeTest<Record: PacketTest>, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        self.reset::<I>(true);
        let f = bound::pyramid(tree, &self.packets, &mut self.done);
        frustum::intersect::<I, _, C>(tree, self, &Bounds::one(&f), counters);
    }

    /// Traces the loaded tile as its four quadrant frusta in SSE lanes (4.1.5): its closest
    /// hits, or any hits in any-hit mode.
    pub fn trace_mft<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_mft_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_mft_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`TileTracer::trace_mft`] with the tree's triangle test `I` (see [`TreeTest`]).
    pub fn trace_mft_with<I: TreeTest<Record: PacketTest>, C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        let bounds = self.prepare_with::<I>(tree);
        frustum::intersect::<I, _, C>(tree, self, &Bounds::four(&bounds), counters);
    }
}
