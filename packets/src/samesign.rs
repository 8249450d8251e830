//! The standard packet traversal (thesis 2.3.1, Listing 2.4, corrected), kept beside the
//! omni-directional one so the two can be compared on packets whose rays disagree on
//! direction signs. Written once for every packet width: four rays with the default `Vec4`
//! lanes (the thesis's 2x2 packet), `W` with a `W`-lane type ([`crate::simd`]).
//!
//! All rays of a packet must agree on the sign of each direction component, because the near
//! and far children are chosen once for the packet from the direction's sign. A packet that
//! mixes signs is split into sub-packets of equal sign patterns (masking the other lanes),
//! each traced on its own: up to eight traversals (four in a 2x2 packet) where the
//! omni-directional packet needs one. The rays need not share an origin.
//!
//! Listing 2.4 picks near/far from `dir[0]` (the x component, whatever the split axis) with
//! the sign test the wrong way round (see `../shared/seeds/README.md`). Here, as in the
//! single-ray kernel, the near child for axis `k` is the upper child when the sign bit of
//! `dir[k]` is set. Each lane's interval follows the single-ray rules: front
//! `[near, min(far, d)]`, back `[max(near, d), far]` (a negative `d` empties the front, so
//! rays may start behind their origin, `t_min < 0`), and a lane lying in the split plane
//! (`d` NaN) visits both children over its whole interval.

use glam::Vec3;
use kdtree::triangle::{Intersector, TriangleTest};
use kdtree::{Counters, KdNode, KdTree, TreeTest, WaldTest, WatertightTest};

use crate::omni::{self, ChildOrder, Step};
use crate::packet::{PacketHit, RayPacket, widen_down, widen_up};
use crate::shadow_cache::ShadowCache;
use crate::simd::{SimdF32, SimdMask};
use crate::triangle4::PacketTest;

/// The closest hits of the packet's rays, splitting it by direction signs. Invalid lanes
/// (rays with NaN or infinite components among them, see [`crate::RayPacket::new`]) get no
/// hit.
#[inline]
pub fn intersect<V: SimdF32, C: Counters>(tree: &KdTree, packet: &RayPacket<V>, counters: &mut C) -> PacketHit<V> {
    match tree.intersector() {
        Intersector::Wald => split_by_signs::<WaldTest, V, C, false, false>(tree, packet, None, counters),
        Intersector::Watertight => split_by_signs::<WatertightTest, V, C, false, false>(tree, packet, None, counters),
    }
}

/// [`intersect`] with the tree's triangle test `I`, chosen once by the caller (see
/// [`TreeTest`]).
#[inline(always)]
pub fn intersect_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    packet: &RayPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    split_by_signs::<I, V, C, false, false>(tree, packet, None, counters)
}

/// Which of the packet's rays are blocked (any hit, the shadow query), splitting it by
/// direction signs: the `found` lanes are the blocked rays, each lane leaving at its first
/// hit. Invalid lanes are never blocked.
#[inline]
pub fn occluded<V: SimdF32, C: Counters>(tree: &KdTree, packet: &RayPacket<V>, counters: &mut C) -> PacketHit<V> {
    match tree.intersector() {
        Intersector::Wald => split_by_signs::<WaldTest, V, C, true, false>(tree, packet, None, counters),
        Intersector::Watertight => split_by_signs::<WatertightTest, V, C, true, false>(tree, packet, None, counters),
    }
}

/// [`occluded`] with the tree's triangle test `I` (see [`TreeTest`]).
#[inline(always)]
pub fn occluded_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    packet: &RayPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    split_by_signs::<I, V, C, true, false>(tree, packet, None, counters)
}

/// Whether each segment `starts[i]` to `ends[i]` (the ray `Ray::new(start, end - start, 0,
/// 1)`, a shadow ray) is blocked, `V::LANES` consecutive ones at a time as one packet
/// ([`RayPacket::from_segments`], [`occluded`]): the answers, in order, appended to `blocked`
/// after clearing it. Segments of neighbouring pixels (a tile's shadow rays in Morton order)
/// make coherent packets, and two things use that:
/// - each packet first tests the triangles that blocked the packets before it (the
///   [`ShadowCache`] of this call), and only its lanes left unblocked walk the tree;
/// - the walk visits each node's back child first (the light's end of the segments,
///   [`SameSign`] with `BACK_FIRST`).
///
/// Neither changes an answer: each is the single ray's (`KdTree::occluded`). Inlined, so
/// that under [`crate::at_width!`] the wide lanes compile to their instruction set.
#[inline(always)]
pub fn occluded_segments<V: SimdF32, C: Counters>(
    tree: &KdTree,
    starts: &[Vec3],
    ends: &[Vec3],
    blocked: &mut Vec<bool>,
    counters: &mut C,
) {
    match tree.intersector() {
        Intersector::Wald => occluded_segments_with::<WaldTest, V, C>(tree, starts, ends, blocked, counters),
        Intersector::Watertight => {
            occluded_segments_with::<WatertightTest, V, C>(tree, starts, ends, blocked, counters)
        }
    }
}

/// The nearest hit of each segment `starts[i]` to `ends[i]` (as [`occluded_segments`], its
/// distance the fraction of the way), `V::LANES` consecutive ones at a time as one packet
/// ([`intersect`]): the hits, in order, appended to `hits` after clearing it. Each is the
/// single ray's (`KdTree::intersect` of `Ray::segment`) bit for bit, as every packet walk's.
/// Inlined, as [`occluded_segments`].
#[inline(always)]
pub fn intersect_segments<V: SimdF32, C: Counters>(
    tree: &KdTree,
    starts: &[Vec3],
    ends: &[Vec3],
    hits: &mut Vec<Option<kdtree::Hit>>,
    counters: &mut C,
) {
    #[inline(always)]
    fn run<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
        tree: &KdTree,
        starts: &[Vec3],
        ends: &[Vec3],
        hits: &mut Vec<Option<kdtree::Hit>>,
        counters: &mut C,
    ) {
        hits.clear();
        for (starts, ends) in starts.chunks(V::LANES).zip(ends.chunks(V::LANES)) {
            let packet = RayPacket::<V>::from_segments(starts, ends);
            let hit = intersect_with::<I, V, C>(tree, &packet, counters);
            // A plain loop: `extend` over an adapter may be left out of line, where reading
            // the lanes would compile without the kernel's instruction set.
            for lane in 0..starts.len().min(ends.len()) {
                hits.push(hit.get(lane));
            }
        }
    }
    match tree.intersector() {
        Intersector::Wald => run::<WaldTest, V, C>(tree, starts, ends, hits, counters),
        Intersector::Watertight => run::<WatertightTest, V, C>(tree, starts, ends, hits, counters),
    }
}

/// [`occluded_segments`] with the tree's triangle test `I` (see [`TreeTest`]), `V::LANES`
/// consecutive segments per packet (four in 2x2 pixels for `Vec4`, sixteen in 4x4 for 16
/// lanes: the shadow kernels' widths, `trace::kernel::shadow::Packets`). The cached
/// triangles' tests count as triangle tests ([`Counters::tests`], one per cached triangle
/// and packet).
#[inline(always)]
pub fn occluded_segments_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    starts: &[Vec3],
    ends: &[Vec3],
    blocked: &mut Vec<bool>,
    counters: &mut C,
) {
    blocked.clear();
    let records = I::records(tree);
    let mut cache = ShadowCache::new();
    for (starts, ends) in starts.chunks(V::LANES).zip(ends.chunks(V::LANES)) {
        let mut packet = RayPacket::<V>::from_segments(starts, ends);
        // The last packets' blockers first (`crate::shadow_cache`); the tree for the rest.
        let mut found = V::Mask::splat(false);
        if !cache.prims().is_empty() {
            let mut hit = PacketHit::new(&packet);
            counters.tests(cache.prims().len() as u64);
            let data = <I::Record as PacketTest<V>>::prepare4(&packet);
            found = cache.test::<I, V>(records, &packet, &data, &mut hit);
        }
        let rest = packet.valid & !found;
        if rest.any() {
            if found.any() {
                // The lanes the cache blocked leave the packet.
                packet.keep_lanes(rest);
            }
            let walked = split_by_signs::<I, V, C, true, true>(tree, &packet, None, counters);
            cache.remember(&walked);
            found |= walked.found;
        }
        let found = found.bitmask();
        blocked.extend((0..starts.len().min(ends.len())).map(|lane| found >> lane & 1 != 0));
    }
}

/// [`occluded`] inside the subtree of node `from.0` only, the lanes' intervals in its box
/// being `from.1` (from `RayPacket::clip` against that box): the shadow frusta of
/// `crate::shadow_frustum` hand their rays over four at a time this way.
#[inline]
pub fn occluded_in<V: SimdF32, C: Counters>(
    tree: &KdTree,
    packet: &RayPacket<V>,
    from: (usize, (V, V)),
    counters: &mut C,
) -> PacketHit<V> {
    match tree.intersector() {
        Intersector::Wald => split_by_signs::<WaldTest, V, C, true, false>(tree, packet, Some(from), counters),
        Intersector::Watertight => {
            split_by_signs::<WatertightTest, V, C, true, false>(tree, packet, Some(from), counters)
        }
    }
}

/// [`occluded_in`] with the tree's triangle test `I` (see [`TreeTest`]).
#[inline(always)]
pub fn occluded_in_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    packet: &RayPacket<V>,
    from: (usize, (V, V)),
    counters: &mut C,
) -> PacketHit<V> {
    split_by_signs::<I, V, C, true, false>(tree, packet, Some(from), counters)
}

/// [`intersect`] or, with `ANY_HIT`, [`occluded`]; from the root, or from `from` as
/// [`occluded_in`]; with `BACK_FIRST`, each inner node's back child first ([`SameSign`]).
#[inline(always)]
fn split_by_signs<
    I: TreeTest<Record: PacketTest<V>>,
    V: SimdF32,
    C: Counters,
    const ANY_HIT: bool,
    const BACK_FIRST: bool,
>(
    tree: &KdTree,
    packet: &RayPacket<V>,
    from: Option<(usize, (V, V))>,
    counters: &mut C,
) -> PacketHit<V> {
    let records = I::records(tree);
    let traverse_group = |sub: &RayPacket<V>, counters: &mut C| {
        traverse::<V, _, C, ANY_HIT, BACK_FIRST>(tree, records, sub, from, counters)
    };
    // The common case (neighbouring rays to one light): every valid lane in one sign group.
    // The group is then the packet itself, and so is its hit (invalid lanes hold empty
    // intervals and keep `PacketHit::new`'s values either way).
    if one_sign_group(packet) {
        return traverse_group(packet, counters);
    }
    let mut hit = PacketHit::new(packet);
    for group in sign_groups(packet) {
        let mut sub = *packet;
        sub.keep_lanes(group);
        let part = traverse_group(&sub, counters);
        V::blend_into(group, part.t, &mut hit.t);
        V::blend_into(group, part.u, &mut hit.u);
        V::blend_into(group, part.v, &mut hit.v);
        hit.found |= part.found & group;
        for lane in 0..V::LANES {
            if group.bitmask() >> lane & 1 != 0 {
                hit.prim[lane] = part.prim[lane];
            }
        }
    }
    hit
}

/// Whether the valid lanes (at least one) share their direction signs on every axis.
#[inline(always)]
fn one_sign_group<V: SimdF32>(packet: &RayPacket<V>) -> bool {
    let valid = packet.valid.bitmask();
    valid != 0
        && (0..3).all(|a| {
            let negative = packet.d[a].is_negative_bitmask() & valid;
            negative == 0 || negative == valid
        })
}

/// The valid lanes grouped by direction sign pattern (sign bits of x, y, z): one mask per
/// distinct pattern, at most eight (four in a 2x2 packet). The groups are found here, in the
/// caller's instruction set, and the iterator's steps only turn lane bits into masks (an
/// iterator adapter that read the lanes would compile out of line, without AVX2's
/// instructions).
#[inline(always)]
pub fn sign_groups<V: SimdF32>(packet: &RayPacket<V>) -> impl Iterator<Item = V::Mask> + use<V> {
    let signs =
        V::array_from_fn(|lane| (0..3).fold(0u32, |s, a| s | u32::from(packet.d[a][lane].is_sign_negative()) << a));
    let valid = packet.valid.bitmask();
    let (mut groups, mut n, mut seen) = ([0u32; 8], 0, 0u32);
    for lane in 0..V::LANES {
        if valid >> lane & 1 == 0 || seen >> lane & 1 != 0 {
            continue;
        }
        let mut bits = 0u32;
        for (l, &s) in signs.as_ref().iter().enumerate() {
            bits |= u32::from(valid >> l & 1 != 0 && s == signs[lane]) << l;
        }
        seen |= bits;
        groups[n] = bits;
        n += 1;
    }
    groups.into_iter().take(n).map(|bits| V::Mask::from_fn(|l| bits >> l & 1 != 0))
}

/// Listing 2.4's child order (corrected) for a packet whose valid lanes share direction
/// signs: bit `axis` of the field is set where the direction's sign bit is, and then the near
/// child is the upper one. A lane lying in the split plane (`d` NaN) keeps its whole interval
/// in both children.
///
/// With `BACK_FIRST` the same two children and intervals are visited the other way round,
/// the back child (the far end of the rays) first: a shadow query may find its blocker
/// anywhere along the rays, and for the shadow segments of [`occluded_segments_with`],
/// which start on a surface among its neighbours and end at the light, starting from the
/// light's end took 3% fewer steps per ray on Sponza, and 4% fewer beside the shadow cache
/// (`docs/results/coherent-shadows.md`). A closest-hit query must go front to back.
struct SameSign<const BACK_FIRST: bool>(usize);

impl<const BACK_FIRST: bool> ChildOrder for SameSign<BACK_FIRST> {
    #[inline(always)]
    fn step<V: SimdF32>(&self, rays: &RayPacket<V>, node: KdNode, near: V, far: V) -> Step<V> {
        let axis = node.axis() & 3;
        let d = (V::splat(node.split()) - rays.o[axis]) * rays.inv[axis];
        let in_plane = d.cmpne(d);
        let upper = (self.0 >> axis) & 1;
        let (front, back) = (node.left_child() + upper, node.left_child() + 1 - upper);
        let front_far = V::select(in_plane, far, far.min(widen_up(d)));
        let back_near = V::select(in_plane, near, near.max(widen_down(d)));
        if BACK_FIRST {
            Step::Spans { first: back, second: front, first_span: (back_near, far), second_span: (near, front_far) }
        } else {
            Step::Split { front, back, front_far, back_near }
        }
    }
}

/// Traversal of a packet whose valid lanes share direction signs.
#[inline(always)]
fn traverse<V: SimdF32, T: TriangleTest + PacketTest<V>, C: Counters, const ANY_HIT: bool, const BACK_FIRST: bool>(
    tree: &KdTree,
    records: &[T],
    rays: &RayPacket<V>,
    from: Option<(usize, (V, V))>,
    counters: &mut C,
) -> PacketHit<V> {
    const { assert!(ANY_HIT || !BACK_FIRST, "a closest-hit walk goes front to back") };
    let first = (rays.valid.bitmask().trailing_zeros() as usize).min(V::LANES - 1);
    let upper_first = (0..3).fold(0usize, |m, a| m | usize::from(rays.d[a][first].is_sign_negative()) << a);
    let order = SameSign::<BACK_FIRST>(upper_first);
    match from {
        None => omni::traverse::<V, _, _, C, ANY_HIT>(tree, records, rays, &order, counters),
        Some((node, (near, far))) => {
            // The lanes outside this sign group are empty intervals.
            let (near, far) = (V::select(rays.valid, near, V::INFINITY), V::select(rays.valid, far, V::NEG_INFINITY));
            omni::traverse_from::<V, _, _, C, ANY_HIT>(tree, records, rays, &order, (node, (near, far)), counters)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::PortableF32;
    use crate::test_support::{self, Rng, check_against_single_rays, packet_hit_bits};
    use glam::Vec4;
    use kdtree::counters::{Counts, NoCounters};
    use kdtree::{BuildConfig, Ray};

    #[test]
    fn sign_groups_partition_the_valid_lanes() {
        let o = Vec3::ZERO;
        let rays =
            [Vec3::X, -Vec3::X, Vec3::new(1.0, 0.0, 0.5), Vec3::new(-0.0, 1.0, 1.0)].map(|d| Ray::new(o, d, 0.0, 1.0));
        let groups: Vec<u32> = sign_groups(&RayPacket::new(&rays)).map(|g| g.bitmask()).collect();
        assert_eq!(groups, vec![0b0101, 0b0010, 0b1000]);
        let groups: Vec<u32> = sign_groups(&RayPacket::new(&rays[..1])).map(|g| g.bitmask()).collect();
        assert_eq!(groups, vec![0b0001]);
    }

    #[test]
    fn split_packets_match_single_rays_with_different_origins() {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let config = BuildConfig { intersector, ..Default::default() };
            let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).unwrap();
            let b = tree.bounds();
            let c = 0.5 * (b.min + b.max);
            let rays = [
                Ray::new(c, Vec3::new(1.0, 0.3, 0.2), 0.0, f32::INFINITY),
                Ray::new(c + Vec3::X, Vec3::new(-1.0, 0.2, 0.1), -5.0, f32::INFINITY),
                Ray::new(c - Vec3::Y, Vec3::new(0.1, -1.0, 0.3), 0.0, f32::INFINITY),
                Ray::new(c, Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY),
            ];
            let hits = intersect(&tree, &RayPacket::new(&rays), &mut NoCounters).hits();
            for (lane, ray) in rays.iter().enumerate() {
                assert_eq!(hits[lane], tree.intersect(ray), "{intersector:?} lane {lane}");
            }
        }
    }

    /// `rays` (any origins) as one same-sign packet of `V`'s width: both queries, and the
    /// any-hit query from the root's subtree (`occluded_in`), checked against single rays.
    /// Returns the number of rays that hit something and of sign groups.
    fn check_samesign<V: SimdF32>(tree: &KdTree, rays: &[Ray], what: &str) -> (usize, usize) {
        let packet = RayPacket::<V>::from_rays(rays);
        let closest = intersect(tree, &packet, &mut NoCounters);
        let any = occluded(tree, &packet, &mut NoCounters);
        let hits = check_against_single_rays(tree, rays, &closest, &any, what);
        let from_root = occluded_in(tree, &packet, (0, omni::root_interval(tree, &packet)), &mut NoCounters);
        assert_eq!(from_root.found.bitmask(), any.found.bitmask(), "{what}: occluded_in");
        (hits, sign_groups(&packet).count())
    }

    /// The same-sign walk at 4 (glam), 8 and 16 lanes (the portable lane type), its packets
    /// split by sign pattern: every lane's closest and any hit are the single ray's, bit for
    /// bit, for both intersectors, on every hard case (rays with their own origins, some
    /// starting behind them), and every scene and case has rays that hit.
    #[test]
    fn same_sign_packets_of_every_width_match_single_rays() {
        let mut rng = Rng(0x000b_ead5);
        let (mut one_group, mut split) = (0, 0);
        for scene in test_support::hard_scenes() {
            let mut hits = [0usize; 6];
            for (t, tree) in scene.trees.iter().enumerate() {
                for round in 0..60 {
                    let kind = round % 6;
                    let what = format!("{} tree {t} round {round} kind {kind}", scene.name);
                    hits[kind] += check_samesign::<Vec4>(tree, &scene.rays(&mut rng, 4, kind, false), &what).0;
                    for (h, groups) in [
                        check_samesign::<PortableF32<8>>(tree, &scene.rays(&mut rng, 8, kind, false), &what),
                        check_samesign::<PortableF32<16>>(tree, &scene.rays(&mut rng, 16, kind, false), &what),
                    ] {
                        hits[kind] += h;
                        if groups == 1 { one_group += 1 } else { split += 1 }
                    }
                }
            }
            assert!(hits.iter().all(|&h| h > 20), "{}: rays that hit, by case: {hits:?}", scene.name);
        }
        assert!(one_group > 20 && split > 20, "one sign group {one_group}, split {split}");
    }

    /// The portable lane type at 4 lanes gives the glam same-sign walk's answers lane for
    /// lane, bit for bit, and the same sign groups.
    #[test]
    fn portable_four_lanes_are_the_glam_walk_bit_for_bit() {
        let mut rng = Rng(0x5eed_cafe);
        for scene in test_support::hard_scenes() {
            for tree in &scene.trees {
                for round in 0..30 {
                    let rays = scene.rays(&mut rng, 4, round % 6, false);
                    let (glam, portable) =
                        (RayPacket::<Vec4>::from_rays(&rays), RayPacket::<PortableF32<4>>::from_rays(&rays));
                    let what = format!("{} round {round}", scene.name);
                    let glam_groups: Vec<u32> = sign_groups(&glam).map(|g| g.bitmask()).collect();
                    let portable_groups: Vec<u32> = sign_groups(&portable).map(|g| g.bitmask()).collect();
                    assert_eq!(glam_groups, portable_groups, "{what}");
                    let (g, p) = (intersect(tree, &glam, &mut NoCounters), intersect(tree, &portable, &mut NoCounters));
                    assert_eq!(packet_hit_bits(&g), packet_hit_bits(&p), "{what}");
                    let (g, p) = (occluded(tree, &glam, &mut NoCounters), occluded(tree, &portable, &mut NoCounters));
                    assert_eq!(packet_hit_bits(&g), packet_hit_bits(&p), "{what} any hit");
                }
            }
        }
    }

    /// The segments of `rays` (each from its origin, a box's diagonal `reach` along its
    /// direction), and a coherent set: a 16x16 grid of starts in the box's lower part, in
    /// Morton order so that each 16 are a 4x4 block, to one light above the box.
    fn shadow_segments(tree: &KdTree, rays: &[Ray]) -> (Vec<Vec3>, Vec<Vec3>) {
        let b = tree.bounds();
        let reach = (b.max - b.min).length();
        let (mut starts, mut ends): (Vec<Vec3>, Vec<Vec3>) =
            rays.iter().map(|r| (r.origin, r.origin + reach * r.dir.normalize_or_zero())).unzip();
        let light =
            Vec3::new(0.5 * (b.min.x + b.max.x), b.max.y + 0.5 * (b.max.y - b.min.y), 0.5 * (b.min.z + b.max.z));
        for i in scenes::morton_order(16, 16) {
            let (x, z) = ((i % 16) as f32 / 15.0, (i / 16) as f32 / 15.0);
            starts.push(b.min + (b.max - b.min) * Vec3::new(x, 0.1, z));
            ends.push(light);
        }
        (starts, ends)
    }

    /// `occluded_segments` (the shadow cache, back child first) at `V`'s width: each answer
    /// is the single segment's. Returns the walk's counts and the plain walk's (each packet
    /// by `occluded`, no cache, front to back).
    fn check_segments<V: SimdF32>(tree: &KdTree, starts: &[Vec3], ends: &[Vec3], what: &str) -> (Counts, Counts) {
        let (mut blocked, mut counts, mut plain) = (Vec::new(), Counts::default(), Counts::default());
        occluded_segments::<V, _>(tree, starts, ends, &mut blocked, &mut counts);
        assert_eq!(blocked.len(), starts.len(), "{what}");
        for (i, (&start, &end)) in starts.iter().zip(ends).enumerate() {
            assert_eq!(blocked[i], tree.occluded(&Ray::segment(start, end)), "{what}: segment {i}");
        }
        for (k, (s, e)) in starts.chunks(V::LANES).zip(ends.chunks(V::LANES)).enumerate() {
            let found = occluded(tree, &RayPacket::<V>::from_segments(s, e), &mut plain).found.bitmask();
            for lane in 0..s.len() {
                assert_eq!(found >> lane & 1 != 0, blocked[k * V::LANES + lane], "{what}: plain walk");
            }
        }
        (counts, plain)
    }

    /// Shadow segments through the shadow cache and the back-first walk, at 4, 8 and 16
    /// lanes, both intersectors, on every hard scene (random soups, split planes, tiny, huge
    /// and far coordinates; origins on planes, zero direction components): every answer is
    /// the single ray's, and the packets of the coherent grid take fewer traversal steps than
    /// the plain walk (the cache answers lanes that would otherwise walk).
    #[test]
    fn shadow_segments_through_the_cache_are_the_single_rays_answers() {
        let mut rng = Rng(0x5_adc0_ffee);
        let mut fewer = 0;
        for scene in test_support::hard_scenes() {
            for (t, tree) in scene.trees.iter().enumerate() {
                let mut rays = Vec::new();
                for kind in 0..6 {
                    rays.extend(scene.rays(&mut rng, 16, kind, false));
                }
                let (starts, ends) = shadow_segments(tree, &rays);
                let what = format!("{} tree {t}", scene.name);
                check_segments::<Vec4>(tree, &starts, &ends, &what);
                check_segments::<PortableF32<8>>(tree, &starts, &ends, &what);
                let (cached, plain) = check_segments::<PortableF32<16>>(tree, &starts, &ends, &what);
                fewer += usize::from(cached.nodes < plain.nodes);
            }
        }
        assert!(fewer >= 6, "the cache and back-first walk took fewer steps in {fewer} of 10 trees");
    }
}
