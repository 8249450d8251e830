//! Omni-directional packets whose rays do not share an origin: the thesis's secondary-ray
//! packets (4.1.2: "omnidirectional ray packets are used for the packet traversal of secondary
//! rays", spawned by the shader proxy from a 2x2 packet's hits, 3.3), the reflections and
//! refractions of neighbouring pixels.
//!
//! Listing 4.1 visits the front voxel, the child on the common origin's side of the plane,
//! before the back voxel. A lane's front interval is `[near, min(far, d)]` and its back
//! interval `[max(near, d), far]`, with `d` taken as `+inf` for a plane behind the origin.
//! Both rules are per ray: they only need the ray to start at its origin (`t_min >= 0`), not
//! the packet to share one. Here each lane's front is its own origin's side:
//! - The packet visits first the child that is the front of most active lanes (the lower
//!   one on a tie).
//! - A lane whose origin lies on the other side takes its back interval there, and its front
//!   interval is deferred with the second child. Its hits can then be found far before near.
//!   That is still exact: a leaf keeps the closest hit of a lane whatever the order, and the
//!   deferred voxel is popped with the lane's `far` clamped to its hit, as in [`crate::omni`].
//! - A lane whose origin lies on the plane (or a NaN distance) gets its whole interval on both
//!   sides, as Listing 4.1's both-children case.
//!
//! On an axis where every lane's direction has the same sign, the packet takes the near child
//! by that sign (Listing 2.4's order) instead: it is every lane's own near child whatever its
//! origin (a lane moving away from a plane behind it has an empty near interval), so no lane
//! is taken far side first. Measured on the garage's and Sponza's reflection rays, taking the
//! origins' side on such axes too was 1.5x slower at 4 lanes than same-sign packets.
//! The rest of the walk is [`crate::omni`]'s: the leaf test, the stack, the pop rule, every
//! width.

use kdtree::{Counters, KdNode, KdTree, TreeTest};

use crate::omni::{ChildOrder, Step, traverse};
use crate::packet::{PacketHit, RayPacket, widen_down, widen_up};
use crate::simd::{SimdF32, SimdMask};
use crate::triangle4::PacketTest;

/// The closest hits of the packet's rays, each from its own origin, with the tree's triangle
/// test `I`. Every valid lane must start at its origin (`t_min >= 0`): see
/// [`starts_at_origins`]. Invalid lanes get no hit.
#[inline(always)]
pub fn intersect_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    rays: &RayPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    debug_assert!(starts_at_origins(rays));
    traverse::<V, _, _, C, false>(tree, I::records(tree), rays, &OmniLanes::new(rays), counters)
}

/// Which of the packet's rays are blocked (any hit), as [`intersect_with`].
#[inline(always)]
pub fn occluded_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    rays: &RayPacket<V>,
    counters: &mut C,
) -> PacketHit<V> {
    debug_assert!(starts_at_origins(rays));
    traverse::<V, _, _, C, true>(tree, I::records(tree), rays, &OmniLanes::new(rays), counters)
}

/// Whether every valid lane starts at its origin (`t_min >= 0`), which the omni-directional
/// rule "a plane behind the origin is never crossed" needs.
#[inline(always)]
pub fn starts_at_origins<V: SimdF32>(rays: &RayPacket<V>) -> bool {
    !(rays.t_min.cmplt(V::ZERO) & rays.valid).any()
}

/// The child order of this module. On an axis where every valid lane's direction has the same
/// sign, the near child by that sign (Listing 2.4's order, corrected): right for every lane
/// whatever its origin, so no lane is ever taken far side first. On the other axes, each
/// lane's front from its own origin, the packet taking first the child most active lanes
/// start in.
struct OmniLanes {
    /// Bit `axis`: the valid lanes' direction signs agree on that axis.
    agree: usize,
    /// Bit `axis`: ... and are negative (the upper child is near).
    upper: usize,
}

impl OmniLanes {
    #[inline(always)]
    fn new<V: SimdF32>(rays: &RayPacket<V>) -> OmniLanes {
        let valid = rays.valid.bitmask();
        let (mut agree, mut upper) = (0, 0);
        for a in 0..3 {
            let negative = rays.d[a].is_negative_bitmask() & valid;
            if negative == 0 || negative == valid {
                agree |= 1 << a;
                upper |= usize::from(negative != 0) << a;
            }
        }
        OmniLanes { agree, upper }
    }
}

impl ChildOrder for OmniLanes {
    #[inline(always)]
    fn step<V: SimdF32>(&self, rays: &RayPacket<V>, node: KdNode, near: V, far: V) -> Step<V> {
        let axis = node.axis() & 3;
        let dist = V::splat(node.split()) - rays.o[axis];
        let inv = rays.inv[axis];
        if (self.agree >> axis) & 1 != 0 {
            // The same-sign step: a plane behind a lane's origin empties its near interval;
            // a lane lying in the plane (`d` NaN) keeps its whole interval on both sides.
            let d = dist * inv;
            let in_plane = d.cmpne(d);
            let upper = (self.upper >> axis) & 1;
            let (front, back) = (node.left_child() + upper, node.left_child() + 1 - upper);
            let front_far = V::select(in_plane, far, far.min(widen_up(d)));
            let back_near = V::select(in_plane, near, near.max(widen_down(d)));
            return Step::Split { front, back, front_far, back_near };
        }
        // Modification 1, per lane: a plane behind the origin (decided by the signs of
        // `dist` and `1 / d`, not of their product, as in `omni::Omni`) is at +inf.
        let (below, above) = (dist.cmpgt(V::ZERO), dist.cmplt(V::ZERO));
        let behind = (below & inv.cmplt(V::ZERO)) | (above & inv.cmpgt(V::ZERO));
        let d = V::select(behind, V::INFINITY, dist * inv);
        let front = (near, far.min(widen_up(d)));
        let back = (near.max(widen_down(d)), far);
        // Modification 2, per lane: the packet takes first the child most active lanes
        // start in.
        let active = near.cmple(far);
        let lower_first = (below & active).bitmask().count_ones() >= (above & active).bitmask().count_ones();
        let agree = if lower_first { below } else { above };
        let on_plane = !(below | above);
        let pick = |a: (V, V), b: (V, V), m: V::Mask| (V::select(m, a.0, b.0), V::select(m, a.1, b.1));
        let first_span = pick((near, far), pick(front, back, agree), on_plane);
        let second_span = pick((near, far), pick(back, front, agree), on_plane);
        let lower = node.left_child();
        let (first, second) = if lower_first { (lower, lower + 1) } else { (lower + 1, lower) };
        Step::Spans { first, second, first_span, second_span }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::PortableF32;
    use crate::test_support::{self, Rng};
    use glam::Vec4;
    use kdtree::{NoCounters, Ray, WaldTest, WatertightTest};

    /// `rays` (each from its own origin) as one packet of `V`'s width, both queries, against
    /// single rays: the same distance bit for bit (the same triangle unless two tie at it) and
    /// the same blocked rays. Returns the rays that hit.
    fn check<V: SimdF32>(tree: &KdTree, rays: &[Ray], what: &str) -> usize {
        let packet = RayPacket::<V>::from_rays(rays);
        assert!(starts_at_origins(&packet));
        let (closest, any) = match tree.intersector() {
            kdtree::Intersector::Wald => (
                intersect_with::<WaldTest, V, _>(tree, &packet, &mut NoCounters),
                occluded_with::<WaldTest, V, _>(tree, &packet, &mut NoCounters),
            ),
            kdtree::Intersector::Watertight => (
                intersect_with::<WatertightTest, V, _>(tree, &packet, &mut NoCounters),
                occluded_with::<WatertightTest, V, _>(tree, &packet, &mut NoCounters),
            ),
        };
        let mut hits = 0;
        for lane in 0..V::LANES {
            let (want, blocked) = rays.get(lane).map_or((None, false), |r| (tree.intersect(r), tree.occluded(r)));
            let have = closest.get(lane);
            assert_eq!(
                have.map(|h| h.t.to_bits()),
                want.map(|h| h.t.to_bits()),
                "{what}: lane {lane} {:?}",
                rays.get(lane)
            );
            if let (Some(h), Some(w)) = (have, want)
                && h.prim != w.prim
            {
                // Only a tie: the packet's triangle lies at the single ray's distance too.
                let ray = rays[lane];
                let [a, b, c] = tree.triangle(h.prim).map(|p| p.as_dvec3());
                let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
                let n = (b - a).cross(c - a);
                let t = n.dot(a - o) / n.dot(d);
                assert!((t - f64::from(w.t)).abs() <= 1e-4 * t.abs().max(1e-30), "{what}: lane {lane} {h:?} {w:?}");
            }
            assert_eq!(any.found.bitmask() >> lane & 1 != 0, blocked, "{what} any hit: lane {lane}");
            hits += usize::from(blocked);
        }
        hits
    }

    /// Packets of rays with their own origins (the hard cases of `test_support`: every octant,
    /// zero direction components of both signs, origins on a split plane with rays in it,
    /// rays from far outside, partial packets, rays at vertices and edges), on a soup, the
    /// grid of split planes, tiny and huge coordinates and 1e5 from the origin, both
    /// intersectors, at 4, 8 and 16 lanes: every lane gives the single ray's answer.
    #[test]
    fn packets_of_scattered_origins_give_the_single_rays_answers_at_every_width() {
        let mut rng = Rng(0x5ec0_00da);
        for scene in test_support::hard_scenes() {
            let mut hits = 0;
            for (t, tree) in scene.trees.iter().enumerate() {
                for round in 0..60 {
                    let kind = round % 6;
                    let what = format!("{} tree {t} round {round} kind {kind}", scene.name);
                    // Each ray from its own origin, starting there (the omni rule's premise).
                    let own = |rays: Vec<Ray>| -> Vec<Ray> {
                        rays.into_iter().map(|r| Ray::new(r.origin, r.dir, r.t_min.max(0.0), r.t_max)).collect()
                    };
                    hits += check::<Vec4>(tree, &own(scene.rays(&mut rng, 4, kind, false)), &what);
                    hits += check::<PortableF32<8>>(tree, &own(scene.rays(&mut rng, 8, kind, false)), &what);
                    hits += check::<PortableF32<16>>(tree, &own(scene.rays(&mut rng, 16, kind, false)), &what);
                }
            }
            assert!(hits > 100, "{}: the test must see hits ({hits})", scene.name);
        }
    }

    /// The AVX2 and AVX-512 lane types give their portable twin's answers bit for bit
    /// (where the CPU runs them; the twins themselves are checked against single rays above).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn wide_lane_types_are_their_portable_twins_bit_for_bit() {
        use crate::simd_x86::{F32x8, F32x16, with_avx2, with_avx512};
        let mut rng = Rng(0x0e1a_7717);
        for scene in test_support::hard_scenes() {
            for tree in scene.trees.iter().filter(|t| t.intersector() == kdtree::Intersector::Wald) {
                for round in 0..30 {
                    let own = |rays: Vec<Ray>| -> Vec<Ray> {
                        rays.into_iter().map(|r| Ray::new(r.origin, r.dir, r.t_min.max(0.0), r.t_max)).collect()
                    };
                    let (r8, r16) = (
                        own(scene.rays(&mut rng, 8, round % 6, false)),
                        own(scene.rays(&mut rng, 16, round % 6, false)),
                    );
                    let want8 = test_support::packet_hit_bits(&intersect_with::<WaldTest, PortableF32<8>, _>(
                        tree,
                        &RayPacket::from_rays(&r8),
                        &mut NoCounters,
                    ));
                    let want16 = test_support::packet_hit_bits(&intersect_with::<WaldTest, PortableF32<16>, _>(
                        tree,
                        &RayPacket::from_rays(&r16),
                        &mut NoCounters,
                    ));
                    if let Some(got) = with_avx2(|| {
                        test_support::packet_hit_bits(&intersect_with::<WaldTest, F32x8, _>(
                            tree,
                            &RayPacket::from_rays(&r8),
                            &mut NoCounters,
                        ))
                    }) {
                        assert_eq!(got, want8, "{} round {round}: 8 lanes", scene.name);
                    }
                    if let Some(got) = with_avx512(|| {
                        test_support::packet_hit_bits(&intersect_with::<WaldTest, F32x16, _>(
                            tree,
                            &RayPacket::from_rays(&r16),
                            &mut NoCounters,
                        ))
                    }) {
                        assert_eq!(got, want16, "{} round {round}: 16 lanes", scene.name);
                    }
                }
            }
        }
    }

    /// With one origin the answers are the omni walk's, bit for bit.
    #[test]
    fn a_common_origin_gives_the_omni_walks_answers() {
        let mut rng = Rng(0x0e1a_0001);
        for scene in test_support::hard_scenes() {
            let tree = &scene.trees[0];
            for round in 0..60 {
                let rays = scene.rays(&mut rng, 4, round % 6, true);
                let packet = RayPacket::<Vec4>::from_rays(&rays);
                let Some(omni) = crate::OmniPacket::new(packet) else { continue };
                let x = intersect_with::<WaldTest, Vec4, _>(tree, &packet, &mut NoCounters);
                let y = crate::omni::intersect_with::<WaldTest, Vec4, _>(tree, &omni, &mut NoCounters);
                assert_eq!(test_support::packet_hit_bits(&x), test_support::packet_hit_bits(&y), "{}", scene.name);
            }
        }
    }
}
