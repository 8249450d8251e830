//! The standard 2x2 packet traversal (thesis 2.3.1, Listing 2.4, corrected), kept beside the
//! omni-directional one so the two can be compared on packets whose rays disagree on
//! direction signs.
//!
//! All rays of a packet must agree on the sign of each direction component, because the near
//! and far children are chosen once for the packet from the direction's sign. A packet that
//! mixes signs is split into sub-packets of equal sign patterns (masking the other lanes),
//! each traced on its own: up to four traversals where the omni-directional packet needs one.
//! The rays need not share an origin.
//!
//! Listing 2.4 picks near/far from `dir[0]` (the x component, whatever the split axis) with
//! the sign test the wrong way round (see `../shared/seeds/README.md`). Here, as in the
//! single-ray kernel, the near child for axis `k` is the upper child when the sign bit of
//! `dir[k]` is set. Each lane's interval follows the single-ray rules: front
//! `[near, min(far, d)]`, back `[max(near, d), far]` (a negative `d` empties the front, so
//! rays may start behind their origin, `t_min < 0`), and a lane lying in the split plane
//! (`d` NaN) visits both children over its whole interval.

use glam::{BVec4A, Vec3, Vec4};
use kdtree::triangle::{Intersector, TriangleTest};
use kdtree::{Counters, KdNode, KdTree};

use crate::omni::{self, ChildOrder, Step};
use crate::packet::{PacketHit, RayPacket, widen_down, widen_up};
use crate::triangle4::PacketTest;

/// The closest hits of the packet's rays, splitting it by direction signs. Invalid lanes
/// (rays with NaN or infinite components among them, see [`crate::RayPacket::new`]) get no
/// hit.
#[inline]
pub fn intersect<C: Counters>(tree: &KdTree, packet: &RayPacket, counters: &mut C) -> PacketHit {
    split_by_signs::<C, false>(tree, packet, None, counters)
}

/// Which of the packet's rays are blocked (any hit, the shadow query), splitting it by
/// direction signs: the `found` lanes are the blocked rays, each lane leaving at its first
/// hit. Invalid lanes are never blocked.
#[inline]
pub fn occluded<C: Counters>(tree: &KdTree, packet: &RayPacket, counters: &mut C) -> PacketHit {
    split_by_signs::<C, true>(tree, packet, None, counters)
}

/// Whether each segment `starts[i]` to `ends[i]` (the ray `Ray::new(start, end - start, 0,
/// 1)`, a shadow ray) is blocked, four consecutive ones at a time as one packet
/// ([`RayPacket::segments`], [`occluded`]): the answers, in order, appended to `blocked`
/// after clearing it. Segments of neighbouring pixels (a tile's shadow rays in Morton order)
/// make coherent packets.
pub fn occluded_segments<C: Counters>(
    tree: &KdTree,
    starts: &[Vec3],
    ends: &[Vec3],
    blocked: &mut Vec<bool>,
    counters: &mut C,
) {
    blocked.clear();
    for (starts, ends) in starts.chunks(4).zip(ends.chunks(4)) {
        let found = occluded(tree, &RayPacket::segments(starts, ends), counters).found.bitmask();
        blocked.extend((0..starts.len().min(ends.len())).map(|lane| found >> lane & 1 != 0));
    }
}

/// [`occluded`] inside the subtree of node `from.0` only, the lanes' intervals in its box
/// being `from.1` (from `RayPacket::clip` against that box): the shadow frusta of
/// `crate::shadow_frustum` hand their rays over four at a time this way.
#[inline]
pub fn occluded_in<C: Counters>(
    tree: &KdTree,
    packet: &RayPacket,
    from: (usize, (Vec4, Vec4)),
    counters: &mut C,
) -> PacketHit {
    split_by_signs::<C, true>(tree, packet, Some(from), counters)
}

/// [`intersect`] or, with `ANY_HIT`, [`occluded`]; from the root, or from `from` as
/// [`occluded_in`].
#[inline(always)]
fn split_by_signs<C: Counters, const ANY_HIT: bool>(
    tree: &KdTree,
    packet: &RayPacket,
    from: Option<(usize, (Vec4, Vec4))>,
    counters: &mut C,
) -> PacketHit {
    let traverse_group = |sub: &RayPacket, counters: &mut C| match tree.intersector() {
        Intersector::Wald => traverse::<_, C, ANY_HIT>(tree, tree.wald_records(), sub, from, counters),
        Intersector::Watertight => traverse::<_, C, ANY_HIT>(tree, tree.watertight_records(), sub, from, counters),
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
        sub.valid &= group;
        sub.t_min = Vec4::select(group, sub.t_min, Vec4::INFINITY);
        sub.t_max = Vec4::select(group, sub.t_max, Vec4::NEG_INFINITY);
        let part = traverse_group(&sub, counters);
        hit.t = Vec4::select(group, part.t, hit.t);
        hit.u = Vec4::select(group, part.u, hit.u);
        hit.v = Vec4::select(group, part.v, hit.v);
        hit.found |= part.found & group;
        for lane in 0..4 {
            if group.bitmask() >> lane & 1 != 0 {
                hit.prim[lane] = part.prim[lane];
            }
        }
    }
    hit
}

/// Whether the valid lanes (at least one) share their direction signs on every axis.
#[inline(always)]
fn one_sign_group(packet: &RayPacket) -> bool {
    let valid = packet.valid.bitmask();
    valid != 0
        && (0..3).all(|a| {
            let negative = packet.d[a].is_negative_bitmask() & valid;
            negative == 0 || negative == valid
        })
}

/// The valid lanes grouped by direction sign pattern (sign bits of x, y, z): one mask per
/// distinct pattern, at most four.
pub fn sign_groups(packet: &RayPacket) -> impl Iterator<Item = BVec4A> + use<> {
    let signs: [u32; 4] =
        std::array::from_fn(|lane| (0..3).fold(0, |s, a| s | u32::from(packet.d[a][lane].is_sign_negative()) << a));
    let valid = packet.valid.bitmask();
    let mut seen = 0u32;
    (0..4).filter_map(move |lane| {
        if valid >> lane & 1 == 0 || seen >> lane & 1 != 0 {
            return None;
        }
        let group: [bool; 4] = std::array::from_fn(|l| valid >> l & 1 != 0 && signs[l] == signs[lane]);
        for (l, &g) in group.iter().enumerate() {
            seen |= u32::from(g) << l;
        }
        Some(BVec4A::from_array(group))
    })
}

/// Listing 2.4's child order (corrected) for a packet whose valid lanes share direction
/// signs: bit `axis` of the field is set where the direction's sign bit is, and then the near
/// child is the upper one. A lane lying in the split plane (`d` NaN) keeps its whole interval
/// in both children.
struct SameSign(usize);

impl ChildOrder for SameSign {
    #[inline(always)]
    fn step(&self, rays: &RayPacket, node: KdNode, near: Vec4, far: Vec4) -> Step {
        let axis = node.axis() & 3;
        let d = (Vec4::splat(node.split()) - rays.o[axis]) * rays.inv[axis];
        let in_plane = d.cmpne(d);
        let upper = (self.0 >> axis) & 1;
        let (front, back) = (node.left_child() + upper, node.left_child() + 1 - upper);
        let front_far = Vec4::select(in_plane, far, far.min(widen_up(d)));
        let back_near = Vec4::select(in_plane, near, near.max(widen_down(d)));
        Step::Split { front, back, front_far, back_near }
    }
}

/// Traversal of a packet whose valid lanes share direction signs.
#[inline(always)]
fn traverse<T: TriangleTest + PacketTest, C: Counters, const ANY_HIT: bool>(
    tree: &KdTree,
    records: &[T],
    rays: &RayPacket,
    from: Option<(usize, (Vec4, Vec4))>,
    counters: &mut C,
) -> PacketHit {
    let first = (rays.valid.bitmask().trailing_zeros() as usize).min(3);
    let upper_first = (0..3).fold(0usize, |m, a| m | usize::from(rays.d[a][first].is_sign_negative()) << a);
    let order = SameSign(upper_first);
    match from {
        None => omni::traverse::<_, _, C, ANY_HIT>(tree, records, rays, &order, counters),
        Some((node, (near, far))) => {
            // The lanes outside this sign group are empty intervals.
            let (near, far) =
                (Vec4::select(rays.valid, near, Vec4::INFINITY), Vec4::select(rays.valid, far, Vec4::NEG_INFINITY));
            omni::traverse_from::<_, _, C, ANY_HIT>(tree, records, rays, &order, (node, (near, far)), counters)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use kdtree::counters::NoCounters;
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
}
