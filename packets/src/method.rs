//! The per-tile entry points of the packet kernels (thesis 4.1.2-4.1.5): each traces a loaded
//! tile one way. They are the one place that turns a kernel into a traversal; the traversals
//! live in [`crate::omni`], [`crate::samesign`] and [`crate::frustum`]. Which one a method
//! runs is chosen once, by the type of its kernel (crate `trace`, `kernel::primary`), and so
//! is the tree's triangle test: the `_with::<I>` forms take it as a type ([`TreeTest`]); the
//! plain names match `tree.intersector()` once and call them.
//!
//! Every entry point takes the tracer's packets at their width (`TileTracer<V>`: 2x2 packets
//! for the default `Vec4`, 4x2 and 4x4 pixels for 8 and 16 lanes). The `_with` forms are
//! `#[inline(always)]`, and so is everything beneath them down to the lane operations, so
//! that a caller compiled for wider registers (`#[target_feature]`) gets the whole kernel
//! compiled for them.

use kdtree::{Counters, Intersector, KdTree, TreeTest, WaldTest, WatertightTest};

use crate::bound::{self, FrustumBound};
use crate::frustum::{self, Bounds};
use crate::simd::{PortableF32, SimdF32};
use crate::tile::TileTracer;
use crate::triangle4::PacketTest;
use crate::{omni, samesign};

impl<V: SimdF32> TileTracer<V> {
    /// Traces the loaded tile's closest hits as packets (2x2 for `Vec4`), each on its own,
    /// omni-directional (4.1.2).
    pub fn trace_packets<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_packets_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_packets_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`TileTracer::trace_packets`] with the tree's triangle test `I`, chosen once by the
    /// caller (see [`TreeTest`]).
    #[inline(always)]
    pub fn trace_packets_with<I: TreeTest<Record: PacketTest<V>>, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        self.reset::<I>(false);
        for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
            *hit = omni::intersect_with::<I, V, C>(tree, packet, counters);
        }
    }

    /// Traces the loaded tile's closest hits as packets (2x2 for `Vec4`), each on its own,
    /// with the standard same-sign traversal split by signs (2.3.1).
    pub fn trace_samesign<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_samesign_with::<WaldTest, C>(tree, counters),
            Intersector::Watertight => self.trace_samesign_with::<WatertightTest, C>(tree, counters),
        }
    }

    /// [`TileTracer::trace_samesign`] with the tree's triangle test `I` (see [`TreeTest`]).
    #[inline(always)]
    pub fn trace_samesign_with<I: TreeTest<Record: PacketTest<V>>, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        self.reset::<I>(false);
        for (packet, hit) in self.packets.iter().zip(&mut self.hits) {
            *hit = samesign::intersect_with::<I, V, C>(tree, &packet.rays, counters);
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
    #[inline(always)]
    pub fn trace_frustum_with<I: TreeTest<Record: PacketTest<V>>, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        self.reset::<I>(true);
        let f = bound::pyramid(tree, &self.packets, &mut self.done);
        frustum::intersect::<I, V, _, C>(tree, self, &Bounds::one(&f), counters);
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
    #[inline(always)]
    pub fn trace_mft_with<I: TreeTest<Record: PacketTest<V>>, C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        let bounds = self.prepare_with::<I>(tree);
        frustum::intersect::<I, V, _, C>(tree, self, &Bounds::four(&bounds), counters);
    }

    /// [`TileTracer::trace_mft_regions_with`] with the portable 16-lane frusta and the tree's
    /// triangle test: the loaded tile (split into 16 regions) as 16 frusta.
    pub fn trace_mft_regions<C: Counters>(&mut self, tree: &KdTree, counters: &mut C) {
        match tree.intersector() {
            Intersector::Wald => self.trace_mft_regions_with::<WaldTest, PortableF32<16>, C>(tree, counters),
            Intersector::Watertight => {
                self.trace_mft_regions_with::<WatertightTest, PortableF32<16>, C>(tree, counters)
            }
        }
    }

    /// Multiple Frustum Traversal with 16 frusta (a measured variant of 4.1.5): the loaded
    /// tile, split into 4 x 4 regions ([`TileTracer::set_regions`]`(16)`), goes down the tree
    /// as 16 frusta in the lanes of `F` (16 lanes: `F32x16` inside an AVX-512 kernel, the
    /// portable twin elsewhere), one per region, each culling and testing only its own
    /// packets at leaves. Against the four quadrant frusta of [`TileTracer::trace_mft_with`]
    /// each frustum is a quarter as wide, so it enters fewer voxels, while each interval
    /// step costs 16 lanes instead of 4. The hits are the single rays' as for four frusta.
    #[inline(always)]
    pub fn trace_mft_regions_with<I: TreeTest<Record: PacketTest<V>>, F: SimdF32, C: Counters>(
        &mut self,
        tree: &KdTree,
        counters: &mut C,
    ) {
        assert!(F::LANES == 16 && self.region_count() == 16, "16 frusta for a tile of 16 regions");
        let bounds: [FrustumBound; 16] = self.prepare_regions_with::<I, 16>(tree);
        frustum::intersect::<I, V, F, C>(tree, self, &Bounds::<F>::lanes(&bounds), counters);
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec4;
    use kdtree::{BruteForce, KdTree, NoCounters, Ray};

    use crate::packet::{OmniPacket, RayPacket};
    use crate::simd::{PortableF32, SimdF32};
    use crate::test_support::{self, Rng, hit_bits};
    use crate::tile::TileTracer;

    /// A tile kernel's plain entry point.
    type Kernel<V> = fn(&mut TileTracer<V>, &KdTree, &mut NoCounters);

    /// The tile kernels at the width of `V`: packets, same-sign packets, one frustum, MFT
    /// (four frusta), MFT with 16 frusta; each with the regions its tile is split into.
    fn kernels<V: SimdF32>() -> [(&'static str, Kernel<V>, usize); 5] {
        [
            ("packet", TileTracer::<V>::trace_packets::<NoCounters>, 4),
            ("samesign", TileTracer::<V>::trace_samesign::<NoCounters>, 4),
            ("frustum", TileTracer::<V>::trace_frustum::<NoCounters>, 4),
            ("mft", TileTracer::<V>::trace_mft::<NoCounters>, 4),
            ("mft-x16", TileTracer::<V>::trace_mft_regions::<NoCounters>, 16),
        ]
    }

    /// Loads `rays` (one origin) as packets of `V` and checks every kernel, culling on and
    /// off, closest and any hit, against the single rays: the packet walks bit for bit; the
    /// frusta bit for bit or, where a tie or a rounding artefact lets the oracle accept
    /// another answer, by its rule; in any-hit mode the frusta's hits are exactly the
    /// blocked rays. Returns the rays that hit.
    fn check_tile<V: SimdF32>(tree: &KdTree, rays: &[Ray], what: &str) -> usize {
        let packets: Vec<OmniPacket<V>> =
            rays.chunks(V::LANES).map(|c| OmniPacket::new(RayPacket::from_rays(c)).expect("one origin")).collect();
        let mut tracer = TileTracer::<V>::with_size(64).unwrap();
        let mut hits = 0;
        for culling in [true, false] {
            for any_hit in [false, true] {
                tracer.set_culling(culling);
                tracer.set_any_hit(any_hit);
                for (method, trace, regions) in kernels::<V>() {
                    tracer.set_regions(regions).unwrap();
                    tracer.load_packets(&packets).expect("one origin");
                    trace(&mut tracer, tree, &mut NoCounters);
                    let frustum = matches!(method, "frustum" | "mft" | "mft-x16");
                    for (i, ray) in rays.iter().enumerate() {
                        let got = tracer.packet_hits()[i / V::LANES].get(i % V::LANES);
                        let what = format!(
                            "{what}: {method} at {} lanes, culling {culling}, any hit {any_hit}, ray {i} {ray:?}",
                            V::LANES
                        );
                        if any_hit && frustum {
                            assert_eq!(got.is_some(), tree.occluded(ray), "{what}");
                            continue;
                        }
                        let want = tree.intersect(ray);
                        if hit_bits(got) != hit_bits(want) {
                            assert!(
                                frustum && BruteForce::for_tree(tree).equivalent_hits(ray, got, want),
                                "{what}: {got:?}, single ray {want:?}"
                            );
                        }
                        hits += usize::from(want.is_some());
                    }
                }
            }
        }
        hits
    }

    /// The tile kernels in packets of 8 and 16 rays (and 4, the same check) on the hard
    /// cases of the packet walks (`test_support::hard_scenes`: a random soup, split planes,
    /// tiny and huge coordinates, 1e5 from the origin; directions in every octant, zero
    /// components, origins on split planes, partial packets, rays at vertices and edges),
    /// four packets of rays from one origin at a time, with both intersectors.
    #[test]
    fn tile_kernels_of_every_width_match_single_rays_on_the_hard_cases() {
        let mut rng = Rng(0x711e_5eed);
        for scene in test_support::hard_scenes() {
            let mut hits = [0usize; 6];
            for (t, tree) in scene.trees.iter().enumerate() {
                for round in 0..18 {
                    let kind = round % 6;
                    let what = format!("{} tree {t} round {round} kind {kind}", scene.name);
                    hits[kind] += check_tile::<Vec4>(tree, &scene.rays(&mut rng, 16, kind, true), &what);
                    hits[kind] += check_tile::<PortableF32<8>>(tree, &scene.rays(&mut rng, 32, kind, true), &what);
                    hits[kind] += check_tile::<PortableF32<16>>(tree, &scene.rays(&mut rng, 64, kind, true), &what);
                }
            }
            assert!(hits.iter().all(|&h| h > 20), "{}: rays that hit, by case: {hits:?}", scene.name);
        }
    }
}
