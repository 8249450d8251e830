//! The bound a frustum of rays goes down the kd-tree with: the pyramid of its extremal rays
//! (thesis 2.3.2, Listing 4.2) or a cone (4.1.7, Listing 4.4, made by the `cones` crate),
//! both in the one form of [`FrustumBound`], and the arithmetic the traversal does with it:
//! the plane interval of a split (Listing 4.2 with modification 1 of 4.1.3), hits converted
//! into the bound's distances, and the pyramid of a run of packets.
//!
//! The pyramid is exact for any ray set: per axis `k`, the smallest and largest direction
//! component over all the rays, `lo[k]` and `hi[k]`. A ray with component `n` in `[lo, hi]`
//! reaches a plane `dist` away at `t = dist / n`, which is monotonic in `n` on each side of
//! 0, so over the rays `t in [min(dist/lo, dist/hi), max(...)]` once negative distances are
//! taken as `+inf` (modification 1; a mixed-sign range gives `+inf` at the top, as it must,
//! since some rays are then parallel to the plane). For unnormalised pinhole rays these
//! extremes are corner rays; for our normalised camera rays an inner ray can hold one (when
//! the axis points into the tile), which the corner rays would miss.

use glam::Vec4;
use kdtree::KdTree;

use crate::packet::{OmniPacket, all_lanes, mask_of, max_lane, min_lane, widen_down, widen_down1, widen_up, widen_up1};
use crate::simd::{SimdF32, SimdMask};

/// The bound a frustum of rays sharing one origin goes down the tree with: at a split plane
/// `dist = split - o[axis]` away from the origin, every ray of the frustum that crosses the
/// plane does so between `min(dist * k0[axis], dist * k1[axis])` and the `max` of the two,
/// negative values taken as `+inf` ([`plane_interval`]), and inside `[near, far]`.
///
/// Two shapes fill it in: the **pyramid** of the extremal rays ([`pyramid`]: `k0 = 1 / lo`,
/// `k1 = 1 / hi`, the per-axis direction extremes, distances in ray parameter `t`) and the
/// **cone** of the `cones` crate (thesis 4.1.7, "cone frustums": Listing 4.4's precomputed
/// values, distances measured along the cone's axis). `hit_scale` converts a ray's hit
/// parameter into the bound's distance: a hit at `t` lies no further than `t * hit_scale`
/// along the bound's measure (1 for the pyramid; for a cone the longest direction among its
/// rays, since a point at parameter `t` of ray `d` is `t |d| cos(angle)` along the axis;
/// the conversion must also cover the rounding of `t`, see [`distance_up`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrustumBound {
    /// First factor per axis (`[x, y, z, 0]`): `1 / lo[k]` for a pyramid.
    pub k0: [f32; 4],
    /// Second factor per axis: `1 / hi[k]` for a pyramid.
    pub k1: [f32; 4],
    /// Start of the interval (`+inf` when no ray is left).
    pub near: f32,
    /// End of the interval (`-inf` when no ray is left).
    pub far: f32,
    /// A bound on `distance / t` for a hit at ray parameter `t` (1 for a pyramid).
    pub hit_scale: f32,
}

impl FrustumBound {
    /// Whether a field is NaN: such a bound holds no ray, and
    /// `TileTracer::trace_frusta` traces with the rays' pyramid instead.
    /// (Infinite fields are meaningful: a factor of `±inf` for a zero direction extreme,
    /// `near = +inf` when no ray is left.)
    pub fn has_nan(&self) -> bool {
        self.k0.iter().chain(&self.k1).any(|k| k.is_nan())
            || self.near.is_nan()
            || self.far.is_nan()
            || self.hit_scale.is_nan()
    }
}

/// Bound on the absolute rounding error of a ray parameter `t` computed in `f32` that
/// underflowed below `f32::MIN_POSITIVE`: the spacing of the subnormals, `2^-149` (the
/// smallest positive `f32`; the error of one rounding is half of it). The relative widening
/// ([`kdtree::traverse::WIDEN`]) adds nothing to such a `t` (`|t| W` rounds to zero), which is
/// harmless while `t` is compared with other parameters rounded alike, but not once `t` is
/// converted into another measure: scaled by a long direction (a cone's `hit_scale`, up to
/// `3e38`) it becomes a large distance. A clip exit of `1.7e-46` rounds to 0 and, times
/// `|d| = 1.7e32`, would put a cone's far end `2.9e-14` short of the ray's (a fuzz finding).
pub const T_UNDERFLOW: f32 = f32::from_bits(1);

/// An upper bound on the distance, along a bound's measure, of a point at a ray parameter
/// computed as `t`, with `scale` the bound's `hit_scale` (`t * scale` when exact):
/// `(t + T_UNDERFLOW) * scale` widened by [`kdtree::traverse::WIDEN`], so that both the
/// parameter's relative rounding and its underflow ([`T_UNDERFLOW`]) are covered.
/// Infinities stay as they are.
#[inline(always)]
pub fn distance_up(t: f32, scale: f32) -> f32 {
    widen_up1((t + T_UNDERFLOW) * scale)
}

/// Marks the lanes of `packets` that miss the tree's root box as finished in `done` (one
/// lane bitmask per packet, bit `l` for lane `l`, no hit), and returns the pyramid bound of
/// the others (thesis 2.3.2, Listing 4.2's extremal rays): per axis the reciprocals of the
/// smallest and largest direction component, and the interval that holds every unfinished
/// ray's clip to the root box. Packets of any width (`V::LANES` rays).
#[inline(always)]
pub fn pyramid<V: SimdF32>(tree: &KdTree, packets: &[OmniPacket<V>], done: &mut [u32]) -> FrustumBound {
    bound_of::<V, true>(tree, packets, done)
}

/// [`pyramid`] without the direction extremes: finishes the lanes of `packets` that miss the
/// root box and returns the interval `(near, far)` of the others' clips to it. What a bound
/// made elsewhere (a cone, thesis 4.1.7) needs from the rays.
#[inline(always)]
pub fn root_interval<V: SimdF32>(tree: &KdTree, packets: &[OmniPacket<V>], done: &mut [u32]) -> (f32, f32) {
    let b = bound_of::<V, false>(tree, packets, done);
    (b.near, b.far)
}

/// [`pyramid`], with the direction extremes only when `DIRS` (else the factors are left 0).
#[inline(always)]
fn bound_of<V: SimdF32, const DIRS: bool>(tree: &KdTree, packets: &[OmniPacket<V>], done: &mut [u32]) -> FrustumBound {
    let b = tree.bounds();
    let (lo_box, hi_box) = (b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array());
    let (mut lo, mut hi) = ([V::INFINITY; 3], [V::NEG_INFINITY; 3]);
    let (mut near_lanes, mut far_lanes) = (V::INFINITY, V::NEG_INFINITY);
    for (packet, done) in packets.iter().zip(done) {
        let rays = &packet.rays;
        let (enter, exit) = rays.clip(lo_box, hi_box);
        let inside = enter.cmple(exit) & !mask_of::<V>(*done);
        *done |= !inside.bitmask() & all_lanes::<V>();
        if !inside.any() {
            continue;
        }
        // Lane-wise accumulation; the horizontal reductions come once at the end.
        near_lanes = near_lanes.min(V::select(inside, enter, V::INFINITY));
        far_lanes = far_lanes.max(V::select(inside, exit, V::NEG_INFINITY));
        if !DIRS {
            continue;
        }
        for a in 0..3 {
            lo[a] = lo[a].min(V::select(inside, rays.d[a], V::INFINITY));
            hi[a] = hi[a].max(V::select(inside, rays.d[a], V::NEG_INFINITY));
        }
    }
    let (k0, k1) = if DIRS {
        let lo = Vec4::new(min_lane(lo[0]), min_lane(lo[1]), min_lane(lo[2]), 0.0);
        let hi = Vec4::new(max_lane(hi[0]), max_lane(hi[1]), max_lane(hi[2]), 0.0);
        (lo.recip().to_array(), hi.recip().to_array())
    } else {
        ([0.0; 4], [0.0; 4])
    };
    FrustumBound { k0, k1, near: min_lane(near_lanes), far: max_lane(far_lanes), hit_scale: 1.0 }
}

/// The plane distances bounding a frustum at a split plane `dist` away from the origin along
/// an axis with factors `k0`, `k1` (see [`FrustumBound`]): `(dmin, dmax)`, negative distances
/// taken as `+inf` (modification 1), widened by a few ulps. `dist` must not be 0.
///
/// A distance is negative when `dist` and the factor have opposite signs, whatever their
/// product rounds to: a product that underflows to -0.0 is still a plane behind the origin
/// (the fuzzer found rays sent to the far side of a plane 2.3e-38 behind their origin, at
/// distance -6e-54, and missing their hit).
#[inline(always)]
pub fn plane_interval(dist: f32, k0: f32, k1: f32) -> (f32, f32) {
    let fix = |k: f32| if (dist > 0.0 && k < 0.0) || (dist < 0.0 && k > 0.0) { f32::INFINITY } else { dist * k };
    let (a, b) = (fix(k0), fix(k1));
    (widen_down1(a.min(b)), widen_up1(a.max(b)))
}

/// [`plane_interval`] of four frusta at once (MFT, thesis 4.1.5), lane `q` with factors
/// `k0[q]`, `k1[q]`: the same arithmetic lane by lane. `dist` must not be 0.
#[inline(always)]
pub fn plane_interval4(dist: f32, k0: Vec4, k1: Vec4) -> (Vec4, Vec4) {
    plane_interval_lanes(dist, k0, k1)
}

/// [`plane_interval`] of `F::LANES` frusta at once (four for MFT, sixteen for a tile split
/// 4 x 4), lane by lane. `dist` must not be 0.
#[inline(always)]
pub fn plane_interval_lanes<F: SimdF32>(dist: f32, k0: F, k1: F) -> (F, F) {
    // Behind the origin by the signs of `dist` and the factor (a product that underflows to
    // -0.0 is still behind).
    let dist_lanes = F::splat(dist);
    let fix = |k: F| {
        let behind = if dist > 0.0 { k.cmplt(F::ZERO) } else { k.cmpgt(F::ZERO) };
        F::select(behind, F::INFINITY, dist_lanes * k)
    };
    let (a, b) = (fix(k0), fix(k1));
    (widen_down(a.min(b)), widen_up(a.max(b)))
}

/// [`distance_up`] of four frusta at once (MFT, thesis 4.1.5), lane by lane.
#[inline(always)]
pub fn distance_up4(t: Vec4, scale: Vec4) -> Vec4 {
    distance_up_lanes(t, scale)
}

/// [`distance_up`] of `F::LANES` frusta at once, lane by lane.
#[inline(always)]
pub fn distance_up_lanes<F: SimdF32>(t: F, scale: F) -> F {
    widen_up((t + F::splat(T_UNDERFLOW)) * scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray parameter computed as `(plane - o) * (1 / d)` in `f32` (as the clips compute
    /// them), against its exact value: once it underflows below `f32::MIN_POSITIVE` the
    /// relative widening adds nothing, and only the absolute term keeps the converted
    /// distance an upper bound.
    #[test]
    fn distances_bound_parameters_that_underflowed() {
        let mut widened_short = 0;
        for i in 0..2000u32 {
            // Origins from 4e-31 down to the subnormals, direction lengths from 1.3 to 2e38:
            // the parameters span both sides of f32::MIN_POSITIVE.
            let o = f32::from_bits(0x0D00_0000 / 2000 * (2000 - i));
            let d = -1.3 * 2f32.powi((i % 127) as i32);
            let (t, exact) = ((0.0 - o) * (1.0 / d), (0.0 - f64::from(o)) / f64::from(d));
            assert!(t >= 0.0 && exact > 0.0);
            let scale = d.abs();
            let bound = f64::from(distance_up(t, scale));
            assert!(bound >= exact * f64::from(scale), "t = {t:e} (exact {exact:e}), |d| = {scale:e}");
            // Without the absolute term some of them fall short.
            widened_short += usize::from(f64::from(widen_up1(t * scale)) < exact * f64::from(scale));
        }
        assert!(widened_short > 0, "the cases include underflowed parameters");
        assert_eq!(distance_up(f32::INFINITY, 3.0), f32::INFINITY);
        assert_eq!(distance_up(f32::NEG_INFINITY, 3.0), f32::NEG_INFINITY);
        assert_eq!(distance_up(0.0, 1.0), T_UNDERFLOW, "at least one subnormal spacing");
        // Normal parameters: the absolute term is below their rounding.
        assert_eq!(distance_up(1.0, 1.0), widen_up1(1.0));
    }
}
