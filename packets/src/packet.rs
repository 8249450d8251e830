//! SoA packets of rays and their hits (thesis 2.3.1, Listings 2.5-2.6).
//!
//! A [`RayPacket<V>`] keeps each coordinate of its rays in one lane vector `V`
//! ([`SimdF32`]), so that a traversal step or a triangle test handles all of them with the
//! same instructions as one. **The packet's width is its lane type's**: `V::LANES` rays. The
//! default, glam's `Vec4` (one SSE register), is the thesis's 2x2 packet, and `RayPacket`
//! without a parameter is that one; [`crate::simd::PortableF32`] gives any width (8 and 16
//! lanes). Per-axis data sits in `[V; 4]` arrays whose fourth entry is padding: an axis read
//! from a node (`0..=2`, masked with `& 3`) indexes them without a bounds check.
//!
//! Lanes that hold no ray (at the edge of an image, or a packet of fewer than `W` rays) are
//! *invalid*: they carry an empty interval (`t_min = +inf`, `t_max = -inf`) and take part in
//! no test.

use glam::{Vec3, Vec4};
use kdtree::traverse::WIDEN;
use kdtree::{Hit, Ray};

use crate::simd::{SimdF32, SimdMask};

/// `W` rays' directions and their reciprocals as [`Ray::new`] makes them, one axis per
/// vector: `1 / d` per lane (one division per axis for `W` rays, each correctly rounded as
/// the scalar division), and a component whose reciprocal overflows (a denormal) flushed to a
/// zero of its sign. NaN components stay NaN, as `Ray::new` keeps them. Shared by the packets
/// built without `Ray`s: [`RayPacket::segments`] and the tile tracer's primary rays.
#[inline(always)]
pub(crate) fn directions<V: SimdF32>(raw: [V; 3]) -> ([V; 3], [V; 3]) {
    let inv: [V; 3] = crate::simd::array_fn(|a| raw[a].recip());
    let d = crate::simd::array_fn(
        #[inline(always)]
        |a| {
            let keep = inv[a].is_finite_mask() | raw[a].cmpeq(V::ZERO) | raw[a].is_nan_mask();
            V::select(keep, raw[a], V::ZERO.copysign(raw[a]))
        },
    );
    (d, inv)
}

/// The first `V::LANES` points of `v` as one vector per axis (`SimdF32::axes`).
#[inline(always)]
fn soa<V: SimdF32>(v: &[Vec3]) -> [V; 4] {
    let v = &v[..V::LANES];
    V::axes(V::array_from_fn(|l| v[l]))
}

/// The lanes finite in every vector of `v`.
#[inline(always)]
fn all_finite<V: SimdF32>(v: &[V]) -> V::Mask {
    let mut finite = V::Mask::splat(true);
    for c in v {
        finite &= c.is_finite_mask();
    }
    finite
}

/// `V::LANES` rays in structure-of-arrays form: by default four, one glam `Vec4` per
/// coordinate.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct RayPacket<V: SimdF32 = Vec4> {
    /// Origins: `o[axis]` holds that coordinate of the rays (`o[3]` is padding).
    pub o: [V; 4],
    /// Directions, as [`Ray::dir`] (denormal components flushed to signed zeros).
    pub d: [V; 4],
    /// `1 / d`, per component (signed infinities for zero components).
    pub inv: [V; 4],
    /// Start of each ray's interval (`+inf` in invalid lanes).
    pub t_min: V,
    /// End of each ray's interval (`-inf` in invalid lanes).
    pub t_max: V,
    /// The lanes that hold a ray.
    pub valid: V::Mask,
}

/// The 4-wide packet's constructors, by the names the workspace calls them (each the generic
/// constructor of its line at `V = Vec4`).
impl RayPacket {
    /// A packet of up to four rays; lanes past `rays.len()` are invalid
    /// ([`RayPacket::from_rays`]).
    #[inline(always)]
    pub fn new(rays: &[Ray]) -> RayPacket {
        RayPacket::from_rays(rays)
    }

    /// A packet from four optional rays ([`RayPacket::from_slots`]).
    pub fn from_lanes(lanes: [Option<Ray>; 4]) -> RayPacket {
        RayPacket::from_slots(lanes)
    }

    /// The packet of up to four segments ([`RayPacket::from_segments`]).
    pub fn segments(origins: &[Vec3], targets: &[Vec3]) -> RayPacket {
        RayPacket::from_segments(origins, targets)
    }
}

impl<V: SimdF32> RayPacket<V> {
    /// A packet of up to `V::LANES` rays; lanes past `rays.len()` are invalid.
    ///
    /// Rays with a NaN or infinite origin or direction, a zero direction, or a NaN or empty
    /// interval are marked invalid, like missing ones: like [`kdtree::KdTree::intersect`],
    /// every method reports no hit for them. Invalid lanes hold a copy of the first usable
    /// ray (or a finite filler), never the rejected one.
    #[inline(always)]
    pub fn from_rays(rays: &[Ray]) -> RayPacket<V> {
        let mut lanes = V::array_from_fn(|_| None);
        for (slot, ray) in lanes.as_mut().iter_mut().zip(rays) {
            *slot = Some(*ray);
        }
        RayPacket::from_slots(lanes)
    }

    /// A packet from one optional ray per lane (`None` lanes, and rays
    /// [`RayPacket::from_rays`] rejects, are invalid).
    #[inline(always)]
    pub fn from_slots(lanes: V::Array<Option<Ray>>) -> RayPacket<V> {
        let usable = V::array_from_fn(|l| lanes[l].filter(Ray::is_valid));
        let fill = usable.as_ref().iter().flatten().next().copied().unwrap_or(Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0));
        let rays = V::array_from_fn(|l| usable[l].unwrap_or(fill));
        let valid = V::Mask::from_fn(|l| usable[l].is_some());
        // Each vector field one axis per vector (`SimdF32::axes`).
        let soa = |field: fn(&Ray) -> Vec3| V::axes(V::array_from_fn(|l| field(&rays[l])));
        let lane = |field: fn(&Ray) -> f32| V::from_fn(|l| field(&rays[l]));
        RayPacket {
            o: soa(|r| r.origin),
            d: soa(|r| r.dir),
            inv: soa(|r| r.inv_dir),
            t_min: V::select(valid, lane(|r| r.t_min), V::INFINITY),
            t_max: V::select(valid, lane(|r| r.t_max), V::NEG_INFINITY),
            valid,
        }
    }

    /// The packet of the segments from `origins[i]` to `targets[i]` (up to `V::LANES` pairs;
    /// the lanes past them are invalid): bit for bit [`RayPacket::from_rays`] of the rays
    /// `Ray::segment(origin, target)`, the shadow rays of a light point or sample, made
    /// `V::LANES` at a time in vectors (one division per axis for all the reciprocals)
    /// instead of ray by ray. A full packet of finite segments of non-zero length takes the
    /// vector path; any other input goes ray by ray.
    #[inline(always)]
    pub fn from_segments(origins: &[Vec3], targets: &[Vec3]) -> RayPacket<V> {
        let n = origins.len().min(targets.len()).min(V::LANES);
        if n == V::LANES {
            let (o, t) = (soa::<V>(origins), soa::<V>(targets));
            let raw: [V; 3] = crate::simd::array_fn(|a| t[a] - o[a]);
            // Then `Ray::is_valid` wants finite, non-zero directions.
            let (d, inv) = directions(raw);
            let zero = d.iter().fold(V::Mask::splat(true), |m, c| m & c.cmpeq(V::ZERO));
            if (all_finite(&o[..3]) & all_finite(&raw) & !zero).all() {
                return RayPacket {
                    o,
                    d: [d[0], d[1], d[2], V::ZERO],
                    inv: [inv[0], inv[1], inv[2], V::ZERO],
                    t_min: V::ZERO,
                    t_max: V::ONE,
                    valid: V::Mask::splat(true),
                };
            }
        }
        let mut lanes = V::array_from_fn(|_| None);
        for (lane, (&o, &t)) in lanes.as_mut().iter_mut().zip(origins.iter().zip(targets)) {
            *lane = Some(Ray::segment(o, t));
        }
        RayPacket::from_slots(lanes)
    }

    /// Keeps only the lanes of `lanes` valid: the others become invalid, with the empty
    /// interval (`+inf`, `-inf`) every invalid lane holds. How a walk is handed part of a
    /// packet (a sign group, the lanes a shadow cache left unblocked).
    #[inline(always)]
    pub fn keep_lanes(&mut self, lanes: V::Mask) {
        self.valid &= lanes;
        V::blend_into(!lanes, V::INFINITY, &mut self.t_min);
        V::blend_into(!lanes, V::NEG_INFINITY, &mut self.t_max);
    }

    /// The ray in `lane` (also for an invalid lane, whose content is filler).
    #[inline(always)]
    pub fn ray(&self, lane: usize) -> Ray {
        let origin = Vec3::new(self.o[0][lane], self.o[1][lane], self.o[2][lane]);
        let dir = Vec3::new(self.d[0][lane], self.d[1][lane], self.d[2][lane]);
        Ray::new(origin, dir, self.t_min[lane], self.t_max[lane])
    }

    /// The common origin of the valid lanes, if they all start at one point (bit for bit).
    #[inline(always)]
    pub fn common_origin(&self) -> Option<Vec3> {
        let first = self.valid.bitmask().trailing_zeros() as usize;
        if first >= V::LANES {
            return None;
        }
        let origin = Vec3::new(self.o[0][first], self.o[1][first], self.o[2][first]);
        let same = (0..3).fold(V::Mask::splat(true), |m, a| m & self.o[a].cmpeq(V::splat(origin[a])));
        // Compare bits, so that -0.0 and 0.0 count as different origins only where they differ.
        (same | !self.valid).all().then_some(origin)
    }

    /// Each lane's interval inside the box `[lo, hi]`, clipped to `[t_min, t_max]` and widened
    /// by [`WIDEN`] like [`kdtree::traverse::clip_to_box`]: a lane misses the box where
    /// `enter > exit`. An axis with a zero direction component constrains nothing when the
    /// origin is inside the slab and empties the interval otherwise (no `0 * inf`).
    #[inline(always)]
    pub fn clip(&self, lo: [f32; 4], hi: [f32; 4]) -> (V, V) {
        let (mut enter, mut exit) = (self.t_min, self.t_max);
        for axis in 0..3 {
            let (l, h) = (V::splat(lo[axis]), V::splat(hi[axis]));
            let (o, inv) = (self.o[axis], self.inv[axis]);
            let (t_l, t_h) = ((l - o) * inv, (h - o) * inv);
            let zero = self.d[axis].cmpeq(V::ZERO);
            let inside = o.cmpge(l) & o.cmple(h);
            let (open_near, open_far) =
                (V::select(inside, V::NEG_INFINITY, V::INFINITY), V::select(inside, V::INFINITY, V::NEG_INFINITY));
            // Infinite distances (an overflowing product) widen to themselves, never NaN.
            let near = V::select(zero, open_near, t_l.min(t_h));
            let far = V::select(zero, open_far, t_l.max(t_h));
            enter = enter.max(widen_down(near));
            exit = exit.min(widen_up(far));
        }
        (enter, exit)
    }
}

/// A packet whose rays share one origin: what the omni-directional traversal (4.1.2) and the
/// frusta (4.1.3-4.1.5) need, since they choose front and back voxels from the origin alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OmniPacket<V: SimdF32 = Vec4> {
    /// The rays (every valid lane starts at `origin`).
    pub rays: RayPacket<V>,
    /// The common origin, `[x, y, z, 0]`.
    pub origin: [f32; 4],
}

impl<V: SimdF32> OmniPacket<V> {
    /// The packet, if its valid lanes share one origin and none has a negative `t_min` (the
    /// omni-directional rule "a plane behind the origin is never crossed" assumes rays start
    /// at their origin). A packet with no valid lane qualifies (its origin is the filler's,
    /// finite). Lanes with NaN or infinite rays are invalid ([`RayPacket::from_rays`]), so
    /// they neither decide the origin nor get a hit.
    #[inline(always)]
    pub fn new(rays: RayPacket<V>) -> Option<OmniPacket<V>> {
        let origin = match rays.common_origin() {
            Some(o) => o,
            None if !rays.valid.any() => Vec3::new(rays.o[0][0], rays.o[1][0], rays.o[2][0]),
            None => return None,
        };
        if (rays.t_min.cmplt(V::ZERO) & rays.valid).any() {
            return None;
        }
        Some(OmniPacket { rays, origin: origin.extend(0.0).to_array() })
    }
}

/// The closest hits of a packet's rays, SoA: `t = +inf` (or the ray's `t_max`) where a lane
/// has no hit yet.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct PacketHit<V: SimdF32 = Vec4> {
    /// Hit distance per lane; the ray's `t_max` while it has no hit.
    pub t: V,
    /// Barycentric weight of the second vertex.
    pub u: V,
    /// Barycentric weight of the third vertex.
    pub v: V,
    /// Triangle index per lane (meaningful where `found` is set).
    pub prim: V::Array<u32>,
    /// Lanes that have a hit.
    pub found: V::Mask,
}

/// Lane by lane `==` of every field (as a derived `PartialEq`).
impl<V: SimdF32> PartialEq for PacketHit<V> {
    fn eq(&self, other: &Self) -> bool {
        self.t == other.t
            && self.u == other.u
            && self.v == other.v
            && self.prim.as_ref() == other.prim.as_ref()
            && self.found == other.found
    }
}

impl<V: SimdF32> PacketHit<V> {
    /// No hits yet: each lane's search ends at its ray's `t_max`.
    #[inline(always)]
    pub fn new(rays: &RayPacket<V>) -> PacketHit<V> {
        PacketHit {
            t: rays.t_max,
            u: V::ZERO,
            v: V::ZERO,
            prim: V::array_from_fn(|_| u32::MAX),
            found: V::Mask::splat(false),
        }
    }

    /// Takes `(t, u, v, prim)` in the lanes of `mask`.
    #[inline(always)]
    pub fn record(&mut self, mask: V::Mask, t: V, u: V, v: V, prim: u32) {
        V::blend_into(mask, t, &mut self.t);
        V::blend_into(mask, u, &mut self.u);
        V::blend_into(mask, v, &mut self.v);
        self.found |= mask;
        // A blend without branches: a branch per lane mispredicts on the lanes a triangle
        // covers, and the 16 lanes' scalar blends cost more than the rest of this record.
        V::blend_u32(mask, prim, &mut self.prim);
    }

    /// The hit of `lane`, as single-ray traversal reports it.
    #[inline(always)]
    pub fn get(&self, lane: usize) -> Option<Hit> {
        (self.found.bitmask() >> lane & 1 != 0).then(|| Hit {
            t: self.t[lane],
            u: self.u[lane],
            v: self.v[lane],
            prim: self.prim[lane],
        })
    }

    /// Every lane's hit, in lane order.
    #[inline(always)]
    pub fn hits(&self) -> V::Array<Option<Hit>> {
        V::array_from_fn(|lane| self.get(lane))
    }
}

/// `t` moved towards `+inf` by [`WIDEN`]: `t + |t| W`, the single-ray kernel's formula;
/// infinities stay as they are (the formula would turn `-inf` into NaN).
#[inline(always)]
pub fn widen_up<V: SimdF32>(t: V) -> V {
    V::select(t.is_finite_mask(), t + t.abs() * V::splat(WIDEN), t)
}

/// `t` moved towards `-inf` by [`WIDEN`]: `t - |t| W`; infinities stay.
#[inline(always)]
pub fn widen_down<V: SimdF32>(t: V) -> V {
    V::select(t.is_finite_mask(), t - t.abs() * V::splat(WIDEN), t)
}

/// Scalar [`widen_up`].
#[inline(always)]
pub fn widen_up1(t: f32) -> f32 {
    if t.is_finite() { t + t.abs() * WIDEN } else { t }
}

/// Scalar [`widen_down`].
#[inline(always)]
pub fn widen_down1(t: f32) -> f32 {
    if t.is_finite() { t - t.abs() * WIDEN } else { t }
}

/// The lanes of a lane bitmask as a mask (bit `l` for lane `l`, as [`SimdMask::bitmask`]):
/// a tile's finished lanes (`TileTracer`'s `done`). At `V = Vec4` the `BVec4A` of the four
/// bits, as before the parameter.
#[inline(always)]
pub(crate) fn mask_of<V: SimdF32>(bits: u32) -> V::Mask {
    V::Mask::from_fn(|lane| bits >> lane & 1 != 0)
}

/// Every lane of a packet of `V` as a bitmask (`0xF` for four lanes).
#[inline(always)]
pub(crate) const fn all_lanes<V: SimdF32>() -> u32 {
    if V::LANES >= 32 { u32::MAX } else { (1 << V::LANES) - 1 }
}

/// The largest lane of `v` among `mask`, `-inf` if none.
#[inline(always)]
pub(crate) fn max_where<V: SimdF32>(mask: V::Mask, v: V) -> f32 {
    max_lane(V::select(mask, v, V::NEG_INFINITY))
}

/// The lanes of `v` four at a time as `Vec4`s folded with `f` (SSE's `minps` / `maxps`),
/// then reduced by `reduce`: at `V = Vec4` exactly `reduce(v)` (the one chunk is `v`). Missing
/// lanes (a width that is not a multiple of four) repeat lane 0.
#[inline(always)]
fn fold_lanes<V: SimdF32>(v: V, f: impl Fn(Vec4, Vec4) -> Vec4, reduce: impl Fn(Vec4) -> f32) -> f32 {
    let lanes = v.to_array();
    let lanes = lanes.as_ref();
    if lanes.len() < 4 {
        return reduce(Vec4::from_array(std::array::from_fn(|l| lanes[if l < lanes.len() { l } else { 0 }])));
    }
    let mut acc = Vec4::from_slice(&lanes[..4]);
    let chunks = lanes[4..].chunks_exact(4);
    let rest = chunks.remainder();
    for chunk in chunks {
        acc = f(acc, Vec4::from_slice(chunk));
    }
    if !rest.is_empty() {
        acc = f(acc, Vec4::from_array(std::array::from_fn(|l| rest.get(l).copied().unwrap_or(lanes[0]))));
    }
    reduce(acc)
}

/// The largest lane of `v` (`Vec4::max_element` at `V = Vec4`).
#[inline(always)]
pub(crate) fn max_lane<V: SimdF32>(v: V) -> f32 {
    fold_lanes(v, Vec4::max, Vec4::max_element)
}

/// The smallest lane of `v` (`Vec4::min_element` at `V = Vec4`).
#[inline(always)]
pub(crate) fn min_lane<V: SimdF32>(v: V) -> f32 {
    fold_lanes(v, Vec4::min, Vec4::min_element)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{PortableF32, PortableMask};
    use crate::test_support::{packet_hit_bits, ray_packet_bits};
    use glam::BVec4A;
    use kdtree::Aabb;
    use kdtree::traverse::clip_to_box;

    fn rays() -> [Ray; 4] {
        [
            Ray::new(Vec3::new(0.5, 0.5, -2.0), Vec3::new(0.1, 0.2, 1.0), 0.0, f32::INFINITY),
            Ray::new(Vec3::new(0.5, 0.5, -2.0), Vec3::new(0.0, -0.0, 1.0), 0.0, 10.0),
            Ray::new(Vec3::new(3.0, 0.5, 0.5), Vec3::new(-1.0, 0.0, 0.0), 1.0, 10.0),
            Ray::new(Vec3::new(3.0, 3.0, 3.0), Vec3::new(0.0, 0.0, 1.0), 0.0, 10.0),
        ]
    }

    #[test]
    fn lanes_round_trip_and_missing_lanes_are_invalid() {
        let r = rays();
        let p = RayPacket::new(&r[..3]);
        assert_eq!(p.valid.bitmask(), 0b0111);
        for (lane, ray) in r[..3].iter().enumerate() {
            assert_eq!(p.ray(lane), *ray);
        }
        assert_eq!((p.t_min[3], p.t_max[3]), (f32::INFINITY, f32::NEG_INFINITY));
        let bad = Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X, 0.0, 1.0);
        assert_eq!(RayPacket::new(&[bad, r[0]]).valid.bitmask(), 0b0010);
    }

    #[test]
    fn lanes_are_the_rays_fields_one_axis_per_vector() {
        let r = rays();
        let bad = Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0);
        for lanes in [
            [Some(r[0]), Some(r[1]), Some(r[2]), Some(r[3])],
            [None, Some(r[2]), Some(bad), Some(r[0])],
            [None, None, None, None],
        ] {
            let p = RayPacket::from_lanes(lanes);
            let usable = lanes.map(|l| l.filter(Ray::is_valid));
            let fill = usable.iter().flatten().next().copied();
            for (lane, usable) in usable.iter().enumerate() {
                assert_eq!(p.valid.bitmask() >> lane & 1 != 0, usable.is_some());
                let ray = usable.or(fill).unwrap_or(Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0));
                for axis in 0..3 {
                    assert_eq!(p.o[axis][lane].to_bits(), ray.origin[axis].to_bits());
                    assert_eq!(p.d[axis][lane].to_bits(), ray.dir[axis].to_bits());
                    assert_eq!(p.inv[axis][lane].to_bits(), ray.inv_dir[axis].to_bits());
                }
                assert_eq!((p.o[3][lane], p.d[3][lane], p.inv[3][lane]), (0.0, 0.0, 0.0));
                let (t_min, t_max) = match usable {
                    Some(ray) => (ray.t_min, ray.t_max),
                    None => (f32::INFINITY, f32::NEG_INFINITY),
                };
                assert_eq!((p.t_min[lane], p.t_max[lane]), (t_min, t_max));
            }
        }
    }

    /// Random segments (and hard lanes: a shared end, a zero-length segment, a denormal or
    /// zero component, non-finite input, fewer segments than lanes), `width` at a time.
    fn segment_cases(width: usize) -> Vec<(Vec<Vec3>, Vec<Vec3>)> {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        let (nan, inf, tiny) = (f32::NAN, f32::INFINITY, 6e-45f32);
        (0..400)
            .map(|case| {
                let scale = [1e-3, 1.0, 1e5][case % 3];
                let mut origins: Vec<Vec3> = (0..width).map(|_| Vec3::new(next(), next(), next()) * scale).collect();
                let mut targets: Vec<Vec3> = (0..width).map(|_| Vec3::new(next(), next(), next()) * scale).collect();
                let last = width - 1;
                match case % 9 {
                    1 => targets = vec![targets[0]; width],
                    2 => targets[1] = origins[1],
                    3 => targets[2] = origins[2] + Vec3::new(tiny, 1.0, 0.0),
                    4 => targets[last].x = origins[last].x,
                    5 => origins[0].y = nan,
                    6 => targets[2].z = inf,
                    7 => origins.truncate(width - 1),
                    8 => targets.truncate(1),
                    _ => {}
                }
                (origins, targets)
            })
            .collect()
    }

    /// `V::LANES` segments at a time: `from_segments` is `from_rays` of their rays, bit for
    /// bit.
    fn check_segments<V: SimdF32>() {
        for (case, (origins, targets)) in segment_cases(V::LANES).into_iter().enumerate() {
            let rays: Vec<Ray> = origins.iter().zip(&targets).map(|(&o, &t)| Ray::segment(o, t)).collect();
            let (got, want) = (RayPacket::<V>::from_segments(&origins, &targets), RayPacket::<V>::from_rays(&rays));
            assert_eq!(ray_packet_bits(&got), ray_packet_bits(&want), "{} lanes, case {case}", V::LANES);
        }
    }

    #[test]
    fn segments_are_the_packet_of_their_rays_bit_for_bit() {
        for (case, (origins, targets)) in segment_cases(4).into_iter().enumerate() {
            let rays: Vec<Ray> = origins.iter().zip(&targets).map(|(&o, &t)| Ray::segment(o, t)).collect();
            let (got, want) = (RayPacket::segments(&origins, &targets), RayPacket::new(&rays));
            let bits = |p: &RayPacket| {
                let v = |x: &[Vec4]| x.iter().flat_map(|c| c.to_array()).map(f32::to_bits).collect::<Vec<_>>();
                (v(&p.o), v(&p.d), v(&p.inv), v(&[p.t_min, p.t_max]), p.valid.bitmask())
            };
            assert_eq!(bits(&got), bits(&want), "case {case}");
        }
        check_segments::<PortableF32<4>>();
        check_segments::<PortableF32<8>>();
        check_segments::<PortableF32<16>>();
    }

    /// The portable lane type at 4 lanes builds the glam packet bit for bit (from rays, from
    /// optional lanes, from segments), clips it to the same intervals, finds the same common
    /// origin and records the same hits.
    #[test]
    fn portable_four_lanes_are_the_glam_packet_bit_for_bit() {
        let r = rays();
        let bad = Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0);
        let boxes = [(Vec3::ZERO, Vec3::ONE), (Vec3::new(0.5, -1.0, 0.0), Vec3::new(0.5, 2.0, 4.0))];
        let lane_sets = [
            [Some(r[0]), Some(r[1]), Some(r[2]), Some(r[3])],
            [None, Some(r[2]), Some(bad), Some(r[0])],
            [Some(r[0]), Some(r[1]), None, None],
            [None; 4],
        ];
        for lanes in lane_sets {
            let (g, p) = (RayPacket::from_lanes(lanes), RayPacket::<PortableF32<4>>::from_slots(lanes));
            assert_eq!(ray_packet_bits(&g), ray_packet_bits(&p), "{lanes:?}");
            assert_eq!(g.common_origin(), p.common_origin());
            assert_eq!(OmniPacket::new(g).map(|o| o.origin), OmniPacket::new(p).map(|o| o.origin));
            for (lo, hi) in boxes {
                let (lo, hi) = (lo.extend(0.0).to_array(), hi.extend(0.0).to_array());
                let (ge, gx) = g.clip(lo, hi);
                let (pe, px) = p.clip(lo, hi);
                assert_eq!(
                    (ge.to_array().map(f32::to_bits), gx.to_array().map(f32::to_bits)),
                    (pe.0.map(f32::to_bits), px.0.map(f32::to_bits))
                );
            }
            let (mut gh, mut ph) = (PacketHit::new(&g), PacketHit::new(&p));
            let mask = [true, false, true, true];
            gh.record(BVec4A::from_array(mask), Vec4::splat(2.0), Vec4::splat(0.25), Vec4::splat(0.5), 7);
            ph.record(
                PortableMask(mask),
                PortableF32::splat(2.0),
                PortableF32::splat(0.25),
                PortableF32::splat(0.5),
                7,
            );
            assert_eq!(packet_hit_bits(&gh), packet_hit_bits(&ph));
            assert_eq!(gh.hits(), ph.hits());
        }
        for (case, (origins, targets)) in segment_cases(4).into_iter().enumerate() {
            let (g, p) = (
                RayPacket::segments(&origins, &targets),
                RayPacket::<PortableF32<4>>::from_segments(&origins, &targets),
            );
            assert_eq!(ray_packet_bits(&g), ray_packet_bits(&p), "case {case}");
        }
    }

    #[test]
    fn non_finite_rays_are_invalid_lanes_filled_with_a_usable_ray() {
        let r = rays();
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        let bad = [
            Ray::new(Vec3::new(nan, 0.0, 0.0), Vec3::X, 0.0, 1.0),
            Ray::new(Vec3::new(0.0, -inf, 0.0), Vec3::X, 0.0, 1.0),
            Ray::new(Vec3::ZERO, Vec3::new(0.0, nan, 1.0), 0.0, 1.0),
            Ray::new(Vec3::ZERO, Vec3::new(inf, 0.0, 1.0), 0.0, 1.0),
            Ray::new(Vec3::ZERO, Vec3::ZERO, 0.0, 1.0),
            Ray::new(Vec3::ZERO, Vec3::X, nan, 1.0),
            Ray::new(Vec3::ZERO, Vec3::X, 0.0, nan),
            Ray::new(Vec3::ZERO, Vec3::X, 2.0, 1.0),
        ];
        for b in bad {
            // In front of a good ray: invalid, and its lane holds the good ray, not NaN.
            let p = RayPacket::new(&[b, r[1]]);
            assert_eq!(p.valid.bitmask(), 0b0010, "{b:?}");
            assert_eq!(p.ray(0).origin, r[1].origin);
            assert!((0..3).all(|a| p.o[a].is_finite() && p.d[a].is_finite()), "{b:?}");
            assert_eq!(p.common_origin(), Some(r[1].origin));
            let omni = OmniPacket::new(p).unwrap();
            assert_eq!(omni.origin[..3], r[1].origin.to_array());
            // Alone: no valid lane and a finite origin.
            let alone = OmniPacket::new(RayPacket::new(&[b, b])).unwrap();
            assert!(!alone.rays.valid.any() && alone.origin.iter().all(|v| v.is_finite()), "{b:?}");
            assert_eq!(PacketHit::new(&alone.rays).hits(), [None; 4]);
        }
    }

    #[test]
    fn clip_agrees_with_the_single_ray_clip() {
        let b = Aabb { min: Vec3::ZERO, max: Vec3::ONE };
        let r = rays();
        let p = RayPacket::new(&r);
        let (enter, exit) = p.clip(b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array());
        for (lane, ray) in r.iter().enumerate() {
            match clip_to_box(ray, &b) {
                Some((t0, t1)) => assert_eq!((enter[lane], exit[lane]), (t0, t1), "lane {lane}"),
                None => assert!(enter[lane] > exit[lane], "lane {lane}"),
            }
        }
    }

    proptest::proptest! {
        /// The packet clip gives each lane the single ray's clip, at 4 and 16 lanes: on random
        /// rays with zero direction components, origins on the box's faces, boxes far from
        /// the origin and intervals that start behind the origin.
        #[test]
        fn clip_is_the_single_ray_clip(
            seeds in proptest::collection::vec((proptest::array::uniform3(-4.0f32..4.0),
                proptest::array::uniform3(-1.0f32..1.0), proptest::array::uniform3(0u8..4), -2.0f32..1.0), 16),
            corner in proptest::array::uniform3(-2.0f32..2.0), size in proptest::array::uniform3(0.0f32..3.0),
            far_away in proptest::bool::ANY,
        ) {
            let shift = if far_away { 1.0e5 } else { 0.0 };
            proptest::prop_assume!(seeds.iter().all(|s| s.1[2].abs() > 1e-3));
            let lo = Vec3::from(corner) + shift;
            let b = Aabb { min: lo, max: lo + Vec3::from(size) };
            let rays: Vec<Ray> = seeds
                .iter()
                .map(|&(o, d, special, t_min)| {
                    let mut o = Vec3::from(o) + shift;
                    let mut d = Vec3::from(d);
                    // Axes 0 and 1 may lose their direction component, not all three.
                    for a in 0..3 {
                        match special[a] {
                            0 if a < 2 => d[a] = 0.0,
                            1 => o[a] = b.min[a],
                            _ => {}
                        }
                    }
                    Ray::new(o, d, t_min, 10.0)
                })
                .collect();
            let (lo4, hi4) = (b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array());
            let check = |lane: usize, enter: f32, exit: f32| match clip_to_box(&rays[lane], &b) {
                Some((t0, t1)) => enter == t0 && exit == t1,
                None => enter > exit || enter.is_nan() || exit.is_nan(),
            };
            let (enter, exit) = RayPacket::<PortableF32<16>>::from_rays(&rays).clip(lo4, hi4);
            for lane in 0..16 {
                proptest::prop_assert!(check(lane, enter[lane], exit[lane]), "16 lanes, lane {}", lane);
            }
            let (enter, exit) = RayPacket::new(&rays[..4]).clip(lo4, hi4);
            for lane in 0..4 {
                proptest::prop_assert!(check(lane, enter[lane], exit[lane]), "4 lanes, lane {}", lane);
            }
        }
    }

    proptest::proptest! {
        /// The lane widenings are the scalar ones bit for bit (infinities kept, NaN kept NaN),
        /// at 4 and 16 lanes, on random bit patterns: normal, subnormal, huge and special.
        #[test]
        fn lane_widenings_are_the_scalar_ones(bits in proptest::array::uniform16(proptest::num::u32::ANY)) {
            let t: [f32; 16] = bits.map(f32::from_bits);
            let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
            let (up, down) = (widen_up(PortableF32::<16>(t)), widen_down(PortableF32::<16>(t)));
            let (up4, down4) = (widen_up(Vec4::from_slice(&t[..4])), widen_down(Vec4::from_slice(&t[..4])));
            for lane in 0..16 {
                proptest::prop_assert!(same(up[lane], widen_up1(t[lane])), "up {:e}", t[lane]);
                proptest::prop_assert!(same(down[lane], widen_down1(t[lane])), "down {:e}", t[lane]);
            }
            for lane in 0..4 {
                proptest::prop_assert!(same(up4[lane], widen_up1(t[lane])) && same(down4[lane], widen_down1(t[lane])));
            }
        }
    }

    #[test]
    fn widenings_keep_infinities() {
        for t in [f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(widen_up(Vec4::splat(t)), Vec4::splat(t));
            assert_eq!(widen_down(Vec4::splat(t)), Vec4::splat(t));
        }
        assert_eq!(widen_up(Vec4::splat(f32::MAX)), Vec4::splat(f32::INFINITY));
        assert_eq!(widen_down(Vec4::splat(-f32::MAX)), Vec4::splat(f32::NEG_INFINITY));
    }

    #[test]
    fn common_origin_needs_every_valid_lane() {
        let r = rays();
        assert_eq!(RayPacket::new(&r[..2]).common_origin(), Some(r[0].origin));
        assert_eq!(RayPacket::new(&r).common_origin(), None);
        assert!(OmniPacket::new(RayPacket::new(&r[..2])).is_some());
        let behind = Ray::new(r[0].origin, r[0].dir, -1.0, 1.0);
        assert!(OmniPacket::new(RayPacket::new(&[r[0], behind])).is_none());
    }

    #[test]
    fn widening_keeps_infinities() {
        let t = Vec4::new(f32::INFINITY, f32::NEG_INFINITY, 2.0, -2.0);
        let (up, down) = (widen_up(t), widen_down(t));
        assert_eq!(up.to_array()[..2], [f32::INFINITY, f32::NEG_INFINITY]);
        assert_eq!(down.to_array()[..2], [f32::INFINITY, f32::NEG_INFINITY]);
        assert!(up[2] > 2.0 && up[3] > -2.0 && down[2] < 2.0 && down[3] < -2.0);
        assert_eq!((widen_up1(f32::NEG_INFINITY), widen_down1(f32::INFINITY)), (f32::NEG_INFINITY, f32::INFINITY));
    }

    #[test]
    fn record_keeps_other_lanes() {
        let p = RayPacket::new(&rays());
        let mut h = PacketHit::new(&p);
        h.record(BVec4A::new(false, true, false, true), Vec4::splat(2.0), Vec4::splat(0.25), Vec4::splat(0.5), 7);
        assert_eq!(h.get(0), None);
        assert_eq!(h.get(1), Some(Hit { t: 2.0, u: 0.25, v: 0.5, prim: 7 }));
        assert_eq!(h.t[2], 10.0);
    }
}
