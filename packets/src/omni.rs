//! Omni-directional packet traversal (thesis 4.1.2, Listing 4.1).
//!
//! The rays of a packet with a common origin `o` and *any* mix of direction signs go down
//! the tree together, without splitting: four with the default `Vec4` lanes (the thesis's
//! 2x2 packet), `W` with a `W`-lane type ([`crate::simd`]); the walk is written once for
//! every width. At a split plane the packet visits the **front voxel** (the child on the
//! origin's side, from the sign of `split - o[axis]` alone) before the **back voxel**, and
//! each lane's plane distance `d = (split - o[axis]) / dir[axis]` is taken as `+inf` when it
//! is negative: that ray moves away from the plane and never reaches the back voxel. Each
//! lane keeps its own interval `[near, far]`: front `[near, min(far, d)]`, back
//! `[max(near, d), far]`; a lane is active where `near <= far`, and a child no lane is
//! active in is skipped.
//!
//! ## Hard cases
//! - **Zero direction components**: `d = dist * (+-inf)` is `+inf` or `-inf` (never NaN,
//!   since `dist != 0` on this path), so the lane stays in the front voxel.
//! - **Origin on the split plane** (`dist == 0`): the sign of `dist` cannot name a front
//!   voxel, lanes may go either way or lie in the plane. Both children are visited over the
//!   lanes' whole intervals (lower first). Correct, since a leaf takes any hit closer than
//!   the lane's best, and rare (the origin exactly on a split).
//! - **Rounding**: plane distances are widened by [`kdtree::traverse::WIDEN`], so a lane is
//!   never dropped from a child it reaches.
//! - **Early exit**: a leaf clamps nothing; deferred back voxels are popped with each lane's
//!   `far` clamped to its closest hit, so a lane whose hit lies before a voxel drops out of
//!   it, and the packet stops when no lane is active (the single-ray rule, per lane).
//! - Rays must start at the origin (`t_min >= 0`): [`OmniPacket::new`] checks it.

use kdtree::descent::{Descent, Entry, Flow, Visit, descend};
use kdtree::stack::Stack;
use kdtree::triangle::{Intersector, TriangleTest};
use kdtree::{Counters, KdNode, KdTree, TreeTest, WaldTest, WatertightTest};

use crate::packet::{OmniPacket, PacketHit, RayPacket, widen_down, widen_up};
use crate::simd::{SimdF32, SimdMask};
use crate::triangle4::PacketTest;

/// The closest hits of the packet's rays. Invalid lanes (missing rays, and rays with NaN or
/// infinite components, see [`crate::RayPacket::new`]) get no hit.
#[inline]
pub fn intersect<V: SimdF32, C: Counters>(tree: &KdTree, packet: &OmniPacket<V>, counters: &mut C) -> PacketHit<V> {
    match tree.intersector() {
        Intersector::Wald => trace::<WaldTest, V, C, false>(tree, packet, counters),
        Intersector::Watertight => trace::<WatertightTest, V, C, false>(tree, packet, counters),
    }
}

/// [`intersect`] with the tree's triangle test `I`, chosen once by the caller (see
/// [`TreeTest`]).
#[inline(always)]
pub fn intersect_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    packet: &OmniPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    trace::<I, V, C, false>(tree, packet, counters)
}

/// Which of the packet's rays are blocked (any hit: the shadow query). The returned hit's
/// `found` lanes are the blocked rays; their `t` is the first blocker found, not the closest.
/// Invalid lanes are never blocked.
#[inline]
pub fn occluded<V: SimdF32, C: Counters>(tree: &KdTree, packet: &OmniPacket<V>, counters: &mut C) -> PacketHit<V> {
    match tree.intersector() {
        Intersector::Wald => trace::<WaldTest, V, C, true>(tree, packet, counters),
        Intersector::Watertight => trace::<WatertightTest, V, C, true>(tree, packet, counters),
    }
}

/// [`occluded`] with the tree's triangle test `I` (see [`TreeTest`]).
#[inline(always)]
pub fn occluded_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    packet: &OmniPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    trace::<I, V, C, true>(tree, packet, counters)
}

/// [`intersect`] (or [`occluded`], with `ANY_HIT`) with the tree's triangle test `I`.
#[inline(always)]
fn trace<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters, const ANY_HIT: bool>(
    tree: &KdTree,
    packet: &OmniPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    let order = Omni(packet.origin);
    traverse::<V, _, _, C, ANY_HIT>(tree, I::records(tree), &packet.rays, &order, counters)
}

/// The lanes' intervals inside the tree's root box (`near > far` where a lane misses it).
#[inline(always)]
pub(crate) fn root_interval<V: SimdF32>(tree: &KdTree, rays: &RayPacket<V>) -> (V, V) {
    let b = tree.bounds();
    rays.clip(b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array())
}

/// How a packet traversal orders an inner node's children, the one part in which
/// Listing 4.1 (omni-directional, [`Omni`]) and Listing 2.4 (same-sign,
/// `samesign::SameSign`) differ; the loop, the leaf and the stack are [`traverse`]'s.
pub(crate) trait ChildOrder {
    /// The children of inner `node` for the packet `rays` with lane intervals `[near, far]`.
    fn step<V: SimdF32>(&self, rays: &RayPacket<V>, node: KdNode, near: V, far: V) -> Step<V>;
}

/// An inner node's children as a [`ChildOrder`] orders them.
pub(crate) enum Step<V> {
    /// Both children over the lanes' whole intervals, `first` first.
    Both { first: usize, second: usize },
    /// The front child with the lanes' intervals `[near, front_far]`, the back child with
    /// `[back_near, far]`.
    Split { front: usize, back: usize, front_far: V, back_near: V },
    /// `first`, then `second`, each with its own lane intervals (rays of one packet whose
    /// origins lie on different sides of the plane: `crate::omni_lanes`).
    Spans { first: usize, second: usize, first_span: (V, V), second_span: (V, V) },
}

/// Listing 4.1's child order: front and back from the common origin's side of the plane
/// (modification 2), negative plane distances as `+inf` (modification 1); both children when
/// the origin lies on the plane. Holds the origin, `[x, y, z, 0]`.
pub(crate) struct Omni(pub(crate) [f32; 4]);

impl ChildOrder for Omni {
    #[inline(always)]
    fn step<V: SimdF32>(&self, rays: &RayPacket<V>, node: KdNode, near: V, far: V) -> Step<V> {
        let axis = node.axis() & 3;
        let dist = node.split() - self.0[axis];
        let left = node.left_child();
        if dist == 0.0 || dist.is_nan() {
            // Origin on the plane: both children, whole intervals.
            return Step::Both { first: left, second: left + 1 };
        }
        // Modification 1: negative distances (planes behind the origin) become +inf. Behind
        // is decided by the signs of `dist` and `1 / d`, not by the product's: a product
        // that underflows to -0.0 is still a plane behind the origin (the fuzzer found a
        // lane sent to the far side of a plane 2.3e-38 behind it, at distance -6e-54).
        let inv = rays.inv[axis];
        let behind = if dist > 0.0 { inv.cmplt(V::ZERO) } else { inv.cmpgt(V::ZERO) };
        let d = V::select(behind, V::INFINITY, V::splat(dist) * inv);
        // Modification 2: front and back from the origin's side of the plane.
        let upper_front = (dist < 0.0) as usize;
        let (front, back) = (left + upper_front, left + 1 - upper_front);
        Step::Split { front, back, front_far: far.min(widen_up(d)), back_near: near.max(widen_down(d)) }
    }
}

/// The packet traversal of Listings 4.1 and 2.4, with the child order `O`, at the width of
/// the lane type `V`: closest hits, or any hits (`ANY_HIT`, a lane finished at its first
/// hit).
#[inline(always)]
pub(crate) fn traverse<V: SimdF32, O: ChildOrder, T: TriangleTest + PacketTest<V>, C: Counters, const ANY_HIT: bool>(
    tree: &KdTree,
    records: &[T],
    rays: &RayPacket<V>,
    order: &O,
    counters: &mut C,
) -> PacketHit<V> {
    traverse_from::<V, O, T, C, ANY_HIT>(tree, records, rays, order, (0, root_interval(tree, rays)), counters)
}

/// A packet walking the tree ([`kdtree::descent`]): the child order `O`'s step, a leaf
/// visitor testing the active lanes against each triangle, and the per-lane pop rule. Its
/// span is one interval per lane, `(near, far)`: the packet's width is `V`'s.
struct Packet<'a, V: SimdF32, O: ChildOrder, T: TriangleTest + PacketTest<V>, const ANY_HIT: bool> {
    records: &'a [T],
    refs: &'a [u32],
    rays: &'a RayPacket<V>,
    order: &'a O,
    data: T::PacketData,
    hit: PacketHit<V>,
    // Ends each lane's search: its closest hit, or -inf once an any-hit lane is done.
    limit: V,
}

impl<V: SimdF32, O: ChildOrder, T: TriangleTest + PacketTest<V>, const ANY_HIT: bool> Descent
    for Packet<'_, V, O, T, ANY_HIT>
{
    type Span = (V, V);
    type Deferred = (V, V);
    type Stack = Stack<Entry<(V, V)>>;

    #[inline(always)]
    fn inner(&mut self, node: KdNode, span: &mut (V, V), _: &Self::Stack) -> Visit<(V, V)> {
        match self.order.step(self.rays, node, span.0, span.1) {
            Step::Both { first, second } => Visit::Both { first, second, deferred: *span },
            Step::Split { front, back, front_far, back_near } => {
                descend_split(span, (front, back), (front_far, back_near))
            }
            Step::Spans { first, second, first_span, second_span } => {
                descend_spans(span, (first, second), (first_span, second_span))
            }
        }
    }

    #[inline(always)]
    fn leaf<C: Counters>(&mut self, node: KdNode, &(near, far): &(V, V), _: &Self::Stack, counters: &mut C) -> Flow {
        counters.leaf();
        let active = near.cmple(far);
        let prims = &self.refs[node.prim_range()];
        counters.tests(prims.len() as u64);
        let rays = self.rays;
        for &prim in prims {
            let lanes = self.records[prim as usize].intersect4(
                rays,
                &self.data,
                active & !and_if(self.hit.found, ANY_HIT),
                &mut self.hit,
                prim,
            );
            if ANY_HIT && lanes.any() {
                V::blend_into(self.hit.found, V::NEG_INFINITY, &mut self.limit);
                if (self.hit.found | !rays.valid).all() {
                    return Flow::Stop;
                }
            }
        }
        if !ANY_HIT {
            self.limit = self.hit.t;
        }
        Flow::Continue
    }

    /// Each lane clamped to its closest hit; dropped where no lane is left active.
    #[inline(always)]
    fn resume(&mut self, (near, far): (V, V)) -> Option<(V, V)> {
        let far = far.min(self.limit);
        near.cmple(far).any().then_some((near, far))
    }
}

/// [`traverse`] from the node `start` with the lanes' intervals `(near, far)` inside its box
/// (those from the root box for the root), visiting only its subtree: a group of rays handed
/// over from a wider traversal (`crate::shadow_frustum`).
#[inline(always)]
pub(crate) fn traverse_from<
    V: SimdF32,
    O: ChildOrder,
    T: TriangleTest + PacketTest<V>,
    C: Counters,
    const ANY_HIT: bool,
>(
    tree: &KdTree,
    records: &[T],
    rays: &RayPacket<V>,
    order: &O,
    (start, (near, far)): (usize, (V, V)),
    counters: &mut C,
) -> PacketHit<V> {
    let mut group = Packet::<V, O, T, ANY_HIT> {
        records,
        refs: tree.prim_refs(),
        rays,
        order,
        data: T::prepare4(rays),
        hit: PacketHit::new(rays),
        limit: rays.t_max,
    };
    if near.cmple(far).any() {
        descend(tree, &mut group, (start, (near, far)), &mut Stack::new(), counters);
    }
    group.hit
}

/// The step after an inner node's plane distances (Listing 4.1, and Listing 2.4's with the
/// same-sign children): the lanes are active in the front child over `[near, front_far]`
/// and in the back child over `[back_near, far]`. Enters the front child, unless no lane is
/// active in it; the back child is deferred when lanes are active in both. `span` becomes
/// the entered child's.
#[inline(always)]
pub(crate) fn descend_split<V: SimdF32>(
    span: &mut (V, V),
    (front, back): (usize, usize),
    (front_far, back_near): (V, V),
) -> Visit<(V, V)> {
    let (near, far) = *span;
    let in_front = near.cmple(front_far);
    let in_back = back_near.cmple(far);
    if !in_back.any() {
        span.1 = front_far;
        Visit::One(front)
    } else if !in_front.any() {
        span.0 = back_near;
        Visit::One(back)
    } else {
        span.1 = front_far;
        Visit::Both { first: front, second: back, deferred: (back_near, far) }
    }
}

/// [`descend_split`] with each child's own lane intervals: enters `first` over `first_span`
/// unless no lane is active in it, and defers `second` over `second_span` when lanes are
/// active in both.
#[inline(always)]
pub(crate) fn descend_spans<V: SimdF32>(
    span: &mut (V, V),
    (first, second): (usize, usize),
    (first_span, second_span): ((V, V), (V, V)),
) -> Visit<(V, V)> {
    let in_first = first_span.0.cmple(first_span.1);
    let in_second = second_span.0.cmple(second_span.1);
    if !in_second.any() {
        *span = first_span;
        Visit::One(first)
    } else if !in_first.any() {
        *span = second_span;
        Visit::One(second)
    } else {
        *span = first_span;
        Visit::Both { first, second, deferred: second_span }
    }
}

/// `mask` where `enabled`, else all false: a mask that only applies to one query kind.
#[inline(always)]
fn and_if<M: SimdMask>(mask: M, enabled: bool) -> M {
    if enabled { mask } else { M::splat(false) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::PortableF32;
    use crate::test_support::{self, Rng, check_against_single_rays, packet_hit_bits, ray_packet_bits};
    use glam::{Vec3, Vec4};
    use kdtree::counters::NoCounters;
    use kdtree::triangle::WatertightTriangle;
    use kdtree::{BuildConfig, Ray};

    fn tree(intersector: Intersector) -> KdTree {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        let config = BuildConfig { intersector, ..Default::default() };
        KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).unwrap()
    }

    /// Rays from one origin in all eight octants at once, compared lane by lane with single
    /// rays.
    #[test]
    fn mixed_sign_packets_match_single_rays() {
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let tree = tree(intersector);
            let b = tree.bounds();
            let c = 0.5 * (b.min + b.max);
            for (i, dirs) in [
                [
                    Vec3::new(1.0, 0.3, 0.2),
                    Vec3::new(-1.0, 0.2, 0.1),
                    Vec3::new(0.1, -1.0, 0.3),
                    Vec3::new(0.2, 0.1, -1.0),
                ],
                [Vec3::X, -Vec3::X, Vec3::new(0.0, -0.0, 1.0), Vec3::new(-0.0, 1.0, 0.0)],
            ]
            .iter()
            .enumerate()
            {
                let rays = dirs.map(|d| Ray::new(c, d, 0.0, f32::INFINITY));
                let packet = OmniPacket::new(RayPacket::new(&rays)).unwrap();
                let hits = intersect(&tree, &packet, &mut NoCounters).hits();
                let blocked = occluded(&tree, &packet, &mut NoCounters);
                for (lane, ray) in rays.iter().enumerate() {
                    assert_eq!(hits[lane], tree.intersect(ray), "{intersector:?} packet {i} lane {lane}");
                    assert_eq!(blocked.found.bitmask() >> lane & 1 != 0, tree.occluded(ray));
                }
            }
        }
    }

    /// `rays` (one origin) as one omni-directional packet of `V`'s width: both queries,
    /// checked against single rays. Returns the number of rays that hit something and
    /// whether the packet's watertight shear is uniform.
    fn check_omni<V: SimdF32>(tree: &KdTree, rays: &[Ray], what: &str) -> (usize, bool) {
        let packet = OmniPacket::new(RayPacket::<V>::from_rays(rays)).expect("one origin, t_min = 0");
        let closest = intersect(tree, &packet, &mut NoCounters);
        let any = occluded(tree, &packet, &mut NoCounters);
        let hits = check_against_single_rays(tree, rays, &closest, &any, what);
        (hits, WatertightTriangle::prepare4(&packet.rays).uniform)
    }

    /// The one walk at 4 (glam), 8 and 16 lanes (the portable lane type): every lane's
    /// closest and any hit are the single ray's, bit for bit, for both intersectors, on a
    /// random soup, on split planes (origins on them, rays in them), with zero direction
    /// components, at tiny and huge coordinates and 1e5 from the origin, in partial packets
    /// and aimed at vertices and edges. Both watertight paths (shared shear axes, and the
    /// scalar lanes of mixed axes) run, and every scene and case has rays that hit.
    #[test]
    fn omni_packets_of_every_width_match_single_rays() {
        let mut rng = Rng(0x00a1_1ce5);
        let mut uniform = [0usize; 2];
        for scene in test_support::hard_scenes() {
            let mut hits = [0usize; 6];
            for (t, tree) in scene.trees.iter().enumerate() {
                for round in 0..60 {
                    let kind = round % 6;
                    let what = format!("{} tree {t} round {round} kind {kind}", scene.name);
                    hits[kind] += check_omni::<Vec4>(tree, &scene.rays(&mut rng, 4, kind, true), &what).0;
                    for (h, u) in [
                        check_omni::<PortableF32<8>>(tree, &scene.rays(&mut rng, 8, kind, true), &what),
                        check_omni::<PortableF32<16>>(tree, &scene.rays(&mut rng, 16, kind, true), &what),
                    ] {
                        hits[kind] += h;
                        uniform[usize::from(u)] += 1;
                    }
                }
            }
            assert!(hits.iter().all(|&h| h > 20), "{}: rays that hit, by case: {hits:?}", scene.name);
        }
        assert!(uniform[0] > 100 && uniform[1] > 100, "mixed and shared shear axes: {uniform:?}");
    }

    /// The portable lane type at 4 lanes gives the glam packet's answers lane for lane, bit
    /// for bit: the packet, its root interval, and every lane of both queries' hits (the
    /// misses' `t_max` and the barycentrics included).
    #[test]
    fn portable_four_lanes_are_the_glam_walk_bit_for_bit() {
        let mut rng = Rng(0xface_f00d);
        for scene in test_support::hard_scenes() {
            for tree in &scene.trees {
                for round in 0..30 {
                    let rays = scene.rays(&mut rng, 4, round % 6, true);
                    let glam = OmniPacket::new(RayPacket::<Vec4>::from_rays(&rays)).unwrap();
                    let portable = OmniPacket::new(RayPacket::<PortableF32<4>>::from_rays(&rays)).unwrap();
                    let what = format!("{} round {round}", scene.name);
                    assert_eq!(ray_packet_bits(&glam.rays), ray_packet_bits(&portable.rays), "{what}");
                    assert_eq!(glam.origin.map(f32::to_bits), portable.origin.map(f32::to_bits), "{what}");
                    let (g, p) = (root_interval(tree, &glam.rays), root_interval(tree, &portable.rays));
                    assert_eq!((g.0.to_array(), g.1.to_array()), (p.0.0, p.1.0), "{what}");
                    for any in [false, true] {
                        let (g, p) = if any {
                            (occluded(tree, &glam, &mut NoCounters), occluded(tree, &portable, &mut NoCounters))
                        } else {
                            (intersect(tree, &glam, &mut NoCounters), intersect(tree, &portable, &mut NoCounters))
                        };
                        assert_eq!(packet_hit_bits(&g), packet_hit_bits(&p), "{what} any {any}");
                    }
                }
            }
        }
    }
}
