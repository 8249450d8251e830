//! Cone proxy traversal of a tile (thesis 4.1.6-4.1.8, Listing 4.5 corrected) and MFT cones
//! (4.1.9).
//!
//! A cone bounds the tile's rays and goes down the kd-tree in their place, as the pyramid
//! frustum does in `packets::frustum`; at the leaves the tile's packets are culled against
//! the leaf's box and intersected exactly as there, so the hits are the single rays' hits.
//! The packets are the tracer's, of any width (`TileTracer<V>`: 2x2 pixels for the default
//! `Vec4`, 4x2 and 4x4 for 8 and 16 lanes): [`trace_cone_wide_with`] and
//! [`trace_mft_cone_wide_with`] take any, the other entry points the 4-wide one. The traversal step is Listing 4.5 with its error fixed: front and back voxels are
//! chosen from `split_minus_o` (the listing reads an undefined `dist`), i.e. from the side of
//! the plane the apex lies on, and an apex *on* the plane visits both children over the whole
//! interval (the listing would compute `0 * k` and see the single point `t = 0`). Listing
//! 4.3's step, `dist * k0`, `dist * k1`, negative values to `+inf`, then min and max, has the
//! very form of the pyramid's step with `1 / lo`, `1 / hi`, so the cone is handed to the same
//! traversal as a [`FrustumBound`] whose factors are Listing 4.4's ([`Cone::factors`]).
//!
//! Distances along a cone are measured along its axis, a ray's hits by its parameter `t`:
//! a point at parameter `t` of a ray `d` inside the cone lies `t |d| cos θ <= t |d|` along the
//! axis, so the bound converts hits with `hit_scale = max |d|` and the root box interval of
//! the rays (from their pyramid) with `min |d| cos α` and `max |d|`.
//!
//! **Which cone.** For a primary tile, the narrowest cone holding the four corner rays of
//! the tile (or of the quadrant, for MFT cones): the rays through a rectangle of the image
//! plane are inside every convex cone holding its corners. It is opened by
//! [`CORNER_MARGIN`] radians for the rounding of the inner rays, which are bounded without
//! being looked at (the per-tile cost of the cone is independent of the tile's size, the
//! thesis's argument for cones). For packets loaded from elsewhere the axis is the rays'
//! mean direction and the angle the widest ray's. A set of directions no cone narrower than
//! [`crate::cone::MAX_HALF_ANGLE`] holds falls back to the pyramid.

use glam::Vec4;
use glam::{DVec3, Vec3};
use kdtree::{Counters, Intersector, KdTree, TreeTest, WaldTest, WatertightTest};
use packets::bound::T_UNDERFLOW;
use packets::simd::{SimdF32, SimdMask};
use packets::triangle4::PacketTest;
use packets::{Frusta, FrustumBound, OmniPacket, PacketTreeTest, TileTracer};
use scenes::{Camera, Tile};

use crate::cone::{Cone, ConeError, angle_between};

/// The angle in radians a primary tile's cone is opened by beyond its corner rays: well
/// above the rounding of a normalised camera ray's direction (a few `1e-7`), well below a
/// pixel's angle at any usable resolution.
pub const CORNER_MARGIN: f64 = 2e-6;

/// How far from 1 a normalised camera ray's length may be, for the distance conversions.
const UNIT_SLACK: f64 = 1e-5;

/// The cone of a primary tile: the narrowest cone from the camera's eye holding the rays of
/// the tile's four corner pixels, opened by [`CORNER_MARGIN`]. A camera with a NaN or
/// infinite field (made by hand; `Camera::look_at` refuses them) is
/// [`ConeError::NotFinite`].
pub fn primary_cone(camera: &Camera, tile: &Tile) -> Result<Cone, ConeError> {
    let (x1, y1) = (tile.x1.saturating_sub(1).max(tile.x0), tile.y1.saturating_sub(1).max(tile.y0));
    let corners = [(tile.x0, tile.y0), (x1, tile.y0), (tile.x0, y1), (x1, y1)].map(|(x, y)| camera.pixel_ray(x, y).1);
    Cone::smallest_enclosing(camera.eye, &corners, CORNER_MARGIN)
}

/// The frustum bound of `cone` (apex at the rays' origin) for rays whose root box interval of
/// ray parameters is `pyramid.near..pyramid.far` and whose direction lengths lie in
/// `len = (min, max)`: Listing 4.4's factors and that interval converted to distances along
/// the axis, moved outwards by the rounding of the parameters it is made of (relative, and
/// [`T_UNDERFLOW`] absolute). NaN in the cone or the pyramid gives a bound with a NaN, which
/// `TileTracer::trace_frusta` replaces by the pyramid.
pub fn cone_bound(cone: &Cone, pyramid: &FrustumBound, len: (f64, f64)) -> FrustumBound {
    let f = cone.factors();
    if is_empty(pyramid) {
        return FrustumBound { k0: f.k0, k1: f.k1, ..*pyramid };
    }
    let cos = 1.0 / (1.0 + cone.tan_alpha * cone.tan_alpha).sqrt();
    // The pyramid's interval is in ray parameters computed in f32: widened relatively, but a
    // parameter that underflowed is off by up to `T_UNDERFLOW` absolutely (a clip exit of
    // 1.7e-46 is 0), which the conversion to distances multiplies by up to `|d|` (a fuzz
    // finding: 1.7e32). Both ends are moved out by it before they are scaled.
    let t_err = f64::from(T_UNDERFLOW);
    let near = f64::from(pyramid.near);
    let near = if near > 0.0 { ((near - t_err).max(0.0) * len.0 * cos * (1.0 - 1e-6)) as f32 } else { pyramid.near };
    let up = |t: f64| if t.is_finite() { (t * (1.0 + 1e-6)) as f32 } else { t as f32 };
    FrustumBound { k0: f.k0, k1: f.k1, near, far: up((f64::from(pyramid.far) + t_err) * len.1), hit_scale: up(len.1) }
}

/// Whether no ray is left in the bound (an empty or NaN interval).
fn is_empty(b: &FrustumBound) -> bool {
    b.near.is_nan() || b.far.is_nan() || b.near > b.far
}

/// Calls `f` with the valid lanes' directions of `packets`, in order. A plain loop, not an
/// iterator adapter: the optimiser may leave an adapter's fold out of line, where the lanes'
/// reads would compile without the kernel's instruction set.
#[inline(always)]
fn for_directions<V: SimdF32>(packets: &[OmniPacket<V>], mut f: impl FnMut(Vec3)) {
    for p in packets {
        let mask = p.rays.valid.bitmask();
        for l in 0..V::LANES {
            if mask >> l & 1 != 0 {
                f(Vec3::new(p.rays.d[0][l], p.rays.d[1][l], p.rays.d[2][l]));
            }
        }
    }
}

/// The cone of loaded packets (mean axis, widest ray) and their direction lengths.
#[inline(always)]
fn loaded_cone<V: SimdF32>(origin: Vec3, packets: &[OmniPacket<V>]) -> Result<(Cone, (f64, f64)), ConeError> {
    let mut sum = DVec3::ZERO;
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for_directions(packets, |d| {
        let d = d.as_dvec3();
        let l = d.length();
        lo = lo.min(l);
        hi = hi.max(l);
        sum += d / l;
    });
    if lo.is_nan() || lo <= 0.0 || !sum.is_finite() || sum.length() == 0.0 {
        return Err(ConeError::ZeroAxis);
    }
    let axis = sum.normalize();
    let mut alpha = 0.0f64;
    for_directions(packets, |d| alpha = alpha.max(angle_between(axis, d.as_dvec3())));
    // The angle is computed in f64 from the rays' own directions; the margin covers its
    // rounding.
    let alpha = alpha * (1.0 + 1e-12) + 1e-12;
    if alpha.is_nan() || alpha > crate::cone::MAX_HALF_ANGLE {
        return Err(ConeError::BadAngle(alpha));
    }
    Ok((Cone::from_tan(origin.as_dvec3(), axis, alpha.tan())?, (lo * (1.0 - 1e-12), hi * (1.0 + 1e-12))))
}

/// The cone of the loaded tile (`q = None`) or of its quadrant `q`, with the rays' direction
/// lengths.
#[inline(always)]
fn tile_cone<V: SimdF32>(tracer: &TileTracer<V>, q: Option<usize>) -> Result<(Cone, (f64, f64)), ConeError> {
    if let Some((camera, tile)) = tracer.primary() {
        let tile = match q {
            None => tile,
            Some(q) => tracer.quadrant_tile(q).ok_or(ConeError::ZeroAxis)?,
        };
        return Ok((primary_cone(camera, &tile)?, (1.0 - UNIT_SLACK, 1.0 + UNIT_SLACK)));
    }
    let packets = match q {
        None => tracer.packets(),
        Some(q) => tracer.quadrant(q),
    };
    loaded_cone(tracer.origin(), packets)
}

/// The frustum of one cone for the whole loaded tile (4.1.8), given its quadrants' root box
/// intervals (from [`TileTracer::prepare_intervals`]), falling back to the quadrants'
/// pyramids where no cone holds its rays.
#[inline(always)]
pub fn tile_cone_frusta<V: SimdF32>(tree: &KdTree, tracer: &mut TileTracer<V>, intervals: &[(f32, f32); 4]) -> Frusta {
    let near = intervals.iter().map(|i| i.0).fold(f32::INFINITY, f32::min);
    let far = intervals.iter().map(|i| i.1).fold(f32::NEG_INFINITY, f32::max);
    match tile_cone(tracer, None) {
        Ok((cone, len)) => Frusta::One(cone_bound(&cone, &interval_bound((near, far)), len)),
        Err(_) => Frusta::Four(packets::simd::array_fn(
            #[inline(always)]
            |q| tracer.pyramid(tree, q),
        )),
    }
}

/// The frusta of the loaded tile's four quadrant cones (4.1.9), given their root box
/// intervals, each falling back to the quadrant's pyramid where no cone holds its rays.
#[inline(always)]
pub fn quadrant_cone_frusta<V: SimdF32>(
    tree: &KdTree,
    tracer: &mut TileTracer<V>,
    intervals: &[(f32, f32); 4],
) -> Frusta {
    Frusta::Four(packets::simd::array_fn(
        #[inline(always)]
        |q| {
            let interval = interval_bound(intervals[q]);
            if is_empty(&interval) {
                return interval;
            }
            match tile_cone(tracer, Some(q)) {
                Ok((cone, len)) => cone_bound(&cone, &interval, len),
                Err(_) => tracer.pyramid(tree, q),
            }
        },
    ))
}

/// A bound with the root box interval `(near, far)` and no factors yet.
fn interval_bound((near, far): (f32, f32)) -> FrustumBound {
    FrustumBound { k0: [0.0; 4], k1: [0.0; 4], near, far, hit_scale: 1.0 }
}

/// Traces the tile loaded in `tracer` (a primary tile or packets sharing one origin) with
/// one cone (4.1.8): the closest hits (any hits in the tracer's any-hit mode), exactly those
/// of single rays. Invalid lanes (rays with NaN or infinite components, see
/// `packets::RayPacket::new`) get no hit and do not shape the cone.
pub fn trace_cone<C: Counters>(tree: &KdTree, tracer: &mut TileTracer, counters: &mut C) {
    match tree.intersector() {
        Intersector::Wald => trace_cone_with::<WaldTest, C>(tree, tracer, counters),
        Intersector::Watertight => trace_cone_with::<WatertightTest, C>(tree, tracer, counters),
    }
}

/// [`trace_cone`] with the tree's triangle test `I`, chosen once by the caller (see
/// [`kdtree::TreeTest`]).
pub fn trace_cone_with<I: PacketTreeTest, C: Counters>(tree: &KdTree, tracer: &mut TileTracer, counters: &mut C) {
    trace_cone_wide_with::<I, Vec4, C>(tree, tracer, counters)
}

/// [`trace_cone_with`] for a tracer of packets of any width (`V::LANES` rays; 4x4 pixels for
/// 16 lanes): the cone is the tile's, only the packets tested at the leaves are wider.
#[inline(always)]
pub fn trace_cone_wide_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    tracer: &mut TileTracer<V>,
    counters: &mut C,
) {
    let intervals = tracer.prepare_intervals_with::<I>(tree);
    let frusta = tile_cone_frusta(tree, tracer, &intervals);
    tracer.trace_frusta_with::<I, C>(tree, &frusta, counters);
}

/// [`trace_cone`] with the tile's four quadrant cones in the lanes of a `Vec4` (MFT cones,
/// 4.1.9).
pub fn trace_mft_cone<C: Counters>(tree: &KdTree, tracer: &mut TileTracer, counters: &mut C) {
    match tree.intersector() {
        Intersector::Wald => trace_mft_cone_with::<WaldTest, C>(tree, tracer, counters),
        Intersector::Watertight => trace_mft_cone_with::<WatertightTest, C>(tree, tracer, counters),
    }
}

/// [`trace_mft_cone`] with the tree's triangle test `I` (see [`kdtree::TreeTest`]).
pub fn trace_mft_cone_with<I: PacketTreeTest, C: Counters>(tree: &KdTree, tracer: &mut TileTracer, counters: &mut C) {
    trace_mft_cone_wide_with::<I, Vec4, C>(tree, tracer, counters)
}

/// [`trace_mft_cone_with`] for a tracer of packets of any width (`V::LANES` rays).
#[inline(always)]
pub fn trace_mft_cone_wide_with<I: TreeTest<Record: PacketTest<V>>, V: SimdF32, C: Counters>(
    tree: &KdTree,
    tracer: &mut TileTracer<V>,
    counters: &mut C,
) {
    let intervals = tracer.prepare_intervals_with::<I>(tree);
    let frusta = quadrant_cone_frusta(tree, tracer, &intervals);
    tracer.trace_frusta_with::<I, C>(tree, &frusta, counters);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pixel ray of every tile lies inside the cone of its corner rays *before* the
    /// margin is added, up to far less than the margin: the margin covers the rounding of the
    /// rays the primary cone does not look at.
    #[test]
    fn corner_cones_hold_every_ray_of_their_tile() {
        let mut worst: f64 = 0.0;
        for (w, h, fov, target) in [
            (64, 64, 60.0, Vec3::new(0.3, -0.2, -1.0)),
            (96, 40, 120.0, Vec3::new(1.0, 0.5, 0.0)),
            (33, 71, 10.0, Vec3::new(0.0, 0.0, 1.0)),
            (50, 50, 170.0, Vec3::new(0.0, -1.0, 0.01)),
        ] {
            let camera =
                Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, 3.0) + target, fov, w, h).unwrap();
            for size in [4, 8, 16, 32] {
                for tile in scenes::tile::tiles(w, h, size) {
                    let (x1, y1) = (tile.x1 - 1, tile.y1 - 1);
                    let corners = [(tile.x0, tile.y0), (x1, tile.y0), (tile.x0, y1), (x1, y1)]
                        .map(|(x, y)| camera.pixel_ray(x, y).1);
                    let bare = Cone::smallest_enclosing(camera.eye, &corners, 0.0).unwrap();
                    for (x, y) in tile.pixels() {
                        let d = camera.pixel_ray(x, y).1.as_dvec3();
                        worst = worst.max(angle_between(bare.axis, d) - bare.half_angle());
                    }
                    let cone = primary_cone(&camera, &tile).unwrap();
                    assert!(tile.pixels().all(|(x, y)| cone.contains(camera.pixel_ray(x, y).1)));
                }
            }
        }
        assert!(worst < CORNER_MARGIN / 4.0, "a ray lies {worst} rad outside its tile's corner cone");
    }

    /// The pyramid's ends are ray parameters that may have underflowed; the cone's ends must
    /// still bound the distances along the axis. The far end is the `traversal` fuzz
    /// finding's: a ray leaving the root box through y = -7.7e-37 from y = 2.9e-14 with
    /// `d.y = -1.66e32`, whose clip exit (exactly 1.75e-46) is computed as 0.
    #[test]
    fn cone_ends_cover_parameters_that_underflowed() {
        let (o, lo, d) = (2.9090455e-14f32, -7.740593e-37f32, -1.6607714e32f32);
        let computed = (lo - o) * (1.0 / d);
        let exact = (f64::from(lo) - f64::from(o)) / f64::from(d);
        assert_eq!(computed, 0.0, "the exit underflows");
        let cone = Cone::from_tan(DVec3::ZERO, DVec3::NEG_Y, 1e-12).unwrap();
        let len = (f64::from(d.abs()), f64::from(d.abs()));
        let pyramid = FrustumBound { k0: [0.0; 4], k1: [0.0; 4], near: 0.0, far: computed, hit_scale: 1.0 };
        let bound = cone_bound(&cone, &pyramid, len);
        assert!(f64::from(bound.far) >= exact * len.1, "far {} < {}", bound.far, exact * len.1);
        // A near end computed as the smallest subnormal, exactly 0.6 of it: the cone's starts
        // at or before the exact distance.
        let exact_near = 0.6 * f64::from(T_UNDERFLOW);
        let pyramid = FrustumBound { near: T_UNDERFLOW, far: 1.0, ..pyramid };
        let bound = cone_bound(&cone, &pyramid, len);
        assert!(f64::from(bound.near) <= exact_near * len.0, "near {} > {}", bound.near, exact_near * len.0);
    }

    #[test]
    fn camera_rays_have_unit_length() {
        let camera = Camera::look_at(Vec3::ZERO, Vec3::new(0.2, 0.1, -1.0), 100.0, 97, 53).unwrap();
        for y in 0..53 {
            for x in 0..97 {
                let l = camera.pixel_ray(x, y).1.as_dvec3().length();
                assert!((l - 1.0).abs() < UNIT_SLACK / 10.0, "{l}");
            }
        }
    }
}
